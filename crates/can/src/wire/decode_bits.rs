//! Wire bits → frame in one pass over words, for the simulator's frame-level fast path.
//!
//! Gives exactly what [`super::decode`] (the bit-by-bit [`super::Receiver`]) gives for the same
//! bits — the frame, or the same error at the same wire bit in the same field — but removes
//! stuff bits one run at a time with word operations and computes the CRC a byte at a time.

use super::crc::crc15_of;
use super::stuffing::{first_run_end, low_mask, msb_first};
use super::{Bits, DecodeError, Decoded, Field, WireError, WireErrorKind};
use crate::{ExtendedId, Frame, Id, StandardId};

/// Decode a whole wire bit string starting at SOF (`true` = 1 = recessive); recessive bits
/// after EOF are allowed. The result equals [`super::decode`]`(bits.iter())`.
pub fn decode_bits(bits: &Bits) -> Result<Decoded, DecodeError> {
    let len = bits.len() as u32;
    if len == 0 {
        return Err(DecodeError::Empty);
    }
    if bits.bit(0) {
        return Err(form(0, Field::Sof));
    }
    let mut rx = Destuffer {
        bits,
        len,
        wire: 0,
        run_bit: true,
        run_len: 0,
        data: 0,
        taken: 0,
        stuff: 0,
    };
    // SOF..DLC of a standard frame; the IDE bit (13) says whether 20 more header bits follow.
    rx.take(STANDARD_HEADER)?;
    let extended = rx.data_bit(13);
    let header = if extended {
        rx.take(EXTENDED_HEADER)?;
        EXTENDED_HEADER
    } else {
        STANDARD_HEADER
    };
    let dlc = msb_first(rx.data, header - 4, 4) as u8;
    let remote = rx.data_bit(if extended { 32 } else { 12 });
    let data_bytes = if remote { 0 } else { dlc.min(8) as u32 };
    let covered = header + 8 * data_bytes;
    rx.take(covered + 15)?;

    let crc_computed = crc15_of(
        (rx.data & low_mask(covered)).reverse_bits() >> (128 - covered),
        covered,
    );
    let crc_received = msb_first(rx.data, covered, 15) as u16;
    // The fixed-form bits after the CRC (and its trailing stuff bit, if any) are not stuffed.
    let end = rx.wire;
    let fixed = |i: u32, field: Field| {
        if end + i >= len {
            return Err(DecodeError::Truncated { bits: len, field });
        }
        Ok(bits.bit((end + i) as usize))
    };
    if !fixed(0, Field::CrcDelimiter)? {
        return Err(form(end, Field::CrcDelimiter));
    }
    let acked = !fixed(1, Field::AckSlot)?;
    if !fixed(2, Field::AckDelimiter)? {
        return Err(form(end + 2, Field::AckDelimiter));
    }
    if crc_received != crc_computed {
        return Err(DecodeError::Wire(WireError {
            kind: WireErrorKind::Crc {
                received: crc_received,
                computed: crc_computed,
            },
            bit: end + 2,
            field: Field::AckDelimiter,
        }));
    }
    for i in 3..10 {
        if !fixed(i, Field::Eof)? {
            return Err(form(end + i, Field::Eof));
        }
    }
    let frame_end = end + 10;

    let Some(frame) = rx.frame(extended, remote, dlc, data_bytes) else {
        // The receiver would wait for more bits forever (it cannot happen: every field value
        // makes a valid frame).
        return Err(DecodeError::Truncated {
            bits: len,
            field: Field::Eof,
        });
    };
    if let Some(bit) = (frame_end..len).find(|&i| !bits.bit(i as usize)) {
        return Err(DecodeError::TrailingDominant { bit });
    }
    Ok(Decoded {
        frame,
        dlc,
        crc: crc_received,
        acked,
        stuff_bits: rx.stuff,
        wire_len: frame_end,
    })
}

/// SOF..DLC: 1 + 11 + RTR + IDE + r0 + 4.
const STANDARD_HEADER: u32 = 19;
/// SOF..DLC: 1 + 11 + SRR + IDE + 18 + RTR + r1 + r0 + 4.
const EXTENDED_HEADER: u32 = 39;

fn form(bit: u32, field: Field) -> DecodeError {
    DecodeError::Wire(WireError {
        kind: WireErrorKind::Form,
        bit,
        field,
    })
}

/// De-stuffs the stuffed region (SOF..CRC, at most 118 data bits) a run at a time.
struct Destuffer<'a> {
    bits: &'a Bits,
    len: u32,
    /// Wire index of the next bit.
    wire: u32,
    /// The run of equal bits before `wire` (at most 4 long; a stuff bit starts a new run).
    run_bit: bool,
    run_len: u32,
    /// De-stuffed bits taken so far, first bit lowest.
    data: u128,
    taken: u32,
    stuff: u32,
}

