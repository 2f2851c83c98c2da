//! The original bit-by-bit wire encoder, kept as the reference the table-driven one in
//! `buslab_can::wire::encode` is checked (tests/wire_fast.rs) and benchmarked (benches/wire.rs)
//! against. It uses only the public API, pushes one bit at a time and computes the CRC bit by
//! bit, exactly as the encoder did before it was rewritten.

// Each user (tests, bench) uses part of it.
#![allow(dead_code)]

use buslab_can::Frame;
use buslab_can::wire::{Bits, Crc15, Field, Span};

/// What the reference encoder produces; mirrors `wire::Encoded`'s accessors.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Reference {
    pub crc: u16,
    pub unstuffed: Bits,
    pub stuffed: Bits,
    /// Wire indices of the stuff bits.
    pub stuff_bits: Vec<usize>,
    pub fields: Vec<Span>,
    pub wire_fields: Vec<Span>,
}

pub fn encode(frame: &Frame) -> Reference {
    encode_with_dlc(frame, frame.dlc())
}

/// `dlc` must mean the same length as the frame's DLC (the caller checks, as the library does).
pub fn encode_with_dlc(frame: &Frame, dlc: u8) -> Reference {
    let mut layout = Layout {
        raw: Bits::new(),
        fields: Vec::new(),
        crc: Crc15::new(),
    };
    let mut put = |field, value, len| layout.put(field, value, len);
    let id = frame.id().as_raw() as u64;
    let rtr = frame.is_remote() as u64;
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
    put(Field::Dlc, dlc as u64, 4);
    let payload = frame.payload();
    if !payload.is_empty() {
        let mut bytes = [0u8; 8];
        bytes[..payload.len()].copy_from_slice(payload);
        let len = 8 * payload.len() as u16;
        put(Field::Data, u64::from_be_bytes(bytes) >> (64 - len), len);
    }
    let crc_value = layout.crc.value();
    let mut put = |field, value, len| layout.put(field, value, len);
    put(Field::Crc, crc_value as u64, 15);
    put(Field::CrcDelimiter, 1, 1);
    put(Field::AckSlot, 1, 1);
    put(Field::AckDelimiter, 1, 1);
    put(Field::Eof, 0x7F, 7);
    let Layout { raw, fields, .. } = layout;
    let stuff_end = raw.len() - 10;

    let mut stuffed = Bits::new();
    let mut stuff_bits = Vec::new();
    let mut wire_fields = Vec::new();
    let (mut run_bit, mut run_len) = (true, 0u8);
    for span in &fields {
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
                stuff_bits.push(stuffed.len());
                stuffed.push(!bit);
                (run_bit, run_len) = (!bit, 1);
            }
        }
        wire_fields.push(Span {
            field: span.field,
            start: wire_start as u16,
            len: (stuffed.len() - wire_start) as u16,
        });
    }
    Reference {
        crc: crc_value,
        unstuffed: raw,
        stuffed,
        stuff_bits,
        fields,
        wire_fields,
    }
}

struct Layout {
    raw: Bits,
    fields: Vec<Span>,
    crc: Crc15,
}

impl Layout {
    /// Append a field bit by bit; the CRC follows SOF..data.
    fn put(&mut self, field: Field, value: u64, len: u16) {
        self.fields.push(Span {
            field,
            start: self.raw.len() as u16,
            len,
        });
        for n in (0..len).rev() {
            let bit = value >> n & 1 == 1;
            self.raw.push(bit);
            if !matches!(
                field,
                Field::Crc
                    | Field::CrcDelimiter
                    | Field::AckSlot
                    | Field::AckDelimiter
                    | Field::Eof
            ) {
                self.crc.push(bit);
            }
        }
    }
}
