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

/// De-stuffed bits with their field spans, built field by field; the CRC follows along until
/// the CRC field.
struct Layout {
    raw: Bits,
    fields: Spans,
    crc: Crc15,
}

impl Layout {
    fn put(&mut self, field: Field, value: u64, len: u16) {
        self.fields.push(Span {
            field,
            start: self.raw.len() as u16,
            len,
        });
        self.raw.push_msb_first(value, len as u32);
        match field {
            Field::Data => {
                for byte in (0..len / 8).rev() {
                    self.crc.push_byte((value >> (8 * byte)) as u8);
                }
            }
            Field::Crc
            | Field::CrcDelimiter
            | Field::AckSlot
            | Field::AckDelimiter
            | Field::Eof => {}
            _ => self.crc.push_bits(value as u32, len as u32),
        }
    }
}

fn encode_bits(frame: &Frame, dlc: u8) -> Encoded {
    let mut layout = Layout {
        raw: Bits::new(),
        fields: Spans::new(),
        crc: Crc15::new(),
    };
    let id = frame.id().as_raw() as u64;
    let rtr = frame.is_remote() as u64;
    layout.put(Field::Sof, 0, 1);
    if frame.is_extended() {
        layout.put(Field::Id, id >> 18, 11);
        layout.put(Field::Srr, 1, 1);
        layout.put(Field::Ide, 1, 1);
        layout.put(Field::IdExt, id & 0x3_FFFF, 18);
        layout.put(Field::Rtr, rtr, 1);
        layout.put(Field::R1, 0, 1);
    } else {
        layout.put(Field::Id, id, 11);
        layout.put(Field::Rtr, rtr, 1);
        layout.put(Field::Ide, 0, 1);
    }
    layout.put(Field::R0, 0, 1);
    layout.put(Field::Dlc, dlc as u64, 4);
    let payload = frame.payload();
    if !payload.is_empty() {
        let mut bytes = [0u8; 8];
        bytes[..payload.len()].copy_from_slice(payload);
        let len = 8 * payload.len() as u16;
        layout.put(Field::Data, u64::from_be_bytes(bytes) >> (64 - len), len);
    }
    let crc = layout.crc.value();
    let stuff_end = layout.raw.len() + 15;
    layout.put(Field::Crc, crc as u64, 15);
    layout.put(Field::CrcDelimiter, 1, 1);
    layout.put(Field::AckSlot, 1, 1);
    layout.put(Field::AckDelimiter, 1, 1);
    layout.put(Field::Eof, 0x7F, 7);
    let Layout { raw, fields, .. } = layout;

    // Stuff SOF..last CRC bit. A stuff bit belongs to the field whose bits caused it, so a
    // field's wire span runs up to the first bit of the next field.
    let mut stuffed = Bits::new();
    let mut stuff_mask = Bits::new();
    let mut wire_fields = Spans::new();
    let (mut run_bit, mut run_len) = (true, 0u8);
    for span in fields.as_slice() {
        let wire_start = stuffed.len();
        for i in span.start as usize..span.end() {
            let bit = raw.bit(i);
            stuffed.push(bit);
            if i >= stuff_end {
                continue;
            }
            run_len = if bit == run_bit { run_len + 1 } else { 1 };
            run_bit = bit;
            if run_len == 5 {
                stuff_mask.set_len(stuffed.len());
                stuffed.push(!bit);
                stuff_mask.push(true);
                (run_bit, run_len) = (!bit, 1);
            }
        }
        wire_fields.push(Span {
            field: span.field,
            start: wire_start as u16,
            len: (stuffed.len() - wire_start) as u16,
        });
    }
    stuff_mask.set_len(stuffed.len());
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
