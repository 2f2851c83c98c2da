; CPU-bound: a running 16-bit checksum over the 2 KiB of external memory from 0000h
; (the program itself and what follows), `passes` times; then it loops at `done` (0017h).
; 12 machine cycles and 9 instructions a byte, no branch that depends on the data.
; Assembled with as31 into checksum.hex (tests/bench_program.rs checks they agree).
        .equ    passes, 255
        .org    0
start:  mov     r7, #passes
pass:   mov     dptr, #0
        mov     r5, #8          ; 8 pages of 256 bytes
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
