//! Frame → wire bits, table-driven.
//!
//! The bits SOF..CRC (at most 118) are laid out as one `u128`; the CRC is computed a byte at a
//! time from a table; stuffing takes a few word operations per stuff bit
//! rather than a step per bit. Field spans are derived from the frame and the stuff bits only when asked
//! ([`Encoded::fields`], [`Encoded::wire_fields`]), so the simulator's per-frame cost is the
//! encoding alone.

use super::crc::crc15_of;
use super::{Bits, Decoded, Field, Span, Spans};
use crate::Frame;

/// A frame laid out on the wire, SOF to the end of EOF (intermission not included).
///
/// The bit strings are the **transmitter's view**: the ACK slot is recessive, as the transmitter
/// sends it. [`Encoded::on_bus`] gives the view on a bus where a receiver acknowledged
/// (ACK slot dominant).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Encoded {
    frame: Frame,
    dlc: u8,
    crc: u16,
    unstuffed: Bits,
    stuffed: Bits,
    stuff_mask: Bits,
}

/// Encode a frame with its own DLC.
pub fn encode(frame: &Frame) -> Encoded {
    encode_bits(frame, frame.dlc())
}

/// Encode with a raw DLC of 9..15, which ISO 11898-1 allows a classic transmitter to send for
/// 8 data bytes. `None` unless `dlc` is 0..15 and means the same length as the frame's DLC
/// (`min(dlc, 8) == frame.dlc()`).
pub fn encode_with_dlc(frame: &Frame, dlc: u8) -> Option<Encoded> {
    (dlc <= 15 && dlc.min(8) == frame.dlc()).then(|| encode_bits(frame, dlc))
}

/// CRC delimiter, ACK slot (as sent), ACK delimiter and 7 EOF bits: all recessive.
const TAIL: u128 = 0x3FF;
const TAIL_LEN: u32 = 10;

/// SOF..DLC, most significant bit first, and its length (19 or 39 bits).
#[inline]
fn header(frame: &Frame, dlc: u8) -> (u128, u32) {
    let id = frame.id().as_raw() as u128;
    let rtr = frame.is_remote() as u128;
    let dlc = dlc as u128 & 0xF;
    if frame.is_extended() {
        // SOF 0, ID28..18, SRR 1, IDE 1, ID17..0, RTR, r1 0, r0 0, DLC.
        let value = (id >> 18) << 27 | 0b11 << 25 | (id & 0x3_FFFF) << 7 | rtr << 6 | dlc;
        (value, 39)
    } else {
        // SOF 0, ID10..0, RTR, IDE 0, r0 0, DLC.
        (id << 7 | rtr << 6 | dlc, 19)
    }
}

fn encode_bits(frame: &Frame, dlc: u8) -> Encoded {
    let (head, head_len) = header(frame, dlc);
    let payload = frame.payload();
    let data_len = 8 * payload.len() as u32;
    let mut bytes = [0u8; 16];
    bytes[16 - payload.len()..].copy_from_slice(payload);
    let covered = head << data_len | u128::from_be_bytes(bytes);
    let covered_len = head_len + data_len;
    let crc = crc15_of(covered, covered_len);
    // SOF..CRC in wire order (first bit lowest), at most 118 bits.
    let region_len = covered_len + 15;
    let region = (covered << 15 | crc as u128).reverse_bits() >> (128 - region_len);
    let unstuffed = region | TAIL << region_len;
    let unstuffed = bits_from(unstuffed, 0, region_len + TAIL_LEN);
    let (stuffed, stuff_mask) = stuff(region, region_len);
    Encoded {
        frame: *frame,
        dlc,
        crc,
        unstuffed,
        stuffed,
        stuff_mask,
    }
}

/// Alternating bits: put above the region, they never make a run of 5 of their own, so runs
/// are looked for without masking the region off.
const SENTINEL: u128 = u128::MAX / 3;

/// The stuffed bits of `region` (`len` ≤ 118 bits, first bit lowest) followed by the
/// recessive tail, and the mask of the stuff bits.
///
/// Each step finds the end of the next run of 5 with word operations, puts the stuff bit in
/// front of the rest (it begins a new run) and writes that rest over the output from the stuff
/// bit on; so the work is per stuff bit, not per bit.
#[inline]
fn stuff(region: u128, len: u32) -> (Bits, Bits) {
    // The region then the sentinel; after each step the top fills with zeros, but always more
    // than 4 sentinel bits lie between them and the region, so a run found there is past the end.
    let mut seg = region | SENTINEL << len;
    let mut seg_len = len;
    let mut out = Wide { low: seg, high: 0 };
    let mut mask = Wide { low: 0, high: 0 };
    // Output index of the first bit of `seg`.
    let mut at = 0;
    loop {
        let same = !(seg ^ seg << 1) & !1;
        let run_end = (same & same << 1 & same << 2 & same << 3).trailing_zeros();
        if run_end >= seg_len {
            break;
        }
        let stuff_bit = !(seg >> run_end) & 1;
        // run_end ≤ 117, so the shifts stay in range.
        seg = (seg >> (run_end + 1)) << 1 | stuff_bit;
        seg_len -= run_end;
        at += run_end + 1;
        out.write_from(at, seg);
        mask.set(at);
    }
    out.write_from(at + seg_len, TAIL);
    let len = at + seg_len + TAIL_LEN;
    (
        bits_from(out.low, out.high, len),
        bits_from(mask.low, mask.high, len),
    )
}

/// A 192-bit string being built, first bit lowest.
struct Wide {
    low: u128,
    high: u64,
}

