//! Following a growing log, as `tail -F` does: at the end of the file, wait for more; notice
//! when the file is truncated (`copytruncate`, `> file`), rewritten from its start, or replaced
//! by a new file at its path (rotation), warn naming which, and read the new content from its
//! start with a fresh reader (the new content has its own header).

use std::fmt;
use std::fs::{self, File};
use std::io::{self, BufReader, Read};
use std::os::unix::fs::{FileExt, MetadataExt};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Duration;

use crate::codec::{ByteCounter, LogReader, READ_BUFFER};
use crate::error::{LogError, ReadError};
use crate::format::Format;
use crate::input::{open_regular, reader};
use crate::{Message, blf};

/// How often a followed file is looked at for new bytes.
const POLL: Duration = Duration::from_millis(100);
/// How many of the last bytes read are compared with the file when it grows again: a file
/// truncated and written again past the reader's position differs there.
const TAIL: usize = 64;

/// What happened to a followed file.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) enum Change {
    /// It is shorter than what was read.
    Truncated { read: u64, now: u64 },
    /// The bytes before the reader's position are no longer those it read (truncated and
    /// written again before the reader looked).
    Rewritten { at: u64 },
    /// Its path names another file now (rotated: renamed away, a new one created).
    Replaced,
}

impl fmt::Display for Change {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Change::Truncated { read, now } => {
                write!(f, "truncated to {now} bytes after {read} were read")
            }
            Change::Rewritten { at } => write!(
                f,
                "rewritten: its bytes from {at} on differ from those read (truncated and written again)"
            ),
            Change::Replaced => write!(f, "replaced by a new file (rotated)"),
        }
    }
}

type Slot = Arc<Mutex<Option<Change>>>;

fn lock(slot: &Slot) -> MutexGuard<'_, Option<Change>> {
    slot.lock().unwrap_or_else(|p| p.into_inner())
}

/// How to follow.
pub(crate) struct Watch {
    pub stop: Arc<AtomicBool>,
    pub on_wait: Option<OnWait>,
    pub count: ByteCounter,
}

/// The bytes of a followed file: at its end, waits for more until told to stop; when the file
/// changed under it, records the [`Change`] and ends (the reader above starts again).
struct Follow {
    file: File,
    path: PathBuf,
    /// The file's device and inode, to tell when the path names another one.
    identity: (u64, u64),
    pos: u64,
    /// The last bytes read (at most [`TAIL`]), none before `keep_from`.
    tail: Vec<u8>,
    /// Bytes before this offset may be rewritten in place by the writer (a BLF header).
    keep_from: u64,
    stop: Arc<AtomicBool>,
    on_wait: Option<OnWait>,
    count: ByteCounter,
    change: Slot,
}

impl Follow {
    fn open(path: &Path, keep_from: u64, watch: &Watch, change: Slot) -> Result<Self, LogError> {
        let file = open_regular(path)?;
        let meta = file.metadata().map_err(|source| LogError::Open {
            path: path.to_path_buf(),
            source,
        })?;
        Ok(Self {
            file,
            path: path.to_path_buf(),
            identity: (meta.dev(), meta.ino()),
            pos: 0,
            tail: Vec::with_capacity(2 * TAIL),
            keep_from,
            stop: watch.stop.clone(),
            on_wait: watch.on_wait.clone(),
            count: watch.count.clone(),
            change,
        })
    }

    /// Truncated or replaced, seen at the end of what was read.
    fn changed(&self) -> io::Result<Option<Change>> {
        let now = self.file.metadata()?.len();
        if now < self.pos {
            return Ok(Some(Change::Truncated {
                read: self.pos,
                now,
            }));
        }
        Ok(match fs::metadata(&self.path) {
            Ok(m) if (m.dev(), m.ino()) != self.identity => Some(Change::Replaced),
            // Gone for now (between a rotation's rename and create): keep waiting.
            _ => None,
        })
    }

