/* Reading and writing SJA1000 registers through the card's two ports (seed 002 §3.1.2.1):
 * r18 holds the address port (CS5), r19 the data port (CS6); the loader sets both before it
 * jumps to the program. r2 is the macros' scratch register. */

/* wrsjai d, r: write the constant d to register r. */
        .macro wrsjai d, r
        li      r2,\r
        stb     r2,0(r18)
        li      r2,\d
        stb     r2,0(r19)
        .endm

/* wrsja p1, p2: write the low byte of GPR p1 to register p2. */
        .macro wrsja p1, p2
        li      r2,\p2
        stb     r2,0(r18)
        stb     \p1,0(r19)
        .endm

/* rdsja p1, p2: read register p1 into the low byte of GPR p2 (zero-extended). */
        .macro rdsja p1, p2
        li      r2,\p1
        stb     r2,0(r18)
        lbz     \p2,0(r19)
        .endm
