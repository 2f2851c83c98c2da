//! Frame → wire bits.

use super::{Bits, Crc15, Field, Span, Spans};
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
    fields: Spans,
    wire_fields: Spans,
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

fn encode_bits(frame: &Frame, dlc: u8) -> Encoded {
    let mut raw = Bits::new();
    let mut fields = Spans::new();
    let mut put = |field: Field, value: u32, len: u16| {
        fields.push(Span {
            field,
            start: raw.len() as u16,
            len,
        });
        for n in (0..len).rev() {
            raw.push(value >> n & 1 == 1);
        }
    };
    let id = frame.id().as_raw();
    let rtr = frame.is_remote() as u32;
    put(Field::Sof, 0, 1);
    if frame.is_extended() {
        put(Field::Id, id >> 18, 11);
        put(Field::Srr, 1, 1);
        put(Field::Ide, 1, 1);
        put(Field::IdExt, id & 0x3_FFFF, 18);
        put(Field::Rtr, rtr, 1);
        put(Field::R1, 0, 1);
    } else {
        put(Field::Id, id, 11);
        put(Field::Rtr, rtr, 1);
        put(Field::Ide, 0, 1);
    }
    put(Field::R0, 0, 1);
    put(Field::Dlc, dlc as u32, 4);
    let payload = frame.payload();
    if !payload.is_empty() {
        fields.push(Span {
            field: Field::Data,
            start: raw.len() as u16,
            len: 8 * payload.len() as u16,
        });
        for byte in payload {
            for n in (0..8).rev() {
                raw.push(byte >> n & 1 == 1);
            }
        }
    }
    let mut crc = Crc15::new();
    for bit in raw.iter() {
        crc.push(bit);
    }
    let crc = crc.value();
    let mut put = |field: Field, value: u32, len: u16| {
        fields.push(Span {
            field,
            start: raw.len() as u16,
            len,
        });
        for n in (0..len).rev() {
            raw.push(value >> n & 1 == 1);
        }
    };
    put(Field::Crc, crc as u32, 15);
    put(Field::CrcDelimiter, 1, 1);
    put(Field::AckSlot, 1, 1);
    put(Field::AckDelimiter, 1, 1);
    put(Field::Eof, 0x7F, 7);

    // Stuff SOF..last CRC bit. A stuff bit belongs to the field whose bits caused it, so a
    // field's wire span runs up to the first bit of the next field.
    let stuff_end = fields.get(Field::Crc).map_or(0, |s| s.end());
    let mut stuffed = Bits::new();
    let mut stuff_mask = Bits::new();
    let mut wire_fields = Spans::new();
    let mut next_field = 0;
    let (mut run_bit, mut run_len) = (true, 0u8);
    for (i, bit) in raw.iter().enumerate() {
        if let Some(span) = fields.as_slice().get(next_field)
            && span.start as usize == i
        {
            wire_fields.push(Span {
                field: span.field,
                start: stuffed.len() as u16,
                len: 0,
            });
            next_field += 1;
        }
        stuffed.push(bit);
        stuff_mask.push(false);
        if i >= stuff_end {
            continue;
        }
        if bit == run_bit {
            run_len += 1;
        } else {
            (run_bit, run_len) = (bit, 1);
        }
        if run_len == 5 {
            stuffed.push(!bit);
            stuff_mask.push(true);
            (run_bit, run_len) = (!bit, 1);
        }
    }
    let starts = wire_fields;
    let mut wire_fields = Spans::new();
    let spans = starts.as_slice();
    for (k, span) in spans.iter().enumerate() {
        let end = spans.get(k + 1).map_or(stuffed.len(), |s| s.start as usize);
        wire_fields.push(Span {
            len: (end - span.start as usize) as u16,
            ..*span
        });
    }
    Encoded {
        frame: *frame,
        dlc,
        crc,
        unstuffed: raw,
        stuffed,
        stuff_mask,
        fields,
        wire_fields,
    }
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
        let ack = self
            .fields
            .get(Field::AckSlot)
            .map_or(0, |s| s.start as usize);
        bits.set(ack, false);
        bits
    }

    /// Wire index of the ACK slot.
    pub fn ack_slot(&self) -> usize {
        self.wire_fields
            .get(Field::AckSlot)
            .map_or(0, |s| s.start as usize)
    }

    /// Whether wire bit `i` is a stuff bit.
    pub fn is_stuff_bit(&self, i: usize) -> bool {
        i < self.stuff_mask.len() && self.stuff_mask.bit(i)
    }

    /// Number of stuff bits.
    pub fn stuff_bits(&self) -> usize {
        self.stuffed.len() - self.unstuffed.len()
    }

    /// Field spans in the de-stuffed bits.
    pub fn fields(&self) -> &[Span] {
        self.fields.as_slice()
    }

    /// Field spans in the wire bits; each includes the stuff bits its own bits caused (so the
    /// stuff bit after the last CRC bit, if any, belongs to the CRC).
    pub fn wire_fields(&self) -> &[Span] {
        self.wire_fields.as_slice()
    }
}
