//! Special function register addresses and bits of the 80C51 (the 8051 with IDLE and
//! power-down). Addresses 80h..FFh not listed here hold no register: reads give
//! [`UNIMPLEMENTED_READ`], writes go nowhere. The reserved bits of the registers that exist
//! (IE.6..5, IP.7..5, PCON.6..4) keep what was written.

/// Port 0.
pub const P0: u8 = 0x80;
/// Stack pointer.
pub const SP: u8 = 0x81;
/// Data pointer, low byte.
pub const DPL: u8 = 0x82;
/// Data pointer, high byte.
pub const DPH: u8 = 0x83;
/// Power control: SMOD, GF1, GF0, PD, IDL.
pub const PCON: u8 = 0x87;
/// Timer control: TF1 TR1 TF0 TR0 IE1 IT1 IE0 IT0.
pub const TCON: u8 = 0x88;
/// Timer mode: GATE C/T M1 M0 of timer 1 (high nibble) and timer 0.
pub const TMOD: u8 = 0x89;
/// Timer 0, low byte.
pub const TL0: u8 = 0x8A;
/// Timer 1, low byte.
pub const TL1: u8 = 0x8B;
/// Timer 0, high byte.
pub const TH0: u8 = 0x8C;
/// Timer 1, high byte.
pub const TH1: u8 = 0x8D;
/// Port 1.
pub const P1: u8 = 0x90;
/// Serial control: SM0 SM1 SM2 REN TB8 RB8 TI RI.
pub const SCON: u8 = 0x98;
/// Serial buffer: writes send, reads give the last byte received.
pub const SBUF: u8 = 0x99;
/// Port 2.
pub const P2: u8 = 0xA0;
/// Interrupt enable: EA - - ES ET1 EX1 ET0 EX0.
pub const IE: u8 = 0xA8;
/// Port 3: RxD TxD INT0 INT1 T0 T1 WR RD (bits 0..7).
pub const P3: u8 = 0xB0;
/// Interrupt priority: - - - PS PT1 PX1 PT0 PX0.
pub const IP: u8 = 0xB8;
/// Program status word: CY AC F0 RS1 RS0 OV F1 P.
pub const PSW: u8 = 0xD0;
/// Accumulator.
pub const ACC: u8 = 0xE0;
/// B register.
pub const B: u8 = 0xF0;

/// What a read of an address with no register behind it gives (open bus).
pub const UNIMPLEMENTED_READ: u8 = 0xFF;

/// PSW bits.
pub mod psw {
    /// Carry.
    pub const CY: u8 = 0x80;
    /// Auxiliary carry (out of bit 3).
    pub const AC: u8 = 0x40;
    /// User flag 0.
    pub const F0: u8 = 0x20;
    /// Register bank select, high bit.
    pub const RS1: u8 = 0x10;
    /// Register bank select, low bit.
    pub const RS0: u8 = 0x08;
    /// Overflow.
    pub const OV: u8 = 0x04;
    /// User flag 1.
    pub const F1: u8 = 0x02;
    /// Parity of the accumulator (odd number of ones), kept by the hardware.
    pub const P: u8 = 0x01;
}

/// TCON bits.
pub mod tcon {
    pub const TF1: u8 = 0x80;
    pub const TR1: u8 = 0x40;
    pub const TF0: u8 = 0x20;
    pub const TR0: u8 = 0x10;
    pub const IE1: u8 = 0x08;
    pub const IT1: u8 = 0x04;
    pub const IE0: u8 = 0x02;
    pub const IT0: u8 = 0x01;
}

/// SCON bits.
pub mod scon {
    pub const SM0: u8 = 0x80;
    pub const SM1: u8 = 0x40;
    pub const SM2: u8 = 0x20;
    pub const REN: u8 = 0x10;
    pub const TB8: u8 = 0x08;
    pub const RB8: u8 = 0x04;
    pub const TI: u8 = 0x02;
    pub const RI: u8 = 0x01;
}

/// PCON bits.
pub mod pcon {
    /// Doubles the baud rate of serial modes 1, 2 and 3.
    pub const SMOD: u8 = 0x80;
    pub const GF1: u8 = 0x08;
    pub const GF0: u8 = 0x04;
    /// Power-down: the oscillator stops; only a reset ends it.
    pub const PD: u8 = 0x02;
    /// Idle: the CPU stops, timers, UART and interrupts run; an interrupt ends it.
    pub const IDL: u8 = 0x01;
}

/// IE bits.
pub mod ie {
    pub const EA: u8 = 0x80;
    pub const ES: u8 = 0x10;
    pub const ET1: u8 = 0x08;
    pub const EX1: u8 = 0x04;
    pub const ET0: u8 = 0x02;
    pub const EX0: u8 = 0x01;
}

/// IP bits.
pub mod ip {
    pub const PS: u8 = 0x10;
    pub const PT1: u8 = 0x08;
    pub const PX1: u8 = 0x04;
    pub const PT0: u8 = 0x02;
    pub const PX0: u8 = 0x01;
}
