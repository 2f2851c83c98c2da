//! One message: its signals decoded from a payload, and encoded into one.

use std::time::Duration;

use buslab_can::Id;

use crate::error::EncodeError;
use crate::signal::{Codec, Multiplexing, Signal};

/// A message of the database (`BO_`).
#[derive(Clone, Debug, PartialEq)]
pub struct Message {
    pub(crate) id: Id,
    pub(crate) name: String,
    pub(crate) length: usize,
    /// The transmitter (`BO_`) first, then the nodes `BO_TX_BU_` adds.
    pub(crate) senders: Vec<String>,
    pub(crate) signals: Vec<Signal>,
    pub(crate) cycle_time: Option<Duration>,
    pub(crate) comment: Option<String>,
    pub(crate) fd: bool,
    /// Whether any signal is multiplexed (decoding checks selection only then).
    pub(crate) multiplexed: bool,
    /// The signals' codecs, in order.
    pub(crate) codecs: Vec<Codec>,
}

/// One signal's value in a frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Decoded {
    /// Index of the signal in [`Message::signals`].
    pub signal: usize,
    /// Its raw bits, right-aligned.
    pub raw: u64,
    /// Raw value times factor plus offset.
    pub physical: f64,
}

impl Message {
    pub fn id(&self) -> Id {
        self.id
    }
    pub fn name(&self) -> &str {
        &self.name
    }
    /// Its length in bytes as the database declares it (up to 64 for CAN FD).
    pub fn length(&self) -> usize {
        self.length
    }
    /// The node that sends it, if the database names one.
    pub fn transmitter(&self) -> Option<&str> {
        self.senders.first().map(String::as_str)
    }
    /// Every node that sends it: the transmitter, then the nodes `BO_TX_BU_` adds.
    pub fn senders(&self) -> &[String] {
        &self.senders
    }
    pub fn signals(&self) -> &[Signal] {
        &self.signals
    }
    /// The signal called `name`, with its index.
    pub fn signal_by_name(&self, name: &str) -> Option<(usize, &Signal)> {
        self.signals
            .iter()
            .enumerate()
            .find(|(_, s)| s.name == name)
    }
    /// `GenMsgCycleTime`, when the database gives one (and it is not 0).
    pub fn cycle_time(&self) -> Option<Duration> {
        self.cycle_time
    }
    pub fn comment(&self) -> Option<&str> {
        self.comment.as_deref()
    }
    /// Whether the database sends it as a CAN FD frame (`VFrameFormat`).
    pub fn is_fd(&self) -> bool {
        self.fd
    }

    /// The signals `payload` carries, in the database's order: every signal whose bits are in
    /// the payload and whose multiplexor selects it. A payload shorter than the message gives
    /// the signals that fit.
    pub fn decode(&self, payload: &[u8]) -> Vec<Decoded> {
        let mut out = Vec::with_capacity(self.signals.len());
        self.decode_into(payload, &mut out);
        out
    }

    /// [`Message::decode`] into a buffer the caller reuses (cleared first).
    pub fn decode_into(&self, payload: &[u8], out: &mut Vec<Decoded>) {
        out.clear();
        for (index, codec) in self.codecs.iter().enumerate() {
            if self.multiplexed && !self.selected(index, payload) {
                continue;
            }
            if let Some(raw) = codec.layout.extract(payload) {
                out.push(Decoded {
                    signal: index,
                    raw,
                    physical: codec.physical(raw),
                });
            }
        }
    }

    /// Whether signal `index` is sent in `payload` as far as multiplexing goes.
    fn selected(&self, index: usize, payload: &[u8]) -> bool {
        let mut at = index;
        // Validation at load time rules out cycles; the bound is a second guard.
        for _ in 0..=self.signals.len() {
            let Multiplexing::Multiplexed {
                multiplexor,
                values,
                ..
            } = &self.signals[at].multiplexing
            else {
                return true;
            };
            let Some(selector) = self.codecs[*multiplexor].layout.extract(payload) else {
                return false;
            };
            if !values.iter().any(|r| r.contains(&selector)) {
                return false;
            }
            at = *multiplexor;
        }
        false
    }

    /// The payload ([`Message::length`] bytes) carrying `values` (physical, by signal name).
    /// A signal not given is sent with its start value (`GenSigStartValue`) when the
    /// database has one, else as raw 0; a multiplexed signal is sent only when the
    /// multiplexors (given, else their start value or 0) select it, and giving one they do
    /// not select is an error.
    pub fn encode(&self, values: &[(&str, f64)]) -> Result<Vec<u8>, EncodeError> {
        let mut raws: Vec<Option<u64>> = self.signals.iter().map(Signal::start_raw).collect();
        let mut given = vec![false; self.signals.len()];
        for &(name, value) in values {
            let (index, signal) =
                self.signal_by_name(name)
                    .ok_or_else(|| EncodeError::UnknownSignal {
                        message: self.name.clone(),
                        signal: name.to_string(),
                        known: self
                            .signals
                            .iter()
                            .map(|s| s.name.as_str())
                            .collect::<Vec<_>>()
                            .join(", "),
                    })?;
            if value.is_nan() {
                return Err(EncodeError::NotANumber {
                    message: self.name.clone(),
                    signal: name.to_string(),
                    value,
                });
            }
            raws[index] = Some(signal.raw_from_physical(value).ok_or_else(|| {
                let (min, max) = signal.allowed();
                EncodeError::OutOfRange {
                    message: self.name.clone(),
                    signal: name.to_string(),
                    value,
                    min,
                    max,
                }
            })?);
            given[index] = true;
        }
        let mut payload = vec![0u8; self.length];
        // Multiplexors first, so that the branch checks read them back from the payload.
        let selector = |index: usize| self.is_selector(index);
        for (index, codec) in self.codecs.iter().enumerate() {
            if selector(index) {
                codec.layout.insert(&mut payload, raws[index].unwrap_or(0));
            }
        }
        // Then the start values of the signals not given, then the signals given (a
        // signal given wins over a start value where they overlap).
        for pass_given in [false, true] {
            for (index, codec) in self.codecs.iter().enumerate() {
                if given[index] != pass_given || (selector(index) && !pass_given) {
                    continue;
                }
                let Some(raw) = raws[index] else { continue };
                if !self.selected(index, &payload) {
                    if !pass_given {
                        continue;
                    }
                    let Multiplexing::Multiplexed { multiplexor, .. } =
                        self.signals[index].multiplexing
                    else {
                        unreachable!("a signal that is not multiplexed is always selected")
                    };
                    return Err(EncodeError::InactiveBranch {
                        message: self.name.clone(),
                        signal: self.signals[index].name.clone(),
                        multiplexor: self.signals[multiplexor].name.clone(),
                        selector: raws[multiplexor].unwrap_or(0),
                    });
                }
                codec.layout.insert(&mut payload, raw);
            }
        }
        Ok(payload)
    }

    /// Whether signal `index` selects others: marked as a multiplexor, or named as one.
    fn is_selector(&self, index: usize) -> bool {
        self.signals[index].is_multiplexor()
            || self.signals.iter().any(|s| {
                matches!(s.multiplexing, Multiplexing::Multiplexed { multiplexor, .. } if multiplexor == index)
            })
    }
}
