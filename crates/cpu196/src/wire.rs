//! Byte-level layout of the PC ↔ board protocol (SPEC C1, C3): command numbers, sub-codes, how
//! many parameter bytes follow, and the `FA` checksum. The typed messages are in
//! [`crate::message`].
//!
//! A frame is `cmd, !cmd, params…`. There is no length field: the parameter count follows from
//! the command, its sub-code and (for strings) a count byte.

pub const THREAD: u8 = 0xF0;
pub const CPUINF: u8 = 0xF1;
pub const START: u8 = 0xF2;
pub const STOP: u8 = 0xF3;
pub const POWERDOWN: u8 = 0xF4;
pub const PRGFLASH: u8 = 0xF5;
pub const PRGPIC: u8 = 0xF6;
pub const CPUFORMAT: u8 = 0xF7;
pub const PWM: u8 = 0xF8;
pub const I2CSPI: u8 = 0xF9;
pub const ADCONT: u8 = 0xFA;
pub const ADSAMPLE: u8 = 0xFB;
pub const CFGAD: u8 = 0xFC;
pub const ALERT: u8 = 0xFD;
pub const MSG: u8 = 0xFE;
pub const WATCHDOG: u8 = 0xFF;

/// Highest command number left to user applications.
pub const USER_MAX: u8 = 0xEF;

/// Bytes in a flash block, blocks in a bank, banks.
pub const FLASH_BLOCK: usize = 256;
pub const FLASH_BLOCKS: usize = 256;
pub const FLASH_BANKS: usize = 8;
/// Bytes in a PIC program block (`F6`), and its EEPROM.
pub const PIC_BLOCK: usize = 4096;
pub const PIC_EEPROM: usize = 256;
/// Bytes in a boot flash block, the compression table.
pub const BOOT_BLOCK: usize = 256;
pub const LOG_TABLE: usize = 512;

/// Name of a kernel command, for messages.
pub fn command_name(cmd: u8) -> &'static str {
    match cmd {
        THREAD => "THREAD",
        CPUINF => "CPUINF",
        START => "START",
        STOP => "STOP",
        POWERDOWN => "POWERDOWN",
        PRGFLASH => "PRGFLASH",
        PRGPIC => "PRGPIC",
        CPUFORMAT => "CPUFORMAT",
        PWM => "PWM",
        I2CSPI => "I2CSPI",
        ADCONT => "ADCONT",
        ADSAMPLE => "ADSAMPLE",
        CFGAD => "CFGAD",
        ALERT => "ALERTE",
        MSG => "MSG",
        WATCHDOG => "WATCHDOG",
        _ => "user",
    }
}

/// The bytes a frame starts with.
pub fn header(cmd: u8) -> [u8; 2] {
    [cmd, !cmd]
}

/// XOR of the data bytes (`FA` checksum).
pub fn checksum(data: &[u8]) -> u8 {
    data.iter().fold(0, |acc, b| acc ^ b)
}

/// A sub-code that no format defines for this command.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{name} ({cmd:02X}h) has no sub-command {sub:02X}h", name = command_name(*cmd))]
pub struct UnknownSubcode {
    pub cmd: u8,
    pub sub: u8,
}

/// What the decoder knows beyond the bytes: parameter counts of user commands and of `FA`.
pub trait Lengths {
    /// Parameter bytes after user command `cmd` (00h..EFh).
    fn user_len(&self, cmd: u8) -> usize;
    /// Data bytes of an `FA` frame (checksum excluded), if an acquisition layout is known.
    fn adcont_len(&self) -> Option<usize>;
}

