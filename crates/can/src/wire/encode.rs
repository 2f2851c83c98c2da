//! Frame → wire bits, table-driven.
//!
//! The bits SOF..CRC (at most 118) are laid out as one `u128`; the CRC is computed a byte at a
//! time from a table; stuffing goes a byte at a time through a table of
//! the stuffed forms of each byte. Field spans are derived from the frame and the stuff bits only when asked
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
    let data_len = 8 * frame.payload().len() as u32;
    let covered = head << data_len | u128::from(frame.payload_bits());
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

/// The stuffed bits of `region` (`len` ≤ 118 bits, first bit lowest) followed by the
/// recessive tail, and the mask of the stuff bits.
///
/// A byte of the region at a time: [`STUFF_TABLE`] gives, for the run the byte starts in and
/// its 8 bits, the bits to send (stuff bits inserted), where the stuff bits are and the run it
/// ends in. The last, partial byte goes bit by bit.
#[inline]
fn stuff(region: u128, len: u32) -> (Bits, Bits) {
    let bytes = region.to_le_bytes();
    let mut out = Writer::default();
    let mut state = 0;
    for &byte in &bytes[..(len / 8) as usize] {
        let entry = STUFF_TABLE[state][byte as usize];
        out.append(
            (entry & 0x3FF) as u64,
            (entry >> 10 & 0x3FF) as u64,
            8 + (entry >> 20 & 3),
        );
        state = (entry >> 24) as usize & 0xF;
    }
    let last = bytes[(len / 8) as usize & 15];
    let (mut run_bit, mut run_len) = (state as u8 & 1, state as u32 >> 1);
    for i in 0..len % 8 {
        let bit = last >> i & 1;
        out.append(bit as u64, 0, 1);
        run_len = if bit == run_bit { run_len + 1 } else { 1 };
        run_bit = bit;
        if run_len == 5 {
            out.append((bit ^ 1) as u64, 1, 1);
            (run_bit, run_len) = (bit ^ 1, 1);
        }
    }
    out.append(TAIL as u64, 0, TAIL_LEN);
    out.finish()
}

/// Run states: `2 × run length (0..=4) + run bit`; 0 before the first bit.
const RUN_STATES: usize = 10;

/// For each run state and byte (first wire bit lowest): the bits sent, stuff bits included
/// (bits 0..10), the stuff-bit mask (bits 10..20), the number of stuff bits (20..22, at most 2
/// per byte) and the run state after the byte (24..28). Built at compile time.
static STUFF_TABLE: [[u32; 256]; RUN_STATES] = {
    let mut table = [[0; 256]; RUN_STATES];
    let mut state = 0;
    while state < RUN_STATES {
        let mut byte = 0;
        while byte < 256 {
            table[state][byte] = stuff_byte(state as u32, byte as u32);
            byte += 1;
        }
        state += 1;
    }
    table
};

/// One [`STUFF_TABLE`] entry, computed bit by bit.
const fn stuff_byte(state: u32, byte: u32) -> u32 {
    let (mut run_bit, mut run_len) = (state & 1, state >> 1);
    let (mut bits, mut mask, mut len) = (0, 0, 0);
    let mut i = 0;
    while i < 8 {
        let bit = byte >> i & 1;
        bits |= bit << len;
        len += 1;
        run_len = if bit == run_bit { run_len + 1 } else { 1 };
        run_bit = bit;
        if run_len == 5 {
            mask |= 1 << len;
            bits |= (bit ^ 1) << len;
            len += 1;
            (run_bit, run_len) = (bit ^ 1, 1);
        }
        i += 1;
    }
    bits | mask << 10 | (len - 8) << 20 | (2 * run_len + run_bit) << 24
}

/// Appends bits and their stuff mask to 64-bit words (up to 192 bits: a frame has ≤ 157).
#[derive(Default)]
struct Writer {
    bits: [u64; 4],
    mask: [u64; 4],
    word_bits: u64,
    word_mask: u64,
    /// Bits in the current word (< 64) and words completed.
    filled: u32,
    words: usize,
}

impl Writer {
    /// Append `len` (1..=10) bits and the matching mask bits.
    #[inline(always)]
    fn append(&mut self, bits: u64, mask: u64, len: u32) {
        self.word_bits |= bits << self.filled;
        self.word_mask |= mask << self.filled;
        self.filled += len;
        if self.filled >= 64 {
            self.filled -= 64;
            self.bits[self.words & 3] = self.word_bits;
            self.mask[self.words & 3] = self.word_mask;
            self.words += 1;
            // The bits that did not fit; none if the word ended exactly with them.
            let written = len - self.filled;
            self.word_bits = bits >> written;
            self.word_mask = mask >> written;
        }
    }

    fn finish(mut self) -> (Bits, Bits) {
        self.bits[self.words & 3] = self.word_bits;
        self.mask[self.words & 3] = self.word_mask;
        let len = (64 * self.words as u32 + self.filled) as u16;
        let [b0, b1, b2, _] = self.bits;
        let [m0, m1, m2, _] = self.mask;
        (
            Bits::from_words([b0, b1, b2], len),
            Bits::from_words([m0, m1, m2], len),
        )
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

    /// Which wire bits are stuff bits (1 = stuff bit), as long as [`Self::stuffed`].
    pub(crate) const fn stuff_mask(&self) -> &Bits {
        &self.stuff_mask
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
        for base in [0, 128] {
            let mut stuff = self.stuff_mask.window(base);
            while stuff != 0 && count < causes.len() {
                let wire = base + stuff.trailing_zeros() as usize;
                stuff &= stuff - 1;
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
