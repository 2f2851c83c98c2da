//! The PowerPC 403 board around the core: what answers at each address (docs/loader.md has
//! the map).
//!
//! - DRAM, 4 MiB from 0: the firmware's data and vectors below 0x20000, programs above (the
//!   loader's map), all of it the running program's;
//! - the 403GA's serial port at 0x4000_0000 ([`Spu`]);
//! - the SJA1000 card (seed 002 §3.1): its EPLD turns chip select CS5 into ALE and CS6 into
//!   the chip's CS, so a byte written anywhere in the CS5 bank (0x7500_0000, 1 MiB) latches
//!   the register number and a byte read or written anywhere in the CS6 bank (0x7600_0000)
//!   reaches that register — what the seed's `wrsjai`/`wrsja`/`rdsja` do through r18/r19;
//! - the flash with the resident firmware at 0xFFFE_0000 (128 KiB, read-only): the firmware
//!   is the Rust model, so a fetch there means the program returned to the firmware.
//!
//! Everything else is a bus error (the core's machine check).

use buslab_ppc403::{Bus, BusError, Cycles, Size};
use buslab_sja1000::Sja1000;

use crate::spu::{self, Spu};

pub use crate::clocks::CPU_HZ;
/// DRAM from address 0.
pub const RAM_SIZE: u32 = 4 * 1024 * 1024;
/// Below this the RAM is the firmware's (its data and exception vectors).
pub const FIRMWARE_RAM_END: u32 = 0x0002_0000;
/// The serial port's registers.
pub const SPU_BASE: u32 = 0x4000_0000;
/// The SJA1000 card's address port (CS5) and data port (CS6), each a 1 MiB bank.
pub const ADDRESS_PORT: u32 = 0x7500_0000;
pub const DATA_PORT: u32 = 0x7600_0000;
pub const PORT_BANK: u32 = 0x0010_0000;
/// The flash with the resident firmware.
pub const FLASH_BASE: u32 = 0xFFFE_0000;
/// The loader's entry in the flash (the seed's link file): where a program's `blr` returns.
pub const LOADER_ENTRY: u32 = 0xFFFE_2000;
/// The stack pointer a program starts with: the top of program RAM.
pub const STACK_TOP: u32 = 0x001F_FFF0;
/// What a read of the flash gives (the firmware is not PowerPC code: erased flash).
pub const FLASH_READS: u8 = 0xFF;
/// What a read of the address port gives: nothing drives the data bus (pull-ups).
pub const FLOATING: u8 = 0xFF;

/// What answers at an address.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Region {
    /// The firmware's part of the RAM (data, exception vectors).
    FirmwareRam,
    /// RAM a program is loaded into and runs in.
    ProgramRam,
    Spu,
    AddressPort,
    DataPort,
    Flash,
    Nothing,
}

/// The region `addr` is in.
pub fn region(addr: u32) -> Region {
    match addr {
        0..FIRMWARE_RAM_END => Region::FirmwareRam,
        FIRMWARE_RAM_END..RAM_SIZE => Region::ProgramRam,
        a if (SPU_BASE..SPU_BASE + spu::SPAN).contains(&a) => Region::Spu,
        a if (ADDRESS_PORT..ADDRESS_PORT + PORT_BANK).contains(&a) => Region::AddressPort,
        a if (DATA_PORT..DATA_PORT + PORT_BANK).contains(&a) => Region::DataPort,
        FLASH_BASE.. => Region::Flash,
        _ => Region::Nothing,
    }
}

/// The board's own state: RAM, the serial port, the card's latched register number.
pub struct Board {
    ram: Vec<u8>,
    pub spu: Spu,
    /// The register number the last write to the address port latched.
    latch: u8,
    /// The first fetch from the flash: the program returned to the firmware there.
    returned: Option<u32>,
}

impl core::fmt::Debug for Board {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("Board")
            .field("latch", &self.latch)
            .field("returned", &self.returned)
            .finish_non_exhaustive()
    }
}

impl Board {
    /// A board with zeroed RAM and the serial port as the firmware leaves it.
    pub fn new() -> Self {
        Self {
            ram: vec![0; RAM_SIZE as usize],
            spu: Spu::new(),
            latch: 0,
            returned: None,
        }
    }

    /// Copies `data` into RAM from `addr`; what lies beyond the RAM is left out.
    pub fn load(&mut self, addr: u32, data: &[u8]) {
        let start = (addr as usize).min(self.ram.len());
        let end = start.saturating_add(data.len()).min(self.ram.len());
        self.ram[start..end].copy_from_slice(&data[..end - start]);
    }

    /// RAM bytes from `addr`, `None` past its end.
    pub fn ram(&self, addr: u32, len: usize) -> Option<&[u8]> {
        let start = addr as usize;
        self.ram.get(start..start.checked_add(len)?)
    }

    /// Where the program returned to the firmware, if it did.
    pub fn returned(&self) -> Option<u32> {
        self.returned
    }

    /// The board with the SJA1000 wired in, for one run of the core.
    pub fn wired<'a>(&'a mut self, chip: &'a mut Sja1000) -> Wired<'a> {
        Wired { board: self, chip }
    }
}

impl Default for Board {
    fn default() -> Self {
        Self::new()
    }
}

