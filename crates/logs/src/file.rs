//! Log files by format: open a reader, create a writer. Inputs are regular files only (a FIFO
//! or a device would block or never end); reading is streamed through a fixed buffer.

use std::fs::{self, File};
use std::io::{self, BufReader, BufWriter, Read, Seek, SeekFrom, Write};
use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use buslab_fs::Staged;
use flate2::read::MultiGzDecoder;

use crate::codec::{ByteCounter, Encoder, Entries, LogReader, LogWriter, READ_BUFFER};
use crate::error::{LogError, ReadError};
use crate::follow::{Following, OnWait, Watch};
use crate::format::Format;
use crate::input::{Counted, Named, check_regular, is_gzip, open_regular, reader};
#[cfg(feature = "sqlite")]
use crate::sqlite;
use crate::{Message, asc, blf, candump, csv, pcap, pcapng, trc};

/// The write buffer of a log file.
const WRITE_BUFFER: usize = 256 * 1024;

/// An opened log: its reader, the bytes read so far, the file's size when opened.
pub struct LogSource {
    pub reader: Box<dyn LogReader + Send>,
    pub bytes_read: ByteCounter,
    pub len: u64,
}

/// How to open a log.
#[derive(Clone, Default)]
pub struct OpenOptions {
    /// Follow a growing file (like `tail -F`): at its end, wait for more until this flag is
    /// set, then end; when the file is truncated, rewritten or replaced (rotated), warn and
    /// read its new content from the start. Not for SQLite.
    pub follow_until: Option<Arc<AtomicBool>>,
    /// While following: called once each time the reader catches up with the file's end.
    pub on_wait: Option<OnWait>,
}

/// Opens a log file for reading as `format`; errors name the file and, when reading, the line
/// or byte offset.
pub fn open_reader(
    path: &Path,
    format: Format,
) -> Result<Box<dyn Iterator<Item = Result<Message, ReadError>> + Send>, LogError> {
    let source = open_source(path, format, &OpenOptions::default())?;
    Ok(Box::new(Entries::new(source.reader)))
}

/// Opens a log file for reading as `format`, with a byte counter for progress. A
/// gzip-compressed file (python-can's `.asc.gz`) is decompressed as it is read; the counter
/// counts its compressed bytes.
pub fn open_source(
    path: &Path,
    format: Format,
    options: &OpenOptions,
) -> Result<LogSource, LogError> {
    require_built(path, format)?;
    let mut file = open_regular(path)?;
    let len = file.metadata().map(|m| m.len()).unwrap_or(0);
    let bytes_read = ByteCounter::default();
    let gzip = is_gzip(&mut file).map_err(|source| LogError::Open {
        path: path.to_path_buf(),
        source,
    })?;
    #[cfg(feature = "sqlite")]
    if format == Format::Sqlite {
        if gzip {
            return Err(LogError::Gzip {
                path: path.to_path_buf(),
                what: "an SQLite database is read uncompressed (gunzip it first)",
            });
        }
        if options.follow_until.is_some() {
            return Err(LogError::CannotFollow {
                path: path.to_path_buf(),
                format: "an SQLite database",
            });
        }
        drop(file);
        let reader = sqlite::Reader::open(path).map_err(|e| LogError::Read {
            source: e.in_file(path),
        })?;
        bytes_read.set(len);
        return Ok(LogSource {
            reader: Box::new(Named::new(reader, path)),
            bytes_read,
            len,
        });
    }
    if let Some(stop) = &options.follow_until {
        if gzip {
            return Err(LogError::Gzip {
                path: path.to_path_buf(),
                what: "a compressed log cannot be followed (gunzip it, or convert it without --follow)",
            });
        }
        drop(file);
        let watch = Watch {
            stop: stop.clone(),
            on_wait: options.on_wait.clone(),
            count: bytes_read.clone(),
        };
        let reader = Following::open(path, format, watch)?;
        return Ok(LogSource {
            reader: Box::new(Named::new(reader, path)),
            bytes_read,
            len,
        });
    }
    let counted = Counted {
        inner: file,
        count: bytes_read.clone(),
    };
    let input: Box<dyn Read + Send> = if gzip {
        Box::new(MultiGzDecoder::new(counted))
    } else {
        Box::new(counted)
    };
    let input = BufReader::with_capacity(READ_BUFFER, input);
    let reader = reader(input, format).map_err(|e| LogError::Read {
        source: e.in_file(path),
    })?;
    Ok(LogSource {
        reader: Box::new(Named::new(reader, path)),
        bytes_read,
        len,
    })
}

/// Where a writer's file goes.
enum Output {
    /// Straight to its path (a live log: what was flushed is there if the process dies).
    Direct,
    /// To a temporary file beside it, put in place by `finish` (the one atomic writer,
    /// `buslab-fs`).
    Atomic(Staged),
}

