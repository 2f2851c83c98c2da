/* The stack macros the seed's routines use (push, pop, pushlr, poplr) but do not show: a full
 * descending stack on r1, one word per push. pushlr/poplr go through r0. */
        .macro push r
        stwu    \r,-4(r1)
        .endm

        .macro pop r
        lwz     \r,0(r1)
        addi    r1,r1,4
        .endm

        .macro pushlr
        mflr    r0
        stwu    r0,-4(r1)
        .endm

        .macro poplr
        lwz     r0,0(r1)
        addi    r1,r1,4
        mtlr    r0
        .endm
