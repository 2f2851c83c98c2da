//! can-utils' candump formats.
//!
//! The **log line** (candump `-l`/`-L`, read by canplayer, log2asc and python-can):
//!
//! ```text
//! (1700000000.123456) vcan0 123#1122334455667788
//! (1700000000.200000) can0 7FF#R
//! (1700000000.400000) can0 20000088#0000000000000000     <- an error frame
//! (1700000000.500000) can0 123#112233 T                  <- with candump -x: R or T
//! ```
//!
//! [`parse_line`] reads one (never panics, whatever the text), [`format_line`] writes one;
//! [`Reader`] and [`Writer`] stream them. The **terminal layout** (candump without `-L`) is
//! [`Terminal`], with candump's views: `-t a|d|z` timestamps, `-a` ASCII, `-x` direction,
//! `-e` error frames in words.

use std::fmt::Write as _;
use std::io::{self, BufRead, Write};
use std::time::Duration;

use buslab_can::Frame;
use buslab_canbus::ErrorFrame;
use buslab_canbus::error_frame::ERROR_FLAG;

use crate::{Direction, Entry, Record};

/// The longest line [`Reader`] takes (a classic CAN line is under 80 characters).
pub const MAX_LINE: usize = 4096;

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

/// Reads one log line: `(SEC.FRACTION) IFACE FRAME [R|T]`. Runs of spaces separate the
/// fields (candump right-aligns interface names to the longest one).
pub fn parse_line(line: &str) -> Result<Entry, LineError> {
    let mut fields = line.split_ascii_whitespace();
    let stamp = fields.next().ok_or(LineError::Empty)?;
    let timestamp = parse_timestamp(stamp)?;
    let interface = fields.next().ok_or(LineError::NoInterface)?;
    let frame = fields
        .next()
        .ok_or_else(|| LineError::NoFrame(interface.to_string()))?;
    let direction = match fields.next() {
        None => None,
        Some("R") => Some(Direction::Rx),
        Some("T") => Some(Direction::Tx),
        Some(other) => return Err(LineError::Trailing(excerpt(other))),
    };
    if let Some(more) = fields.next() {
        return Err(LineError::Trailing(excerpt(more)));
    }
    Ok(Entry {
        timestamp,
        interface: interface.to_string(),
        record: parse_record(frame)?,
        direction,
    })
}

/// `(1700000000.123456)`: seconds and 1..9 decimals (candump writes 6, with `-N` 9).
fn parse_timestamp(text: &str) -> Result<Duration, LineError> {
    let bad = || LineError::Timestamp(excerpt(text));
    let inner = text
        .strip_prefix('(')
        .and_then(|t| t.strip_suffix(')'))
        .ok_or_else(bad)?;
    let (secs, fraction) = inner.split_once('.').ok_or_else(bad)?;
    let digits = |t: &str| !t.is_empty() && t.bytes().all(|b| b.is_ascii_digit());
    if !digits(secs) || !digits(fraction) || fraction.len() > 9 || secs.len() > 20 {
        return Err(bad());
    }
    let secs: u64 = secs.parse().map_err(|_| bad())?;
    let nanos: u32 = format!("{fraction:0<9}").parse().map_err(|_| bad())?;
    Ok(Duration::new(secs, nanos))
}

/// A frame in can-utils syntax, or an error frame (`20000088#…`: 8 digits with the error flag).
fn parse_record(text: &str) -> Result<Record, LineError> {
    if let Some((id, data)) = text.split_once('#')
        && id.len() == 8
        && let Ok(raw) = u32::from_str_radix(id, 16)
        && raw & ERROR_FLAG != 0
    {
        let bad = |reason: String| LineError::ErrorFrame {
            text: excerpt(text),
            reason,
        };
        let hex: Vec<u8> = data.bytes().filter(|&b| b != b'.').collect();
        if !hex.len().is_multiple_of(2) || !hex.iter().all(u8::is_ascii_hexdigit) {
            return Err(bad(format!("data {data:?} must be pairs of hex digits")));
        }
        let bytes: Vec<u8> = hex
            .chunks(2)
            .map(|pair| (hex_value(pair[0]) << 4) | hex_value(pair[1]))
            .collect();
        return ErrorFrame::decode(raw, &bytes)
            .map(Record::Error)
            .map_err(|e| bad(e.to_string()));
    }
    Ok(Record::Frame(text.parse::<Frame>()?))
}

fn hex_value(digit: u8) -> u8 {
    match digit {
        b'0'..=b'9' => digit - b'0',
        b'a'..=b'f' => digit - b'a' + 10,
        _ => digit.wrapping_sub(b'A').wrapping_add(10),
    }
}

