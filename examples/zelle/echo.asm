; echo.asm: answers every byte the host sends with the byte plus one, through the OS's
; routines Empf (0033h: waits for a byte, returns it in A) and Sende (0030h: sends A).
; A "q" ends it: RET from the outermost level returns to the OS (program mode kept, so RESET
; runs it again). Inside Empf a 0 is data, not a stop (seed 003): "q" is the way out, or the
; START key held ~5 s after a RESET. Send a byte, wait for its answer, send the next: while the
; program is in Sende the 8051's one-byte receive buffer may lose a second byte, and a 0 that
; comes then stops the program as Sende returns (only Empf takes a 0 as data).
; Build: as31 echo.asm (echo.hex).

        .equ    sende, 0x0030
        .equ    empf, 0x0033

        .org    0x0400
loop:   lcall   empf            ; A = the next byte from the host
        cjne    a, #0x71, answer ; "q"?
        ret                     ; back to the OS
answer: inc     a
        lcall   sende
        sjmp    loop
