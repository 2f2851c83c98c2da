/* The terminal on the 403GA's serial port (SPU), 19200 baud 8N1, by polling. */
        .include "board.h"
        .include "stack.h"

        .text
        .globl term_init, putc, puts, puthex, time_now

/* term_init: baud rate, 8N1, transmitter and receiver on. GPRs changed: r10, r11. */
term_init:
        lis     r10,SPU@h
        li      r11,0
        stb     r11,BRDH(r10)
        li      r11,BRD_19200
        stb     r11,BRDL(r10)
        li      r11,SPCTL_8N1
        stb     r11,SPCTL(r10)
        li      r11,SPTC_ET
        stb     r11,SPTC(r10)
        li      r11,SPRC_ER
        stb     r11,SPRC(r10)
        blr

/* putc: sends the byte r3 once the transmit buffer is free. GPRs changed: r10, r11. */
putc:
        lis     r10,SPU@h
1:      lbz     r11,SPLS(r10)
        andi.   r11,r11,SPLS_TBR
        beq     1b
        stb     r3,SPTB(r10)
        blr

/* puts: sends the NUL-terminated string at r3. GPRs changed: r3, r10..r12. */
puts:
        pushlr
        addi    r12,r3,-1
1:      lbzu    r3,1(r12)
        cmpwi   r3,0
        beq     2f
        bl      putc
        b       1b
2:      poplr
        blr

/* puthex: sends the low r4 hex digits of r3 (r4 = 1..8). GPRs changed: r10..r12. */
puthex:
        pushlr
        push    r3
        push    r4
        push    r13
        mr      r13,r3
        mtctr   r4
        slwi    r4,r4,2                 /* the first digit's shift: 4 * (digits - 1) */
        addi    r4,r4,-4
1:      srw     r3,r13,r4
        andi.   r3,r3,0x0F
        cmpwi   r3,10
        blt     2f
        addi    r3,r3,'A'-'0'-10
2:      addi    r3,r3,'0'
        bl      putc
        addi    r4,r4,-4
        bdnz    1b
        pop     r13
        pop     r4
        pop     r3
        poplr
        blr

/* time_now: r3 = the time base's low word (CPU cycles, 25 per microsecond). */
time_now:
        mfspr   r3,TBLO
        blr
