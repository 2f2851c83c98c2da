//! User programs for command 5: raw binary images or Intel HEX files, placed at 0400h.

use ihex::Record;

use crate::PROGRAM_AREA;
use crate::memory::DATA_AREA;

/// What unprogrammed gaps in a HEX image are filled with (erased EPROM, `MOVX` no-op).
const FILL: u8 = 0xFF;

/// Why a program file was refused.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum ProgramError {
    #[error("Intel HEX: {0}")]
    Hex(String),
    #[error("Intel HEX data at {addr:04X}h is outside the program area 0400h..07FFh")]
    OutsideArea { addr: u32 },
    #[error(
        "the program is {len} bytes; the program area 0400h..07FFh holds 1024 (a raw image \
         from 0000h, as `as31 -Fbin` writes, is taken if it ends by 07FFh with 0000h..03FFh blank)"
    )]
    TooLong { len: usize },
    #[error("the program is empty")]
    Empty,
}

const AREA_LEN: usize = (DATA_AREA - PROGRAM_AREA) as usize;

/// The bytes to load from 0400h. A file whose first non-blank character is `:` is read as
/// Intel HEX with absolute addresses (which must lie in 0400h..07FFh; gaps are filled with
/// FFh); anything else is a raw binary image of the program area, or of memory from 0000h
/// (what `as31 -Fbin` and `objcopy -O binary` write for code at 0400h) if it is longer than
/// the area, ends by 07FFh and has 0000h..03FFh blank (all 00h or all FFh).
pub fn image_from_file(contents: &[u8]) -> Result<Vec<u8>, ProgramError> {
    let first = contents.iter().find(|b| !b.is_ascii_whitespace());
    let image = match first {
        Some(b':') => {
            let text = std::str::from_utf8(contents)
                .map_err(|_| ProgramError::Hex("the file is not text".into()))?;
            from_hex(text)?
        }
        _ => match contents.split_at_checked(usize::from(PROGRAM_AREA)) {
            Some((below, program))
                if contents.len() > AREA_LEN
                    && contents.len() <= usize::from(DATA_AREA)
                    && (below.iter().all(|&b| b == 0) || below.iter().all(|&b| b == 0xFF)) =>
            {
                program.to_vec()
            }
            _ => contents.to_vec(),
        },
    };
    if image.is_empty() {
        return Err(ProgramError::Empty);
    }
    if image.len() > AREA_LEN {
        return Err(ProgramError::TooLong { len: image.len() });
    }
    Ok(image)
}

fn from_hex(text: &str) -> Result<Vec<u8>, ProgramError> {
    let mut image: Vec<u8> = Vec::new();
    let mut base: u32 = 0;
    for record in ihex::Reader::new(text.trim()) {
        match record.map_err(|e| ProgramError::Hex(e.to_string()))? {
            Record::Data { offset, value } => {
                let start = base + u32::from(offset);
                // In u64: a record at the top of the 32-bit space would overflow.
                let end = u64::from(start) + value.len() as u64;
                let area = u32::from(PROGRAM_AREA)..u32::from(DATA_AREA);
                if !area.contains(&start) || end > u64::from(area.end) {
                    return Err(ProgramError::OutsideArea { addr: start });
                }
                let at = (start - area.start) as usize;
                if image.len() < at + value.len() {
                    image.resize(at + value.len(), FILL);
                }
                image[at..at + value.len()].copy_from_slice(&value);
            }
            Record::ExtendedSegmentAddress(seg) => base = u32::from(seg) << 4,
            Record::ExtendedLinearAddress(high) => base = u32::from(high) << 16,
            Record::EndOfFile => break,
            Record::StartSegmentAddress { .. } | Record::StartLinearAddress(_) => {}
        }
    }
    Ok(image)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn hex(records: &[Record]) -> String {
        ihex::create_object_file_representation(records).unwrap()
    }

    #[test]
    fn raw_binary_is_taken_as_is() {
        assert_eq!(image_from_file(&[0x02, 0x04, 0x00]).unwrap(), [2, 4, 0]);
        assert_eq!(image_from_file(&[]), Err(ProgramError::Empty));
        assert_eq!(
            image_from_file(&[0x74; 1025]),
            Err(ProgramError::TooLong { len: 1025 })
        );
    }

    #[test]
    fn hex_lands_relative_to_0400h_with_gaps_filled() {
        let file = hex(&[
            Record::Data {
                offset: 0x0400,
                value: vec![0x74, 0x55],
            },
            Record::Data {
                offset: 0x0404,
                value: vec![0x80, 0xFE],
            },
            Record::EndOfFile,
        ]);
        assert_eq!(
            image_from_file(file.as_bytes()).unwrap(),
            [0x74, 0x55, 0xFF, 0xFF, 0x80, 0xFE]
        );
    }

    #[test]
    fn a_raw_image_from_0000h_is_taken_from_0400h_if_blank_below() {
        // as31 -Fbin of code at 0400h: 1024 zero bytes, then the program.
        let mut image = vec![0u8; 0x400];
        image.extend_from_slice(&[0x80, 0xFE]);
        assert_eq!(image_from_file(&image), Ok(vec![0x80, 0xFE]));
        image[..0x400].fill(0xFF);
        assert_eq!(image_from_file(&image), Ok(vec![0x80, 0xFE]));
        // Something below 0400h is not a program for the area.
        image[0x10] = 0x12;
        assert_eq!(
            image_from_file(&image),
            Err(ProgramError::TooLong { len: 0x402 })
        );
        // Past 07FFh: too long, whatever is below.
        let mut long = vec![0u8; 0x801];
        long[0x400] = 1;
        let err = image_from_file(&long).unwrap_err();
        assert_eq!(err, ProgramError::TooLong { len: 0x801 });
        assert!(err.to_string().contains("as31 -Fbin"), "{err}");
    }

    #[test]
    fn hex_outside_the_area_or_broken_is_refused() {
        let low = hex(&[
            Record::Data {
                offset: 0x0000,
                value: vec![1],
            },
            Record::EndOfFile,
        ]);
        assert_eq!(
            image_from_file(low.as_bytes()),
            Err(ProgramError::OutsideArea { addr: 0 })
        );
        // Addresses at the top of the 32-bit space must not overflow.
        let top = hex(&[
            Record::ExtendedLinearAddress(0xFFFF),
            Record::Data {
                offset: 0xFFFF,
                value: vec![1, 2],
            },
            Record::EndOfFile,
        ]);
        let err = image_from_file(top.as_bytes()).unwrap_err();
        assert_eq!(err, ProgramError::OutsideArea { addr: 0xFFFF_FFFF });
        assert_eq!(
            err.to_string(),
            "Intel HEX data at FFFFFFFFh is outside the program area 0400h..07FFh"
        );
        let err = image_from_file(b":10garbage\n").unwrap_err();
        assert!(matches!(err, ProgramError::Hex(_)), "{err:?}");
        assert!(image_from_file(b":\xff\xfe").is_err());
    }
}
