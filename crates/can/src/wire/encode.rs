//! Frame → wire bits, table-driven and lazy.
//!
//! The bits SOF..CRC (at most 118) are laid out as one `u128`; the CRC is computed a byte at a
//! time from a table; stuffing goes a byte at a time through a table of the stuffed forms of
//! each byte. Only the stuffed bits are kept: the de-stuffed bits follow from the frame and its
//! CRC, the stuff-bit mask from the stuffed bits themselves (a bit is a stuff bit exactly when
//! the five before it are equal), and field spans from both, each computed when asked
//! ([`Encoded::unstuffed`], [`Encoded::is_stuff_bit`], [`Encoded::fields`],
//! [`Encoded::wire_fields`]), so the simulator's per-frame cost is the encoding alone.

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
    /// De-stuffed bits SOF..CRC (the stuffed region before stuffing).
    region_len: u8,
    stuffed: Bits,
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

/// The bits the CRC covers (SOF..data), most significant first, and how many.
#[inline]
fn covered(frame: &Frame, dlc: u8) -> (u128, u32) {
    let (head, head_len) = header(frame, dlc);
    let data_len = 8 * frame.payload().len() as u32;
    (
        head << data_len | u128::from(frame.payload_bits()),
        head_len + data_len,
    )
}

/// SOF..CRC in wire order (first bit lowest, at most 118 bits) from the covered bits and
/// their CRC.
#[inline]
fn region(covered: u128, covered_len: u32, crc: u16) -> (u128, u32) {
    let len = covered_len + 15;
    (
        (covered << 15 | crc as u128).reverse_bits() >> (128 - len),
        len,
    )
}

fn encode_bits(frame: &Frame, dlc: u8) -> Encoded {
    let (covered, covered_len) = covered(frame, dlc);
    let crc = crc15_of(covered, covered_len);
    // SOF..CRC is stuffed most significant bit first, from left-aligned words: their bytes
    // from the top are the wire's bytes, the first bit in each byte's top bit. The whole bytes
    // before the CRC go first: they do not wait for the CRC, so the processor works on both at
    // once.
    let mut out = Stuffer::default();
    let left = covered << (128 - covered_len);
    let whole = covered_len / 8;
    out.bytes((left >> 64) as u64, whole.min(8));
    out.bytes(left as u64, whole.saturating_sub(8));
    // The covered bits left over (fewer than 8) and the CRC: at most 22 bits.
    let rest = covered_len % 8;
    let trailer_len = rest + 15;
    let trailer = ((covered as u64) & ((1 << rest) - 1)) << 15 | u64::from(crc);
    out.bytes(trailer << (64 - trailer_len), trailer_len / 8);
    out.last_bits(trailer & ((1 << (trailer_len % 8)) - 1), trailer_len % 8);
    Encoded {
        frame: *frame,
        dlc,
        crc,
        region_len: (covered_len + 15) as u8,
        stuffed: out.finish(),
    }
}

/// Stuffs SOF..CRC a byte at a time: [`STUFF_TABLE`] gives, for the run a byte starts in and
/// its 8 bits, the bits to send (stuff bits inserted), how many and the run it ends in; the
/// last, partial byte goes through [`TAIL_TABLE`] the same way. The recessive tail follows.
#[derive(Default)]
struct Stuffer {
    out: Writer,
    /// Where the current run state's entries start (run state × 256).
    row: usize,
}

impl Stuffer {
    /// The top `count` (≤ 8) bytes of `word`, two per append (at most 20 bits).
    #[inline(always)]
    fn bytes(&mut self, word: u64, count: u32) {
        let byte = |i: u32| (word >> (56 - 8 * i) & 0xFF) as usize;
        let mut i = 0;
        while i + 1 < count {
            let first = STUFF_TABLE[self.row + byte(i)];
            let second = STUFF_TABLE[next_row(first) + byte(i + 1)];
            let first_len = first >> LEN_SHIFT & 0xF;
            self.out.append_bits(
                u64::from(first & 0x3FF) | u64::from(second & 0x3FF) << first_len,
                first_len + (second >> LEN_SHIFT & 0xF),
            );
            self.row = next_row(second);
            i += 2;
        }
        if i < count {
            let entry = STUFF_TABLE[self.row + byte(i)];
            self.out.append(entry);
            self.row = next_row(entry);
        }
    }

