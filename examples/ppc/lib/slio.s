/* The seed's SLIO library (002 §4.2, slio.s), rewritten for this board. */
        .include "board.h"
        .include "sja1000.h"
        .include "rwsja.h"
        .include "stack.h"

        .text
        .globl calibration_slio, send_calibration, make_slio_ffi, wr_reg_slio, test_slio_id

/* calibration_slio: the 48 calibration frames (ID 0AA, AA 04) of the seed, each aborted once it
 * is on the wire (nobody acknowledges them before the SLIOs are calibrated). GPRs kept. */
calibration_slio:
        pushlr
        push    r3
        push    r4
        li      r4,48
1:      rdsja   STATUS,r3
        andi.   r3,r3,0x04              /* transmit buffer free? */
        beq     1b
        wrsjai  0x40,TX_ID_2_S
        wrsjai  0x15,TX_ID_1_S
        wrsjai  0x02,TX_FRAME_INFO
        wrsjai  0xAA,TX_DATA_S
        wrsjai  0x04,TX_DATA_S+1
2:      rdsja   STATUS,r3               /* the previous transmission is over */
        andi.   r3,r3,0x20
        bne     2b
        wrsjai  0x01,COMMAND            /* transmission request */
3:      rdsja   STATUS,r3               /* it has started */
        andi.   r3,r3,0x20
        beq     3b
        wrsjai  0x02,COMMAND            /* abort: one attempt only */
        subic.  r4,r4,1
        bne     2b
        pop     r4
        pop     r3
        poplr
        blr

/* send_calibration: one calibration frame, sent as any frame (retried until acknowledged):
 * calibrated SLIOs need one at least every 8192 bit-times or they must be calibrated again. */
send_calibration:
        pushlr
        push    r3
        push    r4
        push    r5
        lis     r3,0x0002               /* DLC 2 */
        ori     r3,r3,0x1540            /* ID 0AA */
        lis     r4,0xAA04
        li      r5,0
        bl      send_trame
        pop     r5
        pop     r4
        pop     r3
        poplr
        blr

/* make_slio_ffi: r3 = a 3-byte frame to SLIO r6 (0..15), on its command identifier
 * 0 1 P3 1 0 P2 P1 P0 1 0 0. GPRs changed: r3. */
make_slio_ffi:
        push    r6
        andi.   r6,r6,0x0F
        lis     r3,0x0003               /* DLC 3 */
        ori     r3,r3,0x5080            /* the fixed bits, DIR 0 */
        push    r6
        andi.   r6,r6,0x07              /* P2 P1 P0 -> ID.5..3 */
        slwi    r6,r6,8
        or      r3,r3,r6
        pop     r6
        andi.   r6,r6,0x08              /* P3 -> ID.8 */
        slwi    r6,r6,10
        or      r3,r3,r6
        pop     r6
        blr

/* wr_reg_slio: r4 = register r6 and value r7 (16 bits, high byte first), r5 = 0: the data of
 * a write to a SLIO register. GPRs changed: r4, r5. */
wr_reg_slio:
        push    r7
        andi.   r7,r7,0xFFFF
        slwi    r7,r7,8
        slwi    r4,r6,24
        or      r4,r4,r7
        li      r5,0
        pop     r7
        blr

/* test_slio_id: r6 = 1 and r7 = the SLIO's number if the frame in r3 comes from a SLIO (its
 * reply identifier), else r6 = 0. GPRs changed: r6, r7. */
test_slio_id:
        andi.   r6,r3,0xD8E0            /* the fixed bits of the identifier */
        cmpwi   r6,0x50A0
        bne     1f
        andi.   r6,r3,0x0700            /* P2 P1 P0 */
        srwi    r6,r6,8
        andi.   r7,r3,0x2000            /* P3 */
        srwi    r7,r7,10
        or      r7,r7,r6
        li      r6,1
        blr
1:      li      r6,0
        blr
