; checksum.a51's loop with the peripherals busy: timer 0 interrupts every 100 machine cycles
; (mode 2), the UART sends at 9600 baud without a pause from its own interrupt, timer 1 is
; the baud generator. Loops at `done` (005Fh). Assembled with as31 into busy.hex.
        .equ    passes, 255
        .org    0
        ljmp    main
        .org    0x0b
        inc     r4              ; timer 0: count ticks
        reti
        .org    0x23
        clr     ti              ; serial: send the tick count
        mov     sbuf, r4
        reti
        .org    0x30
main:   mov     tmod, #0x22
        mov     th0, #156       ; 256 - 100
        mov     th1, #0xfd
        mov     tl1, #0xfd
        mov     tcon, #0x50     ; TR1, TR0
        mov     scon, #0x40
        mov     ie, #0x92       ; EA, ES, ET0
        mov     sbuf, #0
        mov     r7, #passes
pass:   mov     dptr, #0
        mov     r5, #8
page:   mov     r6, #0
octet:  movx    a, @dptr
        add     a, r2
        mov     r2, a
        clr     a
        addc    a, r3
        xrl     a, r2
        mov     r3, a
        inc     dptr
        djnz    r6, octet
        djnz    r5, page
        djnz    r7, pass
done:   sjmp    done
