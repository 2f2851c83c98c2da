//! The bit-level wire codec: frame → bits (unstuffed and stuffed, CRC-15) and a bit-by-bit
//! receiver that rebuilds frames and reports stuff, CRC and form errors with their position.
//!
//! Bits are `bool`s: `false` = 0 = dominant, `true` = 1 = recessive, first on the wire first.

mod bits;
mod crc;
mod encode;
mod field;
mod receive;

pub use bits::Bits;
pub use crc::{CRC15_POLY, Crc15};
pub use encode::{Encoded, encode, encode_with_dlc};
pub use field::{Field, Span, Spans};
pub use receive::{DecodeError, Decoded, Receiver, Step, WireError, WireErrorKind, decode};

#[cfg(test)]
mod tests;
