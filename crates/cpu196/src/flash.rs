//! The 8 flash banks of 256 blocks × 256 bytes and the kernel's table of blank blocks.

use std::sync::{Arc, OnceLock};

use crate::wire::{FLASH_BANKS, FLASH_BLOCK, FLASH_BLOCKS};

/// Why a flash operation was refused (mapped to `FE` messages by the kernel).
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum FlashError {
    /// `msg_invalid_parameter_value`.
    #[error(
        "bank {bank} block {block:#04x} is outside the user flash (banks 0..7, blocks 28h..3Fh and 60h..FFh)"
    )]
    Forbidden { bank: u8, block: u8 },
    /// `msg_not_blank_error`.
    #[error("bank {bank} block {block:#04x} is not blank; erase the bank first")]
    NotBlank { bank: u8, block: u8 },
}

/// Whether a block may be written: the 80C196 reaches user flash only at 2800h..3FFFh and
/// 6000h..FFFFh of a bank; below 2800h sit RAM, the PSD registers, the kernel's tables and the
/// boot flash, and 4000h..5FFFh is external RAM.
pub fn is_user_block(block: u8) -> bool {
    matches!(block, 0x28..=0x3F | 0x60..=0xFF)
}

/// Flash contents plus the blank-block bitmap (`_bloc_[256]` at 300h: one bit per block).
///
/// The 512 KiB of contents are shared between clones until one of them is written (copy on
/// write): an image is cloned for every board, and most boards never write their flash.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Flash {
    data: Arc<Vec<u8>>,
    blank: [u8; 256],
}

impl Default for Flash {
    fn default() -> Self {
        static ERASED: OnceLock<Arc<Vec<u8>>> = OnceLock::new();
        Self {
            data: ERASED
                .get_or_init(|| Arc::new(vec![0xFF; FLASH_BANKS * FLASH_BLOCKS * FLASH_BLOCK]))
                .clone(),
            blank: [0xFF; 256],
        }
    }
}

impl Flash {
    fn index(bank: u8, block: u8) -> usize {
        bank as usize * FLASH_BLOCKS + block as usize
    }

    fn range(bank: u8, block: u8) -> core::ops::Range<usize> {
        let start = Self::index(bank, block) * FLASH_BLOCK;
        start..start + FLASH_BLOCK
    }

    fn check(bank: u8, block: u8) -> Result<(), FlashError> {
        if (bank as usize) < FLASH_BANKS && is_user_block(block) {
            Ok(())
        } else {
            Err(FlashError::Forbidden { bank, block })
        }
    }

    /// Whether the kernel's table lists the block as blank.
    pub fn is_blank(&self, bank: u8, block: u8) -> bool {
        let i = Self::index(bank, block);
        self.blank[i / 8] & (1 << (i % 8)) != 0
    }

    fn set_blank(&mut self, bank: u8, block: u8, blank: bool) {
        let i = Self::index(bank, block);
        if blank {
            self.blank[i / 8] |= 1 << (i % 8);
        } else {
            self.blank[i / 8] &= !(1 << (i % 8));
        }
    }

    /// Any block of a valid bank can be read (outside user flash it reads as erased).
    pub fn read(&self, bank: u8, block: u8) -> Result<&[u8], FlashError> {
        if bank as usize >= FLASH_BANKS {
            return Err(FlashError::Forbidden { bank, block });
        }
        Ok(&self.data[Self::range(bank, block)])
    }

    /// Programs a blank user block.
    pub fn write(
        &mut self,
        bank: u8,
        block: u8,
        data: &[u8; FLASH_BLOCK],
    ) -> Result<(), FlashError> {
        Self::check(bank, block)?;
        if !self.is_blank(bank, block) {
            return Err(FlashError::NotBlank { bank, block });
        }
        Arc::make_mut(&mut self.data)[Self::range(bank, block)].copy_from_slice(data);
        self.set_blank(bank, block, false);
        Ok(())
    }

    /// Sets a block's contents as written, whatever the table said (replaying a journal).
    /// `false` if there is no such bank.
    pub fn restore_block(&mut self, bank: u8, block: u8, data: &[u8; FLASH_BLOCK]) -> bool {
        if bank as usize >= FLASH_BANKS {
            return false;
        }
        Arc::make_mut(&mut self.data)[Self::range(bank, block)].copy_from_slice(data);
        self.set_blank(bank, block, false);
        true
    }

