/* echo: every data frame on 600..67F comes back on its ID + 80 with the same data; each one
 * is shown on the terminal. Runs until a reset. */
        .include "board.h"

        .section .text.start
        .globl _start
_start:
        bl      term_init
        bl      sja_init_pelican
        lis     r3,banner@h
        ori     r3,r3,banner@l
        bl      puts
loop:
        bl      receive_trame
        cmpwi   r6,0
        beq     loop
        bl      echo_frame
        b       loop

        .section .rodata
banner:
        .asciz  "\r\necho: data frames on 600..67F come back on ID + 80\r\n"
