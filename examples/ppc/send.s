/* send: initialises the SJA1000 the seed's way, sends 123#5050433430 33 ("PPC403"), waits
 * until it is on the wire, says so on the terminal and returns to the firmware. */
        .include "board.h"
        .include "sja1000.h"
        .include "rwsja.h"

        .section .text.start
        .globl _start
_start:
        bl      term_init
        bl      sja_init_pelican
        lis     r3,0x0006               /* DLC 6 */
        ori     r3,r3,0x2460            /* ID 123: ID1 24, ID2 60 */
        lis     r4,0x5050               /* "PP" */
        ori     r4,r4,0x4334            /* "C4" */
        lis     r5,0x3033               /* "03" */
        bl      send_trame
1:      rdsja   STATUS,r6               /* transmission complete */
        andi.   r6,r6,0x08
        beq     1b
        lis     r3,sent@h
        ori     r3,r3,sent@l
        bl      puts
        li      r0,1                    /* exit(0) */
        li      r3,0
        sc

        .section .rodata
sent:
        .asciz  "\r\nsent 123#505043343033 (PPC403)\r\n"
