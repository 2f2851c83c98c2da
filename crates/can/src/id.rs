//! CAN identifiers: 11-bit standard (CAN 2.0A) and 29-bit extended (CAN 2.0B).

use core::cmp::Ordering;
use core::fmt;
use core::str::FromStr;

use crate::error::ParseError;

/// Largest standard (11-bit) identifier.
pub const SFF_MAX: u16 = 0x7FF;
/// Largest standard identifier CAN 2.0A lets a node send: its 7 most significant bits must
/// not all be recessive, so 0x7F0..=0x7FF are not sent (the rule the SJA1000's era followed;
/// ISO 11898-1:2003 lifted it). buslab's own protocol identifiers (MoniCAN's mail, the loader,
/// file transfer) keep to it.
pub const SFF_MAX_CAN20A: u16 = 0x7EF;
/// Largest extended (29-bit) identifier.
pub const EFF_MAX: u32 = 0x1FFF_FFFF;

/// A CAN identifier. Construct with [`Id::standard`] / [`Id::extended`] (checked) so the value is
/// always in range.
///
/// `Ord` is bus priority: `a < b` means a data frame with `a` wins arbitration against a data
/// frame with `b`. A standard ID beats an extended ID with the same 11 base bits (IDE is
/// dominant in the standard format).
#[derive(Clone, Copy, PartialEq, Eq, Hash, Debug)]
pub enum Id {
    Standard(StandardId),
    Extended(ExtendedId),
}

/// An 11-bit identifier, 0..=0x7FF.
#[derive(Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Debug)]
pub struct StandardId(u16);

/// A 29-bit identifier, 0..=0x1FFFFFFF.
#[derive(Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Debug)]
pub struct ExtendedId(u32);

impl StandardId {
    /// An identifier as a person types it for one of buslab's protocols: hex with `0x`, or
    /// decimal (`0x700`, `1792`), 0x000..=[`SFF_MAX_CAN20A`]. Digits only: no sign, no spaces
    /// inside.
    pub fn parse_protocol_id(text: &str) -> Result<Self, ParseError> {
        let t = text.trim();
        let parsed = match t.strip_prefix("0x").or_else(|| t.strip_prefix("0X")) {
            Some(hex) if !hex.is_empty() && hex.bytes().all(|b| b.is_ascii_hexdigit()) => {
                u16::from_str_radix(hex, 16).ok()
            }
            Some(_) => None,
            None if !t.is_empty() && t.bytes().all(|b| b.is_ascii_digit()) => t.parse().ok(),
            None => None,
        };
        parsed
            .filter(|&id| id <= SFF_MAX_CAN20A)
            .map(Self)
            .ok_or_else(|| ParseError::ProtocolId { text: text.into() })
    }

    pub const fn new(raw: u16) -> Result<Self, ParseError> {
        if raw > SFF_MAX {
            return Err(ParseError::IdOutOfRange {
                value: raw as u32,
                max: SFF_MAX as u32,
                extended: false,
            });
        }
        Ok(Self(raw))
    }
    pub const fn as_raw(self) -> u16 {
        self.0
    }
}

impl ExtendedId {
    pub const fn new(raw: u32) -> Result<Self, ParseError> {
        if raw > EFF_MAX {
            return Err(ParseError::IdOutOfRange {
                value: raw,
                max: EFF_MAX,
                extended: true,
            });
        }
        Ok(Self(raw))
    }
    pub const fn as_raw(self) -> u32 {
        self.0
    }
    /// The 11 most significant bits (ID28..ID18), sent first on the wire.
    pub const fn base(self) -> u16 {
        (self.0 >> 18) as u16
    }
    /// The 18 least significant bits (ID17..ID0).
    pub const fn extension(self) -> u32 {
        self.0 & 0x3_FFFF
    }
}

impl Id {
    /// A standard identifier; errors if `raw > 0x7FF`.
    pub fn standard(raw: u16) -> Result<Self, ParseError> {
        StandardId::new(raw).map(Id::Standard)
    }

    /// An extended identifier; errors if `raw > 0x1FFFFFFF`.
    pub fn extended(raw: u32) -> Result<Self, ParseError> {
        ExtendedId::new(raw).map(Id::Extended)
    }

    /// The numeric value (11 or 29 bits).
    pub const fn as_raw(self) -> u32 {
        match self {
            Id::Standard(id) => id.0 as u32,
            Id::Extended(id) => id.0,
        }
    }

    pub const fn is_extended(self) -> bool {
        matches!(self, Id::Extended(_))
    }

    /// Number of identifier bits: 11 or 29.
    pub const fn width(self) -> u32 {
        if self.is_extended() { 29 } else { 11 }
    }

    /// Bit `n` of the identifier (0 = least significant).
    pub const fn bit(self, n: u32) -> bool {
        n < self.width() && (self.as_raw() >> n) & 1 == 1
    }

