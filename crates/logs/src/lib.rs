//! CAN log formats, each a module with a streaming reader and writer over one shared record
//! type, [`Entry`]:
//!
//! - [`candump`]: can-utils' log line `(SEC.USEC) IFACE FRAME` (candump `-l`, canplayer,
//!   python-can's `.log`), and candump's terminal layout with its `-t`/`-a`/`-x`/`-e` views.
//!
//! Timestamps are [`Duration`]s since the Unix epoch (or since whatever zero the log uses),
//! exact to the nanosecond a format carries.

use std::time::Duration;

use buslab_can::Frame;
use buslab_canbus::{BusEvent, ErrorFrame, ErrorMessage, Message};

pub mod candump;

/// One logged event: a frame or an error frame, when and where.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Entry {
    pub timestamp: Duration,
    /// The interface or channel name (`vcan0`, `can1`).
    pub interface: String,
    pub record: Record,
    /// Received or sent, when the log says (candump `-x`).
    pub direction: Option<Direction>,
}

/// What happened.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Record {
    Frame(Frame),
    Error(ErrorFrame),
}

/// Received by this interface, or sent by it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Direction {
    Rx,
    Tx,
}

impl Entry {
    /// A received or sent frame from a bus.
    pub fn from_message(m: &Message) -> Self {
        Self {
            timestamp: seconds(m.timestamp),
            interface: m.channel.clone(),
            record: Record::Frame(m.frame),
            direction: Some(if m.is_rx {
                Direction::Rx
            } else {
                Direction::Tx
            }),
        }
    }

    /// An error frame from a bus.
    pub fn from_error(e: &ErrorMessage) -> Self {
        Self {
            timestamp: seconds(e.timestamp),
            interface: e.channel.clone(),
            record: Record::Error(e.error.clone()),
            direction: Some(Direction::Rx),
        }
    }

    pub fn from_event(event: &BusEvent) -> Self {
        match event {
            BusEvent::Frame(m) => Self::from_message(m),
            BusEvent::Error(e) => Self::from_error(e),
        }
    }
}

/// Float seconds (as buses give them) to a duration, rounded to the microsecond (the
/// precision socketcand and candump carry; truncating would turn `.218691` into `.218690`).
/// Negative, NaN or huge values are clamped to 0 and `u64::MAX` µs.
pub fn seconds(t: f64) -> Duration {
    let micros = (t * 1e6).round();
    if micros.is_nan() || micros <= 0.0 {
        Duration::ZERO
    } else if micros >= u64::MAX as f64 {
        Duration::from_micros(u64::MAX)
    } else {
        Duration::from_micros(micros as u64)
    }
}
