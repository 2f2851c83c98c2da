//! Wire bits → frame, one bit at a time, with the checks a CAN receiver makes.

use core::fmt;

use super::{Crc15, Encoded, Field};
use crate::{ExtendedId, Frame, Id, StandardId};

/// A frame rebuilt from the wire.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Decoded {
    /// The frame. A raw DLC of 9..15 (8 data bytes) is stored as DLC 8; see [`Decoded::dlc`].
    pub frame: Frame,
    /// The DLC as received, 0..15.
    pub dlc: u8,
    /// The received CRC sequence (equal to the computed one, or this would be an error).
    pub crc: u16,
    /// Whether the ACK slot was dominant (some receiver acknowledged).
    pub acked: bool,
    /// Number of stuff bits removed.
    pub stuff_bits: u32,
    /// Wire bits SOF..end of EOF.
    pub wire_len: u32,
}

/// What went wrong, per the CAN error kinds a receiver checks.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum WireErrorKind {
    /// Six equal consecutive bits in SOF..CRC.
    Stuff,
    /// A fixed-form bit (SOF, CRC delimiter, ACK delimiter, EOF) had the wrong level.
    Form,
    /// The received CRC sequence differs from the one computed over the received bits.
    Crc { received: u16, computed: u16 },
}

/// An error found by the [`Receiver`], at wire bit `bit` (SOF = 0, stuff bits counted).
///
/// `field` is the field of the offending bit; a stuff bit belongs to the field whose bits
/// caused it. A CRC error is signalled, as the protocol does, at the ACK delimiter.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, thiserror::Error)]
pub struct WireError {
    pub kind: WireErrorKind,
    pub bit: u32,
    pub field: Field,
}

impl fmt::Display for WireError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let (bit, field) = (self.bit, self.field);
        match self.kind {
            WireErrorKind::Stuff => write!(
                f,
                "stuff error at wire bit {bit} ({field}): 6 consecutive equal bits"
            ),
            WireErrorKind::Form => write!(
                f,
                "form error at wire bit {bit} ({field}): must be {}",
                if field == Field::Sof {
                    "dominant (0)"
                } else {
                    "recessive (1)"
                }
            ),
            WireErrorKind::Crc { received, computed } => write!(
                f,
                "CRC error signalled at wire bit {bit} ({field}): received CRC 0x{received:04X}, computed 0x{computed:04X}"
            ),
        }
    }
}

/// Where the receiver is; also the field of the next data bit.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Stage {
    Sof,
    Id,
    /// Bit 12: RTR if standard, SRR if extended (not known before IDE).
    RtrOrSrr,
    Ide,
    IdExt,
    Rtr,
    R1,
    R0,
    Dlc,
    Data,
    Crc,
    CrcDelimiter,
    AckSlot,
    AckDelimiter,
    Eof,
    Done,
    Failed,
}

impl Stage {
    const fn field(self) -> Field {
        match self {
            Stage::Sof => Field::Sof,
            Stage::Id => Field::Id,
            Stage::RtrOrSrr | Stage::Rtr => Field::Rtr,
            Stage::Ide => Field::Ide,
            Stage::IdExt => Field::IdExt,
            Stage::R1 => Field::R1,
            Stage::R0 => Field::R0,
            Stage::Dlc => Field::Dlc,
            Stage::Data => Field::Data,
            Stage::Crc => Field::Crc,
            Stage::CrcDelimiter => Field::CrcDelimiter,
            Stage::AckSlot => Field::AckSlot,
            Stage::AckDelimiter => Field::AckDelimiter,
            Stage::Eof | Stage::Done | Stage::Failed => Field::Eof,
        }
    }
}

/// The result of one [`Receiver::push`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Step {
    /// More bits needed (also: the receiver has finished and ignores bits until reset).
    Pending,
    /// The last EOF bit was received; the frame is complete.
    Frame(Decoded),
    /// An error; the receiver stops until [`Receiver::reset`].
    Error(WireError),
}

