//! Files as buslab writes and reads them: written atomically ([`Staged`], [`AtomicFile`],
//! [`write_atomic`]), read with a size limit ([`read_limited`]), opened only when they are
//! regular files ([`open_regular`]). std, `tempfile` and `libc` only, so any host crate can
//! write its files the one way (`buslab-link` re-exports it as `buslab_link::fs`, `buslab-logs`
//! puts its converted logs in place with it). Long output to a regular file goes in whole,
//! aligned blocks ([`BlockWriter`]).

mod blocks;

pub use blocks::{BLOCK, BlockWriter};

use std::fs::{self, File, OpenOptions};
use std::io::{self, Read, Write};
use std::os::unix::fs::{FileTypeExt, OpenOptionsExt, PermissionsExt};
use std::path::{Path, PathBuf};

/// Why a file could not be written.
#[derive(Debug, thiserror::Error)]
#[error("cannot write {}: {source}", path.display())]
pub struct WriteError {
    pub path: PathBuf,
    #[source]
    pub source: io::Error,
}

/// Why a file could not be read.
#[derive(Debug, thiserror::Error)]
pub enum ReadError {
    #[error("cannot read {}: {source}", path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: io::Error,
    },
    #[error("{} is {kind}, not a regular file; give the path of a file", path.display())]
    NotRegular { path: PathBuf, kind: &'static str },
    #[error("{} is larger than {max_bytes} bytes, the most accepted here", path.display())]
    TooLarge { path: PathBuf, max_bytes: u64 },
    #[error("{} is not UTF-8 text", path.display())]
    NotText { path: PathBuf },
}

impl ReadError {
    /// Whether the file does not exist (a missing state file means a fresh device).
    pub fn is_not_found(&self) -> bool {
        matches!(self, ReadError::Io { source, .. } if source.kind() == io::ErrorKind::NotFound)
    }
}

/// Writes `path` so that a crash or a concurrent writer leaves either the old or the new
/// contents ([`Staged`]: a temporary file with a unique name in the same folder, synced,
/// renamed over `path`, then the folder synced).
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), WriteError> {
    let mut file = AtomicFile::create(path)?;
    file.write_all(bytes)?;
    file.commit()
}

/// A file that replaces its target whole or not at all: the one way buslab writes a file
/// atomically. [`create`](Self::create) checks the target and makes a temporary file with a
/// unique name in the target's folder (so the rename stays on one file system and concurrent
/// writers never share a file); [`commit`](Self::commit) syncs it, renames it over the
/// target and syncs the folder, so the new contents survive a crash once `commit` returns.
/// Dropped without a commit, the temporary file is removed and the target left as it was.
///
/// It is unbuffered: [`AtomicFile`] buffers it for data written as it comes; a writer that
/// keeps its own handle (seeks, cuts back) takes one with [`file`](Self::file), and one that
/// opens by name (SQLite) uses [`temp_path`](Self::temp_path).
#[derive(Debug)]
pub struct Staged {
    path: PathBuf,
    dir: PathBuf,
    temp: tempfile::NamedTempFile,
}

impl Staged {
    /// Refuses a target that exists and is not a regular file (a folder, a FIFO, a device),
    /// and a folder where no file can be made. The temporary file is created with the
    /// target's permissions if it exists (less the umask), else as a plain create makes a
    /// file (0666 less the umask).
    pub fn create(path: &Path) -> Result<Self, WriteError> {
        let error = |source| WriteError {
            path: path.to_path_buf(),
            source,
        };
        let existing = fs::metadata(path).ok();
        if let Some(kind) = existing.as_ref().and_then(not_regular) {
            return Err(error(io::Error::new(
                io::ErrorKind::InvalidInput,
                format!("it is {kind}, not a regular file; give the path of a file"),
            )));
        }
        let dir = path
            .parent()
            .filter(|d| !d.as_os_str().is_empty())
            .unwrap_or(Path::new("."));
        let name = path
            .file_name()
            .ok_or_else(|| error(io::Error::other("the path names no file")))?;
        // Never more open than the file it replaces (a private file's new contents are
        // private from the first byte); the umask narrows it further until the commit.
        let mode = existing.map_or(0o666, |m| m.permissions().mode() & 0o7777);
        let temp = tempfile::Builder::new()
            .prefix(&format!(".{}.", name.to_string_lossy()))
            .suffix(".tmp")
            .permissions(fs::Permissions::from_mode(mode))
            .tempfile_in(dir)
            .map_err(error)?;
        Ok(Self {
            path: path.to_path_buf(),
            dir: dir.to_path_buf(),
            temp,
        })
    }

    /// The target's path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The temporary file's path, for a writer that opens files by name. It goes away with
    /// the commit (renamed) or the drop (removed).
    pub fn temp_path(&self) -> &Path {
        self.temp.path()
    }