    /// The last `count` (< 8) bits of SOF..CRC, the first one highest, then the tail.
    #[inline(always)]
    fn last_bits(&mut self, bits: u64, count: u32) {
        self.out
            .append(TAIL_TABLE[self.row + (1 << count) - 1 + bits as usize]);
    }

    fn finish(mut self) -> Bits {
        self.out.append(TAIL as u32 | TAIL_LEN << LEN_SHIFT);
        self.out.finish()
    }
}

/// Run states: `2 × run length (0..=4) + run bit`; 0 before the first bit.
const RUN_STATES: usize = 10;

/// Where a table entry keeps the number of bits it sends (bits 0..10 are the bits).
const LEN_SHIFT: u32 = 10;
/// Where it keeps the row of the run state after them: run state × 256, up to 12 bits.
const ROW_SHIFT: u32 = 16;

/// The row of the [`STUFF_TABLE`] (and [`TAIL_TABLE`]) to use after `entry`'s bits.
#[inline(always)]
const fn next_row(entry: u32) -> usize {
    (entry >> ROW_SHIFT) as usize
}

/// For each run state (a row of 256) and byte (first wire bit highest): the bits sent, stuff
/// bits included, their number and the row of the run state after the byte, as
/// [`stuff_bits_of`] packs them. Built at compile time.
static STUFF_TABLE: [u32; RUN_STATES * 256] = {
    let mut table = [0; RUN_STATES * 256];
    let mut state = 0;
    while state < RUN_STATES {
        let mut byte = 0;
        while byte < 256 {
            let first_lowest = (byte as u8).reverse_bits() as u32;
            table[state * 256 + byte] = stuff_bits_of(state as u32, first_lowest, 8);
            byte += 1;
        }
        state += 1;
    }
    table
};

/// The same for the region's last, partial byte of `k` (0..8) bits: entry `2^k - 1 + bits`
/// of each state's row (`bits`: the `k` bits, first bit highest).
static TAIL_TABLE: [u32; RUN_STATES * 256] = {
    let mut table = [0; RUN_STATES * 256];
    let mut state = 0;
    while state < RUN_STATES {
        let mut k = 0;
        while k < 8 {
            let mut bits = 0;
            while bits < 1 << k {
                let first_lowest = ((bits as u32) << (8 - k) & 0xFF) as u8;
                let first_lowest = first_lowest.reverse_bits() as u32;
                table[state * 256 + (1 << k) - 1 + bits] =
                    stuff_bits_of(state as u32, first_lowest, k);
                bits += 1;
            }
            k += 1;
        }
        state += 1;
    }
    table
};

/// `count` (≤ 8) bits of `byte` (first wire bit lowest) stuffed, starting in run `state`: the
/// bits sent (bits 0..10), their number (from [`LEN_SHIFT`]) and the row of the run state after
/// them (from [`ROW_SHIFT`]). A stuff bit that the last bit calls for is sent with it, as at the
/// end of the CRC.
const fn stuff_bits_of(state: u32, byte: u32, count: u32) -> u32 {
    let (mut run_bit, mut run_len) = (state & 1, state >> 1);
    let (mut bits, mut len) = (0, 0);
    let mut i = 0;
    while i < count {
        let bit = byte >> i & 1;
        bits |= bit << len;
        len += 1;
        run_len = if bit == run_bit { run_len + 1 } else { 1 };
        run_bit = bit;
        if run_len == 5 {
            bits |= (bit ^ 1) << len;
            len += 1;
            (run_bit, run_len) = (bit ^ 1, 1);
        }
        i += 1;
    }
    let row = (2 * run_len + run_bit) * 256;
    bits | len << LEN_SHIFT | row << ROW_SHIFT
}

/// Appends table entries' bits to 64-bit words (up to 192 bits: a frame has ≤ 157). No field
/// is indexed, so all of them stay in registers.
#[derive(Default)]
struct Writer {
    /// Bits not yet in a completed word, first bit lowest, and how many (< 64).
    word: u64,
    fill: u32,
    /// The completed words, the last one in `last`, and how many (≤ 2).
    first: u64,
    last: u64,
    done: u32,
}