impl Destuffer<'_> {
    fn data_bit(&self, i: u32) -> bool {
        self.data >> i & 1 == 1
    }

    /// Take data bits until `limit` (≤ 118) are taken, removing stuff bits, and the stuff bit
    /// after them if they end a run of 5. Errors as the receiver reports them: a stuff error,
    /// or the input ending.
    fn take(&mut self, limit: u32) -> Result<(), DecodeError> {
        while self.taken < limit {
            let available = self.len - self.wire;
            if available == 0 {
                return Err(self.truncated());
            }
            // The earlier bits of the current run go below the new bits, so a run of 5 that
            // started before `wire` is found too (at most 4 + 118 bits).
            let new = available.min(limit - self.taken);
            let context = self.run_len;
            let run = if self.run_bit { low_mask(context) } else { 0 };
            let seg = (self.bits.window(self.wire as usize) & low_mask(new)) << context | run;
            let seg_len = context + new;
            let Some(k) = first_run_end(seg, seg_len) else {
                self.push(seg >> context, new);
                let last = seg >> (seg_len - 1) & 1 == 1;
                let differing = if last { !seg } else { seg } & low_mask(seg_len);
                self.run_bit = last;
                self.run_len = match differing {
                    0 => seg_len,
                    d => seg_len - 1 - (127 - d.leading_zeros()),
                };
                continue;
            };
            // The run ends at k (never inside the ≤ 4 context bits): a stuff bit follows.
            let count = k + 1 - context;
            self.push(seg >> context, count);
            let run_bit = seg >> k & 1 == 1;
            if self.wire >= self.len {
                return Err(self.truncated());
            }
            let stuff_bit = self.bits.bit(self.wire as usize);
            if stuff_bit == run_bit {
                return Err(DecodeError::Wire(WireError {
                    kind: WireErrorKind::Stuff,
                    bit: self.wire,
                    field: self.field_of(self.taken - 1),
                }));
            }
            self.wire += 1;
            self.stuff += 1;
            (self.run_bit, self.run_len) = (stuff_bit, 1);
        }
        Ok(())
    }

    /// Append `count` data bits (the low bits of `seg`), which are the next wire bits.
    fn push(&mut self, seg: u128, count: u32) {
        self.data |= (seg & low_mask(count)) << self.taken;
        self.taken += count;
        self.wire += count;
    }

    /// The input ended: named, as the receiver does, by the field of the next data bit.
    fn truncated(&self) -> DecodeError {
        DecodeError::Truncated {
            bits: self.len,
            field: self.field_of(self.taken),
        }
    }

    /// The field of de-stuffed bit `i`, as far as the bits taken tell (bit `i` ≥ 14 needs the
    /// IDE bit, bits past the header the DLC; both are taken by then). Bit 12 reads as RTR, as
    /// in the receiver, because only IDE tells SRR apart.
    fn field_of(&self, i: u32) -> Field {
        let extended = self.taken > 13 && self.data_bit(13);
        let (header, remote) = if extended {
            (EXTENDED_HEADER, self.data_bit(32))
        } else {
            (STANDARD_HEADER, self.data_bit(12))
        };
        let data_bits = if remote || self.taken < header {
            0
        } else {
            8 * (msb_first(self.data, header - 4, 4).min(8))
        };
        match i {
            0 => Field::Sof,
            1..=11 => Field::Id,
            12 => Field::Rtr,
            13 => Field::Ide,
            14..=31 if extended => Field::IdExt,
            32 if extended => Field::Rtr,
            33 if extended => Field::R1,
            34 if extended => Field::R0,
            14 if !extended => Field::R0,
            _ if i < header => Field::Dlc,
            _ if i < header + data_bits => Field::Data,
            _ if i < header + data_bits + 15 => Field::Crc,
            _ => Field::CrcDelimiter,
        }
    }

    /// The frame from the de-stuffed header and data.
    fn frame(&self, extended: bool, remote: bool, dlc: u8, data_bytes: u32) -> Option<Frame> {
        let id = if extended {
            let raw = msb_first(self.data, 1, 11) << 18 | msb_first(self.data, 14, 18);
            Id::Extended(ExtendedId::new(raw).ok()?)
        } else {
            Id::Standard(StandardId::new(msb_first(self.data, 1, 11) as u16).ok()?)
        };
        if remote {
            return Frame::remote(id, dlc.min(8)).ok();
        }
        let header = if extended {
            EXTENDED_HEADER
        } else {
            STANDARD_HEADER
        };
        let mut bytes = [0u8; 8];
        for (n, byte) in bytes.iter_mut().enumerate().take(data_bytes as usize) {
            *byte = msb_first(self.data, header + 8 * n as u32, 8) as u8;
        }
        Frame::data(id, &bytes[..data_bytes as usize]).ok()
    }
}
