//! One signal: where its bits are, how its raw value becomes a physical one, its value table
//! and when it is sent (multiplexing).

use std::ops::RangeInclusive;

use crate::layout::Layout;

/// DBC's bit numbering of a signal (`@1` Intel, `@0` Motorola).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ByteOrder {
    /// Intel, `@1`: the start bit is the least significant bit.
    LittleEndian,
    /// Motorola, `@0`: the start bit is the most significant bit.
    BigEndian,
}

/// How a signal's raw bits are read as a number.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ValueKind {
    Unsigned,
    /// Two's complement over the signal's size.
    Signed,
    /// IEEE 754 single (`SIG_VALTYPE_ … 1`), 32 bits.
    Float32,
    /// IEEE 754 double (`SIG_VALTYPE_ … 2`), 64 bits.
    Float64,
}

/// When a signal is in a frame.
#[derive(Clone, Debug, PartialEq)]
pub enum Multiplexing {
    /// Always.
    Plain,
    /// Always: it is the message's multiplexor (`M`), its value selects the other signals.
    Multiplexor,
    /// Only while the signal `multiplexor` (an index into the message's signals) is in the
    /// frame with a raw value in one of `values` (`mN`: one value; `SG_MUL_VAL_`: ranges).
    /// `selects` says whether this signal is itself a multiplexor (`mNM`, extended
    /// multiplexing).
    Multiplexed {
        multiplexor: usize,
        values: Vec<RangeInclusive<u64>>,
        selects: bool,
    },
}

/// A signal of a message.
#[derive(Clone, Debug, PartialEq)]
pub struct Signal {
    pub(crate) name: String,
    pub(crate) start_bit: u32,
    pub(crate) size: u32,
    pub(crate) byte_order: ByteOrder,
    pub(crate) kind: ValueKind,
    pub(crate) factor: f64,
    pub(crate) offset: f64,
    pub(crate) min: f64,
    pub(crate) max: f64,
    pub(crate) unit: String,
    pub(crate) receivers: Vec<String>,
    pub(crate) choices: Vec<(i64, String)>,
    pub(crate) comment: Option<String>,
    /// `GenSigStartValue`, raw.
    pub(crate) start_value: Option<f64>,
    pub(crate) multiplexing: Multiplexing,
    pub(crate) codec: Codec,
}

/// What decoding needs of a signal, packed together: a message keeps one per signal, in
/// order, so that decoding reads only these.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Codec {
    pub layout: Layout,
    pub kind: ValueKind,
    pub size: u32,
    pub factor: f64,
    pub offset: f64,
}

impl Codec {
    #[inline]
    pub(crate) fn integer(&self, raw: u64) -> i64 {
        match self.kind {
            ValueKind::Signed if self.size < 64 => {
                let unused = 64 - self.size;
                ((raw << unused) as i64) >> unused
            }
            _ => raw as i64,
        }
    }

    /// The number the bits hold times the factor plus the offset (in this order, as cantools
    /// computes it: the same f64).
    #[inline]
    pub(crate) fn physical(&self, raw: u64) -> f64 {
        let number = match self.kind {
            ValueKind::Unsigned => raw as f64,
            ValueKind::Signed => self.integer(raw) as f64,
            ValueKind::Float32 => f64::from(f32::from_bits(raw as u32)),
            ValueKind::Float64 => f64::from_bits(raw),
        };
        number * self.factor + self.offset
    }
}

