//! The cell's hardware around its 8051: the battery-backed RAM, the parallel interface bus, the
//! A/D inputs and converter, what outside circuits do to the port pins, the START key. One
//! model, used by the OS (the Rust model of it) and by a user program through the core's
//! `MOVX`, code fetches and port pins alike.
//!
//! External memory as the 8051 addresses it:
//!
//! ```text
//! code   0000h..03FFh  the OS EPROM (the stand-in of rom.rs)
//!        0400h..7FFFh  the RAM (PSEN and RD combined: a program runs from 0400h)
//!        8000h..FFFFh  nothing answers: FFh
//! MOVX   0000h..7FFFh  the RAM (start byte at 03FFh, program, data)
//!        8000h..FFFFh  the parallel interface bus: address lines A0..A6 select one of its
//!                      128 addresses (mirrored every 128 bytes)
//! ```

use buslab_device::ChangeLog;
use buslab_mcs51::{Bus, Clocks, Crystal};

use crate::analog::Source;
use crate::converter::Converter;
use crate::memory::{BatteryRam, OPEN_BUS, PROGRAM_AREA};
use crate::rom;

/// Where the parallel interface bus starts in `MOVX` space (A15 selects it).
pub const BUS_BASE: u16 = 0x8000;

/// The cell's crystal: 11.0592 MHz (docs/decisions.md, "The MCS-51 core").
pub(crate) const CRYSTAL: Crystal = Crystal::MHZ_11_0592;

#[derive(Clone, Debug)]
pub(crate) struct Board {
    pub ram: BatteryRam,
    pub ram_generation: u64,
    /// Writes to the battery-backed RAM not yet taken by the host (for its journal).
    pub changes: ChangeLog,
    /// The latches of the parallel interface bus's 128 addresses.
    pub bus: [u8; 128],
    pub analog: [Source; 4],
    pub converter: Converter,
    /// Port 1 pins outside circuits pull low (bit set = low).
    pub p1_pulled_low: u8,
    pub p26_pulled_low: bool,
    pub key_down: bool,
}

impl Board {
    pub fn new(ram: BatteryRam) -> Board {
        Board {
            ram,
            ram_generation: 0,
            changes: ChangeLog::default(),
            bus: [OPEN_BUS; 128],
            analog: Default::default(),
            converter: Converter::default(),
            p1_pulled_low: 0,
            p26_pulled_low: false,
            key_down: false,
        }
    }

    /// Writes one byte of battery-backed RAM and notes it for the state file and its journal.
    pub fn write_ram(&mut self, addr: u16, value: u8) {
        self.ram.write(addr, value);
        self.ram_generation += 1;
        if let Some(last) = self.changes.last_mut()
            && let [high, low, data @ ..] = &last[..]
            && u32::from(u16::from_be_bytes([*high, *low])) + data.len() as u32 == u32::from(addr)
        {
            last.push(value);
            self.changes.extended(1);
            return;
        }
        let [high, low] = addr.to_be_bytes();
        self.changes.record(vec![high, low, value]);
    }

    /// A read of external data memory (`MOVX`, commands 2 and 18).
    pub fn read_data(&self, addr: u16) -> u8 {
        if addr >= BUS_BASE {
            self.bus[usize::from(addr & 0x7F)]
        } else {
            self.ram.read(addr)
        }
    }

    /// A write of external data memory (`MOVX`, commands 1, 3, 5, 19).
    pub fn write_data(&mut self, addr: u16, value: u8) {
        if addr >= BUS_BASE {
            self.bus[usize::from(addr & 0x7F)] = value;
        } else {
            self.write_ram(addr, value);
        }
    }
}

impl Bus for Board {
    fn code(&mut self, addr: u16) -> u8 {
        if addr < PROGRAM_AREA {
            rom::code(addr)
        } else if addr < BUS_BASE {
            self.ram.read(addr)
        } else {
            OPEN_BUS
        }
    }

    fn read_xdata(&mut self, addr: u16, _at: Clocks) -> u8 {
        self.read_data(addr)
    }

    fn write_xdata(&mut self, addr: u16, value: u8, _at: Clocks) {
        self.write_data(addr, value);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn movx_reaches_ram_below_8000h_and_the_bus_above() {
        let mut b = Board::new(BatteryRam::default());
        b.write_xdata(0x03FF, 130, Clocks::ZERO);
        b.write_xdata(0x8005, 0x42, Clocks::ZERO);
        assert_eq!(b.ram.read(0x03FF), 130);
        assert_eq!(b.bus[5], 0x42);
        assert_eq!(b.read_xdata(0xFF85, Clocks::ZERO), 0x42, "mirrored");
        assert_eq!(b.read_xdata(0x8006, Clocks::ZERO), OPEN_BUS);
        // Code: the stand-in EPROM below 0400h, the RAM up to 7FFFh, nothing above.
        b.write_xdata(0x0400, 0x74, Clocks::ZERO);
        assert_eq!(b.code(0x0400), 0x74);
        assert_eq!(b.code(0x03F4), 0x30, "Sende's wait: JNB TI,$");
        assert_eq!(
            b.code(0x03FF),
            0x39,
            "Empf's wait, not the start byte: that is data space"
        );
        assert_eq!(b.code(0x8005), OPEN_BUS);
        assert_eq!(b.ram_generation, 2, "the two RAM writes, not the bus write");
    }
}
