//! CAN log formats, each a module with a streaming reader and writer over the bus vocabulary's
//! record, [`Message`] (a frame or an error frame with its time, channel and direction):
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
//! byte (class, bytes and length). CAN FD frames (with BRS and ESI) go through candump, ASC,
//! BLF, TRC 2.1, pcap and pcapng whole; TRC 1.1 has no FD record and refuses them by name;
//! python-can's CSV and SQLite columns keep their ID and data only, as python-can does.
//!
//! Times are [`Timestamp`]s since the Unix epoch (or since whatever zero the log uses), exact
//! to the nanosecond a format carries.

pub mod asc;
mod bit_stamps;
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
pub mod replay;
mod socketcan;
#[cfg(feature = "sqlite")]
pub mod sqlite;
pub mod stats;
pub mod text;
mod time;
pub mod trc;

pub use bit_stamps::BitTimeStamps;
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

/// One logged event, a frame or an error frame, when and where: the bus vocabulary's
/// [`Message`], the same a bus gives.
pub use buslab_bus::{Direction, Message, Record, Timestamp};
