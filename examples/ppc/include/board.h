/* The buslab PowerPC 403 board (docs/loader.md, "The board"): a PPC403GA at 25 MHz. */
        .equ CPU_HZ,        25000000

/* The 403GA's on-chip serial port (SPU): the VT100 terminal of MoniCAN, 19200 baud 8N1. */
        .equ SPU,           0x40000000
        .equ SPLS,          0           /* line status: read, write 1s to clear */
        .equ SPHS,          2
        .equ BRDH,          4
        .equ BRDL,          5
        .equ SPCTL,         6
        .equ SPRC,          7
        .equ SPTC,          8
        .equ SPRB,          9           /* receive buffer (read) */
        .equ SPTB,          9           /* transmit buffer (write) */
        .equ SPLS_RBR,      0x80        /* a received byte waits */
        .equ SPLS_TBR,      0x04        /* the transmit buffer is free */
        .equ SPCTL_8N1,     0x38        /* DTR, RTS, 8 data bits, no parity, 1 stop bit */
        .equ SPRC_ER,       0x80        /* enable the receiver */
        .equ SPTC_ET,       0x80        /* enable the transmitter */
        .equ BRD_19200,     80          /* 25 MHz / (16 * (80 + 1)) = 19290 baud */

/* The time base's low word (mfspr rD,TBLO): counts CPU cycles. */
        .equ TBLO,          989
        .equ TBHI,          988

/* Bus timing for the bus the program joins (the lab's 125 kbit/s by default; build.sh sets
 * BITRATE): the SJA1000's crystal is 16 MHz. The seed's 0x07/0x4D (§4.1.2.1) give 20 us bits,
 * its 50 kbit/s bus. */
        .ifndef BITRATE
        .equ BITRATE, 125000
        .endif
        .if BITRATE == 125000
        .equ BTR0_VALUE, 0x83           /* BRP 4: 0.5 us quanta, SJW 3 */
        .equ BTR1_VALUE, 0x67           /* TSEG1 8, TSEG2 7: 16 quanta, sample point 56 % (MoniCAN's) */
        .elseif BITRATE == 50000
        .equ BTR0_VALUE, 0x07
        .equ BTR1_VALUE, 0x4D
        .else
        .error "BITRATE: 125000 (the lab) or 50000 (the seed's bus)"
        .endif
