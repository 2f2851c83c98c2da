//! How a module sits in a flash bank: a 32-byte header at the start of its first block, the
//! module's bytes right after it, on through the following blocks of the same bank.
//!
//! Header (little-endian): magic `W196` · length (u32) · CRC-32 of the module's bytes (u32) ·
//! name (20 bytes of UTF-8, padded with zero bytes). The blocks must all be user flash in one
//! run (28h..3Fh or 60h..FFh: a module never crosses the RAM at 4000h..5FFFh).

use buslab_cpu196::flash::Flash;
use buslab_cpu196::wire::FLASH_BLOCK;

pub const MAGIC: [u8; 4] = *b"W196";
pub const HEADER: usize = 32;
pub const NAME_LEN: usize = 20;
/// Where `buslab cpu196 program flash` puts a module: the bank's larger user area.
pub const DEFAULT_BLOCK: u8 = 0x60;
/// The largest module: the 160 blocks of 60h..FFh less the header (40 KiB).
pub const MAX_MODULE: usize = 160 * FLASH_BLOCK - HEADER;

/// Why a module cannot be stored at, or read from, a place in flash.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum LayoutError {
    #[error("block {block:02X}h is not user flash (28h..3Fh, 60h..FFh)")]
    NotUserFlash { block: u8 },
    #[error(
        "no module starts at bank {bank} block {block:02X}h (its first bytes are {found:02X?}, not `W196`); flash one with `buslab cpu196 program flash`"
    )]
    NoModule { bank: u8, block: u8, found: [u8; 4] },
    #[error(
        "a module of {len} bytes does not fit from block {block:02X}h: it needs {blocks} blocks and the user flash there ends at {end:02X}h (at most {max} bytes)"
    )]
    TooLong {
        len: usize,
        block: u8,
        blocks: usize,
        end: u8,
        max: usize,
    },
    #[error(
        "the module at bank {bank} block {block:02X}h is damaged: its CRC-32 is {found:08X}h, the header says {expected:08X}h (a write that did not finish? flash it again)"
    )]
    Damaged {
        bank: u8,
        block: u8,
        expected: u32,
        found: u32,
    },
    #[error("no flash bank {0} (0..7)")]
    NoBank(u8),
}

/// A module as kept in flash.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct StoredModule {
    pub name: String,
    pub bytes: Vec<u8>,
}

/// The last block of the user area that `block` is in.
fn area_end(block: u8) -> Option<u8> {
    match block {
        0x28..=0x3F => Some(0x3F),
        0x60..=0xFF => Some(0xFF),
        _ => None,
    }
}

/// How many blocks a module of `len` bytes takes.
pub fn blocks_for(len: usize) -> usize {
    (HEADER + len).div_ceil(FLASH_BLOCK)
}

fn check_fit(len: usize, block: u8) -> Result<(), LayoutError> {
    let end = area_end(block).ok_or(LayoutError::NotUserFlash { block })?;
    let room = usize::from(end - block) + 1;
    let blocks = blocks_for(len);
    if blocks > room {
        return Err(LayoutError::TooLong {
            len,
            block,
            blocks,
            end,
            max: room * FLASH_BLOCK - HEADER,
        });
    }
    Ok(())
}

/// The name as stored: at most [`NAME_LEN`] bytes, cut at a character boundary.
pub fn stored_name(name: &str) -> &str {
    let mut end = name.len().min(NAME_LEN);
    while !name.is_char_boundary(end) {
        end -= 1;
    }
    &name[..end]
}

/// The blocks to write for `module` starting at `block`: `(block, data)`, the last one padded
/// with FFh (erased flash).
pub fn encode(
    name: &str,
    module: &[u8],
    block: u8,
) -> Result<Vec<(u8, [u8; FLASH_BLOCK])>, LayoutError> {
    check_fit(module.len(), block)?;
    let mut bytes = Vec::with_capacity(HEADER + module.len());
    bytes.extend_from_slice(&MAGIC);
    bytes.extend_from_slice(&(module.len() as u32).to_le_bytes());
    bytes.extend_from_slice(&crc32fast::hash(module).to_le_bytes());
    let mut field = [0u8; NAME_LEN];
    let name = stored_name(name).as_bytes();
    field[..name.len()].copy_from_slice(name);
    bytes.extend_from_slice(&field);
    bytes.extend_from_slice(module);
    Ok(bytes
        .chunks(FLASH_BLOCK)
        .zip(block..=0xFF)
        .map(|(chunk, k)| {
            let mut data = [0xFF; FLASH_BLOCK];
            data[..chunk.len()].copy_from_slice(chunk);
            (k, data)
        })
        .collect())
}

