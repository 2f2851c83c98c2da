//! The values a host tool takes for a board, checked before anything goes on the line: bytes,
//! banks, blocks, serial numbers, battery thresholds, boot STARTs, PWM and bridge operations,
//! analog inputs, flash files. Errors name the value and what is allowed.

use crate::flash::is_user_block;
use crate::message::{Bridge, Pwm, Start};
use crate::source::{CHANNELS, SourceSpec};
use crate::wire::FLASH_BLOCK;

/// A value refused, with the reason.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ValueError {
    #[error("`{0}` is not a byte (0..255, 0x1F or 1Fh)")]
    Byte(String),
    #[error("`{0}` is out of range 0..7")]
    Bank(String),
    #[error("PIC block `{0}` is out of range 1..3")]
    PicBlock(String),
    #[error("serial number `{0}` must be exactly 8 ASCII characters")]
    SerialNumber(String),
    #[error("thresholds `{0}` must be three numbers 0..255, e.g. 100,140,220")]
    Thresholds(String),
    #[error("boot START `{0}` is not BANK:CONFIG (each 0..7) or none")]
    BootStart(String),
    #[error("`{0}` is not on or off")]
    OnOff(String),
    #[error("user command {0:02X}h is out of range 00h..EFh (F0h..FFh are the kernel's)")]
    UserCommand(u8),
    #[error("PWM output `{0}` is not 0, 1, 2, 3 or dac")]
    PwmOutput(String),
    #[error("{what} value {value} is out of range 0..{max}")]
    PwmValue {
        what: &'static str,
        value: u16,
        max: u16,
    },
    #[error("bridge operation `{0}` is not spi, sci, par-write, par-mask or par-read")]
    BridgeOp(String),
    #[error("bridge {0} needs a byte")]
    BridgeByte(String),
    #[error(transparent)]
    Source(#[from] crate::source::SourceError),
    #[error(
        "data in block {0:02X}h, outside the user flash (blocks 28h..3Fh, 60h..FFh); nothing \
         written"
    )]
    FlashBlock(u8),
    #[error("{len} bytes do not fit a flash bank of 65536")]
    FlashSize { len: usize },
}

/// `42`, `0x2A` or `2Ah`.
pub fn parse_byte(text: &str) -> Result<u8, ValueError> {
    let t = text.trim();
    // Digits only: `from_str_radix` and `parse` would take a sign (`+f`, `+5`).
    let parsed = if !t.bytes().all(|b| b.is_ascii_alphanumeric()) {
        "-".parse::<u8>()
    } else if let Some(h) = t.strip_prefix("0x").or_else(|| t.strip_prefix("0X")) {
        u8::from_str_radix(h, 16)
    } else if let Some(h) = t.strip_suffix(['h', 'H']) {
        u8::from_str_radix(h, 16)
    } else {
        t.parse()
    };
    parsed.map_err(|_| ValueError::Byte(text.to_owned()))
}

/// A flash bank or a configuration set: 0..7.
pub fn parse_bank(text: &str) -> Result<u8, ValueError> {
    match text.trim().parse::<u8>() {
        Ok(v) if v < 8 => Ok(v),
        _ => Err(ValueError::Bank(text.to_owned())),
    }
}

/// A PIC program block: 1..3.
pub fn parse_pic_block(text: &str) -> Result<u8, ValueError> {
    match text.trim().parse::<u8>() {
        Ok(v @ 1..=3) => Ok(v),
        _ => Err(ValueError::PicBlock(text.to_owned())),
    }
}

/// Exactly 8 ASCII characters.
pub fn parse_serial_number(text: &str) -> Result<[u8; 8], ValueError> {
    text.as_bytes()
        .try_into()
        .ok()
        .filter(|_| text.is_ascii())
        .ok_or_else(|| ValueError::SerialNumber(text.to_owned()))
}

/// Three battery thresholds `A,B,C` (255 disables one).
pub fn parse_thresholds(text: &str) -> Result<[u8; 3], ValueError> {
    let bad = || ValueError::Thresholds(text.to_owned());
    let v: Vec<u8> = text
        .split(',')
        .map(|x| x.trim().parse::<u8>())
        .collect::<Result<_, _>>()
        .map_err(|_| bad())?;
    v.try_into().map_err(|_| bad())
}

