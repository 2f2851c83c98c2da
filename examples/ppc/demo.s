/* demo: what the PowerPC node can do once a program runs on it (issue 30's acceptance):
 * a banner on MoniCAN's terminal, the SJA1000 initialised the seed's way, 123#505043343033
 * ("PPC403") sent, the SLIOs calibrated and LED P7 of demo board A lit, then until a reset:
 * a calibration frame every 20 ms (the SLIOs stay calibrated), data frames on 600..67F echoed
 * on ID + 80, keys typed on the terminal echoed back. */
        .include "board.h"
        .include "sja1000.h"
        .include "rwsja.h"

        .equ PERIOD, CPU_HZ / 50        /* 20 ms */

        .section .text.start
        .globl _start
_start:
        bl      term_init
        lis     r3,banner@h
        ori     r3,r3,banner@l
        bl      puts
        bl      sja_init_pelican
        lis     r3,0x0006               /* 123#505043343033, DLC 6 */
        ori     r3,r3,0x2460
        lis     r4,0x5050
        ori     r4,r4,0x4334
        lis     r5,0x3033
        bl      send_trame
        lis     r3,sent@h
        ori     r3,r3,sent@l
        bl      puts
        bl      calibration_slio
        bl      light_led               /* ends with a calibration frame */
        bl      time_now
        mr      r16,r3                  /* the last calibration frame */
        li      r0,4                    /* write(1, lit, lit_len): the firmware sends it while */
        li      r3,1                    /* the program goes on (the SLIOs' watchdog runs) */
        lis     r4,lit@h
        ori     r4,r4,lit@l
        li      r5,lit_end-lit
        sc
loop:
        bl      receive_trame
        cmpwi   r6,0
        beq     1f
        bl      echo_frame
1:      lis     r10,SPU@h               /* a key? */
        lbz     r11,SPLS(r10)
        andi.   r11,r11,SPLS_RBR
        beq     2f
        lbz     r3,SPRB(r10)
        bl      putc
2:      bl      time_now
        subf    r3,r16,r3
        lis     r8,PERIOD@h
        ori     r8,r8,PERIOD@l
        cmplw   r3,r8
        blt     loop
        bl      send_calibration
        bl      time_now
        mr      r16,r3
        b       loop

        .section .rodata
banner:
        .asciz  "\r\n*** buslab PowerPC 403 demo (examples/ppc/demo.s) ***\r\n"
sent:
        .asciz  "SJA1000 initialised (PeliCAN, accept all); sent 123#505043343033\r\n"
lit:
        .ascii  "SLIO A: LED P7 lit. Frames on 600..67F are echoed on ID + 80; keys are echoed.\r\n"
lit_end:
