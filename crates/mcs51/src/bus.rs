//! The memory the core is wired to: code fetches (PSEN) and `MOVX` (RD/WR).
//!
//! The core owns only what is on the chip (128 bytes of RAM, the special function registers).
//! Everything outside is the board's: it implements [`Bus`] and hands it to each
//! [`run`](crate::Mcs51::run). A board where code and data are one memory (PSEN and RD
//! combined, as on the ZELLE cell) answers [`code`](Bus::code) and
//! [`read_xdata`](Bus::read_xdata) from the same bytes; [`FlatMemory`] is that, 64 KiB of it.

use alloc::boxed::Box;
use alloc::vec;

use crate::Clocks;

/// Memory outside the chip.
pub trait Bus {
    /// The code byte at `addr`: opcode and operand fetches and `MOVC`.
    fn code(&mut self, addr: u16) -> u8;
    /// A `MOVX` read of `addr` in the machine cycle that starts at `at`.
    fn read_xdata(&mut self, addr: u16, at: Clocks) -> u8;
    /// A `MOVX` write of `value` to `addr` in the machine cycle that starts at `at`.
    fn write_xdata(&mut self, addr: u16, value: u8, at: Clocks);
}

/// 64 KiB where code and external data are the same bytes (PSEN and RD combined).
#[derive(Clone, PartialEq, Eq)]
pub struct FlatMemory {
    bytes: Box<[u8; 0x10000]>,
}

impl Default for FlatMemory {
    fn default() -> Self {
        FlatMemory::new()
    }
}

impl core::fmt::Debug for FlatMemory {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str("FlatMemory { 64 KiB }")
    }
}

impl FlatMemory {
    /// All zero (`NOP`s).
    pub fn new() -> FlatMemory {
        let bytes: Box<[u8]> = vec![0; 0x10000].into_boxed_slice();
        FlatMemory {
            bytes: bytes.try_into().expect("64 KiB"),
        }
    }

    /// Copies `data` in from `addr` on; what would run past FFFFh wraps to 0000h.
    pub fn load(&mut self, addr: u16, data: &[u8]) {
        for (i, &b) in data.iter().enumerate() {
            self.bytes[usize::from(addr.wrapping_add(i as u16))] = b;
        }
    }

    /// All 64 KiB.
    pub fn as_bytes(&self) -> &[u8; 0x10000] {
        &self.bytes
    }

    /// All 64 KiB, to change.
    pub fn as_bytes_mut(&mut self) -> &mut [u8; 0x10000] {
        &mut self.bytes
    }
}

impl Bus for FlatMemory {
    #[inline(always)]
    fn code(&mut self, addr: u16) -> u8 {
        self.bytes[usize::from(addr)]
    }

    #[inline(always)]
    fn read_xdata(&mut self, addr: u16, _at: Clocks) -> u8 {
        self.bytes[usize::from(addr)]
    }

    #[inline(always)]
    fn write_xdata(&mut self, addr: u16, value: u8, _at: Clocks) {
        self.bytes[usize::from(addr)] = value;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn code_and_data_are_one_memory() {
        let mut m = FlatMemory::new();
        m.write_xdata(0x0400, 0x74, Clocks::ZERO);
        assert_eq!(m.code(0x0400), 0x74);
        m.load(0xFFFF, &[1, 2]);
        assert_eq!(m.read_xdata(0xFFFF, Clocks::ZERO), 1);
        assert_eq!(m.code(0x0000), 2);
    }
}
