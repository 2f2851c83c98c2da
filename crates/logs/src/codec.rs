//! What every format implements: a reader of entries, a writer (the file layer wraps a
//! format's [`Encoder`] into a [`LogWriter`]), and the byte helpers of the binary formats.

use std::io::{self, Read};
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

use crate::error::{Location, Problem, ReadError};
use crate::{LogBitRate, Message};

/// The read buffer of a log file.
pub(crate) const READ_BUFFER: usize = 256 * 1024;

/// A log being read, one entry at a time into the caller's [`Message`] (the text formats then
/// allocate nothing per entry).
pub trait LogReader: Send {
    /// Reads the next entry into `entry`; `Ok(false)` at the end. After an error that is not
    /// [fatal](ReadError::is_fatal) the next call goes on with the next record; after a fatal
    /// one it returns `Ok(false)`.
    fn read_into(&mut self, entry: &mut Message) -> Result<bool, ReadError>;
    /// The bus's bit rate the log gives for `channel` in what was read so far: its header
    /// names it (TRC) or its frames carry their length on the wire (ASC, BLF). `None` when it
    /// does not say (candump, CSV, SQLite and pcap logs never do).
    fn bit_rate(&self, channel: &str) -> Option<LogBitRate> {
        let _ = channel;
        None
    }
}

impl<R: LogReader + ?Sized> LogReader for Box<R> {
    fn read_into(&mut self, entry: &mut Message) -> Result<bool, ReadError> {
        (**self).read_into(entry)
    }
    fn bit_rate(&self, channel: &str) -> Option<LogBitRate> {
        (**self).bit_rate(channel)
    }
}

/// A log being written.
pub trait LogWriter {
    fn write(&mut self, entry: &Message) -> io::Result<()>;
    /// Hands everything written so far to the operating system (the SQLite writer commits),
    /// so it survives the process being killed.
    fn flush(&mut self) -> io::Result<()>;
    /// Completes the file (headers that need the totals, the last container or transaction),
    /// syncs it to disk and, for an atomic writer, puts it in place.
    fn finish(self: Box<Self>) -> io::Result<()>;
    /// Entries the format cannot hold, left out so far (each kind warned about once).
    fn left_out(&self) -> u64 {
        0
    }
}

/// A format's writer over some output (the file layer wraps it into a [`LogWriter`]).
pub(crate) trait Encoder<W>: Send {
    fn write(&mut self, entry: &Message) -> io::Result<()>;
    fn flush(&mut self) -> io::Result<()>;
    /// Writes what is still pending and gives the output back.
    fn finish(self) -> io::Result<W>;
    fn left_out(&self) -> u64 {
        0
    }
}

/// The entries of a [`LogReader`] as an iterator (one allocation per entry for its interface
/// name; [`LogReader::read_into`] avoids it).
pub struct Entries<R> {
    reader: R,
    done: bool,
}

impl<R: LogReader> Entries<R> {
    pub fn new(reader: R) -> Self {
        Self {
            reader,
            done: false,
        }
    }
}

impl<R: LogReader> Iterator for Entries<R> {
    type Item = Result<Message, ReadError>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.done {
            return None;
        }
        let mut entry = Message::default();
        match self.reader.read_into(&mut entry) {
            Ok(true) => Some(Ok(entry)),
            Ok(false) => {
                self.done = true;
                None
            }
            Err(e) => {
                self.done = e.is_fatal();
                Some(Err(e))
            }
        }
    }
}

/// How many bytes of a file were read so far (for a progress bar in another thread).
#[derive(Clone, Debug, Default)]
pub struct ByteCounter(Arc<AtomicU64>);

impl ByteCounter {
    pub fn get(&self) -> u64 {
        self.0.load(Ordering::Relaxed)
    }

    pub(crate) fn add(&self, n: u64) {
        self.0.fetch_add(n, Ordering::Relaxed);
    }

    #[cfg(feature = "sqlite")]
    pub(crate) fn set(&self, n: u64) {
        self.0.store(n, Ordering::Relaxed);
    }
}

/// Reads as many bytes as there are, up to `buf.len()`: fewer only at the end of the input.
pub(crate) fn read_full(input: &mut impl Read, buf: &mut [u8]) -> io::Result<usize> {
    let mut got = 0;
    while got < buf.len() {
        match input.read(&mut buf[got..]) {
            Ok(0) => break,
            Ok(n) => got += n,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(got)
}

/// A fatal error: the input ended `have` bytes into a `need`-byte `what` at offset `at`.
pub(crate) fn truncated(at: u64, what: &'static str, have: usize, need: usize) -> ReadError {
    ReadError::fatal(
        Some(Location::Offset(at)),
        Problem::Truncated {
            what,
            have: have as u64,
            need: need as u64,
        },
    )
}