/// A bit-by-bit CAN receiver: feed it the wire bits from SOF on; it removes stuff bits, follows
/// the fields, checks CRC and fixed-form bits and says where an error happened.
///
/// It is a bus observer: it accepts the ACK slot either way (see [`Decoded::acked`]), and any
/// value of the reserved bits and SRR. It is strict about EOF: a dominant 7th EOF bit is a form
/// error here, while a protocol controller treats it as an overload condition (that policy
/// lives in [`crate::controller`]).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Receiver {
    stage: Stage,
    /// The stage before `Failed`, for [`Receiver::field`] after an error.
    failed_in: Stage,
    /// Bits left in a multi-bit stage.
    left: u8,
    shift: u32,
    /// Wire bits taken so far (= wire index of the next bit).
    pos: u32,
    /// Stuff bits taken so far.
    stuff_count: u32,
    run_bit: bool,
    run_len: u8,
    stuffing: bool,
    /// CRC over the completed fields (fed a field at a time, off the per-bit path).
    crc: Crc15,
    /// The CRC computed over SOF..data, fixed when the CRC field starts.
    crc_computed: u16,
    crc_rx: u16,
    id: u32,
    ide: bool,
    rtr: bool,
    dlc: u8,
    data_len: u8,
    bytes: u8,
    data: [u8; 8],
    acked: bool,
}

impl Default for Receiver {
    fn default() -> Self {
        Self::new()
    }
}

impl Receiver {
    /// A receiver waiting for SOF.
    pub const fn new() -> Self {
        Self {
            stage: Stage::Sof,
            failed_in: Stage::Sof,
            left: 0,
            shift: 0,
            pos: 0,
            stuff_count: 0,
            run_bit: true,
            run_len: 0,
            stuffing: true,
            crc: Crc15::new(),
            crc_computed: 0,
            crc_rx: 0,
            id: 0,
            ide: false,
            rtr: false,
            dlc: 0,
            data_len: 0,
            bytes: 0,
            data: [0; 8],
            acked: false,
        }
    }

    pub fn reset(&mut self) {
        *self = Self::new();
    }

    /// The receiver that has taken `encoded`'s bits SOF..ACK delimiter on a bus where the ACK
    /// slot was dominant, built without taking them one by one: exactly the state
    /// [`Receiver::push`] leaves (the whole-frame path needs it for every frame).
    pub(crate) fn after_ack_delimiter(encoded: &Encoded) -> Self {
        let frame = encoded.frame();
        let (stuffed, mask) = (encoded.stuffed(), encoded.stuff_mask());
        // The stuffed region ends just before the CRC delimiter, with a stuff bit if the CRC
        // ended with five equal bits. Runs of equal wire bits are the receiver's runs: a stuff
        // bit differs from the bit before it, so it starts a run as the receiver counts.
        let last = encoded.ack_slot() - 2;
        let run_bit = stuffed.bit(last);
        let run_len = if mask.bit(last) {
            1
        } else {
            1 + (0..last)
                .rev()
                .take_while(|&i| stuffed.bit(i) == run_bit)
                .count() as u8
        };
        let (id, ide) = match frame.id() {
            Id::Standard(id) => (u32::from(id.as_raw()), false),
            Id::Extended(id) => (id.as_raw(), true),
        };
        let rtr = frame.is_remote();
        let data_len = if rtr { 0 } else { frame.payload().len() as u8 };
        let mut data = [0; 8];
        data[..data_len as usize].copy_from_slice(frame.payload());
        let crc = encoded.crc();
        Self {
            stage: Stage::Eof,
            failed_in: Stage::Sof,
            left: 7,
            // The CRC field was the last one shifted in (from 0).
            shift: u32::from(crc),
            pos: encoded.ack_slot() as u32 + 2,
            stuff_count: encoded.stuff_bits() as u32,
            run_bit,
            run_len,
            stuffing: false,
            crc: Crc15::from_value(crc),
            crc_computed: crc,
            crc_rx: crc,
            id,
            ide,
            rtr,
            dlc: encoded.dlc(),
            data_len,
            bytes: data_len,
            data,
            acked: true,
        }
    }

    /// Wire index of the next bit (= wire bits taken since SOF).
    #[inline]
    pub const fn position(&self) -> u32 {
        self.pos
    }

    /// De-stuffed index of the next data bit.
    #[inline]
    pub const fn index(&self) -> u32 {
        self.pos - self.stuff_count
    }

