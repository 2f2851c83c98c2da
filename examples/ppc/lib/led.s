/* light_led: LED P7 of the lab's demo board A, confirmed by the SLIO (slio_led.s, demo.s). */
        .include "board.h"

        .equ SLIO, 0x0A                 /* the lab's demo board A */
        .equ OUTPUT_ENABLE_REG, 4
        .equ DATA_OUTPUT_REG, 3
        .equ PERIOD, CPU_HZ / 50        /* 20 ms */

        .text
/* light_led: SLIO A's outputs enabled (the demo board's 3F90), then DATA_OUTPUT = 2080 (P13,
 * the input selection, and LED P7), each write repeated until the SLIO answers it; ends with
 * a calibration frame. */
        .globl light_led
light_led:
        mflr    r0
        stwu    r0,-4(r1)
        li      r6,OUTPUT_ENABLE_REG
        li      r7,0x3F90
        bl      write_slio
        li      r6,DATA_OUTPUT_REG
        li      r7,0x2080
        bl      write_slio
        /* A calibration frame now: the SLIOs' 8192 bit-times (65 ms at 125 kbit/s) start
         * again, so the caller may spend a few tens of milliseconds (a line on the terminal
         * takes 0.5 ms a character) before its own periodic calibration. */
        bl      send_calibration
        lwz     r0,0(r1)
        addi    r1,r1,4
        mtlr    r0
        blr

/* write_slio: register r6 of SLIO A := r7, sent again every 20 ms until the SLIO's reply with
 * that register arrives, each time after a calibration frame (some of calibration_slio's 48
 * may have lost arbitration on a busy bus and been aborted: the SLIO then waits for one more,
 * and the others keep theirs). GPRs changed: r2..r9, r14, r15. */
write_slio:
        mflr    r0
        stwu    r0,-4(r1)
        mr      r14,r6
        mr      r15,r7
1:      bl      send_calibration        /* a SLIO still calibrating needs one to answer */
        mr      r6,r14
        bl      wr_reg_slio             /* r4, r5 = the data */
        li      r6,SLIO
        bl      make_slio_ffi           /* r3 = the frame's information and ID */
        bl      send_trame
        bl      time_now
        mr      r9,r3
2:      bl      receive_trame
        cmpwi   r6,0
        beq     3f
        bl      test_slio_id
        cmpwi   r6,0
        beq     3f
        cmpwi   r7,SLIO
        bne     3f
        rlwinm  r8,r4,8,28,31           /* the reply's register (low nibble of byte 1) */
        cmpw    r8,r14
        beq     4f
3:      bl      time_now
        subf    r3,r9,r3
        lis     r8,PERIOD@h
        ori     r8,r8,PERIOD@l
        cmplw   r3,r8
        blt     2b
        mr      r7,r15
        b       1b
4:      lwz     r0,0(r1)
        addi    r1,r1,4
        mtlr    r0
        blr

