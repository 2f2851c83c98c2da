//! CAN log formats, each a module with a streaming reader and writer over one shared record
//! type, [`Entry`]:
//!
//! - [`candump`]: can-utils' log line `(SEC.USEC) IFACE FRAME` (candump `-l`, canplayer,
//!   python-can's `.log`), and candump's terminal layout with its `-t`/`-a`/`-x`/`-e` views;
//! - [`asc`]: Vector ASC text logs; [`blf`]: Vector BLF binary logs (zlib containers);
//! - [`trc`]: PEAK TRC 1.1 and 2.1 (reads 1.0 to 2.1); [`csv`]: python-can's CSV;
//! - [`pcap`] and [`pcapng`]: captures with `LINKTYPE_CAN_SOCKETCAN` (227), for Wireshark
//!   (Wireshark's exported SocketCAN PDUs, link type 252, are read too);
//! - [`sqlite`]: python-can's SQLite database (table `messages`, checked before any row).
//!
//! [`open_reader`] and [`create_writer`] pick the module by [`Format`] (from a file's
//! extension or a name; a `.gz` log is read through gzip). Every reader is bounded in memory
//! whatever the input size, names the line or byte offset of a bad record, and goes on after
//! one that it can step over. Every reader's core works on any `BufRead`/`Read`, so a fuzz
//! target can feed it bytes. Error frames go through every format that holds them byte for
//! byte (class, bytes and length).
//!
//! Timestamps are [`Duration`]s since the Unix epoch (or since whatever zero the log uses),
//! exact to the nanosecond a format carries.

use std::time::Duration;

use buslab_bus::{BusEvent, ErrorFrame, ErrorMessage, Message};
use buslab_can::Frame;

pub mod asc;
mod bitrate;
pub mod blf;
pub mod candump;
mod channel;
mod codec;
pub mod csv;
mod error;
mod file;
mod follow;
mod format;
mod input;
pub mod pcap;
pub mod pcapng;
mod socketcan;
#[cfg(feature = "sqlite")]
pub mod sqlite;
pub mod stats;
pub mod text;
mod time;
pub mod trc;

pub use bitrate::{BitRateSource, LogBitRate};
pub use channel::{ChannelMap, channel_name};
pub use codec::{ByteCounter, Entries, LogReader, LogWriter};
pub use error::{Location, LogError, Problem, ReadError};
pub use file::{
    LogSource, OpenOptions, WriteOptions, create_writer, create_writer_atomic, create_writer_with,
    open_reader, open_source,
};
pub use follow::OnWait;
pub use format::{Format, FormatError};
pub use input::reader;

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

impl Default for Entry {
    /// An empty error frame at time 0 on no interface: a buffer for
    /// [`LogReader::read_into`].
    fn default() -> Self {
        Self {
            timestamp: Duration::ZERO,
            interface: String::new(),
            record: Record::Error(ErrorFrame::default()),
            direction: None,
        }
    }
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

    /// The frame, if this entry is one (not an error frame).
    pub fn frame(&self) -> Option<&Frame> {
        match &self.record {
            Record::Frame(f) => Some(f),
            Record::Error(_) => None,
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