    /// The field the next data bit belongs to. Bit 12 reads as [`Field::Rtr`] because SRR and
    /// RTR are told apart only by the IDE bit that follows.
    #[inline]
    pub const fn field(&self) -> Field {
        match self.stage {
            Stage::Failed => self.failed_in.field(),
            stage => stage.field(),
        }
    }

    /// The next wire bit is a stuff bit.
    #[inline]
    pub const fn expects_stuff_bit(&self) -> bool {
        self.stuffing && self.run_len == 5
    }

    /// The next wire bit is still inside the stuffed region (SOF..CRC incl. a trailing stuff bit).
    #[inline]
    pub const fn in_stuffed_region(&self) -> bool {
        self.stuffing
    }

    /// After the CRC field: whether the received CRC matched.
    #[inline]
    pub fn crc_ok(&self) -> bool {
        self.crc_rx == self.crc_computed
    }

    /// Finished (frame or error).
    pub const fn is_finished(&self) -> bool {
        matches!(self.stage, Stage::Done | Stage::Failed)
    }

    /// The frame, once the ACK delimiter has been received without error.
    pub fn decoded(&self) -> Option<Decoded> {
        if !matches!(self.stage, Stage::Eof | Stage::Done) {
            return None;
        }
        self.rebuilt()
    }

    /// The frame as soon as its CRC delimiter has been received with a matching CRC, before
    /// the ACK slot (what an observer that neither acknowledges nor checks the rest sees, e.g.
    /// a SLIO calibrating itself on unacknowledged frames). `acked` is not known yet (false).
    pub fn decoded_before_ack(&self) -> Option<Decoded> {
        if !matches!(
            self.stage,
            Stage::AckSlot | Stage::AckDelimiter | Stage::Eof | Stage::Done
        ) || !self.crc_ok()
        {
            return None;
        }
        self.rebuilt()
    }

    fn rebuilt(&self) -> Option<Decoded> {
        let id = if self.ide {
            Id::Extended(ExtendedId::new(self.id).ok()?)
        } else {
            Id::Standard(StandardId::new(self.id as u16).ok()?)
        };
        let frame = if self.rtr {
            Frame::remote(id, self.dlc.min(8)).ok()?
        } else {
            Frame::data(id, &self.data[..self.data_len as usize]).ok()?
        };
        Some(Decoded {
            frame,
            dlc: self.dlc,
            crc: self.crc_rx,
            acked: self.acked,
            stuff_bits: self.stuff_count,
            wire_len: self.stuff_count + self.fixed_len(),
        })
    }

    /// De-stuffed frame length SOF..end of EOF.
    fn fixed_len(&self) -> u32 {
        (if self.ide { 64 } else { 44 }) + 8 * self.data_len as u32
    }

    #[cold]
    fn fail(&mut self, kind: WireErrorKind, bit: u32, field: Field) -> Step {
        self.failed_in = self.stage;
        self.stage = Stage::Failed;
        self.stuffing = false;
        Step::Error(WireError { kind, bit, field })
    }

    /// Take one wire bit (`true` = recessive).
    #[inline]
    pub fn push(&mut self, bit: bool) -> Step {
        if self.push_mid_field(bit) {
            return Step::Pending;
        }
        self.push_slow(bit)
    }

    /// The common case, kept small enough to inline into a controller's per-bit step: a data
    /// bit inside a multi-bit field of the stuffed region (not its last bit), or a correct
    /// stuff bit before the end of the stuffed region.
    /// Takes the bit and returns true in that case; otherwise takes nothing and returns false.
    #[inline(always)]
    pub fn push_mid_field(&mut self, bit: bool) -> bool {
        if !self.stuffing {
            return false;
        }
        if self.run_len == 5 {
            // A correct stuff bit, not the last one of the region.
            if bit == self.run_bit || self.stage == Stage::CrcDelimiter {
                return false;
            }
            self.pos += 1;
            self.stuff_count += 1;
            (self.run_bit, self.run_len) = (bit, 1);
            return true;
        }
        // `left` is at most 1 in single-bit stages, so `left > 1` means "inside a field". The
        // end of a data byte that is not the last one is handled here too.
        if self.left > 1 {
            self.take_data_bit(bit);
            return true;
        }
        if self.stage == Stage::Data && self.left == 1 && self.bytes + 1 < self.data_len {
            self.take_data_bit(bit);
            self.data[self.bytes as usize & 7] = self.shift as u8;
            self.crc.push_byte(self.shift as u8);
            self.bytes += 1;
            (self.shift, self.left) = (0, 8);
            return true;
        }
        false
    }