    /// The temporary file; `&File` writes and seeks, and `try_clone` gives a handle of one's
    /// own on it.
    pub fn file(&self) -> &File {
        self.temp.as_file()
    }

    /// Makes the target the written bytes, durably: an existing target's permissions carried
    /// over, the file synced, renamed over the target, the folder synced.
    pub fn commit(self) -> Result<(), WriteError> {
        let Self { path, dir, temp } = self;
        let error = |source| WriteError {
            path: path.clone(),
            source,
        };
        if let Ok(meta) = fs::metadata(&path) {
            temp.as_file()
                .set_permissions(meta.permissions())
                .map_err(error)?;
        }
        temp.as_file().sync_all().map_err(error)?;
        temp.persist(&path).map_err(|e| error(e.error))?;
        // The rename is durable once the folder is.
        File::open(&dir).and_then(|d| d.sync_all()).map_err(error)
    }
}

impl Write for Staged {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        self.temp.write(buf)
    }
    fn flush(&mut self) -> io::Result<()> {
        self.temp.flush()
    }
}

/// A [`Staged`] file written as it comes, buffered ([`write_atomic`] for data that does not
/// fit in memory, or arrives slowly): a target that cannot be written is refused by
/// [`create`](Self::create), before the first byte.
pub struct AtomicFile {
    staged: io::BufWriter<Staged>,
}

impl AtomicFile {
    /// [`Staged::create`].
    pub fn create(path: &Path) -> Result<Self, WriteError> {
        Ok(Self {
            staged: io::BufWriter::new(Staged::create(path)?),
        })
    }

    /// The target's path.
    pub fn path(&self) -> &Path {
        self.staged.get_ref().path()
    }

    pub fn write_all(&mut self, bytes: &[u8]) -> Result<(), WriteError> {
        self.staged.write_all(bytes).map_err(|source| WriteError {
            path: self.path().to_path_buf(),
            source,
        })
    }

    /// Makes the target the written bytes, durably ([`Staged::commit`]).
    pub fn commit(self) -> Result<(), WriteError> {
        let path = self.path().to_path_buf();
        let staged = self.staged.into_inner().map_err(|e| WriteError {
            path,
            source: e.into_error(),
        })?;
        staged.commit()
    }
}

/// Reads the whole of `path`, refusing what is not a regular file (a FIFO would block, a
/// device such as `/dev/zero` never ends) and files larger than `max_bytes`.
pub fn read_limited(path: &Path, max_bytes: u64) -> Result<Vec<u8>, ReadError> {
    let io_error = |source| ReadError::Io {
        path: path.to_path_buf(),
        source,
    };
    // Non-blocking: opening a FIFO for reading would otherwise wait for a writer. Regular
    // files ignore the flag.
    let file = OpenOptions::new()
        .read(true)
        .custom_flags(libc::O_NONBLOCK)
        .open(path)
        .map_err(io_error)?;
    let meta = file.metadata().map_err(io_error)?;
    if let Some(kind) = not_regular(&meta) {
        return Err(ReadError::NotRegular {
            path: path.to_path_buf(),
            kind,
        });
    }
    let too_large = || ReadError::TooLarge {
        path: path.to_path_buf(),
        max_bytes,
    };
    if meta.len() > max_bytes {
        return Err(too_large());
    }
    // The file may grow while it is read: never more than the limit.
    let mut bytes = Vec::with_capacity(meta.len() as usize);
    file.take(max_bytes.saturating_add(1))
        .read_to_end(&mut bytes)
        .map_err(io_error)?;
    if bytes.len() as u64 > max_bytes {
        return Err(too_large());
    }
    Ok(bytes)
}

/// What a file that is not a regular one is, for messages; `None` for a regular file.
fn not_regular(meta: &fs::Metadata) -> Option<&'static str> {
    let kind = meta.file_type();
    Some(if kind.is_file() {
        return None;
    } else if kind.is_dir() {
        "a folder"
    } else if kind.is_fifo() {
        "a FIFO"
    } else if kind.is_socket() {
        "a socket"
    } else if kind.is_char_device() || kind.is_block_device() {
        "a device"
    } else {
        "not a file"
    })
}

/// Opens a regular file for reading, or for writing (created if missing, emptied), and
/// never blocks: a FIFO or a device is refused (opening a FIFO would wait for its other end,
/// a device may never end). The error names the path.
pub fn open_regular(path: &Path, write: bool) -> io::Result<File> {
    let refuse = |kind: &str| {
        io::Error::new(
            io::ErrorKind::InvalidInput,
            format!("{} is {kind}, not a regular file", path.display()),
        )
    };
    // Looked at first, so nothing is opened (or truncated) that is not a plain file.
    if let Ok(meta) = fs::metadata(path)
        && let Some(kind) = not_regular(&meta)
    {
        return Err(refuse(kind));
    }
    let file = OpenOptions::new()
        .read(!write)
        .write(write)
        .create(write)
        .truncate(write)
        .custom_flags(libc::O_NONBLOCK)
        .open(path)?;
    // It may have been replaced between the look and the open.
    if let Some(kind) = not_regular(&file.metadata()?) {
        return Err(refuse(kind));
    }
    Ok(file)
}