/// The START word performed at boot: `BANK:CONFIG` (80C196 A/D on) or `none`.
pub fn parse_boot_start(text: &str) -> Result<u16, ValueError> {
    if text.trim() == "none" {
        return Ok(Start::NO_START);
    }
    let bad = || ValueError::BootStart(text.to_owned());
    let (bank, config) = text.split_once(':').ok_or_else(bad)?;
    let bank = parse_bank(bank).map_err(|_| bad())?;
    let config = parse_bank(config).map_err(|_| bad())?;
    Ok(Start::run(bank, config, true).word())
}

/// `on` or `off`.
pub fn parse_on_off(text: &str) -> Result<bool, ValueError> {
    match text.trim() {
        "on" => Ok(true),
        "off" => Ok(false),
        _ => Err(ValueError::OnOff(text.to_owned())),
    }
}

/// A user command: 00h..EFh.
pub fn parse_user_command(text: &str) -> Result<u8, ValueError> {
    match parse_byte(text)? {
        cmd @ 0..=0xEF => Ok(cmd),
        cmd => Err(ValueError::UserCommand(cmd)),
    }
}

/// A PWM setting: output `0`..`2` (80C196, 8-bit), `3` (PIC, 10-bit) or `dac` (PIC D/A,
/// 5-bit), and its value.
pub fn pwm(output: &str, value: u16) -> Result<Pwm, ValueError> {
    let range = |what, max| {
        if value > max {
            Err(ValueError::PwmValue { what, value, max })
        } else {
            Ok(())
        }
    };
    Ok(match output.trim() {
        "dac" => {
            range("D/A", 31)?;
            Pwm::Dac(value as u8)
        }
        n @ ("0" | "1" | "2") => {
            range("PWM (8-bit)", 255)?;
            Pwm::Set {
                n: n.parse().expect("a digit"),
                low: 0,
                value: value as u8,
            }
        }
        "3" => {
            range("PWM 3 (10-bit)", 1023)?;
            Pwm::Set {
                n: 3,
                low: (value & 3) as u8,
                value: (value >> 2) as u8,
            }
        }
        other => return Err(ValueError::PwmOutput(other.to_owned())),
    })
}

/// A bridge operation: `spi`/`sci` send a byte, `par-write`/`par-mask` a byte, `par-read`.
pub fn bridge(op: &str, byte: Option<u8>) -> Result<Bridge, ValueError> {
    let need = || byte.ok_or_else(|| ValueError::BridgeByte(op.to_owned()));
    Ok(match op {
        "spi" => Bridge::SpiSend(need()?),
        "sci" => Bridge::SciSend(need()?),
        "par-write" => Bridge::ParallelWrite(need()?),
        "par-mask" => Bridge::ParallelAddress(need()?),
        "par-read" => Bridge::ParallelReadRequest,
        other => return Err(ValueError::BridgeOp(other.to_owned())),
    })
}

/// `CH=SOURCE` for an analog input: channel 0..7 and a source spec (`0=const:4`; the file of
/// a `csv:FILE` replay is the caller's to read).
pub fn parse_input(text: &str) -> Result<(u8, SourceSpec), ValueError> {
    Ok(buslab_analog::parse_channel_source(text, CHANNELS)?)
}

