; blink.asm: the ZELLE cell's LED (P1.0, lit while low) on for 100 ms, off for 100 ms, forever.
; Timer 0 in mode 1 counts 10 ms (9216 machine cycles at 11.0592 MHz) per overflow; timer 1
; stays as the OS set it (the 9600-baud generator), so the line keeps working.
; Build: as31 blink.asm (blink.hex); load: buslab zelle -p PTY load blink.hex; run; stop.
; A 0 on the line stops it: the program never masks the OS's RxD interrupt.

        .org    0x0400
start:  mov     tmod, #0x21     ; timer 0: mode 1 (16 bit); timer 1: mode 2 (baud), kept
toggle: cpl     p1.0            ; the LED
        mov     r7, #10         ; 10 x 10 ms
tick:   mov     th0, #0xDC      ; 65536 - 9216 = DC00h
        mov     tl0, #0x00
        clr     tf0
        setb    tr0
wait:   jnb     tf0, wait
        clr     tr0
        djnz    r7, tick
        sjmp    toggle