#[cfg(feature = "sqlite")]
impl Output {
    /// The file being written: `path` itself, or the temporary file beside it.
    fn written<'a>(&'a self, path: &'a Path) -> &'a Path {
        match self {
            Output::Direct => path,
            Output::Atomic(staged) => staged.temp_path(),
        }
    }
}

/// Creates (or truncates) a log file written as `format`, straight to `path`: what was
/// flushed is in the file even if the process is killed (the choice for live logging).
pub fn create_writer(path: &Path, format: Format) -> Result<Box<dyn LogWriter + Send>, LogError> {
    create(path, format, false, WriteOptions::default())
}

/// Choices a format leaves to the writer.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct WriteOptions {
    /// candump: ` R`/` T` after each frame that has a direction (candump `-x`); the other
    /// formats record the direction wherever they have a field for it.
    pub direction: bool,
}

/// [`create_writer`] with options.
pub fn create_writer_with(
    path: &Path,
    format: Format,
    options: WriteOptions,
) -> Result<Box<dyn LogWriter + Send>, LogError> {
    create(path, format, false, options)
}

/// Creates a log file written as `format` into a temporary file in the same directory, put in
/// place (fsync, rename, fsync of the directory) by [`LogWriter::finish`]; dropped without
/// `finish`, nothing replaces `path` (the choice for conversions).
pub fn create_writer_atomic(
    path: &Path,
    format: Format,
) -> Result<Box<dyn LogWriter + Send>, LogError> {
    create(path, format, true, WriteOptions::default())
}

fn create(
    path: &Path,
    format: Format,
    atomic: bool,
    options: WriteOptions,
) -> Result<Box<dyn LogWriter + Send>, LogError> {
    require_built(path, format)?;
    let create_err = |source| LogError::Create {
        path: path.to_path_buf(),
        source,
    };
    if path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("gz"))
    {
        return Err(LogError::Gzip {
            path: path.to_path_buf(),
            what: "buslab writes logs uncompressed (leave out .gz, compress the finished file)",
        });
    }
    if let Ok(meta) = fs::metadata(path) {
        check_regular(path, &meta)?;
    }
    let (file, output) = if atomic {
        let staged = Staged::create(path).map_err(|e| create_err(e.source))?;
        // The writer's own handle: it seeks and cuts back; the staged file commits.
        let file = staged.file().try_clone().map_err(create_err)?;
        (file, Output::Atomic(staged))
    } else {
        if format == Format::Sqlite {
            // A new database: an old file's table would be appended to otherwise.
            match fs::remove_file(path) {
                Ok(()) => {}
                Err(e) if e.kind() == io::ErrorKind::NotFound => {}
                Err(e) => return Err(create_err(e)),
            }
        }
        (File::create(path).map_err(create_err)?, Output::Direct)
    };
    #[cfg(feature = "sqlite")]
    if format == Format::Sqlite {
        drop(file);
        let writer =
            sqlite::Writer::create(output.written(path)).map_err(|source| LogError::Sqlite {
                path: path.to_path_buf(),
                source,
            })?;
        return Ok(Box::new(SqliteFile { writer, output }));
    }
    let out = BufWriter::with_capacity(WRITE_BUFFER, CutBack::new(file));
    let mut writer = match format {
        Format::Candump => FileWriter::boxed(
            candump::Writer::new(out).with_direction(options.direction),
            output,
        ),
        Format::Asc => FileWriter::boxed(asc::Writer::new(out), output),
        Format::Blf => FileWriter::boxed(blf::Writer::new(out).map_err(create_err)?, output),
        Format::Trc11 => FileWriter::boxed(trc::Writer::new(out, trc::Version::V1_1), output),
        Format::Trc21 => FileWriter::boxed(trc::Writer::new(out, trc::Version::V2_1), output),
        Format::Csv => FileWriter::boxed(csv::Writer::new(out), output),
        Format::Pcap => FileWriter::boxed(pcap::Writer::new(out).map_err(create_err)?, output),
        Format::Pcapng => FileWriter::boxed(pcapng::Writer::new(out).map_err(create_err)?, output),
        Format::Sqlite => unreachable!("created above"),
    };
    // The headers a format writes before any entry (BLF, pcap, pcapng) are in the file at
    // once: a log killed before its first entry is still a valid, empty log.
    writer.flush().map_err(create_err)?;
    Ok(writer)
}

/// The file under a writer's buffer. After a failed write (a full disk, `EFBIG` past a
/// file-size limit, an I/O error) it cuts the file back to the length the last successful
/// flush left, so no half record follows what was flushed, and refuses every later write
/// (the buffer's leftovers included).
struct CutBack {
    file: File,
    /// Where the next write goes, and the end of what was written.
    pos: u64,
    end: u64,
    /// The file's length at the last successful flush.
    flushed: u64,
    failed: bool,
}

impl CutBack {
    fn new(file: File) -> Self {
        Self {
            file,
            pos: 0,
            end: 0,
            flushed: 0,
            failed: false,
        }
    }