impl Wide {
    /// Replace the bits from `at` (1..192) on with `bits` (cut at 192).
    #[inline]
    fn write_from(&mut self, at: u32, bits: u128) {
        if at < 128 {
            self.low = self.low & u128::MAX >> (128 - at) | bits << at;
            self.high = (bits >> (128 - at)) as u64;
        } else {
            let at = at - 128;
            self.high = self.high & !(u64::MAX << at) | (bits as u64) << at;
        }
    }

    /// Set bit `at` (< 192).
    #[inline]
    fn set(&mut self, at: u32) {
        if at < 128 {
            self.low |= 1 << at;
        } else {
            self.high |= 1 << (at - 128);
        }
    }
}

/// A [`Bits`] of `len` bits from the low 192 bits of `high:low`.
#[inline]
fn bits_from(low: u128, high: u64, len: u32) -> Bits {
    // At most 157 bits: the stuffed region (≤ 147) and the tail; the rest is zero already.
    Bits::from_words([low as u64, (low >> 64) as u64, high], len as u16)
}

impl Encoded {
    pub const fn frame(&self) -> &Frame {
        &self.frame
    }

    /// The DLC as transmitted (9..15 only via [`encode_with_dlc`]).
    pub const fn dlc(&self) -> u8 {
        self.dlc
    }

    /// The CRC-15 over SOF..data.
    pub const fn crc(&self) -> u16 {
        self.crc
    }

    /// De-stuffed bits SOF..end of EOF, ACK slot recessive (as sent).
    pub const fn unstuffed(&self) -> &Bits {
        &self.unstuffed
    }

    /// Wire bits SOF..end of EOF with stuff bits, ACK slot recessive (as sent).
    pub const fn stuffed(&self) -> &Bits {
        &self.stuffed
    }

    /// Wire bits as seen on a bus where a receiver acknowledged: ACK slot dominant.
    pub fn on_bus(&self) -> Bits {
        let mut bits = self.stuffed;
        bits.set(self.ack_slot(), false);
        bits
    }

    /// De-stuffed bits with the ACK slot dominant.
    pub fn unstuffed_on_bus(&self) -> Bits {
        let mut bits = self.unstuffed;
        bits.set(self.unstuffed.len() - FROM_ACK_SLOT, false);
        bits
    }

    /// Wire index of the ACK slot.
    pub const fn ack_slot(&self) -> usize {
        self.stuffed.len() - FROM_ACK_SLOT
    }

    /// Whether wire bit `i` is a stuff bit.
    pub fn is_stuff_bit(&self, i: usize) -> bool {
        i < self.stuff_mask.len() && self.stuff_mask.bit(i)
    }

    /// Number of stuff bits.
    pub const fn stuff_bits(&self) -> usize {
        self.stuffed.len() - self.unstuffed.len()
    }

    /// What a receiver rebuilds from these bits on an undisturbed bus (the same as
    /// [`super::decode`] of [`Encoded::on_bus`] or [`Encoded::stuffed`]), without decoding.
    pub const fn decoded(&self, acked: bool) -> Decoded {
        Decoded {
            frame: self.frame,
            dlc: self.dlc,
            crc: self.crc,
            acked,
            stuff_bits: self.stuff_bits() as u32,
            wire_len: self.stuffed.len() as u32,
        }
    }

    /// Field spans in the de-stuffed bits (computed on each call; they depend only on the
    /// format and the data length).
    pub fn fields(&self) -> Spans {
        let mut spans = Spans::new();
        let mut at = 0;
        let mut put = |field, len| {
            spans.push(Span {
                field,
                start: at,
                len,
            });
            at += len;
        };
        put(Field::Sof, 1);
        if self.frame.is_extended() {
            put(Field::Id, 11);
            put(Field::Srr, 1);
            put(Field::Ide, 1);
            put(Field::IdExt, 18);
            put(Field::Rtr, 1);
            put(Field::R1, 1);
        } else {
            put(Field::Id, 11);
            put(Field::Rtr, 1);
            put(Field::Ide, 1);
        }
        put(Field::R0, 1);
        put(Field::Dlc, 4);
        let data = 8 * self.frame.payload().len() as u16;
        if data > 0 {
            put(Field::Data, data);
        }
        put(Field::Crc, 15);
        put(Field::CrcDelimiter, 1);
        put(Field::AckSlot, 1);
        put(Field::AckDelimiter, 1);
        put(Field::Eof, 7);
        spans
    }

    /// Field spans in the wire bits; each includes the stuff bits its own bits caused (so the
    /// stuff bit after the last CRC bit, if any, belongs to the CRC). Computed on each call.
    pub fn wire_fields(&self) -> Spans {
        // De-stuffed index of the bit that caused each stuff bit, in order.
        let mut causes = [0u16; 32];
        let mut count = 0;
        for wire in 0..self.stuff_mask.len() {
            if self.stuff_mask.bit(wire) && count < causes.len() {
                causes[count] = (wire - 1 - count) as u16;
                count += 1;
            }
        }
        let causes = &causes[..count];
        // A field starts on the wire after the stuff bits caused by the bits before it.
        let wire_start = |start: u16| start + causes.iter().filter(|&&c| c < start).count() as u16;
        let mut spans = Spans::new();
        for span in self.fields().iter() {
            let start = wire_start(span.start);
            let end = if span.field == Field::Eof {
                self.stuffed.len() as u16
            } else {
                wire_start(span.start + span.len)
            };
            spans.push(Span {
                field: span.field,
                start,
                len: end - start,
            });
        }
        spans
    }
}

/// ACK slot, ACK delimiter and EOF: the ACK slot is this many bits before the end.
const FROM_ACK_SLOT: usize = 9;
