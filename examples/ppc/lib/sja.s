/* The seed's SJA1000 routines (002 §4.1.2), rewritten for this board.
 * A frame is three registers, the seed's format: r3 = frame information << 16 | ID1 << 8 | ID2
 * (an 11-bit ID: ID1 = ID >> 3, ID2 = (ID & 7) << 5; the information byte holds RTR and the
 * DLC), r4 = data bytes 1..4 (byte 1 in the high byte), r5 = data bytes 5..8. */
        .include "board.h"
        .include "sja1000.h"
        .include "rwsja.h"
        .include "stack.h"

        .text
        .globl sja_init_pelican, receive_trame, send_trame, send_trame_sans_verif

/* sja_init_pelican: reset mode, PeliCAN, every frame accepted, the bus timing, output control
 * 0xDB, interrupts off, then normal mode. GPRs changed: r2. */
sja_init_pelican:
        push    r3
1:      wrsjai  0x01,MODE               /* reset mode */
        rdsja   MODE,r3
        andi.   r3,r3,0x01
        beq     1b
2:      wrsjai  0x80,CLOCK_DIVIDER      /* PeliCAN (bit 7) */
        rdsja   CLOCK_DIVIDER,r3
        andi.   r3,r3,0x80
        beq     2b
        wrsjai  0xFF,ACCEPTANCE_MASK_0  /* accept everything */
        wrsjai  0xFF,ACCEPTANCE_MASK_1
        wrsjai  0xFF,ACCEPTANCE_MASK_2
        wrsjai  0xFF,ACCEPTANCE_MASK_3
        wrsjai  BTR0_VALUE,BUS_TIMING_0
        wrsjai  BTR1_VALUE,BUS_TIMING_1
        wrsjai  0x00,INTERRUPT_ENABLE
        wrsjai  0xDB,OUTPUT_CONTROL
3:      wrsjai  0x08,MODE               /* leave reset: single acceptance filter, not listen-only */
        rdsja   MODE,r3
        andi.   r3,r3,0x01
        bne     3b
        pop     r3
        blr

/* receive_trame: the next frame of the receive buffer into r3, r4, r5 (r6 = 1), or r6 = 0 when
 * the buffer is empty. GPRs changed: r2..r6. */
receive_trame:
        rdsja   STATUS,r6
        andi.   r6,r6,0x01              /* receive buffer status */
        beqlr
        rdsja   RX_FRAME_INFO,r3
        slwi    r3,r3,8
        rdsja   RX_ID_1_S,r6
        or      r3,r3,r6
        slwi    r3,r3,8
        rdsja   RX_ID_2_S,r6
        or      r3,r3,r6
        rdsja   RX_DATA_S,r4
        slwi    r4,r4,8
        rdsja   RX_DATA_S+1,r6
        or      r4,r4,r6
        slwi    r4,r4,8
        rdsja   RX_DATA_S+2,r6
        or      r4,r4,r6
        slwi    r4,r4,8
        rdsja   RX_DATA_S+3,r6
        or      r4,r4,r6
        rdsja   RX_DATA_S+4,r5
        slwi    r5,r5,8
        rdsja   RX_DATA_S+5,r6
        or      r5,r5,r6
        slwi    r5,r5,8
        rdsja   RX_DATA_S+6,r6
        or      r5,r5,r6
        slwi    r5,r5,8
        rdsja   RX_DATA_S+7,r6
        or      r5,r5,r6
        wrsjai  0x04,COMMAND            /* release the receive buffer */
        li      r6,1
        rdsja   STATUS,r2               /* a data overrun is cleared */
        andi.   r2,r2,0x02
        beqlr
        wrsjai  0x08,COMMAND
        blr

/* send_trame: waits until the transmit buffer is free, then sends r3, r4, r5. */
send_trame:
        push    r3
1:      rdsja   STATUS,r3
        andi.   r3,r3,0x04              /* transmit buffer status */
        beq     1b
        pop     r3
        /* falls through */

/* send_trame_sans_verif: sends r3, r4, r5 without waiting for the transmit buffer (it may
 * overwrite a frame not yet sent). r3, r4, r5 are kept. GPRs changed: r2. */
send_trame_sans_verif:
        push    r3
        wrsja   r3,TX_ID_2_S
        srwi    r3,r3,8
        wrsja   r3,TX_ID_1_S
        srwi    r3,r3,8
        wrsja   r3,TX_FRAME_INFO
        mr      r3,r4
        wrsja   r3,TX_DATA_S+3
        srwi    r3,r3,8
        wrsja   r3,TX_DATA_S+2
        srwi    r3,r3,8
        wrsja   r3,TX_DATA_S+1
        srwi    r3,r3,8
        wrsja   r3,TX_DATA_S
        mr      r3,r5
        wrsja   r3,TX_DATA_S+7
        srwi    r3,r3,8
        wrsja   r3,TX_DATA_S+6
        srwi    r3,r3,8
        wrsja   r3,TX_DATA_S+5
        srwi    r3,r3,8
        wrsja   r3,TX_DATA_S+4
        wrsjai  0x01,COMMAND            /* transmission request */
        pop     r3
        blr