/// The board and its SJA1000 as the core sees them.
pub struct Wired<'a> {
    board: &'a mut Board,
    chip: &'a mut Sja1000,
}

fn be(bytes: &[u8]) -> u32 {
    bytes.iter().fold(0, |acc, &b| (acc << 8) | u32::from(b))
}

impl Wired<'_> {
    fn ram_range(&self, addr: u32, size: Size) -> core::ops::Range<usize> {
        let start = addr as usize;
        start..start + size.bytes() as usize
    }
}

impl Bus for Wired<'_> {
    #[inline]
    fn fetch(&mut self, addr: u32) -> Result<u32, BusError> {
        let at = addr as usize;
        if let Some(word) = self.board.ram.get(at..at + 4) {
            return Ok(u32::from_be_bytes(word.try_into().expect("4 bytes")));
        }
        match region(addr) {
            Region::Flash => {
                self.board.returned.get_or_insert(addr);
                Err(BusError { addr })
            }
            _ => Err(BusError { addr }),
        }
    }

    fn read(&mut self, addr: u32, size: Size, at: Cycles) -> Result<u32, BusError> {
        let fail = Err(BusError { addr });
        match region(addr) {
            Region::FirmwareRam | Region::ProgramRam => {
                let r = self.ram_range(addr, size);
                match self.board.ram.get(r) {
                    Some(bytes) => Ok(be(bytes)),
                    None => fail,
                }
            }
            Region::Flash => Ok(be(&[FLASH_READS; 4][..size.bytes() as usize])),
            _ if size != Size::Byte => fail,
            Region::Spu => match self.board.spu.read(addr - SPU_BASE, at) {
                Some(v) => Ok(v.into()),
                None => fail,
            },
            Region::AddressPort => Ok(FLOATING.into()),
            Region::DataPort => Ok(self.chip.read(self.board.latch).into()),
            Region::Nothing => fail,
        }
    }

    fn write(&mut self, addr: u32, size: Size, value: u32, at: Cycles) -> Result<(), BusError> {
        let fail = Err(BusError { addr });
        match region(addr) {
            Region::FirmwareRam | Region::ProgramRam => {
                let r = self.ram_range(addr, size);
                let n = size.bytes() as usize;
                match self.board.ram.get_mut(r) {
                    Some(bytes) => {
                        bytes.copy_from_slice(&value.to_be_bytes()[4 - n..]);
                        Ok(())
                    }
                    None => fail,
                }
            }
            _ if size != Size::Byte => fail,
            Region::Spu if self.board.spu.write(addr - SPU_BASE, value as u8, at) => Ok(()),
            Region::AddressPort => {
                self.board.latch = value as u8;
                Ok(())
            }
            Region::DataPort => {
                self.chip.write(self.board.latch, value as u8);
                Ok(())
            }
            Region::Spu | Region::Flash | Region::Nothing => fail,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_card_latches_the_register_number_then_reaches_it() {
        let mut board = Board::new();
        let mut chip = Sja1000::new();
        let mut bus = board.wired(&mut chip);
        // wrsjai 0x5A, 16 (ACR0 in BasicCAN's reset mode is 4; any register will do).
        bus.write(ADDRESS_PORT + 0x1234, Size::Byte, 6, Cycles(0))
            .unwrap();
        bus.write(DATA_PORT + 0x10, Size::Byte, 0x5A, Cycles(0))
            .unwrap();
        assert_eq!(bus.read(DATA_PORT, Size::Byte, Cycles(0)), Ok(0x5A));
        assert_eq!(chip.peek(6), 0x5A);
        let mut bus = board.wired(&mut chip);
        assert!(bus.write(DATA_PORT, Size::Word, 1, Cycles(0)).is_err());
        assert!(bus.read(ADDRESS_PORT, Size::Half, Cycles(0)).is_err());
    }

    #[test]
    fn ram_flash_and_holes() {
        let mut board = Board::new();
        board.load(0x32000, &[0x38, 0x60, 0x00, 0x07]);
        let mut chip = Sja1000::new();
        let mut bus = board.wired(&mut chip);
        assert_eq!(bus.fetch(0x32000), Ok(0x3860_0007));
        assert_eq!(bus.read(0x32002, Size::Half, Cycles(0)), Ok(7));
        bus.write(RAM_SIZE - 4, Size::Word, 0xDEAD_BEEF, Cycles(0))
            .unwrap();
        assert_eq!(bus.read(RAM_SIZE - 1, Size::Byte, Cycles(0)), Ok(0xEF));
        assert!(bus.read(RAM_SIZE, Size::Byte, Cycles(0)).is_err());
        assert!(bus.fetch(0x8000_0000).is_err());
        assert_eq!(bus.read(FLASH_BASE, Size::Word, Cycles(0)), Ok(0xFFFF_FFFF));
        assert!(bus.write(FLASH_BASE, Size::Byte, 0, Cycles(0)).is_err());
        assert!(bus.fetch(LOADER_ENTRY).is_err());
        assert_eq!(board.returned(), Some(LOADER_ENTRY));
        assert_eq!(region(0x1FFFF), Region::FirmwareRam);
        assert_eq!(region(0x20000), Region::ProgramRam);
        assert_eq!(region(SPU_BASE + spu::SPAN), Region::Nothing);
    }
}
