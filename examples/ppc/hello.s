/* hello: text on MoniCAN's terminal, once through the serial port and once through the
 * firmware's write service, then back to the firmware with exit(0). */
        .include "board.h"

        .section .text.start
        .globl _start
_start:
        bl      term_init
        lis     r3,greeting@h
        ori     r3,r3,greeting@l
        bl      puts
        li      r0,4                    /* write(1, service, service_len) */
        li      r3,1
        lis     r4,service@h
        ori     r4,r4,service@l
        li      r5,service_end-service
        sc
        li      r0,1                    /* exit(0) */
        li      r3,0
        sc

        .section .rodata
greeting:
        .asciz  "\r\nHello from the PowerPC 403, through its serial port.\r\n"
service:
        .ascii  "And through the firmware's write service (sc).\r\n"
service_end:
