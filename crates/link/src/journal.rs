//! The journal beside a device's state file: the changes the device made since the state file
//! was last written, appended as they happen and synced before the device's next byte leaves,
//! so that nothing a device acknowledged is lost when the process is killed.
//!
//! A state file `S` has journals `S.journal.1`, `S.journal.2`, … (the number grows each time a
//! new snapshot starts being written). A snapshot that reached the disk makes the journals
//! before it redundant, and they are deleted. After a crash, [`replay`] applies every journal,
//! oldest first, over the state file; records are absolute writes, so replaying one the state
//! file already holds changes nothing.
//!
//! Each record is framed as `length (u32 LE) · CRC-32 of the payload (u32 LE) · payload`; a
//! record cut short by a kill (never acknowledged: the sync comes after the whole write) ends
//! the journal.

use std::fs::{self, File, OpenOptions};
use std::io::{self, Write};
use std::path::{Path, PathBuf};

use buslab_device::{Persistent, ReplayError};

use crate::fs::{ReadError, read_limited};

/// The largest journal read back (a journal holds the changes of about one save period).
const MAX_JOURNAL: u64 = 1 << 30;

/// Bytes before each record's payload.
const FRAME: usize = 8;

/// Why a journal could not be replayed.
#[derive(Debug, thiserror::Error)]
pub enum JournalError {
    #[error(transparent)]
    Read(#[from] ReadError),
    #[error("cannot list the journals of {}: {source}", state.display())]
    List {
        state: PathBuf,
        #[source]
        source: io::Error,
    },
    #[error("journal {} record {index}: {source}", path.display())]
    Replay {
        path: PathBuf,
        index: usize,
        #[source]
        source: ReplayError,
    },
}

/// What [`replay`] did.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Replayed {
    /// Journal files read.
    pub journals: usize,
    /// Records applied.
    pub records: usize,
    /// Bytes at the end of a journal that were not a whole record (a write cut by a kill).
    pub torn_bytes: usize,
}

/// The journal numbered `seq` of the state file `state`.
pub fn journal_path(state: &Path, seq: u64) -> PathBuf {
    let mut name = state.file_name().unwrap_or_default().to_os_string();
    name.push(format!(".journal.{seq}"));
    state.with_file_name(name)
}

/// The journals of `state` on disk, oldest first.
pub fn existing(state: &Path) -> io::Result<Vec<(u64, PathBuf)>> {
    let dir = state
        .parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let Some(name) = state.file_name().and_then(|n| n.to_str()) else {
        return Ok(Vec::new());
    };
    let prefix = format!("{name}.journal.");
    let entries = match fs::read_dir(dir) {
        Ok(entries) => entries,
        Err(e) if e.kind() == io::ErrorKind::NotFound => return Ok(Vec::new()),
        Err(e) => return Err(e),
    };
    let mut found = Vec::new();
    for entry in entries {
        let entry = entry?;
        let file_name = entry.file_name();
        let Some(seq) = file_name
            .to_str()
            .and_then(|n| n.strip_prefix(&prefix))
            .and_then(|n| n.parse::<u64>().ok())
        else {
            continue;
        };
        found.push((seq, entry.path()));
    }
    found.sort();
    Ok(found)
}

/// Applies every journal of the state file `state` to `snapshot` (the state file's contents,
/// or a fresh device's state if there is no file), oldest first.
pub fn replay<D: Persistent>(
    state: &Path,
    snapshot: &mut D::Snapshot,
) -> Result<Replayed, JournalError> {
    let journals = existing(state).map_err(|source| JournalError::List {
        state: state.to_path_buf(),
        source,
    })?;
    let mut done = Replayed::default();
    for (_, path) in journals {
        let bytes = read_limited(&path, MAX_JOURNAL)?;
        let (records, torn) = records(&bytes);
        for (index, record) in records.into_iter().enumerate() {
            D::replay(snapshot, record).map_err(|source| JournalError::Replay {
                path: path.clone(),
                index,
                source,
            })?;
            done.records += 1;
        }
        if torn > 0 {
            tracing::warn!(
                "journal {}: the last {torn} bytes are a record cut short (the server was \
                 stopped while writing it; it was never acknowledged); ignored",
                path.display()
            );
        }
        done.torn_bytes += torn;
        done.journals += 1;
    }
    Ok(done)
}