    #[inline(always)]
    fn take_data_bit(&mut self, bit: bool) {
        self.pos += 1;
        let same = bit == self.run_bit;
        self.run_len = if same { self.run_len + 1 } else { 1 };
        self.run_bit = bit;
        self.shift = self.shift << 1 | bit as u32;
        self.left -= 1;
    }

    #[inline(never)]
    fn push_slow(&mut self, bit: bool) -> Step {
        let pos = self.pos;
        self.pos += 1;
        if self.stuffing {
            if self.run_len == 5 {
                return self.stuff_bit(bit, pos);
            }
            // Branch-free run counting (the bits are data).
            let same = bit == self.run_bit;
            self.run_len = if same { self.run_len + 1 } else { 1 };
            self.run_bit = bit;
        }
        // The CRC is fed when a field (or a single-bit field) of SOF..data is complete.
        match self.stage {
            Stage::Sof => {
                if bit {
                    return self.fail(WireErrorKind::Form, pos, Field::Sof);
                }
                self.crc.push(bit);
                (self.stage, self.left) = (Stage::Id, 11);
            }
            Stage::Id => {
                if self.shift_in(bit) {
                    self.crc.push_bits(self.shift, 11);
                    (self.id, self.stage) = (self.shift, Stage::RtrOrSrr);
                }
            }
            Stage::RtrOrSrr => {
                self.crc.push(bit);
                self.rtr = bit;
                self.stage = Stage::Ide;
            }
            Stage::Ide => {
                self.crc.push(bit);
                self.ide = bit;
                if bit {
                    (self.stage, self.left, self.shift) = (Stage::IdExt, 18, 0);
                } else {
                    self.stage = Stage::R0;
                }
            }
            Stage::IdExt => {
                if self.shift_in(bit) {
                    self.crc.push_bits(self.shift, 18);
                    self.id = self.id << 18 | self.shift;
                    self.stage = Stage::Rtr;
                }
            }
            Stage::Rtr => {
                self.crc.push(bit);
                self.rtr = bit;
                self.stage = Stage::R1;
            }
            Stage::R1 => {
                self.crc.push(bit);
                self.stage = Stage::R0;
            }
            Stage::R0 => {
                self.crc.push(bit);
                (self.stage, self.left, self.shift) = (Stage::Dlc, 4, 0);
            }
            Stage::Dlc => {
                if self.shift_in(bit) {
                    self.crc.push_bits(self.shift, 4);
                    self.dlc = self.shift as u8;
                    self.data_len = if self.rtr { 0 } else { self.dlc.min(8) };
                    self.shift = 0;
                    if self.data_len > 0 {
                        (self.stage, self.left) = (Stage::Data, 8);
                    } else {
                        self.start_crc();
                    }
                }
            }
            Stage::Data => {
                if self.shift_in(bit) {
                    self.crc.push_byte(self.shift as u8);
                    self.data[self.bytes as usize] = self.shift as u8;
                    self.bytes += 1;
                    self.shift = 0;
                    if self.bytes == self.data_len {
                        self.start_crc();
                    } else {
                        self.left = 8;
                    }
                }
            }
            Stage::Crc => {
                if self.shift_in(bit) {
                    self.crc_rx = self.shift as u16;
                    self.stage = Stage::CrcDelimiter;
                    // A trailing stuff bit follows if the CRC ended with 5 equal bits.
                    self.stuffing = self.run_len == 5;
                }
            }
            Stage::CrcDelimiter => {
                if !bit {
                    return self.fail(WireErrorKind::Form, pos, Field::CrcDelimiter);
                }
                self.stage = Stage::AckSlot;
            }
            Stage::AckSlot => {
                self.acked = !bit;
                self.stage = Stage::AckDelimiter;
            }
            Stage::AckDelimiter => {
                if !bit {
                    return self.fail(WireErrorKind::Form, pos, Field::AckDelimiter);
                }
                if !self.crc_ok() {
                    let kind = WireErrorKind::Crc {
                        received: self.crc_rx,
                        computed: self.crc_computed,
                    };
                    return self.fail(kind, pos, Field::AckDelimiter);
                }
                (self.stage, self.left) = (Stage::Eof, 7);
            }
            Stage::Eof => {
                if !bit {
                    return self.fail(WireErrorKind::Form, pos, Field::Eof);
                }
                self.left -= 1;
                if self.left == 0 {
                    let decoded = self.decoded();
                    self.stage = Stage::Done;
                    return decoded.map_or(Step::Pending, Step::Frame);
                }
            }
            Stage::Done | Stage::Failed => {}
        }
        Step::Pending
    }