    /// Whether the last bytes read are still there.
    fn rewritten(&self) -> io::Result<Option<Change>> {
        if self.tail.is_empty() {
            return Ok(None);
        }
        let at = self.pos - self.tail.len() as u64;
        let mut now = [0u8; TAIL];
        let now = &mut now[..self.tail.len()];
        match self.file.read_exact_at(now, at) {
            Ok(()) if now == self.tail.as_slice() => Ok(None),
            Ok(()) => Ok(Some(Change::Rewritten { at })),
            Err(e) if e.kind() == io::ErrorKind::UnexpectedEof => {
                Ok(Some(Change::Rewritten { at }))
            }
            Err(e) => Err(e),
        }
    }

    fn advance(&mut self, bytes: &[u8]) {
        self.pos += bytes.len() as u64;
        self.tail
            .extend_from_slice(&bytes[bytes.len().saturating_sub(TAIL)..]);
        let excess = self.tail.len().saturating_sub(TAIL);
        let before_keep = self
            .keep_from
            .saturating_sub(self.pos - self.tail.len() as u64)
            .min(self.tail.len() as u64) as usize;
        self.tail.drain(..excess.max(before_keep));
        self.count.add(bytes.len() as u64);
    }

    fn signal(&self, change: Change) -> io::Result<usize> {
        *lock(&self.change) = Some(change);
        Ok(0)
    }
}

impl Read for Follow {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        if buf.is_empty() || lock(&self.change).is_some() {
            return Ok(0);
        }
        let mut waited = false;
        loop {
            let n = self.file.read(buf)?;
            if n > 0 {
                if waited && let Some(change) = self.rewritten()? {
                    return self.signal(change);
                }
                self.advance(&buf[..n]);
                return Ok(n);
            }
            if let Some(change) = self.changed()? {
                return self.signal(change);
            }
            if self.stop.load(Ordering::SeqCst) {
                return Ok(0);
            }
            if !waited {
                waited = true;
                if let Some(f) = &self.on_wait {
                    f();
                }
            }
            std::thread::sleep(POLL);
        }
    }
}

/// A followed log's entries, across truncations and rotations.
pub(crate) struct Following {
    path: PathBuf,
    format: Format,
    watch: Watch,
    change: Slot,
    inner: Box<dyn LogReader + Send>,
}

impl Following {
    pub fn open(path: &Path, format: Format, watch: Watch) -> Result<Self, LogError> {
        let change = Slot::default();
        let inner = open_inner(path, format, &watch, change.clone())?;
        Ok(Self {
            path: path.to_path_buf(),
            format,
            watch,
            change,
            inner,
        })
    }
}

fn open_inner(
    path: &Path,
    format: Format,
    watch: &Watch,
    change: Slot,
) -> Result<Box<dyn LogReader + Send>, LogError> {
    // A BLF writer rewrites its header in place at each flush (buslab's does).
    let keep_from = if format == Format::Blf {
        blf::FILE_HEADER_SIZE as u64
    } else {
        0
    };
    let follow = Follow::open(path, keep_from, watch, change)?;
    reader(BufReader::with_capacity(READ_BUFFER, follow), format).map_err(|e| LogError::Read {
        source: e.in_file(path),
    })
}

impl LogReader for Following {
    fn read_into(&mut self, entry: &mut Message) -> Result<bool, ReadError> {
        loop {
            let result = self.inner.read_into(entry);
            if let Ok(true) = result {
                return result;
            }
            let Some(change) = lock(&self.change).take() else {
                return result;
            };
            let path = self.path.display();
            if let Err(e) = &result {
                tracing::warn!("{path}: the content read before it changed ends with: {e}");
            }
            tracing::warn!("{path} was {change}: reading its new content from the start");
            self.inner = open_inner(&self.path, self.format, &self.watch, self.change.clone())
                .map_err(|e| match e {
                    LogError::Read { source } => source,
                    other => ReadError::io(io::Error::other(other.to_string())),
                })?;
        }
    }
}

/// Called when a followed file has no more bytes for now (e.g. to flush what was written).
pub type OnWait = Arc<dyn Fn() + Send + Sync>;
