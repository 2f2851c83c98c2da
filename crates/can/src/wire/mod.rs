//! The bit-level wire codec: frame → bits (unstuffed and stuffed, CRC-15) and a bit-by-bit
//! receiver that rebuilds frames and reports stuff, CRC and form errors with their position.
//!
//! For the simulator's frame-level fast path: the encoder is table-driven ([`encode`]), an
//! [`EncodeCache`] keeps a node's last encoding, and [`decode_bits`] decodes a whole frame in
//! one pass with the same results as the [`Receiver`].
//!
//! Bits are `bool`s: `false` = 0 = dominant, `true` = 1 = recessive, first on the wire first.

mod bits;
mod cache;
mod crc;
mod decode_bits;
mod encode;
mod field;
mod receive;
mod stuffing;

/// The most bit-times a classic frame takes on the wire, intermission included: an extended
/// data frame of 8 bytes with every possible stuff bit (118 bits from SOF to the end of the
/// CRC, a stuff bit after each 4 of them past the first, 29; 10 from the CRC delimiter to the
/// end of EOF; 3 of intermission). The one place this fact lives: budgets, timeouts and
/// watchdogs elsewhere use it.
pub const LONGEST_FRAME_BITS: u64 = 118 + (118 - 1) / 4 + 10 + INTERMISSION_BITS;
/// [`LONGEST_FRAME_BITS`] as bus time.
pub const LONGEST_FRAME: crate::BitTime = crate::BitTime::new(LONGEST_FRAME_BITS);

/// The recessive bits between two frames (ISO 11898-1's intermission).
pub const INTERMISSION_BITS: u64 = 3;

/// Bit-times `frame` takes on an undisturbed bus: SOF to the end of EOF with its stuff bits,
/// and the intermission after it (the unit of bus load).
pub fn frame_bits(frame: &crate::Frame) -> u64 {
    encode(frame).stuffed().len() as u64 + INTERMISSION_BITS
}

pub use bits::Bits;
pub use cache::EncodeCache;
pub use crc::{CRC15_POLY, Crc15};
pub use decode_bits::decode_bits;
pub use encode::{Encoded, encode, encode_with_dlc};
pub use field::{Field, Span, Spans};
pub use receive::{DecodeError, Decoded, Receiver, Step, WireError, WireErrorKind, decode};

#[cfg(test)]
mod tests;
