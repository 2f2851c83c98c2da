//! CAN FD frames as hosts, logs and adapters carry them.
//!
//! buslab's bit-level world (the engine, the SJA1000 and SLIO models) is classic CAN, as the
//! seed's bench is: an FD frame is data that tools read, write, convert, send through an
//! adapter that speaks FD and decode with a DBC. [`FdFrame`] is its own type so that no FD
//! frame can reach a classic node by mistake.

use core::fmt;
use core::str::FromStr;

use crate::error::ParseError;
use crate::id::Id;

/// The payload lengths a CAN FD frame can have (its DLC 0..15 gives these).
pub const FD_LENGTHS: [usize; 16] = [0, 1, 2, 3, 4, 5, 6, 7, 8, 12, 16, 20, 24, 32, 48, 64];

/// The largest CAN FD payload.
pub const FD_MAX_LEN: usize = 64;

/// A CAN FD data frame: an ID, 0..=64 bytes in one of [`FD_LENGTHS`], and the two flags a
/// receiver sees: BRS (the data phase ran at the faster bit rate) and ESI (the sender was
/// error passive). FD has no remote frames.
#[derive(Clone, Copy, PartialEq, Eq, Hash)]
pub struct FdFrame {
    id: Id,
    brs: bool,
    esi: bool,
    len: u8,
    data: [u8; FD_MAX_LEN],
}

impl FdFrame {
    /// An FD frame carrying `data`, without BRS or ESI. Errors unless `data.len()` is one of
    /// [`FD_LENGTHS`].
    pub fn new(id: Id, data: &[u8]) -> Result<Self, ParseError> {
        if !FD_LENGTHS.contains(&data.len()) {
            return Err(ParseError::FdLength { len: data.len() });
        }
        let mut buf = [0; FD_MAX_LEN];
        buf[..data.len()].copy_from_slice(data);
        Ok(Self {
            id,
            brs: false,
            esi: false,
            len: data.len() as u8,
            data: buf,
        })
    }

    /// The same frame with the bit-rate switch flag set or cleared.
    pub const fn with_brs(mut self, brs: bool) -> Self {
        self.brs = brs;
        self
    }

    /// The same frame with the error-state indicator set or cleared.
    pub const fn with_esi(mut self, esi: bool) -> Self {
        self.esi = esi;
        self
    }

    pub const fn id(&self) -> Id {
        self.id
    }
    pub const fn is_extended(&self) -> bool {
        self.id.is_extended()
    }
    /// Bit rate switch: the data phase at the data bit rate.
    pub const fn brs(&self) -> bool {
        self.brs
    }
    /// Error state indicator: the sender was error passive.
    pub const fn esi(&self) -> bool {
        self.esi
    }
    /// The data bytes.
    pub fn payload(&self) -> &[u8] {
        &self.data[..self.len as usize]
    }
    /// The DLC code 0..=15 that stands for the payload's length.
    pub fn dlc(&self) -> u8 {
        dlc_of_len(self.len as usize).unwrap_or(15)
    }
    /// can-utils' flags nibble: BRS = 1, ESI = 2 (FDF = 4 is not stored: every FdFrame is FD).
    pub const fn flags(&self) -> u8 {
        (self.brs as u8) | (self.esi as u8) << 1
    }
}

/// The payload length of an FD DLC code; `None` above 15.
pub fn fd_len_of_dlc(dlc: u8) -> Option<usize> {
    FD_LENGTHS.get(dlc as usize).copied()
}

/// The FD DLC code for a payload length; `None` when the length is not one of [`FD_LENGTHS`].
pub fn dlc_of_len(len: usize) -> Option<u8> {
    FD_LENGTHS.iter().position(|&l| l == len).map(|d| d as u8)
}

/// can-utils' compact spelling: `123##1112233` (`##`, the flags nibble, the data). The
/// nibble written holds BRS and ESI only, as python-can and can-utils before v2025.01 write it.
impl fmt::Display for FdFrame {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}##{:X}", self.id, self.flags())?;
        for byte in self.payload() {
            write!(f, "{byte:02X}")?;
        }
        Ok(())
    }
}

impl fmt::Debug for FdFrame {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "FdFrame({self})")
    }
}

