//! Opening inputs: the reader for a format over any bytes, regular files only, gzip told by
//! its magic number, the bytes read counted, errors named after their file.

use std::fs::{self, File};
use std::io::{self, BufRead, Read, Seek};
use std::path::{Path, PathBuf};

use crate::codec::{ByteCounter, LogReader, read_full};
use crate::error::{LogError, ReadError};
use crate::format::Format;
use crate::{LogBitRate, Message, asc, blf, candump, csv, pcap, pcapng, trc};

/// The reader for `format` over any buffered input (a file, bytes in memory, a fuzzer's
/// input). The pcap formats tell pcap from pcapng by the first bytes, so either name reads
/// both. SQLite is read from a file only ([`open_source`](crate::open_source)).
pub fn reader<R: BufRead + Send + 'static>(
    mut input: R,
    format: Format,
) -> Result<Box<dyn LogReader + Send>, ReadError> {
    Ok(match format {
        Format::Candump => Box::new(candump::Reader::new(input)),
        Format::Asc => Box::new(asc::Reader::new(input)),
        Format::Blf => Box::new(blf::Reader::new(input)),
        Format::Trc11 | Format::Trc21 => Box::new(trc::Reader::new(input)),
        Format::Csv => Box::new(csv::Reader::new(input)),
        Format::Pcap | Format::Pcapng => {
            let head = input.fill_buf().map_err(ReadError::io)?;
            if head.starts_with(&pcapng::BLOCK_SHB.to_le_bytes()) {
                Box::new(pcapng::Reader::new(input))
            } else {
                Box::new(pcap::Reader::new(input))
            }
        }
        Format::Sqlite => {
            return Err(ReadError::fatal(
                None,
                crate::Problem::NotFormat {
                    format: "stream",
                    reason: "an SQLite database is read from a file".into(),
                },
            ));
        }
    })
}

/// A reader whose errors name its file.
pub(crate) struct Named<R> {
    inner: R,
    path: PathBuf,
}

impl<R> Named<R> {
    pub(crate) fn new(inner: R, path: &Path) -> Self {
        Self {
            inner,
            path: path.to_path_buf(),
        }
    }
}

impl<R: LogReader> LogReader for Named<R> {
    fn read_into(&mut self, entry: &mut Message) -> Result<bool, ReadError> {
        self.inner
            .read_into(entry)
            .map_err(|e| e.in_file(&self.path))
    }
    fn bit_rate(&self, channel: &str) -> Option<LogBitRate> {
        self.inner.bit_rate(channel)
    }
}

/// Counts the bytes read.
pub(crate) struct Counted<R> {
    pub(crate) inner: R,
    pub(crate) count: ByteCounter,
}

impl<R: Read> Read for Counted<R> {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        let n = self.inner.read(buf)?;
        self.count.add(n as u64);
        Ok(n)
    }
}

/// Whether the file starts with gzip's magic number (it is read from its start afterwards).
pub(crate) fn is_gzip(file: &mut File) -> io::Result<bool> {
    let mut magic = [0u8; 2];
    let got = read_full(file, &mut magic)?;
    file.rewind()?;
    Ok(got == 2 && magic == [0x1F, 0x8B])
}

/// Opens `path` for reading if it is a regular file.
pub(crate) fn open_regular(path: &Path) -> Result<File, LogError> {
    let meta = fs::metadata(path).map_err(|source| LogError::Open {
        path: path.to_path_buf(),
        source,
    })?;
    check_regular(path, &meta)?;
    File::open(path).map_err(|source| LogError::Open {
        path: path.to_path_buf(),
        source,
    })
}

pub(crate) fn check_regular(path: &Path, meta: &fs::Metadata) -> Result<(), LogError> {
    use std::os::unix::fs::FileTypeExt;
    let t = meta.file_type();
    let what = if t.is_file() {
        return Ok(());
    } else if t.is_dir() {
        "a directory"
    } else if t.is_fifo() {
        "a FIFO"
    } else if t.is_char_device() {
        "a character device"
    } else if t.is_block_device() {
        "a block device"
    } else if t.is_socket() {
        "a socket"
    } else {
        "something else"
    };
    Err(LogError::NotRegular {
        path: path.to_path_buf(),
        what,
    })
}
