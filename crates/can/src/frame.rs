//! The one CAN frame type used everywhere in buslab.

use core::cmp::Ordering;
use core::fmt;
use core::str::FromStr;

use crate::error::ParseError;
use crate::id::Id;

/// A classic CAN 2.0A/B frame: a data frame with 0..8 bytes, or a remote frame with a DLC.
///
/// Fields are private so the invariants hold: `dlc <= 8`; for a data frame the DLC is the
/// number of data bytes; a remote frame carries no data.
///
/// `Ord` is bus priority (the frame that wins arbitration is the smaller); frames with the same
/// arbitration field are then ordered by DLC and data so the order is total.
#[derive(Clone, Copy, PartialEq, Eq, Hash)]
pub struct Frame {
    id: Id,
    remote: bool,
    dlc: u8,
    data: [u8; 8],
}

impl Frame {
    /// A data frame. Errors if `data` is longer than 8 bytes.
    pub fn data(id: Id, data: &[u8]) -> Result<Self, ParseError> {
        if data.len() > 8 {
            return Err(ParseError::TooMuchData { len: data.len() });
        }
        let mut buf = [0; 8];
        buf[..data.len()].copy_from_slice(data);
        Ok(Self {
            id,
            remote: false,
            dlc: data.len() as u8,
            data: buf,
        })
    }

    /// A remote frame requesting `dlc` bytes. Errors if `dlc > 8`.
    pub fn remote(id: Id, dlc: u8) -> Result<Self, ParseError> {
        if dlc > 8 {
            return Err(ParseError::DlcOutOfRange { dlc });
        }
        Ok(Self {
            id,
            remote: true,
            dlc,
            data: [0; 8],
        })
    }

    pub const fn id(&self) -> Id {
        self.id
    }
    pub const fn is_remote(&self) -> bool {
        self.remote
    }
    pub const fn is_extended(&self) -> bool {
        self.id.is_extended()
    }
    /// The data length code, 0..=8.
    pub const fn dlc(&self) -> u8 {
        self.dlc
    }
    /// The data bytes (empty for a remote frame).
    #[inline]
    pub fn payload(&self) -> &[u8] {
        if self.remote {
            &[]
        } else {
            &self.data[..self.dlc as usize]
        }
    }

    /// The payload as a number, first byte most significant (0 for a remote frame): the wire
    /// encoder's input, without a copy of a slice of variable length. With the DLC (and
    /// whether it is a remote frame) it gives the payload back.
    #[inline]
    pub fn payload_bits(&self) -> u64 {
        let len = self.payload().len() as u32;
        if len == 0 {
            0
        } else {
            u64::from_be_bytes(self.data) >> (64 - 8 * len)
        }
    }

    /// The arbitration field as a comparable key; see [`Id::arbitration_key`].
    pub const fn arbitration_key(&self) -> u32 {
        self.id.arbitration_key(self.remote)
    }
}

impl Ord for Frame {
    fn cmp(&self, other: &Self) -> Ordering {
        self.arbitration_key()
            .cmp(&other.arbitration_key())
            .then(self.dlc.cmp(&other.dlc))
            .then(self.payload().cmp(other.payload()))
    }
}

impl PartialOrd for Frame {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

/// can-utils compact spelling: `123#1122`, `12345678#`, `123#R`, `123#R4`.
impl fmt::Display for Frame {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}#", self.id)?;
        if self.remote {
            f.write_str("R")?;
            if self.dlc > 0 {
                write!(f, "{}", self.dlc)?;
            }
            return Ok(());
        }
        for byte in self.payload() {
            write!(f, "{byte:02X}")?;
        }
        Ok(())
    }
}

impl fmt::Debug for Frame {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "Frame({self})")
    }
}

/// Parses the cansend syntax: `<id>#<data>` where the ID has 3 (standard) or 8 (extended) hex
/// digits and data is up to 8 hex byte pairs, optionally separated by `.`; or `<id>#R[dlc]`.
impl FromStr for Frame {
    type Err = ParseError;

    fn from_str(text: &str) -> Result<Self, Self::Err> {
        let s = text.trim();
        let (id, rest) = s
            .split_once('#')
            .ok_or_else(|| ParseError::MissingSeparator { text: text.into() })?;
        if id.len() == 8 && u32::from_str_radix(id, 16).is_ok_and(|raw| raw & 0x2000_0000 != 0) {
            return Err(ParseError::ErrorFrameNotSupported { text: text.into() });
        }
        // The digit count says standard or extended (`0x800` would be taken by value).
        if !matches!(id.len(), 3 | 8) {
            return Err(ParseError::IdLength { text: id.into() });
        }
        let id: Id = id.parse()?;
        if rest.starts_with('#') {
            return Err(ParseError::FdNotSupported { text: text.into() });
        }
        if let Some((_, dlc)) = rest.rsplit_once('_') {
            let mut chars = dlc.chars();
            if let (Some(d @ ('9' | 'A'..='F' | 'a'..='f')), None) = (chars.next(), chars.next()) {
                return Err(ParseError::RawDlcNotSupported {
                    text: text.into(),
                    dlc: d,
                });
            }
        }
        if let Some(len) = rest.strip_prefix(['R', 'r']) {
            let dlc = match len.as_bytes() {
                [] => 0,
                [d @ b'0'..=b'9'] => d - b'0',
                _ => return Err(ParseError::BadRemoteLength { text: len.into() }),
            };
            return Frame::remote(id, dlc);
        }
        let mut data = [0u8; 8];
        let mut len = 0usize;
        let mut digits = rest.bytes().filter(|&b| b != b'.');
        if !rest.bytes().all(|b| b == b'.' || b.is_ascii_hexdigit()) {
            return Err(ParseError::BadHex { text: rest.into() });
        }
        while let Some(hi) = digits.next() {
            let lo = digits
                .next()
                .ok_or_else(|| ParseError::OddHexDigits { text: rest.into() })?;
            if len == 8 {
                let pairs = rest.bytes().filter(|&b| b != b'.').count().div_ceil(2);
                return Err(ParseError::TooMuchData { len: pairs });
            }
            data[len] = (hex_value(hi) << 4) | hex_value(lo);
            len += 1;
        }
        Frame::data(id, &data[..len])
    }
}