/// The start of a bad field, for a message (never the whole flood).
fn excerpt(text: &str) -> String {
    const KEEP: usize = 40;
    if text.chars().count() > KEEP {
        format!("{}…", text.chars().take(KEEP).collect::<String>())
    } else {
        text.to_string()
    }
}

/// `(%010u.%06u)`: candump's log timestamp (microseconds, truncated as candump does).
fn log_timestamp(out: &mut String, t: Duration) {
    let _ = write!(out, "({:010}.{:06})", t.as_secs(), t.subsec_micros());
}

/// The frame in can-utils syntax; an error frame as `20000088#` and its 8 data bytes.
fn record_text(out: &mut String, record: &Record) {
    match record {
        Record::Frame(f) => {
            let _ = write!(out, "{f}");
        }
        Record::Error(e) => {
            let (class, data) = e.encode();
            let _ = write!(out, "{:08X}#", ERROR_FLAG | class);
            for b in data {
                let _ = write!(out, "{b:02X}");
            }
        }
    }
}

/// One log line without the newline; the direction (` R`/` T`) only if `direction` is set
/// and the entry has one (candump `-x`).
pub fn format_line(entry: &Entry, direction: bool) -> String {
    let mut out = String::with_capacity(64);
    log_timestamp(&mut out, entry.timestamp);
    out.push(' ');
    out.push_str(&entry.interface);
    out.push(' ');
    record_text(&mut out, &entry.record);
    if direction {
        match entry.direction {
            Some(Direction::Rx) => out.push_str(" R"),
            Some(Direction::Tx) => out.push_str(" T"),
            None => {}
        }
    }
    out
}

/// Why [`Reader`] stopped at a line.
#[derive(Debug, thiserror::Error)]
pub enum ReadError {
    #[error("line {line}: {error}")]
    Line { line: u64, error: LineError },
    #[error("{0}")]
    Io(#[from] io::Error),
}

/// Reads a candump log line by line. Like canplayer it skips lines that do not start with
/// `(` (blank lines, `DROPCOUNT: …` notes) and counts them; a bad line is an error naming
/// its number, after which reading goes on with the next line.
pub struct Reader<R> {
    input: R,
    line: u64,
    skipped: u64,
    buf: Vec<u8>,
}

impl<R: BufRead> Reader<R> {
    pub fn new(input: R) -> Self {
        Self {
            input,
            line: 0,
            skipped: 0,
            buf: Vec::new(),
        }
    }

    /// Lines skipped so far because they do not start with `(`.
    pub fn skipped(&self) -> u64 {
        self.skipped
    }

    /// The next line's bytes (without the newline), `Ok(None)` at the end, or
    /// `Err(TooLong)` for a line beyond [`MAX_LINE`] (the rest of it is skipped).
    fn next_raw(&mut self) -> io::Result<Option<Result<(), LineError>>> {
        self.buf.clear();
        let mut too_long = false;
        loop {
            let chunk = self.input.fill_buf()?;
            if chunk.is_empty() {
                return Ok(if self.buf.is_empty() && !too_long {
                    None
                } else if too_long {
                    Some(Err(LineError::TooLong))
                } else {
                    Some(Ok(()))
                });
            }
            let (part, done) = match chunk.iter().position(|&b| b == b'\n') {
                Some(i) => (&chunk[..i], Some(i + 1)),
                None => (chunk, None),
            };
            if !too_long {
                if self.buf.len() + part.len() > MAX_LINE {
                    too_long = true;
                    self.buf.clear();
                } else {
                    self.buf.extend_from_slice(part);
                }
            }
            let used = done.unwrap_or(chunk.len());
            self.input.consume(used);
            if done.is_some() {
                return Ok(Some(if too_long {
                    Err(LineError::TooLong)
                } else {
                    Ok(())
                }));
            }
        }
    }
}

impl<R: BufRead> Iterator for Reader<R> {
    type Item = Result<Entry, ReadError>;

    fn next(&mut self) -> Option<Self::Item> {
        loop {
            let raw = match self.next_raw() {
                Ok(None) => return None,
                Ok(Some(raw)) => raw,
                Err(e) => return Some(Err(e.into())),
            };
            self.line += 1;
            let line = self.line;
            let error = |error| Some(Err(ReadError::Line { line, error }));
            if let Err(e) = raw {
                return error(e);
            }
            let Ok(text) = std::str::from_utf8(&self.buf) else {
                return error(LineError::NotText);
            };
            let text = text.trim_end_matches('\r');
            if !text.trim_start().starts_with('(') {
                self.skipped += 1;
                continue;
            }
            return Some(parse_line(text).map_err(|error| ReadError::Line { line, error }));
        }
    }
}

/// Writes candump log lines.
pub struct Writer<W> {
    out: W,
    direction: bool,
}

impl<W: Write> Writer<W> {
    pub fn new(out: W) -> Self {
        Self {
            out,
            direction: false,
        }
    }

