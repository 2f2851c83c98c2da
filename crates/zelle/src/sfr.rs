//! The 8051's special function registers (80h..FFh) as command 16 reads them.
//!
//! The seed lets command 16 read "the wanted address" (command 17 writes only 0..127), so the
//! OS reads 80h..FFh as special function registers (it builds a `MOV A,direct` in RAM). What
//! each holds at that moment follows from what the OS is doing: it has just received the
//! address byte into the accumulator, inside its serial routine (external interrupt masked),
//! one call deep in the command loop. Addresses no 8051 register lives at read FFh.

use crate::memory::OPEN_BUS;

// The addresses are the 8051's; what this board wires to the ports: P0 is the multiplexed
// address/data bus (its latch holds 1s after every external access), P1 the A/D lines (bits
// 0..3, the LED on bit 0) and digital I/O (bits 4..7), P2 the high address byte and P2.6,
// P3 RxD, TxD, INT0 (wired to RxD), INT1 (the START key), T0, T1, WR, RD; TH1 holds the
// baud-rate reload value.
pub use buslab_mcs51::sfr::{
    ACC, B, DPH, DPL, IE, IP, P0, P1, P2, P3, PCON, PSW, SBUF, SCON, SP, TCON, TH0, TH1, TL0, TL1,
    TMOD,
};

/// SP inside a command: the reset value 07h (the stack starts in register bank 1) plus the
/// command loop's call of the command's function.
pub const SP_IN_COMMAND: u8 = 0x09;
/// TH1 (and TL1 as sampled) for 9600 baud from an 11.0592 MHz crystal, SMOD = 0.
pub const BAUD_RELOAD: u8 = 0xFD;
/// TMOD: timer 1 in mode 2 (8-bit auto-reload), the baud-rate generator.
pub const TMOD_BAUD: u8 = 0x20;
/// TCON: TR1 (timer 1 runs) and IT0 (INT0 edge-triggered, so a 0 byte on RxD interrupts).
pub const TCON_RUNNING: u8 = 0x41;
/// SCON: mode 3 (9 data bits, the 9th being the second stop bit: 8N2), REN, TB8 = RB8 = 1.
pub const SCON_8N2: u8 = 0xDC;
/// IE inside a serial routine: EA on, EX0 masked (the seed: the interrupt is blocked while
/// the serial line is used).
pub const IE_IN_SERIAL: u8 = 0x80;
/// P3's pin for the START key (low while pressed): INT1.
pub const P3_START_KEY: u8 = 1 << 3;

/// What the registers reflect of the cell at the moment of reading.
#[derive(Clone, Copy, Debug)]
pub struct Pins {
    /// Port 1 pins (latch ANDed with outside pull-downs).
    pub p1: u8,
    /// The P2.6 pin.
    pub p26: bool,
    /// Whether the START key is down.
    pub key_down: bool,
    /// The last external RAM address the OS used.
    pub dptr: u16,
}

/// The special function register at `addr` (80h..FFh) while command 16 reads it.
pub fn read(addr: u8, pins: Pins) -> u8 {
    // The OS has just received the address into A.
    let acc = addr;
    let [dph, dpl] = pins.dptr.to_be_bytes();
    match addr {
        P0 => 0xFF,
        SP => SP_IN_COMMAND,
        DPL => dpl,
        DPH => dph,
        PCON => 0x00,
        TCON => TCON_RUNNING,
        TMOD => TMOD_BAUD,
        TL0 | TH0 => 0x00,
        TL1 | TH1 => BAUD_RELOAD,
        P1 => pins.p1,
        SCON => SCON_8N2,
        SBUF => addr,
        P2 => 0xBF | (u8::from(pins.p26) << 6),
        IE => IE_IN_SERIAL,
        // RxD, TxD and INT0 idle high between bytes; WR and RD inactive high.
        P3 if pins.key_down => !P3_START_KEY,
        P3 => 0xFF,
        IP => 0x00,
        // Register bank 0; P is the parity of A.
        PSW => (acc.count_ones() % 2) as u8,
        ACC => acc,
        B => 0x00,
        _ => OPEN_BUS,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn psw_parity_follows_the_accumulator() {
        let pins = Pins {
            p1: 0xFF,
            p26: true,
            key_down: false,
            dptr: 0,
        };
        // A holds D0h (three 1 bits): odd parity.
        assert_eq!(read(PSW, pins), 0x01);
        assert_eq!(read(ACC, pins), 0xE0);
        assert_eq!(read(0x85, pins), OPEN_BUS, "no register lives at 85h");
    }
}