impl Frame {
    /// Parses a frame whose ID is spelled the JerryCAN way ([`Id::from_jerrycan`], e.g.
    /// `246#1122` is `123#1122`); the rest is can-utils syntax.
    pub fn from_jerrycan(text: &str) -> Result<Self, ParseError> {
        let (id, rest) = text
            .trim()
            .split_once('#')
            .ok_or_else(|| ParseError::MissingSeparator { text: text.into() })?;
        let id = Id::from_jerrycan(id)?;
        alloc::format!("{id}#{rest}").parse()
    }
}

pub(crate) fn hex_value(digit: u8) -> u8 {
    match digit {
        b'0'..=b'9' => digit - b'0',
        b'a'..=b'f' => digit - b'a' + 10,
        _ => digit - b'A' + 10,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use alloc::string::ToString;

    fn f(s: &str) -> Frame {
        s.parse().unwrap()
    }

    #[test]
    fn round_trips_can_utils_syntax() {
        for s in [
            "123#1122",
            "12345678#",
            "123#R",
            "123#R4",
            "7FF#0102030405060708",
            "000#",
        ] {
            assert_eq!(f(s).to_string(), s);
        }
        assert_eq!(f("123#11.22.33").payload(), &[0x11, 0x22, 0x33]);
        assert_eq!(f("1ABCDEF0#").id(), Id::extended(0x1ABCDEF0).unwrap());
        assert_eq!(f("123#deadbeef").to_string(), "123#DEADBEEF");
        assert!(f("123#R4").is_remote());
        assert_eq!(f("123#R4").dlc(), 4);
    }

    #[test]
    fn garbage_is_rejected_with_the_value() {
        let cases = [
            ("123", "no '#'"),
            ("800#", "out of range"),
            ("12#00", "3 hex digits"),
            ("123#0", "odd number"),
            ("123#010203040506070809", "9 data bytes"),
            ("123#R9", "DLC 9 is out of range 0..8"),
            ("123#R12", "one digit"),
            // The 3-or-8-digit rule, not the value, says standard or extended.
            ("0x800#", "3 hex digits"),
            ("0x123#11", "3 hex digits"),
            ("1234#", "3 hex digits"),
            ("123#ZZ", "not valid hexadecimal"),
            ("123#1 2", "allowed: 0-9, a-f, A-F"),
            // can-utils syntax that classic 0..8-byte frames cannot carry: named, not "bad hex".
            ("333#R8_E", "raw DLC 9..F (_E)"),
            ("1F334455#1122334455667788_B", "raw DLC 9..F (_B)"),
            ("20000080#0000000000000000", "error frame"),
            ("123##1", "CAN FD"),
            ("#", "3 hex digits"),
            ("", "no '#'"),
        ];
        for (input, needle) in cases {
            let err = input.parse::<Frame>().unwrap_err().to_string();
            assert!(err.contains(needle), "{input:?} -> {err:?}");
        }
    }

    /// Seed 002 §5.4.4.4: "Le format de l'ID est un nombre en hexadécimal sur trois chiffres
    /// de la forme : Chiffre de gauche : ID10 ID9 ID8 ID7, Chiffre du milieu : ID6 ID5 ID4 ID3,
    /// Chiffre de droite : ID2 ID1 ID0 X".
    #[test]
    fn jerrycan_ids_are_the_id_shifted_left_by_one() {
        assert_eq!(
            Frame::from_jerrycan("246#1122").unwrap().to_string(),
            "123#1122"
        );
        assert_eq!(Frame::from_jerrycan("FFF#R").unwrap().to_string(), "7FF#R");
        assert_eq!(Id::from_jerrycan("001").unwrap(), Id::standard(0).unwrap());
        assert_eq!(
            Id::standard(0x123).unwrap().to_jerrycan(),
            Some("246".into())
        );
        for bad in ["", "12", "1000", "+1F", "0x2", "12G"] {
            let err = Id::from_jerrycan(bad).unwrap_err().to_string();
            assert!(err.contains("JerryCAN"), "{bad:?}: {err}");
        }
        assert!(Id::extended(1).unwrap().to_jerrycan().is_none());
    }

    #[test]
    fn builders_check_limits() {
        let id = Id::standard(1).unwrap();
        assert_eq!(
            Frame::remote(id, 9).unwrap_err().to_string(),
            "DLC 9 is out of range 0..8"
        );
        assert!(Frame::data(id, &[0; 9]).is_err());
        assert_eq!(Frame::remote(id, 3).unwrap().payload(), &[] as &[u8]);
    }

    #[test]
    fn order_is_bus_priority() {
        assert!(f("100#") < f("101#"));
        assert!(f("123#") < f("123#R")); // data beats remote
        assert!(f("123#R") < f("048C0000#")); // SFF remote beats EFF with the same base ID
        assert!(f("123#FF") < f("124#00"));
        let mut v = [f("200#"), f("00000001#"), f("100#R"), f("100#")];
        v.sort();
        assert_eq!(
            v.map(|x| x.to_string()),
            ["00000001#", "100#", "100#R", "200#"]
        );
    }
}