    /// Also write ` R`/` T` after each frame (candump `-x`).
    pub fn with_direction(mut self, on: bool) -> Self {
        self.direction = on;
        self
    }

    pub fn write(&mut self, entry: &Entry) -> io::Result<()> {
        let mut line = format_line(entry, self.direction);
        line.push('\n');
        self.out.write_all(line.as_bytes())
    }

    pub fn flush(&mut self) -> io::Result<()> {
        self.out.flush()
    }

    pub fn into_inner(self) -> W {
        self.out
    }
}

/// candump's `-t` modes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum TimestampMode {
    /// `-t a`: the absolute time, `(1700000000.123456)`.
    Absolute,
    /// `-t d`: the time since the previous line, `(000.000512)`.
    Delta,
    /// `-t z`: the time since the first line, `(002.500000)`.
    Zero,
}

/// What candump's terminal lines show besides the frame.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct View {
    pub timestamps: Option<TimestampMode>,
    /// `-a`: the data as ASCII after the bytes (`'.."3'`).
    pub ascii: bool,
    /// `-x`: `RX - -` / `TX - -` after the interface.
    pub extra: bool,
    /// `-e`: an error frame's classes and details in words, one per line after a tab.
    pub error_words: bool,
}

/// candump's terminal layout: `  vcan0  123   [3]  11 22 33`. Once an extended ID was shown,
/// standard IDs are indented to eight columns, as candump does.
#[derive(Clone, Debug, Default)]
pub struct Terminal {
    view: View,
    extended_seen: bool,
    first: Option<Duration>,
    last: Option<Duration>,
}

impl Terminal {
    pub fn new(view: View) -> Self {
        Self {
            view,
            ..Self::default()
        }
    }

    /// The time `-t z` counts from (by default the first line's).
    pub fn with_zero(mut self, zero: Duration) -> Self {
        self.first = Some(zero);
        self
    }

    /// One entry's text without the final newline (with `-e` an error frame takes several
    /// lines).
    pub fn line(&mut self, entry: &Entry) -> String {
        let mut out = String::with_capacity(80);
        out.push(' ');
        if let Some(mode) = self.view.timestamps {
            self.timestamp(&mut out, mode, entry.timestamp);
        }
        out.push(' ');
        out.push_str(&entry.interface);
        if self.view.extra {
            out.push_str(match entry.direction {
                Some(Direction::Tx) => "  TX - -",
                _ => "  RX - -",
            });
        }
        out.push_str("  ");
        match &entry.record {
            Record::Frame(frame) => self.frame(&mut out, frame),
            Record::Error(e) => {
                let (class, data) = e.encode();
                let _ = write!(out, "{:08X}   [8] ", ERROR_FLAG | class);
                for b in data {
                    let _ = write!(out, " {b:02X}");
                }
                out.push_str("   ERRORFRAME");
                if self.view.error_words {
                    out.push_str("\n\t");
                    out.push_str(&e.describe("\n\t"));
                }
            }
        }
        out
    }

    fn timestamp(&mut self, out: &mut String, mode: TimestampMode, t: Duration) {
        let shown = match mode {
            TimestampMode::Absolute => {
                let _ = write!(out, "({:010}.{:06}) ", t.as_secs(), t.subsec_micros());
                return;
            }
            TimestampMode::Delta => {
                let since = t.saturating_sub(self.last.unwrap_or(t));
                self.last = Some(t);
                since
            }
            TimestampMode::Zero => t.saturating_sub(*self.first.get_or_insert(t)),
        };
        let _ = write!(
            out,
            "({:03}.{:06}) ",
            shown.as_secs(),
            shown.subsec_micros()
        );
    }

