//! Everything outside the chip: memory and devices on the chip-select banks.
//!
//! The core asks the board for big-endian loads and stores of 1, 2 or 4 bytes at addresses
//! already checked for alignment (a misaligned access is the core's alignment exception, never
//! the board's business), and for instruction words. An address where nothing answers is a
//! [`BusError`]: the 403 takes a machine check (data) or an instruction machine check (fetch).

use alloc::vec;
use alloc::vec::Vec;

use crate::Cycles;

/// The width of an access.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Size {
    Byte = 1,
    Half = 2,
    Word = 4,
}

impl Size {
    pub const fn bytes(self) -> u32 {
        self as u32
    }
}

/// Nothing answered at the address (no memory, no device there), or the device refused the
/// access (a write to flash).
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[error("bus error at {addr:#010x}")]
pub struct BusError {
    pub addr: u32,
}

/// Memory and devices outside the chip.
pub trait Bus {
    /// The instruction word at `addr` (a multiple of 4).
    fn fetch(&mut self, addr: u32) -> Result<u32, BusError>;
    /// A load of `size` bytes at `addr` (aligned to `size`), big-endian, zero-extended, in the
    /// cycle `at`.
    fn read(&mut self, addr: u32, size: Size, at: Cycles) -> Result<u32, BusError>;
    /// A store of the low `size` bytes of `value` at `addr` (aligned to `size`), big-endian,
    /// in the cycle `at`.
    fn write(&mut self, addr: u32, size: Size, value: u32, at: Cycles) -> Result<(), BusError>;
}

/// RAM from address 0, nothing above it: for tests and benchmarks.
#[derive(Clone, PartialEq, Eq)]
pub struct FlatMemory {
    bytes: Vec<u8>,
}

impl core::fmt::Debug for FlatMemory {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "FlatMemory {{ {} bytes }}", self.bytes.len())
    }
}

impl FlatMemory {
    /// `len` bytes of zeros from address 0.
    pub fn new(len: usize) -> FlatMemory {
        FlatMemory {
            bytes: vec![0; len],
        }
    }

    /// Copies `data` in from `addr` (panics past the end: a test's own mistake).
    pub fn load(&mut self, addr: u32, data: &[u8]) {
        let start = addr as usize;
        self.bytes[start..start + data.len()].copy_from_slice(data);
    }

    /// Copies big-endian instruction words in from `addr`.
    pub fn load_words(&mut self, addr: u32, words: &[u32]) {
        for (i, w) in words.iter().enumerate() {
            self.load(addr + 4 * i as u32, &w.to_be_bytes());
        }
    }

    pub fn as_bytes(&self) -> &[u8] {
        &self.bytes
    }

    pub fn as_bytes_mut(&mut self) -> &mut [u8] {
        &mut self.bytes
    }

    #[inline(always)]
    fn range(&self, addr: u32, size: u32) -> Result<core::ops::Range<usize>, BusError> {
        let start = addr as usize;
        match start.checked_add(size as usize) {
            Some(end) if end <= self.bytes.len() => Ok(start..end),
            _ => Err(BusError { addr }),
        }
    }
}

impl Bus for FlatMemory {
    #[inline]
    fn fetch(&mut self, addr: u32) -> Result<u32, BusError> {
        self.read(addr, Size::Word, Cycles::ZERO)
    }

    #[inline]
    fn read(&mut self, addr: u32, size: Size, _at: Cycles) -> Result<u32, BusError> {
        let r = self.range(addr, size.bytes())?;
        let b = &self.bytes[r];
        Ok(match size {
            Size::Byte => u32::from(b[0]),
            Size::Half => u32::from(u16::from_be_bytes([b[0], b[1]])),
            Size::Word => u32::from_be_bytes([b[0], b[1], b[2], b[3]]),
        })
    }

    fn write(&mut self, addr: u32, size: Size, value: u32, _at: Cycles) -> Result<(), BusError> {
        let r = self.range(addr, size.bytes())?;
        let n = size.bytes() as usize;
        let be = value.to_be_bytes();
        self.bytes[r].copy_from_slice(&be[4 - n..]);
        Ok(())
    }
}