/// The whole records in `bytes`, and how many bytes after them are not one.
fn records(bytes: &[u8]) -> (Vec<&[u8]>, usize) {
    let mut out = Vec::new();
    let mut rest = bytes;
    while rest.len() >= FRAME {
        let len = u32::from_le_bytes(rest[..4].try_into().expect("4 bytes")) as usize;
        let crc = u32::from_le_bytes(rest[4..8].try_into().expect("4 bytes"));
        let Some(payload) = rest.get(FRAME..FRAME + len) else {
            break;
        };
        if crc32fast::hash(payload) != crc {
            break;
        }
        out.push(payload);
        rest = &rest[FRAME + len..];
    }
    (out, rest.len())
}

/// Appends records to the current journal and syncs them on request.
#[derive(Debug)]
pub(crate) struct Writer {
    state: PathBuf,
    seq: u64,
    file: File,
    unsynced: bool,
    buf: Vec<u8>,
}

impl Writer {
    /// Starts journal `seq` of `state` (a new, empty file).
    pub(crate) fn create(state: &Path, seq: u64) -> io::Result<Self> {
        let path = journal_path(state, seq);
        let file = OpenOptions::new()
            .write(true)
            .create(true)
            .truncate(true)
            .open(&path)?;
        // The new name must survive a power cut as well as its contents.
        let dir = state
            .parent()
            .filter(|d| !d.as_os_str().is_empty())
            .unwrap_or(Path::new("."));
        File::open(dir)?.sync_all()?;
        Ok(Self {
            state: state.to_path_buf(),
            seq,
            file,
            unsynced: false,
            buf: Vec::new(),
        })
    }

    /// The number of the journal being written.
    pub(crate) fn seq(&self) -> u64 {
        self.seq
    }

    /// Appends `records` (one write).
    pub(crate) fn append(&mut self, records: &[Vec<u8>]) -> io::Result<()> {
        self.buf.clear();
        for r in records {
            self.buf.extend_from_slice(&(r.len() as u32).to_le_bytes());
            self.buf
                .extend_from_slice(&crc32fast::hash(r).to_le_bytes());
            self.buf.extend_from_slice(r);
        }
        self.file.write_all(&self.buf)?;
        self.unsynced = true;
        Ok(())
    }

    /// Makes what was appended durable (nothing to do if it is).
    pub(crate) fn sync(&mut self) -> io::Result<()> {
        if self.unsynced {
            self.file.sync_data()?;
            self.unsynced = false;
        }
        Ok(())
    }

    /// Continues in a new journal, numbered one more; this one is complete (synced).
    pub(crate) fn rotate(&mut self) -> io::Result<()> {
        self.sync()?;
        *self = Self::create(&self.state, self.seq + 1)?;
        Ok(())
    }
}

/// Deletes the journals of `state` numbered `from..below`.
pub(crate) fn retire(state: &Path, from: u64, below: u64) {
    for seq in from..below {
        match fs::remove_file(journal_path(state, seq)) {
            Ok(()) => {}
            Err(e) if e.kind() == io::ErrorKind::NotFound => {}
            Err(e) => tracing::warn!(
                "cannot delete the journal {} (its changes are in {} already): {e}",
                journal_path(state, seq).display(),
                state.display()
            ),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn records_read_back_until_a_torn_tail() {
        let dir = tempfile::tempdir().unwrap();
        let state = dir.path().join("s.toml");
        let mut w = Writer::create(&state, 3).unwrap();
        w.append(&[vec![1, 2, 3], vec![], vec![4; 300]]).unwrap();
        w.sync().unwrap();
        let path = journal_path(&state, 3);
        assert_eq!(path, dir.path().join("s.toml.journal.3"));
        let mut bytes = fs::read(&path).unwrap();
        let (got, torn) = records(&bytes);
        assert_eq!(got, [&[1u8, 2, 3][..], &[], &[4; 300][..]]);
        assert_eq!(torn, 0);
        // A kill in the middle of a write: the whole records before it count.
        bytes.extend_from_slice(&[9, 0, 0, 0, 1, 2]);
        let (got, torn) = records(&bytes);
        assert_eq!((got.len(), torn), (3, 6));
        // A damaged record ends the journal.
        let last = bytes.len() - 7;
        bytes[last] ^= 1;
        let (got, _) = records(&bytes);
        assert_eq!(got.len(), 2);
        assert_eq!(existing(&state).unwrap(), vec![(3, path)]);
        w.rotate().unwrap();
        assert_eq!(w.seq(), 4);
        assert_eq!(existing(&state).unwrap().len(), 2);
        retire(&state, 3, 5);
        assert!(existing(&state).unwrap().is_empty());
    }
}
