//! SLIO identifiers: four programmable bits, a direction bit, and the calibration frame.
//!
//! An 11-bit identifier of a SLIO reads `0 1 P3 1 0 P2 P1 P0 1 0 DIR` (ID.10..ID.0): P3..P0
//! are the ID pins latched at reset (ID.8, ID.5, ID.4, ID.3, data sheet table 14), the other
//! bits are fixed (the seed's `make_slio_ffi` and `test_slio_id`), DIR is 0 from the host to
//! the SLIO (the higher priority) and 1 from the SLIO to the host. So SLIO 0 listens on 0x284
//! and answers on 0x285, SLIO 15 on 0x3BC / 0x3BD (facts sheet §1.3).

use core::fmt;

use buslab_can::{Frame, Id, StandardId};

/// The identifier shared by every SLIO for calibration (`ID1 = 0x15, ID2 = 0x40` in the
/// seed's `send_calibration`): its alternating bits give the SLIO the edges it measures.
pub const CALIBRATION_ID: u16 = 0x0AA;
/// The calibration frame's data, as the seed sends it.
pub const CALIBRATION_DATA: [u8; 2] = [0xAA, 0x04];

/// The fixed bits of every SLIO identifier (all programmable bits and DIR 0).
const BASE: u16 = 0x284;
/// The bits a SLIO identifier fixes: everything but P3..P0 and DIR.
const FIXED_MASK: u16 = 0x7FF & !(0x100 | 0x020 | 0x010 | 0x008 | 0x001);

/// The calibration frame `0AA#AA04`.
pub fn calibration_frame() -> Frame {
    Frame::data(calibration_id(), &CALIBRATION_DATA).expect("2 bytes")
}

/// `0x0AA` as an identifier.
pub fn calibration_id() -> Id {
    Id::Standard(StandardId::new(CALIBRATION_ID).expect("11 bits"))
}

/// A SLIO's number, 0..=15: the levels of its ID pins P3..P0 at reset.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct SlioId(u8);

/// A SLIO number that does not fit the 4 ID pins.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[error("SLIO number {0} is out of range 0..15 (4 ID pins: at most 16 SLIOs on a bus)")]
pub struct SlioIdError(pub u32);

/// Which way a SLIO frame goes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Direction {
    /// DIR = 0: a command to the SLIO.
    ToSlio,
    /// DIR = 1: a reply, sign-on or input report from the SLIO.
    FromSlio,
}

impl SlioId {
    pub const fn new(number: u8) -> Result<Self, SlioIdError> {
        if number < 16 {
            Ok(Self(number))
        } else {
            Err(SlioIdError(number as u32))
        }
    }

    /// Every SLIO number, 0..=15.
    pub fn all() -> impl Iterator<Item = SlioId> {
        (0..16).map(SlioId)
    }

    pub const fn number(self) -> u8 {
        self.0
    }

    /// The 11-bit identifier for `dir`.
    pub const fn raw_id(self, dir: Direction) -> u16 {
        let p = self.0 as u16;
        let pins = ((p >> 3) & 1) << 8 | ((p >> 2) & 1) << 5 | ((p >> 1) & 1) << 4 | (p & 1) << 3;
        BASE | pins
            | match dir {
                Direction::ToSlio => 0,
                Direction::FromSlio => 1,
            }
    }

    /// The identifier the host sends commands to.
    pub fn command_id(self) -> Id {
        Id::Standard(StandardId::new(self.raw_id(Direction::ToSlio)).expect("11 bits"))
    }

    /// The identifier the SLIO answers with.
    pub fn reply_id(self) -> Id {
        Id::Standard(StandardId::new(self.raw_id(Direction::FromSlio)).expect("11 bits"))
    }