    /// Erases a whole bank.
    pub fn erase(&mut self, bank: u8) -> Result<(), FlashError> {
        if bank as usize >= FLASH_BANKS {
            return Err(FlashError::Forbidden { bank, block: 0 });
        }
        let start = bank as usize * FLASH_BLOCKS * FLASH_BLOCK;
        Arc::make_mut(&mut self.data)[start..start + FLASH_BLOCKS * FLASH_BLOCK].fill(0xFF);
        for block in 0..=255 {
            self.set_blank(bank, block, true);
        }
        Ok(())
    }

    /// The blank-block bitmap (bit `i % 8` of byte `i / 8` for block index `bank·256 + block`).
    pub fn blank_table(&self) -> &[u8; 256] {
        &self.blank
    }

    /// Rebuilds from stored blocks (for the image): `blocks` are written regardless of the
    /// table, then the table is set as given.
    pub fn restore(
        blank: [u8; 256],
        blocks: impl IntoIterator<Item = (u8, u8, [u8; FLASH_BLOCK])>,
    ) -> Self {
        let mut f = Self::default();
        for (bank, block, data) in blocks {
            if (bank as usize) < FLASH_BANKS {
                Arc::make_mut(&mut f.data)[Self::range(bank, block)].copy_from_slice(&data);
            }
        }
        f.blank = blank;
        f
    }

    /// Blocks that hold anything but erased bytes, or are marked written.
    pub fn used_blocks(&self) -> impl Iterator<Item = (u8, u8, &[u8])> + '_ {
        (0..FLASH_BANKS as u8).flat_map(move |bank| {
            (0..=255u8).filter_map(move |block| {
                let d = &self.data[Self::range(bank, block)];
                (!self.is_blank(bank, block) || *d != [0xFF; FLASH_BLOCK])
                    .then_some((bank, block, d))
            })
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_clone_keeps_its_contents_when_the_other_is_written_or_erased() {
        let mut original = Flash::default();
        original.write(0, 0x60, &[1; 256]).unwrap();
        let copy = original.clone();
        let mut other = original.clone();
        original.write(0, 0x61, &[2; 256]).unwrap();
        other.erase(0).unwrap();
        assert_eq!(copy.read(0, 0x60).unwrap(), &[1; 256][..]);
        assert_eq!(copy.read(0, 0x61).unwrap(), &[0xFF; 256][..]);
        assert!(copy.is_blank(0, 0x61));
        assert_eq!(original.read(0, 0x60).unwrap(), &[1; 256][..]);
        assert_eq!(original.read(0, 0x61).unwrap(), &[2; 256][..]);
        assert_eq!(other.read(0, 0x60).unwrap(), &[0xFF; 256][..]);
        assert_eq!(Flash::default(), Flash::default());
        assert_ne!(copy, original);
    }

    #[test]
    fn write_only_blank_user_blocks() {
        let mut f = Flash::default();
        let data = [0x5A; 256];
        assert_eq!(f.write(1, 0x60, &data), Ok(()));
        assert_eq!(f.read(1, 0x60).unwrap(), &data[..]);
        assert_eq!(
            f.write(1, 0x60, &data),
            Err(FlashError::NotBlank {
                bank: 1,
                block: 0x60
            })
        );
        assert_eq!(
            f.write(1, 0x03, &data),
            Err(FlashError::Forbidden { bank: 1, block: 3 })
        );
        assert_eq!(
            f.write(1, 0x45, &data),
            Err(FlashError::Forbidden {
                bank: 1,
                block: 0x45
            })
        );
        assert_eq!(
            f.write(8, 0x60, &data),
            Err(FlashError::Forbidden {
                bank: 8,
                block: 0x60
            })
        );
        // Writing all-FF still marks the block as used: the kernel trusts its table.
        assert_eq!(f.write(2, 0x28, &[0xFF; 256]), Ok(()));
        assert!(!f.is_blank(2, 0x28));
        f.erase(1).unwrap();
        assert!(f.is_blank(1, 0x60));
        assert_eq!(f.read(1, 0x60).unwrap(), &[0xFF; 256][..]);
        assert!(!f.is_blank(2, 0x28));
    }
}
