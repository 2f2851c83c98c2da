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
    /// Signals not given are sent as raw 0; a multiplexed signal may be given only when the
    /// multiplexors given (or 0) select it.
    pub fn encode(&self, values: &[(&str, f64)]) -> Result<Vec<u8>, EncodeError> {
        let mut raws = vec![0u64; self.signals.len()];
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
            raws[index] = signal.raw_from_physical(value).ok_or_else(|| {
                let (min, max) = signal.allowed();
                EncodeError::OutOfRange {
                    message: self.name.clone(),
                    signal: name.to_string(),
                    value,
                    min,
                    max,
                }
            })?;
            given[index] = true;
        }
        let mut payload = vec![0u8; self.length];
        // Multiplexors first, so that the branch check reads them back from the payload.
        for (index, signal) in self.signals.iter().enumerate() {
            if signal.is_multiplexor() && signal.codec.layout.end() <= payload.len() {
                signal.codec.layout.insert(&mut payload, raws[index]);
            }
        }
        for (index, signal) in self.signals.iter().enumerate() {
            if !given[index] {
                continue;
            }
            if let Multiplexing::Multiplexed { multiplexor, .. } = signal.multiplexing
                && !self.selected(index, &payload)
            {
                return Err(EncodeError::InactiveBranch {
                    message: self.name.clone(),
                    signal: signal.name.clone(),
                    multiplexor: self.signals[multiplexor].name.clone(),
                    selector: raws[multiplexor],
                });
            }
            if signal.codec.layout.end() <= payload.len() {
                signal.codec.layout.insert(&mut payload, raws[index]);
            }
        }
        Ok(payload)
    }
}