/// [`read_limited`], as UTF-8 text.
pub fn read_text_limited(path: &Path, max_bytes: u64) -> Result<String, ReadError> {
    String::from_utf8(read_limited(path, max_bytes)?).map_err(|_| ReadError::NotText {
        path: path.to_path_buf(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn writes_replace_the_file_and_leave_no_temporary_behind() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("state.toml");
        write_atomic(&path, b"one").unwrap();
        fs::set_permissions(&path, fs::Permissions::from_mode(0o600)).unwrap();
        write_atomic(&path, b"two").unwrap();
        assert_eq!(fs::read(&path).unwrap(), b"two");
        assert_eq!(
            fs::metadata(&path).unwrap().permissions().mode() & 0o777,
            0o600,
            "an existing file keeps its permissions"
        );
        let names: Vec<_> = fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names, ["state.toml"]);
        let err = write_atomic(&dir.path().join("missing/x.toml"), b"x").unwrap_err();
        assert!(err.to_string().contains("missing/x.toml"), "{err}");
    }

    #[test]
    fn a_file_written_as_it_comes_is_checked_first_and_appears_whole_or_not_at_all() {
        let dir = tempfile::tempdir().unwrap();
        let names = || -> Vec<_> {
            let mut n: Vec<_> = fs::read_dir(dir.path())
                .unwrap()
                .map(|e| e.unwrap().file_name().into_string().unwrap())
                .collect();
            n.sort();
            n
        };
        let path = dir.path().join("out.bin");
        let mut file = AtomicFile::create(&path).unwrap();
        file.write_all(b"part one, ").unwrap();
        assert!(!path.exists(), "nothing before the commit");
        file.write_all(b"part two").unwrap();
        file.commit().unwrap();
        assert_eq!(fs::read(&path).unwrap(), b"part one, part two");
        // Dropped without a commit: the old contents stay, no temporary file is left.
        let mut file = AtomicFile::create(&path).unwrap();
        file.write_all(b"never").unwrap();
        drop(file);
        assert_eq!(fs::read(&path).unwrap(), b"part one, part two");
        assert_eq!(names(), ["out.bin"]);
        // Refused before anything is written: a folder, a FIFO, a missing folder.
        let e = AtomicFile::create(dir.path()).err().unwrap();
        assert!(
            e.to_string().contains("a folder, not a regular file"),
            "{e}"
        );
        let fifo = dir.path().join("fifo");
        nix::unistd::mkfifo(&fifo, nix::sys::stat::Mode::S_IRWXU).unwrap();
        let e = AtomicFile::create(&fifo).err().unwrap();
        assert!(e.to_string().contains("a FIFO"), "{e}");
        let e = AtomicFile::create(&dir.path().join("missing/out.bin"))
            .err()
            .unwrap();
        assert!(e.to_string().contains("missing/out.bin"), "{e}");
    }

    /// The one atomic writer, as `AtomicFile` and the log writers use it: nothing appears
    /// before the commit, a dropped one leaves neither target nor temporary file, two at once
    /// never share a temporary file, and a target that is not a regular file is refused with
    /// nothing made.
    #[test]
    fn a_staged_file_not_committed_leaves_no_file_and_no_temporary_file() {
        let dir = tempfile::tempdir().unwrap();
        let names = || -> Vec<String> {
            let mut n: Vec<_> = fs::read_dir(dir.path())
                .unwrap()
                .map(|e| e.unwrap().file_name().into_string().unwrap())
                .collect();
            n.sort();
            n
        };
        let path = dir.path().join("trace.blf");
        let mut staged = Staged::create(&path).unwrap();
        staged.write_all(b"entries").unwrap();
        let temp = staged.temp_path().to_path_buf();
        assert_eq!(temp.parent(), Some(dir.path()), "beside its target");
        let temp_name = temp.file_name().unwrap().to_str().unwrap().to_owned();
        assert!(
            temp_name.starts_with(".trace.blf.") && temp_name.ends_with(".tmp"),
            "{temp_name}"
        );
        let other = Staged::create(&path).unwrap();
        assert_ne!(other.temp_path(), temp, "two writers, two temporary files");
        drop(other);
        assert!(!path.exists(), "nothing before the commit");
        drop(staged);
        assert!(!temp.exists());
        assert_eq!(names(), Vec::<String>::new(), "no file, no temporary file");

        // Written through a handle of its own (the log writer's), then committed: the
        // target has the bytes, and the permissions a plain create gives.
        let staged = Staged::create(&path).unwrap();
        let mut own = staged.file().try_clone().unwrap();
        own.write_all(b"whole").unwrap();
        drop(own);
        staged.commit().unwrap();
        assert_eq!(fs::read(&path).unwrap(), b"whole");
        let plain = dir.path().join("plain");
        File::create(&plain).unwrap();
        let mode = |p: &Path| fs::metadata(p).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode(&path), mode(&plain));
        fs::remove_file(&plain).unwrap();
        assert_eq!(names(), ["trace.blf"]);
        // A private file's replacement is private from its first byte, and stays so.
        fs::set_permissions(&path, fs::Permissions::from_mode(0o600)).unwrap();
        let staged = Staged::create(&path).unwrap();
        assert_eq!(mode(staged.temp_path()), 0o600);
        staged.commit().unwrap();
        assert_eq!(mode(&path), 0o600);
        assert_eq!(names(), ["trace.blf"]);

        // Existing targets that are not regular files: refused, nothing made beside them.
        let fifo = dir.path().join("fifo");
        nix::unistd::mkfifo(&fifo, nix::sys::stat::Mode::S_IRWXU).unwrap();
        let sub = dir.path().join("sub");
        fs::create_dir(&sub).unwrap();
        for (target, kind) in [(&fifo, "a FIFO"), (&sub, "a folder")] {
            let e = Staged::create(target).unwrap_err();
            assert_eq!(
                e.to_string(),
                format!(
                    "cannot write {}: it is {kind}, not a regular file; give the path of a file",
                    target.display()
                )
            );
        }
        let e = Staged::create(Path::new("/dev/null")).unwrap_err();
        assert!(e.to_string().contains("a device"), "{e}");
        assert_eq!(names(), ["fifo", "sub", "trace.blf"]);
        assert_eq!(fs::read_dir(&sub).unwrap().count(), 0);
    }

    #[test]
    fn concurrent_writers_never_mix_their_contents() {
        // The same file written by many threads at once: each write is whole.
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("image.toml");
        let contents: Vec<Vec<u8>> = (0..8u8).map(|i| vec![b'a' + i; 200_000]).collect();
        std::thread::scope(|s| {
            for c in &contents {
                let path = &path;
                s.spawn(move || {
                    for _ in 0..5 {
                        write_atomic(path, c).unwrap();
                    }
                });
            }
        });
        let read = fs::read(&path).unwrap();
        assert!(
            contents.contains(&read),
            "a mixed file of {} bytes",
            read.len()
        );
    }

    #[test]
    fn reads_refuse_fifos_devices_folders_and_large_files_naming_the_path() {
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("f.bin");
        fs::write(&file, [1, 2, 3]).unwrap();
        assert_eq!(read_limited(&file, 3).unwrap(), [1, 2, 3]);
        let err = read_limited(&file, 2).unwrap_err();
        assert!(matches!(err, ReadError::TooLarge { .. }), "{err}");
        assert!(err.to_string().contains("f.bin"), "{err}");

        let fifo = dir.path().join("fifo");
        nix::unistd::mkfifo(&fifo, nix::sys::stat::Mode::S_IRWXU).unwrap();
        let err = read_limited(&fifo, 100).unwrap_err();
        assert_eq!(
            err.to_string(),
            format!(
                "{} is a FIFO, not a regular file; give the path of a file",
                fifo.display()
            )
        );
        let err = read_limited(Path::new("/dev/zero"), 100).unwrap_err();
        assert!(err.to_string().contains("/dev/zero is a device"), "{err}");
        let err = read_limited(dir.path(), 100).unwrap_err();
        assert!(err.to_string().contains("is a folder"), "{err}");
        let err = read_limited(&dir.path().join("none"), 100).unwrap_err();
        assert!(err.is_not_found(), "{err}");
        fs::write(&file, [0xFF, 0xFE]).unwrap();
        assert!(matches!(
            read_text_limited(&file, 10),
            Err(ReadError::NotText { .. })
        ));
        // Opening never blocks either, for reading or writing.
        for write in [false, true] {
            let err = open_regular(&fifo, write).unwrap_err();
            assert_eq!(
                err.to_string(),
                format!("{} is a FIFO, not a regular file", fifo.display())
            );
        }
        let err = open_regular(Path::new("/dev/zero"), false).unwrap_err();
        assert!(err.to_string().contains("is a device"), "{err}");
        let new = dir.path().join("new.txt");
        open_regular(&new, true).unwrap().write_all(b"x").unwrap();
        let mut text = String::new();
        open_regular(&new, false)
            .unwrap()
            .read_to_string(&mut text)
            .unwrap();
        assert_eq!(text, "x");
    }
}
