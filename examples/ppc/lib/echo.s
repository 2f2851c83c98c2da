/* echo_frame: the echo of echo.s and demo.s. */
        .include "board.h"

        .text
/* echo_frame: the frame in r3, r4, r5 sent back on ID + 80 if it is a data frame on 600..67F.
 * GPRs changed: r2..r12. */
        .globl echo_frame
echo_frame:
        mflr    r0
        stwu    r0,-4(r1)
        rlwinm  r7,r3,27,21,31          /* the 11-bit ID */
        andis.  r6,r3,0x00C0            /* remote or extended frames: not echoed */
        bne     9f
        cmplwi  r7,0x600
        blt     9f
        cmplwi  r7,0x67F
        bgt     9f
        addi    r3,r3,0x80<<5           /* ID + 80 */
        bl      send_trame
        mr      r20,r3
        lis     r3,echoed@h
        ori     r3,r3,echoed@l
        bl      puts
        addi    r3,r7,0x80
        li      r4,3
        bl      puthex
        li      r3,'\r'
        bl      putc
        li      r3,'\n'
        bl      putc
9:      lwz     r0,0(r1)
        addi    r1,r1,4
        mtlr    r0
        blr

        .section .rodata
echoed:
        .asciz  "echoed on "