/// How many parameter bytes the frame `cmd` has, given the ones received so far.
///
/// `Ok(Some(n))`: exactly `n` parameter bytes. `Ok(None)`: one more byte is needed to tell.
/// `Err`: the sub-code is unknown, so the frame cannot be delimited.
pub fn params_len(cmd: u8, p: &[u8], ctx: &dyn Lengths) -> Result<Option<usize>, ParamsError> {
    let unknown = |sub| Err(ParamsError::Subcode(UnknownSubcode { cmd, sub }));
    let fixed = |n| Ok(Some(n));
    if cmd <= USER_MAX {
        return fixed(ctx.user_len(cmd));
    }
    // Commands without a sub-code.
    match cmd {
        STOP | WATCHDOG => return fixed(0),
        ALERT | MSG => return fixed(1),
        START | PWM | ADSAMPLE => return fixed(2),
        ADCONT => {
            return match ctx.adcont_len() {
                Some(n) => fixed(n + 1),
                None => Err(ParamsError::NoAdLayout),
            };
        }
        _ => {}
    }
    let Some(&sub) = p.first() else {
        return Ok(None);
    };
    // `n` counts at p[1]; frames waiting for it return None.
    let counted = |per: usize, extra: usize| match p.get(1) {
        Some(&n) => Ok(Some(2 + per * n as usize + extra)),
        None => Ok(None),
    };
    match (cmd, sub) {
        (THREAD, 0x00 | 0x02 | 0x04 | 0x06 | 0x08 | 0x0A | 0x0C | 0x0E) => counted(1, 0),
        (THREAD, 0x03 | 0x05 | 0x07 | 0x0B | 0x0D | 0x0F) => counted(2, 0),
        (THREAD, 0x40 | 0x41 | 0x20 | 0x30) => counted(1, 1),
        (THREAD, 0x18) => fixed(2),
        (THREAD, 0x10) => fixed(3),
        (CPUINF, 0x00) => fixed(1),
        (CPUINF, 0x01) => fixed(23),
        (POWERDOWN, 0x00..=0x03) => fixed(1),
        (PRGFLASH, 0x00) => fixed(3),
        (PRGFLASH, 0x01) => fixed(1 + FLASH_BLOCK),
        (PRGFLASH, 0x02) => fixed(3 + FLASH_BLOCK),
        (PRGFLASH, 0x03) => fixed(2),
        (PRGPIC, 0x00) => fixed(2),
        (PRGPIC, 0x01) => fixed(1 + PIC_BLOCK),
        (PRGPIC, 0x02) => fixed(2 + PIC_BLOCK),
        (PRGPIC, 0x03) => fixed(1),
        (PRGPIC, 0x04 | 0x05) => fixed(1 + PIC_EEPROM),
        (CPUFORMAT, 0x00) => fixed(9),
        (CPUFORMAT, 0x01) => fixed(1 + PIC_BLOCK),
        (CPUFORMAT, 0x02) => fixed(9 + PIC_BLOCK),
        (CPUFORMAT, 0x03) => fixed(17),
        (CPUFORMAT, 0x04) => fixed(2),
        (CPUFORMAT, 0x05 | 0x06) => fixed(1 + BOOT_BLOCK),
        (CPUFORMAT, 0x07) => fixed(1),
        (CPUFORMAT, 0x08) => fixed(1 + LOG_TABLE + 8),
        (CPUFORMAT, 0x55) => fixed(3),
        (I2CSPI, 0x07) => fixed(1),
        (I2CSPI, 0x00..=0x06) => fixed(2),
        (CFGAD, 0x00) => fixed(2),
        (CFGAD, 0x01) => fixed(22),
        _ => unknown(sub),
    }
}

/// Why a frame cannot be delimited.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ParamsError {
    #[error(transparent)]
    Subcode(#[from] UnknownSubcode),
    #[error("ADCONT (FAh) arrived but no acquisition layout is known (no CFGAD reply seen)")]
    NoAdLayout,
}

#[cfg(test)]
mod tests {
    use super::*;

    struct NoUser;
    impl Lengths for NoUser {
        fn user_len(&self, _: u8) -> usize {
            0
        }
        fn adcont_len(&self) -> Option<usize> {
            None
        }
    }

    #[test]
    fn lengths_match_the_seed_table() {
        let l = &NoUser;
        // The seed's table counts the sub-code with the parameters.
        assert_eq!(params_len(PRGFLASH, &[0x02], l), Ok(Some(259)));
        assert_eq!(params_len(PRGPIC, &[0x02], l), Ok(Some(4098)));
        assert_eq!(params_len(CPUFORMAT, &[0x02], l), Ok(Some(4105)));
        assert_eq!(params_len(CPUFORMAT, &[0x08], l), Ok(Some(521)));
        assert_eq!(params_len(CPUINF, &[0x01], l), Ok(Some(23)));
        assert_eq!(params_len(CFGAD, &[0x01], l), Ok(Some(22)));
        assert_eq!(params_len(THREAD, &[0x05], l), Ok(None));
        assert_eq!(params_len(THREAD, &[0x05, 3], l), Ok(Some(8)));
        assert_eq!(params_len(THREAD, &[0x41, 4], l), Ok(Some(7)));
        assert_eq!(
            params_len(PRGFLASH, &[0x09], l),
            Err(ParamsError::Subcode(UnknownSubcode {
                cmd: PRGFLASH,
                sub: 9
            }))
        );
        assert_eq!(params_len(ADCONT, &[], l), Err(ParamsError::NoAdLayout));
        assert_eq!(checksum(&[1, 2, 4, 8]), 15);
    }
}