    /// The data field is over: the CRC register now holds the CRC to compare with.
    #[inline]
    fn start_crc(&mut self) {
        self.crc_computed = self.crc.value();
        (self.stage, self.left) = (Stage::Crc, 15);
    }

    /// The bit after 5 equal bits: must be their complement, and is dropped.
    #[inline]
    fn stuff_bit(&mut self, bit: bool, pos: u32) -> Step {
        if bit == self.run_bit {
            return self.fail(WireErrorKind::Stuff, pos, self.last_data_field());
        }
        self.stuff_count += 1;
        (self.run_bit, self.run_len) = (bit, 1);
        if self.stage == Stage::CrcDelimiter {
            self.stuffing = false;
        }
        Step::Pending
    }

    /// The field of the last data bit (a stuff bit belongs to it): the current stage if it has
    /// taken bits already, else the one before.
    #[cold]
    fn last_data_field(&self) -> Field {
        let started = match self.stage {
            Stage::Id => self.left < 11,
            Stage::IdExt => self.left < 18,
            Stage::Dlc => self.left < 4,
            Stage::Data => self.left < 8 || self.bytes > 0,
            Stage::Crc => self.left < 15,
            _ => false,
        };
        if started {
            return self.stage.field();
        }
        match self.stage {
            Stage::Id => Field::Sof,
            Stage::RtrOrSrr => Field::Id,
            Stage::Ide => Field::Rtr,
            Stage::IdExt => Field::Ide,
            Stage::Rtr => Field::IdExt,
            Stage::R1 => Field::Rtr,
            Stage::R0 if self.ide => Field::R1,
            Stage::R0 => Field::Ide,
            Stage::Dlc => Field::R0,
            Stage::Data => Field::Dlc,
            Stage::Crc if self.data_len > 0 => Field::Data,
            Stage::Crc => Field::Dlc,
            _ => Field::Crc,
        }
    }

    /// Shift a bit into the current multi-bit field; true when the field is complete.
    #[inline]
    fn shift_in(&mut self, bit: bool) -> bool {
        self.shift = self.shift << 1 | bit as u32;
        self.left -= 1;
        self.left == 0
    }
}

/// Why [`decode`] could not rebuild a frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, thiserror::Error)]
pub enum DecodeError {
    #[error(transparent)]
    Wire(#[from] WireError),
    #[error("the bit string is empty; a frame starts with SOF (0)")]
    Empty,
    #[error(
        "the bit string ends after {bits} bits, inside the {field} field; a frame runs from SOF to the 7th EOF bit"
    )]
    Truncated { bits: u32, field: Field },
    #[error(
        "dominant bit at wire bit {bit} after the end of the frame; only recessive (idle) bits may follow EOF"
    )]
    TrailingDominant { bit: u32 },
}

/// Decode a whole wire bit string starting at SOF (`true` = 1 = recessive). Recessive bits after
/// EOF (intermission, idle) are allowed.
pub fn decode(bits: impl IntoIterator<Item = bool>) -> Result<Decoded, DecodeError> {
    let mut rx = Receiver::new();
    let mut bits = bits.into_iter();
    let mut seen = 0u32;
    let decoded = loop {
        let Some(bit) = bits.next() else {
            return Err(if seen == 0 {
                DecodeError::Empty
            } else {
                DecodeError::Truncated {
                    bits: seen,
                    field: rx.field(),
                }
            });
        };
        seen += 1;
        match rx.push(bit) {
            Step::Pending => {}
            Step::Frame(decoded) => break decoded,
            Step::Error(error) => return Err(error.into()),
        }
    };
    match bits.position(|bit| !bit) {
        Some(n) => Err(DecodeError::TrailingDominant {
            bit: seen + n as u32,
        }),
        None => Ok(decoded),
    }
}