    /// The arbitration field as it goes on the wire (after SOF, before the control field),
    /// left-aligned in a `u32`: SFF `ID10..ID0 RTR IDE=0`, EFF `ID28..ID18 SRR=1 IDE=1
    /// ID17..ID0 RTR`. Comparing these keys as integers is comparing arbitration (0 = dominant
    /// wins), because a standard frame and an extended frame always differ by bit 13 (IDE) at
    /// the latest.
    pub const fn arbitration_key(self, remote: bool) -> u32 {
        let rtr = remote as u32;
        match self {
            Id::Standard(id) => ((id.0 as u32) << 21) | (rtr << 20),
            Id::Extended(id) => {
                ((id.base() as u32) << 21) | (1 << 20) | (1 << 19) | (id.extension() << 1) | rtr
            }
        }
    }
}

impl Ord for Id {
    fn cmp(&self, other: &Self) -> Ordering {
        self.arbitration_key(false)
            .cmp(&other.arbitration_key(false))
    }
}

impl PartialOrd for Id {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

/// can-utils spelling: 3 hex digits for standard, 8 for extended.
impl fmt::Display for Id {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Id::Standard(id) => write!(f, "{:03X}", id.0),
            Id::Extended(id) => write!(f, "{:08X}", id.0),
        }
    }
}

/// Parses can-utils spelling: exactly 3 hex digits = standard, exactly 8 = extended. An optional
/// `0x` prefix selects by value instead (standard if it fits in 11 bits).
impl FromStr for Id {
    type Err = ParseError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        if let Some(hex) = s.strip_prefix("0x").or_else(|| s.strip_prefix("0X")) {
            let value = parse_hex_u32(hex, s)?;
            return if value <= SFF_MAX as u32 {
                Id::standard(value as u16)
            } else {
                Id::extended(value)
            };
        }
        match s.len() {
            3 => Id::standard(parse_hex_u32(s, s)? as u16),
            8 => Id::extended(parse_hex_u32(s, s)?),
            _ => Err(ParseError::IdLength { text: s.into() }),
        }
    }
}

impl Id {
    /// JerryCAN's spelling of a standard ID (seed 002 §5.4.4.4): three hex digits holding ID10..7,
    /// ID6..3 and ID2..0 followed by a don't-care bit, i.e. the ID shifted left by one: `246` is
    /// 123h, `FFE` (or `FFF`) is 7FFh. can-utils writes the ID itself (`123`).
    pub fn from_jerrycan(text: &str) -> Result<Id, ParseError> {
        if text.len() != 3 || !text.bytes().all(|b| b.is_ascii_hexdigit()) {
            return Err(ParseError::JerryCanId { text: text.into() });
        }
        let raw = u16::from_str_radix(text, 16)
            .map_err(|_| ParseError::JerryCanId { text: text.into() })?;
        Id::standard(raw >> 1)
    }

    /// This ID in JerryCAN's spelling (don't-care bit 0); `None` for an extended ID.
    pub fn to_jerrycan(&self) -> Option<alloc::string::String> {
        match self {
            Id::Standard(id) => Some(alloc::format!("{:03X}", id.0 << 1)),
            Id::Extended(_) => None,
        }
    }
}

fn parse_hex_u32(hex: &str, whole: &str) -> Result<u32, ParseError> {
    if hex.is_empty() || hex.len() > 8 || !hex.bytes().all(|b| b.is_ascii_hexdigit()) {
        return Err(ParseError::BadHex { text: whole.into() });
    }
    u32::from_str_radix(hex, 16).map_err(|_| ParseError::BadHex { text: whole.into() })
}

#[cfg(test)]
mod tests {
    use super::*;
    use alloc::string::ToString;

    #[test]
    fn range_checks_name_the_value() {
        let err = Id::standard(0x800).unwrap_err();
        assert_eq!(
            err.to_string(),
            "standard ID 0x800 is out of range 0x000..=0x7FF"
        );
        assert!(Id::extended(0x2000_0000).is_err());
        assert_eq!(Id::extended(EFF_MAX).unwrap().as_raw(), EFF_MAX);
    }

    #[test]
    fn parse_and_print_can_utils_spelling() {
        let sff: Id = "123".parse().unwrap();
        assert_eq!(sff, Id::standard(0x123).unwrap());
        assert_eq!(sff.to_string(), "123");
        let eff: Id = "00000123".parse().unwrap();
        assert_eq!(eff, Id::extended(0x123).unwrap());
        assert_eq!(eff.to_string(), "00000123");
        assert_eq!("0x1FFFFFFF".parse::<Id>().unwrap().as_raw(), EFF_MAX);
        for bad in [
            "",
            "12",
            "1234",
            "12G",
            "800",
            "3FFFFFFFF",
            "20000000",
            "0x",
            "-12",
        ] {
            assert!(bad.parse::<Id>().is_err(), "{bad:?} should not parse");
        }
    }

    #[test]
    fn priority_matches_arbitration() {
        let s = |v| Id::standard(v).unwrap();
        let e = |v| Id::extended(v).unwrap();
        assert!(s(0x100) < s(0x101));
        // Same base ID: standard wins (IDE dominant).
        assert!(s(0x123) < e(0x123 << 18));
        // Extended with a lower base ID beats a standard with a higher one.
        assert!(e(0x122 << 18 | 0x3FFFF) < s(0x123));
        assert!(e(5) < e(6));
    }

    #[test]
    fn bit_access() {
        let id = Id::standard(0b101).unwrap();
        assert!(id.bit(0) && !id.bit(1) && id.bit(2) && !id.bit(11));
        assert_eq!(id.width(), 11);
    }
}