    fn frame(&mut self, out: &mut String, frame: &Frame) {
        self.extended_seen |= frame.is_extended();
        let id = frame.id().to_string();
        if self.extended_seen && !frame.is_extended() {
            let _ = write!(out, "{id:>8}");
        } else {
            out.push_str(&id);
        }
        let _ = write!(out, "   [{}] ", frame.dlc());
        if frame.is_remote() {
            out.push_str(" remote request");
            return;
        }
        for b in frame.payload() {
            let _ = write!(out, " {b:02X}");
        }
        if self.view.ascii {
            // At a fixed column after the bytes, as candump puts it.
            let width = 3 * (8 - frame.payload().len()) + 4;
            let _ = write!(out, "{:>width$}", "'");
            for &b in frame.payload() {
                out.push(if (0x20..0x7F).contains(&b) {
                    b as char
                } else {
                    '.'
                });
            }
            out.push('\'');
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::seconds;

    fn entry(frame: &str, t: f64) -> Entry {
        Entry {
            timestamp: seconds(t),
            interface: "vcan0".into(),
            record: Record::Frame(frame.parse().unwrap()),
            direction: None,
        }
    }

    fn show(view: View, frames: &[&str], t: f64) -> String {
        let mut term = Terminal::new(view);
        frames
            .iter()
            .map(|f| term.line(&entry(f, t)) + "\n")
            .collect()
    }

    #[test]
    fn terminal_layout_is_candumps() {
        assert_eq!(
            show(
                View::default(),
                &["123#112233", "07F#R", "12345678#DEADBEEF", "080#"],
                0.0
            ),
            "  vcan0  123   [3]  11 22 33\n\
             \x20 vcan0  07F   [0]  remote request\n\
             \x20 vcan0  12345678   [4]  DE AD BE EF\n\
             \x20 vcan0       080   [0] \n"
        );
    }

    #[test]
    fn timestamps_like_candump_t() {
        let absolute = View {
            timestamps: Some(TimestampMode::Absolute),
            ..View::default()
        };
        assert_eq!(
            show(absolute, &["123#11"], 1_795_251_323.218_691),
            " (1795251323.218691)  vcan0  123   [1]  11\n"
        );
        // candump -t a pads the seconds to 10 digits, whatever the clock.
        assert_eq!(
            show(absolute, &["123#11"], 1.2345678),
            " (0000000001.234568)  vcan0  123   [1]  11\n"
        );
        for (mode, want) in [
            (
                TimestampMode::Delta,
                ["(000.000000)", "(000.250000)", "(001.000000)"],
            ),
            (
                TimestampMode::Zero,
                ["(000.000000)", "(000.250000)", "(001.250000)"],
            ),
        ] {
            let mut term = Terminal::new(View {
                timestamps: Some(mode),
                ..View::default()
            });
            let got: Vec<String> = [10.0, 10.25, 11.25]
                .iter()
                .map(|&t| term.line(&entry("123#", t))[1..13].to_string())
                .collect();
            assert_eq!(got, want, "{mode:?}");
        }
        let mut since_start = Terminal::new(View {
            timestamps: Some(TimestampMode::Zero),
            ..View::default()
        })
        .with_zero(seconds(9.5));
        assert_eq!(
            since_start.line(&entry("123#", 10.0))[1..13],
            *"(000.500000)"
        );
    }

    #[test]
    fn ascii_and_direction_views() {
        let view = View {
            ascii: true,
            extra: true,
            ..View::default()
        };
        let mut term = Terminal::new(view);
        let mut e = entry("123#41420033", 0.0);
        e.direction = Some(Direction::Tx);
        assert_eq!(
            term.line(&e),
            "  vcan0  TX - -  123   [4]  41 42 00 33               'AB.3'"
        );
        assert_eq!(
            term.line(&entry("123#", 0.0)),
            "  vcan0  RX - -  123   [0]                            ''"
        );
        assert_eq!(
            term.line(&entry("123#R2", 0.0)),
            "  vcan0  RX - -  123   [2]  remote request"
        );
    }

    #[test]
    fn error_frames_in_words_like_candump_e() {
        let e = Entry {
            timestamp: Duration::ZERO,
            interface: "vcan0".into(),
            record: Record::Error(ErrorFrame::decode(0x088, &[]).unwrap()),
            direction: None,
        };
        let mut term = Terminal::new(View {
            error_words: true,
            ..View::default()
        });
        assert_eq!(
            term.line(&e),
            "  vcan0  20000088   [8]  00 00 00 00 00 00 00 00   ERRORFRAME\n\
             \tprotocol-violation{{}{}}\n\
             \tbus-error"
        );
        assert_eq!(
            Terminal::default().line(&e),
            "  vcan0  20000088   [8]  00 00 00 00 00 00 00 00   ERRORFRAME"
        );
        assert_eq!(
            format_line(&e, false),
            "(0000000000.000000) vcan0 20000088#0000000000000000"
        );
    }
}