/// The blocks of a bank image (block 0 at offset 0, up to 64 KiB) that hold data (not all
/// FFh), each of which must be a user block.
pub fn flash_blocks_to_write(data: &[u8]) -> Result<Vec<u8>, ValueError> {
    if data.len() > 256 * FLASH_BLOCK {
        return Err(ValueError::FlashSize { len: data.len() });
    }
    let blocks: Vec<u8> = data
        .chunks(FLASH_BLOCK)
        .enumerate()
        .filter(|(_, block)| block.iter().any(|&x| x != 0xFF))
        .map(|(i, _)| i as u8)
        .collect();
    match blocks.iter().find(|&&b| !is_user_block(b)) {
        Some(&bad) => Err(ValueError::FlashBlock(bad)),
        None => Ok(blocks),
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn a_sign_is_not_a_digit() {
        for bad in ["+5", "0x+f", "+fh", "-1"] {
            assert!(super::parse_byte(bad).is_err(), "{bad}");
        }
        assert_eq!(super::parse_byte("0x2A").unwrap(), 42);
        assert!("script:+f=01".parse::<crate::pic::Peer>().is_err());
        assert!("script:41=+f".parse::<crate::pic::Peer>().is_err());
    }

    use super::*;
    use crate::source::Source;

    #[test]
    fn numbers_in_three_spellings_and_their_ranges() {
        for t in ["42", "0x2A", "2Ah", " 2ah "] {
            assert_eq!(parse_byte(t), Ok(42), "{t}");
        }
        assert_eq!(
            parse_byte("256").unwrap_err().to_string(),
            "`256` is not a byte (0..255, 0x1F or 1Fh)"
        );
        assert_eq!(parse_bank("7"), Ok(7));
        assert!(parse_bank("9").unwrap_err().to_string().contains("0..7"));
        assert!(
            parse_pic_block("4")
                .unwrap_err()
                .to_string()
                .contains("1..3")
        );
        assert_eq!(
            parse_user_command("0xF3").unwrap_err().to_string(),
            "user command F3h is out of range 00h..EFh (F0h..FFh are the kernel's)"
        );
    }

    #[test]
    fn serial_numbers_thresholds_and_boot_starts() {
        assert_eq!(parse_serial_number("ABCD1234"), Ok(*b"ABCD1234"));
        // 8 bytes, but not 8 ASCII characters.
        assert!(parse_serial_number("éééé").is_err());
        assert!(
            parse_serial_number("SHORT")
                .unwrap_err()
                .to_string()
                .contains("exactly 8")
        );
        assert_eq!(parse_thresholds("90, 150,230"), Ok([90, 150, 230]));
        assert!(parse_thresholds("1,2").is_err());
        assert!(parse_thresholds("1,2,300").is_err());
        assert_eq!(parse_boot_start("none"), Ok(0x8000));
        assert_eq!(
            parse_boot_start("0:1").map(Start::from_word),
            Ok(Start::run(0, 1, true))
        );
        assert!(parse_boot_start("0:8").is_err());
        assert_eq!(parse_on_off("off"), Ok(false));
    }

    #[test]
    fn pwm_and_bridge_values() {
        assert_eq!(
            pwm("3", 0x2A5),
            Ok(Pwm::Set {
                n: 3,
                low: 1,
                value: 0xA9
            })
        );
        assert_eq!(
            pwm("dac", 40).unwrap_err().to_string(),
            "D/A value 40 is out of range 0..31"
        );
        assert!(pwm("1", 256).unwrap_err().to_string().contains("0..255"));
        assert!(pwm("4", 1).is_err());
        assert_eq!(bridge("par-read", None), Ok(Bridge::ParallelReadRequest));
        assert_eq!(
            bridge("spi", None).unwrap_err().to_string(),
            "bridge spi needs a byte"
        );
    }

    #[test]
    fn inputs_and_flash_files() {
        assert_eq!(
            parse_input("1=const:4"),
            Ok((1, SourceSpec::Ready(Source::Constant(4.0))))
        );
        assert!(
            parse_input("8=const:4")
                .unwrap_err()
                .to_string()
                .contains("0..7")
        );
        assert!(parse_input("const:4").is_err());
        let mut bank = vec![0xFF; 65536];
        bank[0x6000] = 1;
        bank[0x2A10] = 2;
        assert_eq!(flash_blocks_to_write(&bank), Ok(vec![0x2A, 0x60]));
        bank[0x0300] = 0;
        assert_eq!(
            flash_blocks_to_write(&bank).unwrap_err().to_string(),
            "data in block 03h, outside the user flash (blocks 28h..3Fh, 60h..FFh); nothing written"
        );
        assert!(flash_blocks_to_write(&[0; 65537]).is_err());
    }
}
