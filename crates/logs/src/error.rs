//! What can go wrong reading a log, and where.

use std::fmt;
use std::io;
use std::path::{Path, PathBuf};

use crate::text::MAX_LINE;

/// Why a log line cannot be read.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum LineError {
    #[error("empty line: expected (SECONDS.FRACTION) IFACE FRAME")]
    Empty,
    #[error(
        "timestamp {0:?} must be (SECONDS.FRACTION) with 1..9 decimals, e.g. (1700000000.123456)"
    )]
    Timestamp(String),
    #[error("no interface after the timestamp: expected (SECONDS.FRACTION) IFACE FRAME")]
    NoInterface,
    #[error("no frame after interface {0:?}: expected (SECONDS.FRACTION) IFACE FRAME")]
    NoFrame(String),
    #[error("{0}")]
    Frame(#[from] buslab_can::ParseError),
    #[error("error frame {text:?}: {reason}")]
    ErrorFrame { text: String, reason: String },
    #[error("unexpected {0:?} after the frame: only R or T (candump -x) may follow")]
    Trailing(String),
    #[error("line is longer than {MAX_LINE} bytes")]
    TooLong,
    #[error("line is not UTF-8 text")]
    NotText,
}

/// Where in a file a bad record is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Location {
    /// A text line, counted from 1.
    Line(u64),
    /// A byte offset from the start of the file (binary formats).
    Offset(u64),
    /// A database row, counted from 1 in the table's order.
    Row(u64),
}

impl fmt::Display for Location {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Location::Line(n) => write!(f, "line {n}"),
            Location::Offset(n) => write!(f, "byte {n}"),
            Location::Row(n) => write!(f, "row {n}"),
        }
    }
}

/// What is wrong with the input.
#[derive(Debug, thiserror::Error)]
pub enum Problem {
    #[error("expected {expected}, found {found:?}")]
    Expected {
        expected: &'static str,
        found: String,
    },
    #[error(transparent)]
    Candump(#[from] LineError),
    #[error("{0}")]
    Frame(#[from] buslab_can::ParseError),
    #[error("error frame: {0}")]
    ErrorFrame(#[from] buslab_bus::error_frame::ErrorFrameError),
    #[error("{what} claims {claimed} bytes, more than the {limit} accepted")]
    TooBig {
        what: &'static str,
        claimed: u64,
        limit: u64,
    },
    #[error("the file ends inside {what}: {have} of its {need} bytes are there")]
    Truncated {
        what: &'static str,
        have: u64,
        need: u64,
    },
    #[error(
        "link type {linktype} ({name}) is not CAN: buslab reads LINKTYPE_CAN_SOCKETCAN (227) and Wireshark's exported SocketCAN PDUs (252)"
    )]
    LinkType { linktype: u32, name: &'static str },
    #[error("interface {index} ({name}): {problem}; its packets are left out")]
    Interface {
        index: usize,
        name: String,
        problem: Box<Problem>,
    },
    #[error("not a {format} file: {reason}")]
    NotFormat {
        format: &'static str,
        reason: String,
    },
    #[error("{0}")]
    Io(#[from] io::Error),
    #[cfg(feature = "sqlite")]
    #[error("SQLite: {0}")]
    Sqlite(#[from] rusqlite::Error),
    #[error("zlib data: {0}")]
    Inflate(String),
}

/// A record that cannot be read: the file (when known), where in it, and what is wrong.
///
/// After a *fatal* error ([`is_fatal`](Self::is_fatal)) the reader ends: the input cannot be
/// followed past it (an I/O error, a truncated file, a size field beyond any sane record).
/// After any other error the next read goes on with the next record.
#[derive(Debug)]
pub struct ReadError(Box<Inner>);

#[derive(Debug)]
struct Inner {
    path: Option<PathBuf>,
    at: Option<Location>,
    problem: Problem,
    fatal: bool,
}

impl ReadError {
    /// A bad record the reader steps over.
    pub fn bad(at: Location, problem: impl Into<Problem>) -> Self {
        Self(Box::new(Inner {
            path: None,
            at: Some(at),
            problem: problem.into(),
            fatal: false,
        }))
    }

    /// A problem the reader cannot go past.
    pub fn fatal(at: Option<Location>, problem: impl Into<Problem>) -> Self {
        Self(Box::new(Inner {
            path: None,
            at,
            problem: problem.into(),
            fatal: true,
        }))
    }

    /// An I/O error (fatal).
    pub fn io(error: io::Error) -> Self {
        Self::fatal(None, error)
    }

    /// `expected …, found …` at `at` (not fatal).
    pub fn expected(at: Location, expected: &'static str, found: &[u8]) -> Self {
        Self::bad(
            at,
            Problem::Expected {
                expected,
                found: excerpt(found),
            },
        )
    }

    pub fn is_fatal(&self) -> bool {
        self.0.fatal
    }

    /// The file, when known.
    pub fn path(&self) -> Option<&Path> {
        self.0.path.as_deref()
    }

    /// Where in the file.
    pub fn at(&self) -> Option<Location> {
        self.0.at
    }

    pub fn problem(&self) -> &Problem {
        &self.0.problem
    }

    /// The same error, naming the file.
    pub fn in_file(mut self, path: &Path) -> Self {
        self.0.path = Some(path.to_path_buf());
        self
    }
}

impl fmt::Display for ReadError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if let Some(path) = &self.0.path {
            write!(f, "{}: ", path.display())?;
        }
        if let Some(at) = self.0.at {
            write!(f, "{at}: ")?;
        }
        write!(f, "{}", self.0.problem)
    }
}

impl std::error::Error for ReadError {}

impl From<io::Error> for ReadError {
    fn from(e: io::Error) -> Self {
        Self::io(e)
    }
}

/// The start of a bad field as text, for a message (never the whole flood).
pub(crate) fn excerpt(bytes: &[u8]) -> String {
    const KEEP: usize = 40;
    let text = String::from_utf8_lossy(bytes);
    if text.chars().count() > KEEP {
        format!("{}…", text.chars().take(KEEP).collect::<String>())
    } else {
        text.into_owned()
    }
}

/// A log file that cannot be opened or created.
#[derive(Debug, thiserror::Error)]
pub enum LogError {
    #[error("{}: {source}", path.display())]
    Open { path: PathBuf, source: io::Error },
    #[error("{}: {source}", path.display())]
    Create { path: PathBuf, source: io::Error },
    #[error("{}: is {what}, not a regular file (log files are read and written as files)", path.display())]
    NotRegular { path: PathBuf, what: &'static str },
    #[error("{source}")]
    Read { source: ReadError },
    #[cfg(feature = "sqlite")]
    #[error("{}: SQLite: {source}", path.display())]
    Sqlite {
        path: PathBuf,
        source: rusqlite::Error,
    },
    #[error("{}: --follow needs a file that grows; {format} cannot be followed", path.display())]
    CannotFollow { path: PathBuf, format: &'static str },
    #[error("{}: gzip-compressed: {what}", path.display())]
    Gzip { path: PathBuf, what: &'static str },
    /// A format this build was made without (its cargo feature was off).
    #[error("{}: {what} are not in this build (it was made without the `{feature}` feature)", path.display())]
    NotBuilt {
        path: PathBuf,
        what: &'static str,
        feature: &'static str,
    },
}