    fn refused() -> io::Error {
        io::Error::other("the log was cut back to its last flush after a write error")
    }

    fn fail(&mut self) {
        self.failed = true;
        if let Err(e) = self.file.set_len(self.flushed) {
            tracing::warn!("cannot cut the log back to its last flush: {e}");
        }
    }
}

impl Write for CutBack {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        if self.failed {
            return Err(Self::refused());
        }
        match self.file.write(buf) {
            Ok(n) => {
                self.pos += n as u64;
                self.end = self.end.max(self.pos);
                Ok(n)
            }
            Err(e) if e.kind() == io::ErrorKind::Interrupted => Err(e),
            Err(e) => {
                self.fail();
                Err(e)
            }
        }
    }

    fn flush(&mut self) -> io::Result<()> {
        if self.failed {
            return Err(Self::refused());
        }
        self.flushed = self.end;
        Ok(())
    }
}

impl Seek for CutBack {
    fn seek(&mut self, to: SeekFrom) -> io::Result<u64> {
        if self.failed {
            return Err(Self::refused());
        }
        self.pos = self.file.seek(to)?;
        Ok(self.pos)
    }
}

type Out = BufWriter<CutBack>;

/// A format's encoder writing a file.
struct FileWriter<E> {
    encoder: E,
    output: Output,
}

impl<E: Encoder<Out> + 'static> FileWriter<E> {
    fn boxed(encoder: E, output: Output) -> Box<dyn LogWriter + Send> {
        Box::new(Self { encoder, output })
    }
}

impl<E: Encoder<Out>> LogWriter for FileWriter<E> {
    fn write(&mut self, entry: &Message) -> io::Result<()> {
        self.encoder.write(entry)
    }

    fn flush(&mut self) -> io::Result<()> {
        self.encoder.flush()
    }

    fn finish(self: Box<Self>) -> io::Result<()> {
        let this = *self;
        let out = this.encoder.finish()?;
        let file = match out.into_inner() {
            Ok(inner) => inner.file,
            Err(e) => {
                // What the last flush left is kept: synced, never written over.
                let (inner, _) = e.into_inner().into_parts();
                inner.file.sync_all()?;
                return Err(CutBack::refused());
            }
        };
        match this.output {
            Output::Direct => file.sync_all(),
            Output::Atomic(staged) => {
                drop(file);
                put_in_place(staged)
            }
        }
    }

    fn left_out(&self) -> u64 {
        self.encoder.left_out()
    }
}

/// Refuses a format this build was made without, before its file is touched.
fn require_built(path: &Path, format: Format) -> Result<(), LogError> {
    if format == Format::Sqlite && !cfg!(feature = "sqlite") {
        return Err(LogError::NotBuilt {
            path: path.to_path_buf(),
            what: "SQLite logs",
            feature: "sqlite",
        });
    }
    Ok(())
}

/// The SQLite writer on its file.
#[cfg(feature = "sqlite")]
struct SqliteFile {
    writer: sqlite::Writer,
    output: Output,
}

#[cfg(feature = "sqlite")]
impl LogWriter for SqliteFile {
    fn write(&mut self, entry: &Message) -> io::Result<()> {
        self.writer.write(entry)
    }

    fn flush(&mut self) -> io::Result<()> {
        self.writer.commit()
    }

    fn finish(self: Box<Self>) -> io::Result<()> {
        let this = *self;
        this.writer.finish()?;
        match this.output {
            // SQLite synced its own file.
            Output::Direct => Ok(()),
            Output::Atomic(staged) => put_in_place(staged),
        }
    }
}

/// Syncs an atomic writer's temporary file, renames it over its destination and syncs the
/// folder.
fn put_in_place(staged: Staged) -> io::Result<()> {
    staged.commit().map_err(|e| e.source)
}

#[cfg(all(test, not(feature = "sqlite")))]
mod without_sqlite {
    use super::*;

    /// A build without SQLite refuses a `.db` log by name and feature, and leaves a file
    /// already there as it was (a writer would have truncated it).
    #[test]
    fn an_sqlite_log_is_refused_naming_the_feature_and_the_file_is_untouched() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("trace.db");
        fs::write(&path, b"an older database").unwrap();
        let created = create_writer(&path, Format::Sqlite).err().expect("refused");
        let opened = open_source(&path, Format::Sqlite, &OpenOptions::default())
            .err()
            .expect("refused");
        for error in [created, opened] {
            assert!(matches!(
                error,
                LogError::NotBuilt {
                    feature: "sqlite",
                    ..
                }
            ));
            assert_eq!(
                error.to_string(),
                format!(
                    "{}: SQLite logs are not in this build (it was made without the `sqlite` feature)",
                    path.display()
                )
            );
        }
        assert_eq!(fs::read(&path).unwrap(), b"an older database");
        assert_eq!(
            fs::read_dir(dir.path()).unwrap().count(),
            1,
            "no temporary file left"
        );
    }
}
