/* SJA1000 registers in PeliCAN mode (the names of the seed's sja1000.h, 002 §4.1). */
        .equ MODE,              0
        .equ COMMAND,           1
        .equ STATUS,            2
        .equ INTERRUPT,         3
        .equ INTERRUPT_ENABLE,  4
        .equ BUS_TIMING_0,      6
        .equ BUS_TIMING_1,      7
        .equ OUTPUT_CONTROL,    8
        .equ ACCEPTANCE_CODE_0, 16
        .equ ACCEPTANCE_CODE_1, 17
        .equ ACCEPTANCE_CODE_2, 18
        .equ ACCEPTANCE_CODE_3, 19
        .equ ACCEPTANCE_MASK_0, 20
        .equ ACCEPTANCE_MASK_1, 21
        .equ ACCEPTANCE_MASK_2, 22
        .equ ACCEPTANCE_MASK_3, 23
        /* Standard frames (_S): frame information, two ID bytes, then the data. */
        .equ TX_FRAME_INFO,     16
        .equ TX_ID_1_S,         17
        .equ TX_ID_2_S,         18
        .equ TX_DATA_S,         19
        .equ RX_FRAME_INFO,     16
        .equ RX_ID_1_S,         17
        .equ RX_ID_2_S,         18
        .equ RX_DATA_S,         19
        .equ RX_MESSAGE_COUNTER, 29
        .equ CLOCK_DIVIDER,     31