    /// Which SLIO an identifier belongs to and its direction, if it is a SLIO identifier (the
    /// seed's `test_slio_id`, which checks the fixed bits only).
    pub fn from_id(id: Id) -> Option<(SlioId, Direction)> {
        let Id::Standard(id) = id else { return None };
        let raw = id.as_raw();
        if raw & FIXED_MASK != BASE & FIXED_MASK {
            return None;
        }
        let number = ((raw >> 8) & 1) << 3
            | ((raw >> 5) & 1) << 2
            | ((raw >> 4) & 1) << 1
            | ((raw >> 3) & 1);
        let dir = if raw & 1 == 0 {
            Direction::ToSlio
        } else {
            Direction::FromSlio
        };
        Some((SlioId(number as u8), dir))
    }
}

/// `3`, as MoniCAN numbers the SLIOs (one hex digit).
impl fmt::Display for SlioId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{:X}", self.0)
    }
}

impl core::str::FromStr for SlioId {
    type Err = SlioIdError;

    /// One hex digit (`A`) or a decimal number (`10`).
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let t = s.trim();
        let n = if t.len() == 1 {
            u32::from_str_radix(t, 16).ok()
        } else {
            t.parse::<u32>().ok()
        };
        match n {
            Some(n) if n < 16 => Ok(SlioId(n as u8)),
            Some(n) => Err(SlioIdError(n)),
            None => Err(SlioIdError(u32::MAX)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_sixteen_identifiers_of_the_facts_sheet() {
        let table: [(u16, u16); 16] = [
            (0x284, 0x285),
            (0x28C, 0x28D),
            (0x294, 0x295),
            (0x29C, 0x29D),
            (0x2A4, 0x2A5),
            (0x2AC, 0x2AD),
            (0x2B4, 0x2B5),
            (0x2BC, 0x2BD),
            (0x384, 0x385),
            (0x38C, 0x38D),
            (0x394, 0x395),
            (0x39C, 0x39D),
            (0x3A4, 0x3A5),
            (0x3AC, 0x3AD),
            (0x3B4, 0x3B5),
            (0x3BC, 0x3BD),
        ];
        for (slio, (to, from)) in SlioId::all().zip(table) {
            assert_eq!(slio.raw_id(Direction::ToSlio), to, "SLIO {slio}");
            assert_eq!(slio.raw_id(Direction::FromSlio), from, "SLIO {slio}");
            assert_eq!(
                SlioId::from_id(slio.command_id()),
                Some((slio, Direction::ToSlio))
            );
            assert_eq!(
                SlioId::from_id(slio.reply_id()),
                Some((slio, Direction::FromSlio))
            );
        }
    }

    #[test]
    fn other_identifiers_are_not_slios() {
        for raw in [0x000, 0x0AA, 0x123, 0x283, 0x286, 0x7FF, 0x484] {
            let id = Id::Standard(StandardId::new(raw).unwrap());
            assert_eq!(SlioId::from_id(id), None, "{raw:03X}");
        }
        let ext = "00000285#".parse::<Frame>().unwrap().id();
        assert_eq!(
            SlioId::from_id(ext),
            None,
            "extended IDs are never SLIO IDs"
        );
        // Every standard ID that passes is one of the 32.
        let slio_ids = (0..0x800u16)
            .filter(|&raw| SlioId::from_id(Id::Standard(StandardId::new(raw).unwrap())).is_some())
            .count();
        assert_eq!(slio_ids, 32);
    }

    #[test]
    fn numbers_parse_as_monican_types_them() {
        assert_eq!("A".parse(), Ok(SlioId(10)));
        assert_eq!("f".parse(), Ok(SlioId(15)));
        assert_eq!("12".parse(), Ok(SlioId(12)));
        assert_eq!("16".parse::<SlioId>(), Err(SlioIdError(16)));
        assert!("x".parse::<SlioId>().is_err());
        assert_eq!(SlioId::new(16), Err(SlioIdError(16)));
        assert_eq!(calibration_frame().to_string(), "0AA#AA04");
    }
}
