//! Which log format a file is: from its extension, or named on the command line.

use std::fmt;
use std::path::{Path, PathBuf};
use std::str::FromStr;

/// A log format this crate reads and writes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Format {
    /// can-utils' candump log (`.log`).
    Candump,
    /// Vector ASC (`.asc`).
    Asc,
    /// Vector BLF (`.blf`).
    Blf,
    /// PEAK TRC version 1.1 (written on request; any version 1.0..2.1 is read).
    Trc11,
    /// PEAK TRC version 2.1 (`.trc`).
    Trc21,
    /// python-can's CSV (`.csv`).
    Csv,
    /// pcap with LINKTYPE_CAN_SOCKETCAN (`.pcap`).
    Pcap,
    /// pcapng with LINKTYPE_CAN_SOCKETCAN (`.pcapng`).
    Pcapng,
    /// python-can's SQLite database (`.db`).
    Sqlite,
}

/// A format that cannot be told.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum FormatError {
    #[error("{}: unknown log extension {ext:?}; known: {known} (or name the format with --from/--to)", path.display(), known = Format::EXTENSIONS)]
    UnknownExtension { path: PathBuf, ext: String },
    #[error("{}: no extension to tell the log format by; known: {known} (or name the format with --from/--to)", path.display(), known = Format::EXTENSIONS)]
    NoExtension { path: PathBuf },
    #[error("unknown log format {0:?}; known: {known}", known = Format::NAMES)]
    UnknownName(String),
}

impl Format {
    pub const ALL: [Format; 9] = [
        Format::Candump,
        Format::Asc,
        Format::Blf,
        Format::Trc11,
        Format::Trc21,
        Format::Csv,
        Format::Pcap,
        Format::Pcapng,
        Format::Sqlite,
    ];
    const EXTENSIONS: &'static str =
        ".log .asc .blf .trc .csv .pcap .pcapng .db .sqlite (read also with .gz after them)";
    const NAMES: &'static str =
        "candump (log), asc, blf, trc (= trc21), trc11, trc21, csv, pcap, pcapng, sqlite (db)";

    /// The format a file's extension names (case-insensitive): `.log` candump, `.asc`,
    /// `.blf`, `.trc` (TRC 2.1 when written), `.csv`, `.pcap`, `.pcapng`, `.db`/`.sqlite`.
    /// A `.gz` after one of them names the same format, gzip-compressed (as python-can
    /// writes `.asc.gz`): readers decompress it, writers refuse it.
    pub fn from_path(path: &Path) -> Result<Format, FormatError> {
        let no_extension = || FormatError::NoExtension {
            path: path.to_path_buf(),
        };
        let mut ext = path
            .extension()
            .ok_or_else(no_extension)?
            .to_string_lossy()
            .to_ascii_lowercase();
        if ext == "gz" {
            ext = Path::new(path.file_stem().ok_or_else(no_extension)?)
                .extension()
                .ok_or_else(no_extension)?
                .to_string_lossy()
                .to_ascii_lowercase();
        }
        Ok(match ext.as_str() {
            "log" => Format::Candump,
            "asc" => Format::Asc,
            "blf" => Format::Blf,
            "trc" => Format::Trc21,
            "csv" => Format::Csv,
            "pcap" | "cap" => Format::Pcap,
            "pcapng" => Format::Pcapng,
            "db" | "sqlite" | "sqlite3" => Format::Sqlite,
            _ => {
                return Err(FormatError::UnknownExtension {
                    path: path.to_path_buf(),
                    ext,
                });
            }
        })
    }

    /// The name `--from`/`--to` take.
    pub const fn name(self) -> &'static str {
        match self {
            Format::Candump => "candump",
            Format::Asc => "asc",
            Format::Blf => "blf",
            Format::Trc11 => "trc11",
            Format::Trc21 => "trc21",
            Format::Csv => "csv",
            Format::Pcap => "pcap",
            Format::Pcapng => "pcapng",
            Format::Sqlite => "sqlite",
        }
    }

    /// The usual extension (without the dot).
    pub const fn extension(self) -> &'static str {
        match self {
            Format::Candump => "log",
            Format::Asc => "asc",
            Format::Blf => "blf",
            Format::Trc11 | Format::Trc21 => "trc",
            Format::Csv => "csv",
            Format::Pcap => "pcap",
            Format::Pcapng => "pcapng",
            Format::Sqlite => "db",
        }
    }

    /// A text format (one entry per line).
    pub const fn is_text(self) -> bool {
        matches!(
            self,
            Format::Candump | Format::Asc | Format::Trc11 | Format::Trc21 | Format::Csv
        )
    }
}

impl fmt::Display for Format {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Format {
    type Err = FormatError;

    fn from_str(text: &str) -> Result<Self, Self::Err> {
        Ok(match text.trim().to_ascii_lowercase().as_str() {
            "candump" | "log" => Format::Candump,
            "asc" => Format::Asc,
            "blf" => Format::Blf,
            "trc11" | "trc1.1" => Format::Trc11,
            "trc" | "trc21" | "trc2.1" => Format::Trc21,
            "csv" => Format::Csv,
            "pcap" => Format::Pcap,
            "pcapng" => Format::Pcapng,
            "sqlite" | "db" => Format::Sqlite,
            _ => return Err(FormatError::UnknownName(text.to_string())),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn extensions_and_names() {
        for f in Format::ALL {
            assert_eq!(f.name().parse::<Format>(), Ok(f));
        }
        assert_eq!(Format::from_path(Path::new("a/b.LOG")), Ok(Format::Candump));
        assert_eq!(Format::from_path(Path::new("x.trc")), Ok(Format::Trc21));
        assert_eq!(Format::from_path(Path::new("x.db")), Ok(Format::Sqlite));
        assert_eq!(Format::from_path(Path::new("x.ASC.gz")), Ok(Format::Asc));
        assert!(matches!(
            Format::from_path(Path::new("x.gz")),
            Err(FormatError::NoExtension { .. })
        ));
        assert!(matches!(
            Format::from_path(Path::new("x.tar.gz")),
            Err(FormatError::UnknownExtension { ext, .. }) if ext == "tar"
        ));
        let err = Format::from_path(Path::new("x.mf4"))
            .unwrap_err()
            .to_string();
        assert!(err.contains("\"mf4\"") && err.contains(".blf"), "{err}");
        let err = Format::from_path(Path::new("noext"))
            .unwrap_err()
            .to_string();
        assert!(err.contains("noext") && err.contains("--from"), "{err}");
        let err = "mdf".parse::<Format>().unwrap_err().to_string();
        assert!(err.contains("\"mdf\"") && err.contains("pcapng"), "{err}");
    }
}