impl Signal {
    pub fn name(&self) -> &str {
        &self.name
    }
    /// The start bit as the DBC file writes it (see [`ByteOrder`]).
    pub fn start_bit(&self) -> u32 {
        self.start_bit
    }
    /// Its size in bits, 1..=64.
    pub fn size(&self) -> u32 {
        self.size
    }
    pub fn byte_order(&self) -> ByteOrder {
        self.byte_order
    }
    pub fn kind(&self) -> ValueKind {
        self.kind
    }
    pub fn factor(&self) -> f64 {
        self.factor
    }
    pub fn offset(&self) -> f64 {
        self.offset
    }
    /// The physical range the database declares; `None` for DBC's "no range" `[0|0]`.
    pub fn range(&self) -> Option<(f64, f64)> {
        (self.min != 0.0 || self.max != 0.0).then_some((self.min, self.max))
    }
    pub fn unit(&self) -> &str {
        &self.unit
    }
    pub fn receivers(&self) -> &[String] {
        &self.receivers
    }
    /// Its value table (`VAL_`): raw value and label.
    pub fn choices(&self) -> &[(i64, String)] {
        &self.choices
    }
    pub fn comment(&self) -> Option<&str> {
        self.comment.as_deref()
    }
    /// The raw value a sender puts before it has one (`GenSigStartValue`, given for this
    /// signal; the attribute's default is not taken, as in cantools).
    pub fn start_value(&self) -> Option<f64> {
        self.start_value
    }
    /// [`Signal::start_value`] as the raw bits encoding sends (an integer start value is
    /// rounded and cut to the signal's size, a float one stored as the float).
    pub fn start_raw(&self) -> Option<u64> {
        let value = self.start_value?;
        let mask = if self.size == 64 {
            u64::MAX
        } else {
            (1u64 << self.size) - 1
        };
        Some(match self.kind {
            ValueKind::Unsigned => value.round_ties_even() as u64 & mask,
            ValueKind::Signed => value.round_ties_even() as i64 as u64 & mask,
            ValueKind::Float32 => u64::from((value as f32).to_bits()),
            ValueKind::Float64 => value.to_bits(),
        })
    }
    pub fn multiplexing(&self) -> &Multiplexing {
        &self.multiplexing
    }
    /// Whether other signals depend on its value.
    pub fn is_multiplexor(&self) -> bool {
        matches!(
            self.multiplexing,
            Multiplexing::Multiplexor | Multiplexing::Multiplexed { selects: true, .. }
        )
    }

    /// Its raw bits in `payload`, right-aligned; `None` when the payload is too short.
    #[inline]
    pub fn raw(&self, payload: &[u8]) -> Option<u64> {
        self.codec.layout.extract(payload)
    }

    /// The raw bits as the integer a value table is keyed by (sign-extended when signed).
    #[inline]
    pub fn integer(&self, raw: u64) -> i64 {
        self.codec.integer(raw)
    }

    /// The physical value of raw bits: the number they hold times the factor plus the offset.
    #[inline]
    pub fn physical(&self, raw: u64) -> f64 {
        self.codec.physical(raw)
    }

    /// The value table's label for raw bits, if it has one.
    pub fn choice(&self, raw: u64) -> Option<&str> {
        if matches!(self.kind, ValueKind::Float32 | ValueKind::Float64) {
            return None;
        }
        let key = self.integer(raw);
        self.choices
            .iter()
            .find(|(k, _)| *k == key)
            .map(|(_, label)| label.as_str())
    }

    /// The physical values this signal can carry: its raw range scaled, within the
    /// database's range when it declares one.
    pub fn allowed(&self) -> (f64, f64) {
        let (lo, hi) = match self.kind {
            ValueKind::Unsigned => (0.0, 2f64.powi(self.size as i32) - 1.0),
            ValueKind::Signed => {
                let half = 2f64.powi(self.size as i32 - 1);
                (-half, half - 1.0)
            }
            ValueKind::Float32 => (f64::from(f32::MIN), f64::from(f32::MAX)),
            ValueKind::Float64 => (f64::MIN, f64::MAX),
        };
        let (a, b) = (
            lo * self.factor + self.offset,
            hi * self.factor + self.offset,
        );
        let (lo, hi) = if a <= b { (a, b) } else { (b, a) };
        match self.range() {
            Some((min, max)) => (lo.max(min), hi.min(max)),
            None => (lo, hi),
        }
    }

    /// The raw bits that carry `physical` (rounded half to even to the nearest raw step, as
    /// cantools does); `None` when it is outside [`Signal::allowed`] or not a number.
    pub fn raw_from_physical(&self, physical: f64) -> Option<u64> {
        let (lo, hi) = self.allowed();
        if physical.is_nan() || physical < lo || physical > hi {
            return None;
        }
        let number = (physical - self.offset) / self.factor;
        let mask = if self.size == 64 {
            u64::MAX
        } else {
            (1u64 << self.size) - 1
        };
        Some(match self.kind {
            ValueKind::Unsigned => number.round_ties_even() as u64 & mask,
            ValueKind::Signed => (number.round_ties_even() as i64) as u64 & mask,
            ValueKind::Float32 => u64::from((number as f32).to_bits()),
            ValueKind::Float64 => number.to_bits(),
        })
    }
}
