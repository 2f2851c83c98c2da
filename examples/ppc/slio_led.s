/* slio_led: calibrates the SLIOs (the seed's calibration_slio), makes SLIO A's pins outputs and
 * lights LED P7 of its demo board, says so on the terminal once the SLIO confirmed it, then
 * keeps the SLIOs calibrated (a calibration frame every 20 ms) until a reset. */
        .include "board.h"

        .equ PERIOD, CPU_HZ / 50        /* 20 ms */

        .section .text.start
        .globl _start
_start:
        bl      term_init
        bl      sja_init_pelican
        lis     r3,calibrating@h
        ori     r3,r3,calibrating@l
        bl      puts
        bl      calibration_slio
        bl      light_led               /* ends with a calibration frame */
        li      r0,4                    /* write(1, lit, lit_len), sent by the firmware while */
        li      r3,1                    /* the program keeps the SLIOs calibrated */
        lis     r4,lit@h
        ori     r4,r4,lit@l
        li      r5,lit_end-lit
        sc
        bl      keep_calibrated         /* never returns */

        .text
/* keep_calibrated: a calibration frame every 20 ms; received frames are read and dropped. */
        .globl keep_calibrated
keep_calibrated:
        bl      time_now
        mr      r9,r3
1:      bl      receive_trame
        bl      time_now
        subf    r3,r9,r3
        lis     r8,PERIOD@h
        ori     r8,r8,PERIOD@l
        cmplw   r3,r8
        blt     1b
        bl      send_calibration
        b       keep_calibrated

        .section .rodata
calibrating:
        .asciz  "\r\nslio_led: calibrating the SLIOs (48 frames on 0AA)\r\n"
lit:
        .ascii  "SLIO A: outputs enabled, LED P7 lit (DATA_OUTPUT = 2080)\r\n"
lit_end:
