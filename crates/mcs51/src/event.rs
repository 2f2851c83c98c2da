//! What the core tells its board: why [`run`](crate::Mcs51::run) returned, and the events
//! waiting in [`poll_event`](crate::Mcs51::poll_event).

use crate::sfr::scon;
use crate::{Clocks, Port};

/// Why [`run`](crate::Mcs51::run) (or [`step`](crate::Mcs51::step),
/// [`stall`](crate::Mcs51::stall)) returned.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stop {
    /// The time asked for is reached (at the first instruction boundary at or after it).
    Limit,
    /// Events wait in [`poll_event`](crate::Mcs51::poll_event): take them before running on.
    Events,
    /// The program counter is at `pc`, inside the trap range: the board does what the code
    /// there would (an entry point of the operating system it models) and moves the program
    /// counter on ([`ret`](crate::Mcs51::ret), [`set_pc`](crate::Mcs51::set_pc)); until then
    /// every run returns here at once.
    Trap { pc: u16 },
    /// PCON.PD was set: the oscillator stands still until [`reset`](crate::Mcs51::reset).
    PowerDown,
}

/// Something the program did that the board sees.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Event {
    /// The UART sent a frame (reported when TI is set).
    Serial(SerialFrame),
    /// A port latch changed: the pins now show `latch` AND what the outside drives.
    Port { port: Port, latch: u8, at: Clocks },
    /// The reserved opcode A5h ran at `pc` (as a one-cycle no-op).
    ReservedOpcode { pc: u16, at: Clocks },
}

/// The serial port's mode (SCON.SM0, SM1).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SerialMode {
    /// Shift register: 8 bits, one per machine cycle, clock on TxD.
    Mode0,
    /// 8 data bits, baud from timer 1.
    Mode1,
    /// 9 data bits, fosc/64 (fosc/32 with SMOD).
    Mode2,
    /// 9 data bits, baud from timer 1.
    Mode3,
}

impl SerialMode {
    pub(crate) fn from_scon(scon: u8) -> SerialMode {
        match scon & (scon::SM0 | scon::SM1) {
            0 => SerialMode::Mode0,
            scon::SM1 => SerialMode::Mode1,
            scon::SM0 => SerialMode::Mode2,
            _ => SerialMode::Mode3,
        }
    }
}

/// A frame the UART sent.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SerialFrame {
    pub mode: SerialMode,
    /// The 8 data bits.
    pub data: u8,
    /// The 9th data bit (TB8) in modes 2 and 3.
    pub ninth: Option<bool>,
    /// Modes 1..3: the leading edge of the start bit; mode 0: the first data bit.
    pub start: Clocks,
    /// When TI was set: modes 1..3, the start of the stop bit (the line is high from here for
    /// one bit time, and until the next start bit); mode 0, two cycles after the last bit.
    pub end: Clocks,
}

impl SerialFrame {
    /// Bit times from `start` to `end`.
    pub fn bits(&self) -> u64 {
        match (self.mode, self.ninth) {
            (SerialMode::Mode0, _) => 8,
            (_, Some(_)) => 10,
            (_, None) => 9,
        }
    }

    /// The bit time in clocks (mode 0: one machine cycle). If the baud clock changed while the
    /// frame was out, the average.
    pub fn bit_clocks(&self) -> Clocks {
        match self.mode {
            SerialMode::Mode0 => Clocks::from_cycles(1),
            _ => (self.end - self.start) / self.bits(),
        }
    }

    /// Where the (first) stop bit ends: the frame is complete on the line.
    pub fn stop_end(&self) -> Clocks {
        match self.mode {
            SerialMode::Mode0 => self.end,
            _ => self.end + self.bit_clocks(),
        }
    }
}

/// A frame to put on RxD (see [`Mcs51::send_rxd`](crate::Mcs51::send_rxd)).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LineFrame {
    /// 8 data bits, least significant first.
    pub data: u8,
    /// A 9th data bit (for modes 2 and 3; `None` sends the stop bit right after bit 7).
    pub ninth: Option<bool>,
    /// One bit time in clocks (1152 at 9600 baud from 11.0592 MHz).
    pub bit_clocks: Clocks,
}