/// The header of a block, if it starts a module: `(name, length, crc)`.
pub fn parse_header(data: &[u8]) -> Option<(String, usize, u32)> {
    if data.len() < HEADER || data[..4] != MAGIC {
        return None;
    }
    let word = |at: usize| u32::from_le_bytes([data[at], data[at + 1], data[at + 2], data[at + 3]]);
    let name = &data[12..HEADER];
    let name = &name[..name.iter().position(|&b| b == 0).unwrap_or(NAME_LEN)];
    Some((
        String::from_utf8_lossy(name).into_owned(),
        word(4) as usize,
        word(8),
    ))
}

/// Reads the module that starts at `bank`/`block`, checking its place and its CRC.
pub fn read(flash: &Flash, bank: u8, block: u8) -> Result<StoredModule, LayoutError> {
    area_end(block).ok_or(LayoutError::NotUserFlash { block })?;
    let first = flash
        .read(bank, block)
        .map_err(|_| LayoutError::NoBank(bank))?;
    let Some((name, len, expected)) = parse_header(first) else {
        return Err(LayoutError::NoModule {
            bank,
            block,
            found: [first[0], first[1], first[2], first[3]],
        });
    };
    check_fit(len, block)?;
    let mut bytes = Vec::with_capacity(HEADER + len);
    for k in block..=block + (blocks_for(len) - 1) as u8 {
        bytes.extend_from_slice(flash.read(bank, k).map_err(|_| LayoutError::NoBank(bank))?);
    }
    bytes.truncate(HEADER + len);
    let bytes = bytes.split_off(HEADER);
    let found = crc32fast::hash(&bytes);
    if found != expected {
        return Err(LayoutError::Damaged {
            bank,
            block,
            expected,
            found,
        });
    }
    Ok(StoredModule { name, bytes })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn store(flash: &mut Flash, bank: u8, blocks: &[(u8, [u8; FLASH_BLOCK])]) {
        for (k, data) in blocks {
            flash.write(bank, *k, data).unwrap();
        }
    }

    #[test]
    fn a_module_round_trips_through_the_blocks_it_is_written_to() {
        let module: Vec<u8> = (0..1000u32).map(|i| (i * 7) as u8).collect();
        let blocks = encode("a name longer than twenty bytes", &module, 0x60).unwrap();
        assert_eq!(blocks.len(), 5, "32 + 1000 bytes are 5 blocks");
        assert_eq!(blocks[0].0, 0x60);
        assert_eq!(blocks[4].0, 0x64);
        let mut flash = Flash::default();
        store(&mut flash, 3, &blocks);
        let read = read(&flash, 3, 0x60).unwrap();
        assert_eq!(read.bytes, module);
        assert_eq!(read.name, "a name longer than t");
    }

    #[test]
    fn a_damaged_or_missing_module_is_named_as_such() {
        let mut flash = Flash::default();
        assert_eq!(
            read(&flash, 0, 0x60),
            Err(LayoutError::NoModule {
                bank: 0,
                block: 0x60,
                found: [0xFF; 4]
            })
        );
        let blocks = encode("m", &[0u8; 600], 0x60).unwrap();
        // The header block alone: the rest reads erased.
        store(&mut flash, 0, &blocks[..1]);
        let e = read(&flash, 0, 0x60).unwrap_err();
        assert!(matches!(e, LayoutError::Damaged { .. }), "{e}");
        assert!(e.to_string().contains("flash it again"), "{e}");
    }

    #[test]
    fn a_module_must_fit_in_one_user_area() {
        assert_eq!(
            encode("m", &[0; 10], 0x40),
            Err(LayoutError::NotUserFlash { block: 0x40 })
        );
        let e = encode("m", &[0; 300], 0xFF).unwrap_err();
        assert_eq!(
            e.to_string(),
            "a module of 300 bytes does not fit from block FFh: it needs 2 blocks and the user flash there ends at FFh (at most 224 bytes)"
        );
        assert!(encode("m", &[0; MAX_MODULE], 0x60).is_ok());
        assert!(encode("m", &[0; MAX_MODULE + 1], 0x60).is_err());
        // 28h..3Fh is an area of its own: nothing runs on into 40h.
        assert!(encode("m", &[0; 2 * FLASH_BLOCK], 0x3E).is_err());
    }
}
