//! Errors for building and parsing identifiers and frames.

use alloc::string::String;

/// Bad input when building or parsing an [`Id`](crate::Id) or a [`Frame`](crate::Frame). Every
/// variant names the offending value and what is allowed.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ParseError {
    #[error(
        "{} ID 0x{value:X} is out of range 0x000..=0x{max:X}",
        if *extended { "extended" } else { "standard" }
    )]
    IdOutOfRange {
        value: u32,
        max: u32,
        extended: bool,
    },
    #[error(
        "ID {text:?} must be 3 hex digits (standard, 000..7FF) or 8 hex digits (extended, 00000000..1FFFFFFF)"
    )]
    IdLength { text: String },
    #[error("{text:?} is not valid hexadecimal (allowed: 0-9, a-f, A-F; '.' between data bytes)")]
    BadHex { text: String },
    #[error(
        "frame {text:?} has a raw DLC 9..F (_{dlc}); buslab frames carry DLC 0..8 (9..15 mean 8 bytes on the wire)"
    )]
    RawDlcNotSupported { text: String, dlc: char },
    #[error(
        "frame {text:?} is an error frame (ID with the 0x20000000 flag); buslab sends only data and remote frames"
    )]
    ErrorFrameNotSupported { text: String },
    #[error("DLC {dlc} is out of range 0..8")]
    DlcOutOfRange { dlc: u8 },
    #[error("{len} data bytes given; a classic CAN frame carries 0..8")]
    TooMuchData { len: usize },
    #[error("data {text:?} has an odd number of hex digits; each byte takes two")]
    OddHexDigits { text: String },
    #[error("frame {text:?} has no '#': expected ID#DATA, e.g. 123#DEADBEEF or 123#R")]
    MissingSeparator { text: String },
    #[error(
        "frame {text:?} is CAN FD (##): an FD frame, not a classic one (buslab's bit-level bus is classic CAN)"
    )]
    FdNotSupported { text: String },
    #[error("frame {text:?} is not CAN FD: expected ID##FLAGS DATA, e.g. 123##1112233")]
    NotFd { text: String },
    #[error(
        "frame {text:?}: after ## comes one hex flags digit (BRS = 1, ESI = 2), e.g. 123##1112233"
    )]
    FdFlags { text: String },
    #[error("{len} data bytes given; a CAN FD frame carries 0..8, 12, 16, 20, 24, 32, 48 or 64")]
    FdLength { len: usize },
    #[error("remote frame length {text:?} must be one digit 0..8 after R")]
    BadRemoteLength { text: String },
    #[error(
        "{text:?} is not an 11-bit identifier 0x000..=0x7EF (hex with 0x, or decimal; CAN 2.0A forbids 0x7F0..=0x7FF)"
    )]
    ProtocolId { text: String },
    #[error(
        "JerryCAN ID {text:?} must be 3 hex digits: ID10..ID0 and a don't-care bit (the ID shifted left by one, 000..FFF; 246 is 123)"
    )]
    JerryCanId { text: String },
}
