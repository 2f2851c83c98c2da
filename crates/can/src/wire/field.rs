//! Names and positions of the fields of a frame on the wire.

use core::{fmt, ops::Deref};

/// A field (or single bit) of a data or remote frame, SOF to EOF.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Field {
    Sof,
    /// The 11-bit identifier (SFF) or its 11 most significant bits ID28..ID18 (EFF).
    Id,
    /// Substitute remote request (EFF, sent recessive).
    Srr,
    /// Identifier extension flag: dominant = standard format.
    Ide,
    /// ID17..ID0 of an extended identifier.
    IdExt,
    Rtr,
    /// Reserved bit of the extended format (sent dominant, accepted either way).
    R1,
    /// Reserved bit (sent dominant, accepted either way).
    R0,
    Dlc,
    Data,
    Crc,
    CrcDelimiter,
    AckSlot,
    AckDelimiter,
    Eof,
}

impl Field {
    pub const fn name(self) -> &'static str {
        match self {
            Field::Sof => "SOF",
            Field::Id => "ID",
            Field::Srr => "SRR",
            Field::Ide => "IDE",
            Field::IdExt => "ID ext",
            Field::Rtr => "RTR",
            Field::R1 => "r1",
            Field::R0 => "r0",
            Field::Dlc => "DLC",
            Field::Data => "data",
            Field::Crc => "CRC",
            Field::CrcDelimiter => "CRC delimiter",
            Field::AckSlot => "ACK slot",
            Field::AckDelimiter => "ACK delimiter",
            Field::Eof => "EOF",
        }
    }
}

impl fmt::Display for Field {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// Where a field lies in a bit string: `len` bits from `start`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Span {
    pub field: Field,
    pub start: u16,
    pub len: u16,
}

impl Span {
    /// One past the last bit.
    pub const fn end(&self) -> usize {
        self.start as usize + self.len as usize
    }
}

/// The field spans of one frame, in wire order (at most 15 fields). Reads as a slice of
/// [`Span`]s.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Spans {
    items: [Span; 15],
    len: u8,
}

impl Spans {
    pub(crate) const fn new() -> Self {
        Self {
            items: [Span {
                field: Field::Sof,
                start: 0,
                len: 0,
            }; 15],
            len: 0,
        }
    }

    pub(crate) fn push(&mut self, span: Span) {
        self.items[self.len as usize] = span;
        self.len += 1;
    }

    pub fn as_slice(&self) -> &[Span] {
        &self.items[..self.len as usize]
    }

    /// The span of `field`, if the frame has it (remote frames have no data, SFF no SRR...).
    pub fn get(&self, field: Field) -> Option<Span> {
        self.as_slice().iter().copied().find(|s| s.field == field)
    }

    /// The field containing bit `i`.
    pub fn field_at(&self, i: usize) -> Option<Field> {
        self.as_slice()
            .iter()
            .find(|s| (s.start as usize..s.end()).contains(&i))
            .map(|s| s.field)
    }
}

impl Deref for Spans {
    type Target = [Span];

    fn deref(&self) -> &[Span] {
        self.as_slice()
    }
}

impl IntoIterator for Spans {
    type Item = Span;
    type IntoIter = core::iter::Take<core::array::IntoIter<Span, 15>>;

    fn into_iter(self) -> Self::IntoIter {
        self.items.into_iter().take(self.len as usize)
    }
}

impl<'a> IntoIterator for &'a Spans {
    type Item = &'a Span;
    type IntoIter = core::slice::Iter<'a, Span>;

    fn into_iter(self) -> Self::IntoIter {
        self.as_slice().iter()
    }
}