/// Parses can-utils' FD syntax: `<id>##<flags><data>` with a 3- or 8-digit ID, one hex flags
/// digit (BRS = 1, ESI = 2; FDF = 4 and the 8 bit are accepted and ignored, as readers of
/// newer candump logs must) and 0..=64 bytes in one of [`FD_LENGTHS`], `.` allowed between
/// bytes.
impl FromStr for FdFrame {
    type Err = ParseError;

    fn from_str(text: &str) -> Result<Self, Self::Err> {
        let s = text.trim();
        let (id, rest) = s
            .split_once("##")
            .ok_or_else(|| ParseError::NotFd { text: s.into() })?;
        if !matches!(id.len(), 3 | 8) {
            return Err(ParseError::IdLength { text: id.into() });
        }
        let id: Id = id.parse()?;
        let mut bytes = rest.bytes();
        let flags = match bytes.next() {
            Some(d) if d.is_ascii_hexdigit() => crate::frame::hex_value(d),
            _ => return Err(ParseError::FdFlags { text: s.into() }),
        };
        let hex = &rest[1..];
        if !hex.bytes().all(|b| b == b'.' || b.is_ascii_hexdigit()) {
            return Err(ParseError::BadHex { text: hex.into() });
        }
        let mut data = [0u8; FD_MAX_LEN];
        let mut len = 0usize;
        let mut digits = hex.bytes().filter(|&b| b != b'.');
        while let Some(hi) = digits.next() {
            let lo = digits
                .next()
                .ok_or_else(|| ParseError::OddHexDigits { text: hex.into() })?;
            if len == FD_MAX_LEN {
                let pairs = hex.bytes().filter(|&b| b != b'.').count().div_ceil(2);
                return Err(ParseError::FdLength { len: pairs });
            }
            data[len] = (crate::frame::hex_value(hi) << 4) | crate::frame::hex_value(lo);
            len += 1;
        }
        Ok(Self::new(id, &data[..len])?
            .with_brs(flags & 1 != 0)
            .with_esi(flags & 2 != 0))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use alloc::string::ToString;

    fn f(s: &str) -> FdFrame {
        s.parse().unwrap()
    }

    #[test]
    fn round_trips_can_utils_syntax() {
        for s in ["123##1112233", "12345678##3", "123##0", "7FF##200"] {
            assert_eq!(f(s).to_string(), s);
        }
        let long = alloc::format!("123##1{}", "AB".repeat(64));
        assert_eq!(f(&long).payload().len(), 64);
        assert_eq!(f(&long).dlc(), 15);
        assert!(f("123##1").brs() && !f("123##1").esi());
        assert!(f("123##3").esi());
        // can-utils v2025.01+ also sets FDF (4): read, not kept.
        assert_eq!(f("321##5112233").to_string(), "321##1112233");
        assert_eq!(f("123##0.11.2233").payload(), &[0x11, 0x22, 0x33]);
    }

    #[test]
    fn garbage_is_rejected_with_the_value() {
        let cases = [
            ("123#11", "not CAN FD"),
            ("123##", "flags"),
            ("123##G11", "flags"),
            ("123##0112", "odd number"),
            ("123##0112233445566778899", "9 data bytes"),
            ("12##0", "3 hex digits"),
            ("800##0", "out of range"),
            ("123##0ZZ", "not valid hexadecimal"),
        ];
        for (input, needle) in cases {
            let err = input.parse::<FdFrame>().unwrap_err().to_string();
            assert!(err.contains(needle), "{input:?} -> {err:?}");
        }
        let too_long = alloc::format!("123##0{}", "00".repeat(65));
        assert!(
            too_long
                .parse::<FdFrame>()
                .unwrap_err()
                .to_string()
                .contains("65 data bytes")
        );
    }

    #[test]
    fn lengths_and_dlc_codes_map_both_ways() {
        for (dlc, &len) in FD_LENGTHS.iter().enumerate() {
            assert_eq!(fd_len_of_dlc(dlc as u8), Some(len));
            assert_eq!(dlc_of_len(len), Some(dlc as u8));
        }
        assert_eq!(fd_len_of_dlc(16), None);
        assert_eq!(dlc_of_len(10), None);
        let id = Id::standard(1).unwrap();
        assert!(FdFrame::new(id, &[0; 10]).is_err());
        assert!(FdFrame::new(id, &[0; 12]).is_ok());
    }
}