impl Writer {
    /// Appends the bits of a [`STUFF_TABLE`] or [`TAIL_TABLE`] entry (at most 10).
    #[inline(always)]
    fn append(&mut self, entry: u32) {
        self.append_bits(u64::from(entry & 0x3FF), entry >> LEN_SHIFT & 0xF);
    }

    /// Appends the `len` (≤ 20) low bits of `bits` (the bits above them are zero).
    #[inline(always)]
    fn append_bits(&mut self, bits: u64, len: u32) {
        self.word |= bits << self.fill;
        let fill = self.fill + len;
        if fill >= 64 {
            self.first = self.last;
            self.last = self.word;
            self.done += 1;
            // The bits that did not fit (the shift is below 64: the word had room for one).
            self.word = bits >> (64 - self.fill);
            self.fill = fill - 64;
        } else {
            self.fill = fill;
        }
    }

    fn finish(self) -> Bits {
        let words = match self.done {
            0 => [self.word, 0, 0],
            1 => [self.last, self.word, 0],
            _ => [self.first, self.last, self.word],
        };
        Bits::from_words(words, (64 * self.done + self.fill) as u16)
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

    /// De-stuffed bits SOF..end of EOF, ACK slot recessive (as sent). Computed on each call
    /// (from the frame and its CRC).
    pub fn unstuffed(&self) -> Bits {
        let (covered, covered_len) = covered(&self.frame, self.dlc);
        let (region, len) = region(covered, covered_len, self.crc);
        bits_from(region | TAIL << len, 0, len + TAIL_LEN)
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
        let mut bits = self.unstuffed();
        bits.set(bits.len() - FROM_ACK_SLOT, false);
        bits
    }

    /// Wire index of the ACK slot.
    pub const fn ack_slot(&self) -> usize {
        self.stuffed.len() - FROM_ACK_SLOT
    }

    /// Where the stuffed region (SOF..CRC with its stuff bits) ends: the CRC delimiter.
    const fn stuffed_region_end(&self) -> usize {
        self.stuffed.len() - TAIL_LEN as usize
    }

    /// Whether wire bit `i` is a stuff bit: inside the stuffed region, after five equal bits
    /// (a stuff bit differs from the bit before it, so five equal bits never span one, and
    /// five equal bits are always followed by one).
    pub fn is_stuff_bit(&self, i: usize) -> bool {
        (5..self.stuffed_region_end()).contains(&i)
            && matches!(self.stuffed.window(i - 5) as u8 & 0x1F, 0 | 0x1F)
    }

    /// Which wire bits are stuff bits (1 = stuff bit), as long as [`Self::stuffed`]; computed
    /// on each call, a few word operations (see [`Self::is_stuff_bit`]).
    pub(crate) fn stuff_mask(&self) -> Bits {
        let low = self.stuffed.window(0);
        let high = self.stuffed.window(128) as u64;
        // Shifted left by `k` as one 192-bit number.
        let shl = |k: u32| (low << k, high << k | (low >> (128 - k)) as u64);
        // equal[i]: wire bit i equals bit i - 1.
        let (s_low, s_high) = shl(1);
        let (e_low, e_high) = (!(low ^ s_low), !(high ^ s_high));
        // Bit p: the four pairs p-1/p-2 .. p-4/p-5 equal, i.e. bits p-5..p-1 equal.
        let (mut m_low, mut m_high) = (u128::MAX, u64::MAX);
        for k in 1..=4 {
            m_low &= e_low << k;
            m_high &= e_high << k | (e_low >> (128 - k)) as u64;
        }
        // Only inside the stuffed region, from bit 5 on (the bits before SOF do not count).
        let end = self.stuffed_region_end() as u32;
        let below = |n: u32| -> (u128, u64) {
            if n >= 128 {
                (u128::MAX, (1u64 << (n - 128)) - 1)
            } else {
                ((1u128 << n) - 1, 0)
            }
        };
        let (r_low, r_high) = below(end);
        bits_from(
            m_low & r_low & !0x1F,
            m_high & r_high,
            self.stuffed.len() as u32,
        )
    }

    /// Number of stuff bits.
    pub const fn stuff_bits(&self) -> usize {
        self.stuffed_region_end() - self.region_len as usize
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
        let mask = self.stuff_mask();
        for base in [0, 128] {
            let mut stuff = mask.window(base);
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
