//! Vector ASC logs (text), as CANoe/CANalyzer, log2asc and python-can write them:
//!
//! ```text
//! date Tue Nov 14 22:13:20.123 2023
//! base hex  timestamps absolute
//! internal events logged
//! // buslab start-time 1700000000.123456
//! Begin Triggerblock Tue Nov 14 22:13:20.123 2023
//!    0.000000 Start of measurement
//!    0.000000 1  123             Rx   d 3 11 22 33
//!    0.001000 2  12345678x       Tx   d 4 DE AD BE EF
//!    0.002000 1  7FF             Rx   r 2
//!    0.003000 CANFD   1 Rx        321                                   1 0 9 12 00 01 02 03 04 05 06 07 08 09 0A 0B        0    0     3000        0        0        0        0        0
//! // buslab error-frame 20000088#0000020A00000102
//!    0.005000 1  ErrorFrame
//! End TriggerBlock
//! ```
//!
//! Times are seconds since the first entry with six decimals (microseconds); the header dates
//! are local time with milliseconds, and the `// buslab start-time` comment (ignored by
//! other readers) gives the first entry's time to the microsecond, so buslab reads its own
//! files back exactly. Channels are numbers from 1 ([`ChannelMap`]). An error frame is
//! `ErrorFrame`, which says nothing of what went wrong; the `// buslab error-frame` comment
//! before it carries the SocketCAN frame in candump's syntax, so buslab reads it back byte for
//! byte. An `ErrorFrame` without that comment reads as a bus error, as asc2log reads it.
//!
//! A CAN FD frame is a `CANFD` line, python-can's layout: channel, direction, ID, a blank
//! symbolic name, BRS, ESI, the DLC (hex), the data length (decimal), the data, then duration
//! and bit count (0: not measured), the flags (EDL 0x1000, BRS 0x2000, ESI 0x4000), CRC and
//! bit timings (0). A `CANFD` line is CAN FD when its flags have EDL or its length is above 8;
//! BRS and ESI are read from their columns and the data by its length (python-can reads them
//! so too: the flags and the DLC are not checked against them).
//!
//! The reader takes `base hex|dec`, `timestamps absolute|relative`, the dates of log2asc,
//! python-can and Vector (English or German, am/pm), classic frames in `CANFD` lines, remote
//! frames with or without a DLC, a classic DLC of 9..15 (8 data bytes, as CAN has it), a
//! classic data line whose DLC is a CAN FD length above 15 as that CAN FD frame (python-can 3
//! wrote FD frames so: `d 40` and 64 bytes), the
//! `Length = … BitCount = … ID = …` fields CANoe writes after a frame (the lengths, the
//! frames' time on the wire in nanoseconds, give the channel's bit rate:
//! [`LogReader::bit_rate`]), and skips the events it does not know (statistics, status, J1939,
//! comments).

use std::io::{self, BufRead, Write};
use std::time::Duration;

use buslab_bus::ErrorFrame;
use buslab_bus::error_frame::CanError;
use buslab_can::{FD_MAX_LEN, FdFrame, Frame, Id};

use crate::LogBitRate;
use crate::bitrate::FrameLengths;
use crate::channel::{ChannelMap, channel_of, set_channel_name};
use crate::codec::{Encoder, LogReader};
use crate::error::{Problem, ReadError, excerpt};
use crate::text::{self, Lines, TooLong, field};
use crate::time;
use crate::{Direction, Location, Message, Record, Timestamp};

/// The comment buslab writes with the first entry's exact time.
const START_COMMENT: &str = "// buslab start-time ";
/// The comment buslab writes before an `ErrorFrame` line: the SocketCAN error frame.
const ERROR_COMMENT: &str = "// buslab error-frame ";

/// A `CANFD` line's flags: extended data length (CAN FD), bit rate switch, error state
/// indicator, and a remote frame (classic frames only).
const EDL: u32 = 0x1000;
const FLAG_BRS: u32 = 0x2000;
const FLAG_ESI: u32 = 0x4000;
const FLAG_REMOTE: u32 = 0x10;

/// What an ASC error frame reads back as: a bus error (what asc2log makes of it).
pub fn error_frame() -> ErrorFrame {
    ErrorFrame::new(vec![CanError::BusError], None)
}

/// Reads an ASC log.
pub struct Reader<R> {
    lines: Lines<R>,
    state: State,
}

/// What the header said, and the running time.
struct State {
    hex: bool,
    relative: bool,
    date: Option<Duration>,
    trigger: Option<Duration>,
    exact: Option<Duration>,
    /// The running time of a `timestamps relative` log.
    last: Duration,
    /// The error frame of a `// buslab error-frame` comment, for the `ErrorFrame` line after it.
    error_frame: Option<ErrorFrame>,
    /// The frames' lengths on the wire (`Length = …`), per channel.
    lengths: FrameLengths,
}

impl<R: BufRead> Reader<R> {
    pub fn new(input: R) -> Self {
        Self {
            lines: Lines::new(input),
            state: State {
                hex: true,
                relative: false,
                date: None,
                trigger: None,
                exact: None,
                last: Duration::ZERO,
                error_frame: None,
                lengths: FrameLengths::default(),
            },
        }
    }

    /// Reads the next entry into `entry`; `Ok(false)` at the end.
    pub fn read_into(&mut self, entry: &mut Message) -> Result<bool, ReadError> {
        let state = &mut self.state;
        loop {
            let step = self.lines.next(|number, line| {
                let at = Location::Line(number);
                let line = match line {
                    Ok(line) => text::trim(line),
                    Err(TooLong) => {
                        return Some(Err(ReadError::expected(
                            at,
                            "a line shorter than 4096 bytes",
                            b"...",
                        )));
                    }
                };
                match classify(line) {
                    Kind::Header(h) => {
                        state.header(h);
                        None
                    }
                    Kind::ErrorComment(text) => match error_comment(text) {
                        Ok(e) => {
                            state.error_frame = Some(e);
                            None
                        }
                        Err(p) => Some(Err(ReadError::bad(at, p))),
                    },
                    Kind::Other => None,
                    Kind::Event => match state.event(line, entry) {
                        Ok(true) => Some(Ok(())),
                        Ok(false) => None,
                        Err(p) => Some(Err(ReadError::bad(at, p))),
                    },
                }
            })?;
            match step {
                None => return Ok(false),
                Some(None) => {}
                Some(Some(result)) => return result.map(|()| true),
            }
        }
    }
}

impl State {
    /// The time the log's times count from.
    fn start(&self) -> Duration {
        self.exact
            .or(self.trigger)
            .or(self.date)
            .unwrap_or_default()
    }

    fn header(&mut self, h: Header) {
        match h {
            Header::Date(d) => {
                self.date = time::parse_asc_date(&d);
                if self.date.is_none() {
                    tracing::warn!("ASC date {d:?} not understood: times count from 0");
                }
            }
            Header::Trigger(d) => self.trigger = time::parse_asc_date(&d).or(self.trigger),
            Header::Base { hex, relative } => {
                self.hex = hex;
                self.relative = relative;
            }
            Header::Exact(t) => self.exact = Some(t),
        }
    }

    /// One event line: `Ok(false)` for an event that is not a frame.
    fn event(&mut self, line: &[u8], entry: &mut Message) -> Result<bool, Problem> {
        // A comment's error frame belongs to the line right after it only.
        let commented = self.error_frame.take();
        let error_record = || Record::Error(commented.unwrap_or_else(error_frame));
        let (ts, rest) = field(line);
        let offset =
            text::decimal_duration(ts, buslab_can::Nanos::from_secs(1)).ok_or_else(|| {
                Problem::Expected {
                    expected: "a time in seconds",
                    found: excerpt(ts),
                }
            })?;
        let (channel, rest) = field(rest);
        let (record, direction, channel) = if channel == b"CANFD" {
            match self.fd_line(rest, error_record)? {
                Some(x) => x,
                None => return Ok(false),
            }
        } else {
            let channel = channel_number(channel)?;
            let (id, rest) = field(rest);
            if id.eq_ignore_ascii_case(b"errorframe") {
                (error_record(), Some(Direction::Rx), channel)
            } else {
                let (dir, rest) = field(rest);
                let direction = direction(dir)?;
                let (kind, rest) = field(rest);
                let (dlc, rest) = field(rest);
                let id = self.id(id)?;
                let record = match kind {
                    // CANoe leaves the DLC out of a remote frame of DLC 0; `Length = …` may
                    // follow at once.
                    b"r" | b"R" if dlc.is_empty() || dlc == b"Length" => {
                        Record::Frame(Frame::remote(id, 0)?)
                    }
                    b"r" | b"R" => {
                        let dlc = self.number(dlc, "a DLC")?;
                        Record::Frame(Frame::remote(id, classic_dlc(dlc)?.0)?)
                    }
                    b"d" | b"D" => {
                        let dlc = self.number(dlc, "a DLC")?;
                        if let Some(len) = fd_length_in_classic_line(dlc) {
                            // python-can 3's FD frames: `d 40` and 64 bytes.
                            let data = self.bytes::<FD_MAX_LEN>(rest, len)?;
                            Record::Fd(FdFrame::new(id, &data[..len])?)
                        } else {
                            let len = usize::from(classic_dlc(dlc)?.1);
                            let data = self.bytes::<8>(rest, len)?;
                            Record::Frame(Frame::data(id, &data[..len])?)
                        }
                    }
                    other => {
                        return Err(Problem::Expected {
                            expected: "d (data) or r (remote) after the direction",
                            found: excerpt(other),
                        });
                    }
                };
                (record, Some(direction), channel)
            }
        };
        entry.at = Timestamp::since_epoch(if self.relative {
            self.last = self.last.max(self.start()) + offset;
            self.last
        } else {
            self.start() + offset
        });
        if let (Record::Frame(frame), Some(ns)) = (&record, after_key(line, b"Length = ")) {
            let bits = after_key(line, b"BitCount = ");
            self.lengths.add(channel, frame, ns, bits);
        }
        set_channel_name(&mut entry.channel, channel);
        entry.record = record;
        entry.direction = direction;
        Ok(true)
    }

    /// `CANFD CH DIR ID [NAME] BRS ESI DLC LEN DATA… DURATION BITS FLAGS …`: CAN FD when the
    /// flags have EDL (0x1000) or the length is above 8, else a classic frame.
    fn fd_line(
        &self,
        rest: &[u8],
        error_frame: impl FnOnce() -> Record,
    ) -> Result<Option<(Record, Option<Direction>, u16)>, Problem> {
        let (channel, rest) = field(rest);
        let channel = channel_number(channel)?;
        let (dir, rest) = field(rest);
        let direction = direction(dir)?;
        let (id, rest) = field(rest);
        if id.eq_ignore_ascii_case(b"errorframe") {
            return Ok(Some((error_frame(), Some(direction), channel)));
        }
        let id = self.id(id)?;
        let mut words: Vec<&[u8]> = Vec::with_capacity(24);
        let mut rest = rest;
        while !rest.is_empty() && words.len() < 96 {
            let (w, r) = field(rest);
            if w.is_empty() {
                break;
            }
            words.push(w);
            rest = r;
        }
        // A symbolic name may stand before BRS: a word of digits is BRS (python-can's rule).
        let start = match words.first() {
            Some(w) if w.iter().all(u8::is_ascii_digit) => 0,
            _ => 1,
        };
        let get = |i: usize| {
            words.get(start + i).copied().ok_or(Problem::Expected {
                expected: "CANFD: BRS ESI DLC LENGTH DATA…",
                found: String::new(),
            })
        };
        let len = text::dec_u64(get(3)?).ok_or_else(|| Problem::Expected {
            expected: "a data length",
            found: excerpt(words.get(start + 3).copied().unwrap_or_default()),
        })? as usize;
        if len > FD_MAX_LEN {
            return Err(Problem::Expected {
                expected: "a CAN FD data length 0..8, 12, 16, 20, 24, 32, 48 or 64",
                found: len.to_string(),
            });
        }
        let flags = words
            .get(start + 4 + len + 2)
            .and_then(|w| text::hex_u32(w))
            .unwrap_or(EDL);
        let data = (0..len)
            .map(|i| {
                let w = get(4 + i)?;
                self.byte(w)
            })
            .collect::<Result<Vec<u8>, Problem>>()?;
        let dlc = self.number(get(2)?, "a DLC")?;
        let record = if flags & EDL != 0 || len > 8 {
            Record::Fd(self.fd_frame(id, &words[start..], dlc, &data, flags)?)
        } else if flags & FLAG_REMOTE != 0 {
            Record::Frame(Frame::remote(id, classic_dlc(dlc)?.0)?)
        } else {
            Record::Frame(Frame::data(id, &data)?)
        };
        Ok(Some((record, Some(direction), channel)))
    }

    /// A `CANFD` line's FD frame: `words` from BRS on.
    fn fd_frame(
        &self,
        id: Id,
        words: &[&[u8]],
        dlc: u64,
        data: &[u8],
        flags: u32,
    ) -> Result<FdFrame, Problem> {
        if flags & FLAG_REMOTE != 0 {
            return Err(Problem::Expected {
                expected: "a CAN FD frame without the remote flag 0x10 (CAN FD has no remote frames)",
                found: format!("flags {flags:X}"),
            });
        }
        let bit = |w: &[u8]| match w {
            b"0" => Ok(false),
            b"1" => Ok(true),
            other => Err(Problem::Expected {
                expected: "BRS and ESI as 0 or 1 before the DLC",
                found: excerpt(other),
            }),
        };
        let frame = FdFrame::new(id, data)?;
        if u64::from(frame.dlc()) != dlc {
            // The data length says how many bytes there are; python-can reads it so too.
            tracing::debug!(
                "CANFD line: DLC {dlc:X} with {} data bytes, read by its data",
                data.len()
            );
        }
        Ok(frame.with_brs(bit(words[0])?).with_esi(bit(words[1])?))
    }

    fn id(&self, text: &[u8]) -> Result<Id, Problem> {
        let (digits, extended) = match text.strip_suffix(b"x").or(text.strip_suffix(b"X")) {
            Some(d) => (d, true),
            None => (text, false),
        };
        let raw = self.number(digits, "a CAN ID (x after it for an extended one)")?;
        let raw = u32::try_from(raw).map_err(|_| Problem::Expected {
            expected: "a CAN ID up to 1FFFFFFF",
            found: excerpt(text),
        })?;
        Ok(if extended {
            Id::extended(raw)?
        } else {
            Id::standard(u16::try_from(raw).map_err(|_| Problem::Expected {
                expected: "a standard CAN ID up to 7FF (x after it for an extended one)",
                found: excerpt(text),
            })?)?
        })
    }

    fn number(&self, text: &[u8], what: &'static str) -> Result<u64, Problem> {
        let v = if self.hex {
            text::hex_u32(text).map(u64::from)
        } else {
            text::dec_u64(text)
        };
        v.ok_or_else(|| Problem::Expected {
            expected: what,
            found: excerpt(text),
        })
    }

    fn byte(&self, text: &[u8]) -> Result<u8, Problem> {
        let v = self.number(text, "a data byte")?;
        u8::try_from(v).map_err(|_| Problem::Expected {
            expected: "a data byte",
            found: excerpt(text),
        })
    }

    /// `len` data bytes (at most `N`: 8 for a classic frame, 64 for an FD frame).
    fn bytes<const N: usize>(&self, mut rest: &[u8], len: usize) -> Result<[u8; N], Problem> {
        let mut data = [0u8; N];
        for slot in data.iter_mut().take(len) {
            let (w, r) = field(rest);
            if w.is_empty() {
                return Err(Problem::Expected {
                    expected: "as many data bytes as the DLC",
                    found: String::new(),
                });
            }
            *slot = self.byte(w)?;
            rest = r;
        }
        Ok(data)
    }
}

/// A classic frame's DLC field: (the DLC buslab's frames carry, the data bytes). Classical
/// CAN's DLC 9..15 means 8 bytes (ISO 11898-1).
fn classic_dlc(dlc: u64) -> Result<(u8, u8), Problem> {
    match dlc {
        0..=8 => Ok((dlc as u8, dlc as u8)),
        9..=15 => Ok((8, 8)),
        _ => Err(Problem::Expected {
            expected: "a DLC 0..15, or a CAN FD length 16..64 (a CAN FD frame is a CANFD line)",
            found: format!("{dlc:X}"),
        }),
    }
}

/// A data line whose DLC field is a CAN FD length above 15 (`d 40`: 64 bytes), as python-can 3
/// wrote CAN FD frames: that many bytes. A DLC of 9..15 stays classical CAN's 8 bytes.
fn fd_length_in_classic_line(dlc: u64) -> Option<usize> {
    let len = usize::try_from(dlc).ok()?;
    (len > 15 && buslab_can::FD_LENGTHS.contains(&len)).then_some(len)
}

/// The error frame of a `// buslab error-frame 20000088#…` comment.
fn error_comment(text: &[u8]) -> Result<ErrorFrame, Problem> {
    let bad = || Problem::Expected {
        expected: "an error frame in candump's syntax after \"// buslab error-frame\"",
        found: excerpt(text),
    };
    let text = std::str::from_utf8(text::trim(text)).map_err(|_| bad())?;
    match crate::candump::parse_record(text) {
        Ok(Record::Error(e)) => Ok(e),
        Ok(Record::Frame(_) | Record::Fd(_)) => Err(bad()),
        Err(e) => Err(e.into()),
    }
}

/// A number CANoe writes after a frame: `Length = N` (its time on the wire in nanoseconds) or
/// `BitCount = N`; 0 (not measured) is none.
fn after_key(line: &[u8], key: &[u8]) -> Option<u64> {
    let at = line.windows(key.len()).position(|w| w == key)? + key.len();
    let (value, _) = field(&line[at..]);
    text::dec_u64(value).filter(|&n| n > 0)
}

fn channel_number(text: &[u8]) -> Result<u16, Problem> {
    text::dec_u64(text)
        .and_then(|c| u16::try_from(c).ok())
        .ok_or_else(|| Problem::Expected {
            expected: "a channel number",
            found: excerpt(text),
        })
}

fn direction(text: &[u8]) -> Result<Direction, Problem> {
    match text {
        b"Rx" | b"rx" | b"RX" => Ok(Direction::Rx),
        b"Tx" | b"tx" | b"TX" | b"TxRq" => Ok(Direction::Tx),
        _ => Err(Problem::Expected {
            expected: "Rx or Tx",
            found: excerpt(text),
        }),
    }
}

enum Header {
    Date(String),
    Trigger(String),
    Base { hex: bool, relative: bool },
    Exact(Duration),
}

enum Kind<'a> {
    Header(Header),
    /// The SocketCAN error frame of the `ErrorFrame` line that follows.
    ErrorComment(&'a [u8]),
    /// Not a frame: a comment, a statistic, a status line.
    Other,
    /// A frame or error frame line.
    Event,
}

fn lower_starts(line: &[u8], prefix: &[u8]) -> bool {
    line.len() >= prefix.len() && line[..prefix.len()].eq_ignore_ascii_case(prefix)
}

fn classify(line: &[u8]) -> Kind<'_> {
    let text = || String::from_utf8_lossy(line).into_owned();
    if lower_starts(line, b"date ") {
        let t = text();
        let d = t[5..].trim().to_string();
        return Kind::Header(Header::Date(d));
    }
    if lower_starts(line, b"base ") {
        let t = text().to_ascii_lowercase();
        return Kind::Header(Header::Base {
            hex: !t.contains("base dec"),
            relative: t.contains("timestamps relative"),
        });
    }
    if lower_starts(line, b"begin triggerblock") {
        let t = text();
        return Kind::Header(Header::Trigger(t[18..].trim().to_string()));
    }
    if let Some(rest) = line.strip_prefix(ERROR_COMMENT.as_bytes()) {
        return Kind::ErrorComment(rest);
    }
    if line.starts_with(START_COMMENT.as_bytes()) {
        return match text::decimal_duration(
            text::trim(&line[START_COMMENT.len()..]),
            buslab_can::Nanos::from_secs(1),
        ) {
            Some(t) => Kind::Header(Header::Exact(t)),
            None => Kind::Other,
        };
    }
    // TS then a channel number (or CANFD), then an ID with a direction, or ErrorFrame.
    let (ts, rest) = field(line);
    if ts.is_empty() || !ts.iter().all(|b| b.is_ascii_digit() || *b == b'.') {
        return Kind::Other;
    }
    let (channel, rest) = field(rest);
    if channel == b"CANFD" {
        return Kind::Event;
    }
    if channel.is_empty() || !channel.iter().all(u8::is_ascii_digit) {
        return Kind::Other;
    }
    let (id, rest) = field(rest);
    if id.eq_ignore_ascii_case(b"errorframe") {
        return Kind::Event;
    }
    let (dir, _) = field(rest);
    match dir {
        b"Rx" | b"Tx" | b"rx" | b"tx" | b"RX" | b"TX" | b"TxRq" => Kind::Event,
        _ => Kind::Other,
    }
}

impl<R: BufRead + Send> LogReader for Reader<R> {
    fn read_into(&mut self, entry: &mut Message) -> Result<bool, ReadError> {
        Reader::read_into(self, entry)
    }
    fn bit_rate(&self, channel: &str) -> Option<LogBitRate> {
        self.state.lengths.rate(channel_of(channel)?)
    }
}

/// Writes an ASC log (the header with the first entry, the footer at the end).
pub struct Writer<W> {
    out: W,
    channels: ChannelMap,
    /// The first entry's time, in whole microseconds.
    start_us: Option<u64>,
    line: Vec<u8>,
}

impl<W: Write> Writer<W> {
    pub fn new(out: W) -> Self {
        Self {
            out,
            channels: ChannelMap::new(),
            start_us: None,
            line: Vec::with_capacity(128),
        }
    }

    fn header(&mut self, first: Duration) -> io::Result<u64> {
        let start_us = first
            .as_secs()
            .saturating_mul(1_000_000)
            .saturating_add(u64::from(first.subsec_micros()));
        let start = Duration::from_micros(start_us);
        let date = time::asc_date(start);
        write!(
            self.out,
            "date {date}\nbase hex  timestamps absolute\ninternal events logged\n\
             {START_COMMENT}{}.{:06}\nBegin Triggerblock {date}\n   0.000000 Start of measurement\n",
            start_us / 1_000_000,
            start_us % 1_000_000
        )?;
        self.start_us = Some(start_us);
        Ok(start_us)
    }

    pub fn write(&mut self, entry: &Message) -> io::Result<()> {
        let start = match self.start_us {
            Some(s) => s,
            None => self.header(entry.at.since_epoch_duration())?,
        };
        let t = entry.at.since_epoch_duration();
        let us = t
            .as_secs()
            .saturating_mul(1_000_000)
            .saturating_add(u64::from(t.subsec_micros()));
        let offset = us.saturating_sub(start);
        let channel = self.channels.number(&entry.channel);
        let line = &mut self.line;
        line.clear();
        if let Record::Error(_) = &entry.record {
            line.extend_from_slice(ERROR_COMMENT.as_bytes());
            crate::candump::push_record(line, &entry.record);
            line.push(b'\n');
        }
        text::push_u64_right(line, offset / 1_000_000, 4);
        line.push(b'.');
        text::push_u64_zeros(line, offset % 1_000_000, 6);
        line.push(b' ');
        if let Record::Fd(f) = &entry.record {
            push_fd_line(line, channel, entry.direction, f);
            return self.out.write_all(line);
        }
        text::push_u64(line, u64::from(channel));
        line.extend_from_slice(b"  ");
        match &entry.record {
            Record::Error(_) => line.extend_from_slice(b"ErrorFrame"),
            Record::Fd(_) => unreachable!("written above"),
            Record::Frame(f) => {
                let col = line.len();
                match f.id() {
                    Id::Standard(id) => text::push_hex(line, u32::from(id.as_raw()), 1),
                    Id::Extended(id) => {
                        text::push_hex(line, id.as_raw(), 1);
                        line.push(b'x');
                    }
                }
                text::pad_to(line, col, 15);
                line.extend_from_slice(match entry.direction {
                    Some(Direction::Tx) => b" Tx   ",
                    _ => b" Rx   ",
                });
                if f.is_remote() {
                    line.extend_from_slice(b"r ");
                    text::push_hex(line, u32::from(f.dlc()), 1);
                } else {
                    line.extend_from_slice(b"d ");
                    text::push_hex(line, u32::from(f.dlc()), 1);
                    text::push_spaced_hex(line, f.payload());
                }
            }
        }
        line.push(b'\n');
        self.out.write_all(line)
    }

    /// Writes the footer (and the header, for a log without entries).
    pub fn finish(mut self) -> io::Result<W> {
        if self.start_us.is_none() {
            let now = std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .unwrap_or_default();
            self.header(now)?;
        }
        self.out.write_all(b"End TriggerBlock\n")?;
        self.out.flush()?;
        Ok(self.out)
    }
}

/// `CANFD CH DIR ID NAME BRS ESI DLC LEN DATA… DURATION BITS FLAGS CRC BTR…` after the
/// time, in python-can's columns (durations, CRC and bit timings 0: not measured), with the
/// newline.
fn push_fd_line(line: &mut Vec<u8>, channel: u16, direction: Option<Direction>, f: &FdFrame) {
    line.extend_from_slice(b"CANFD ");
    text::push_u64_right(line, u64::from(channel), 3);
    line.extend_from_slice(match direction {
        Some(Direction::Tx) => b" Tx   ",
        _ => b" Rx   ",
    });
    let col = line.len();
    match f.id() {
        Id::Standard(id) => text::push_hex(line, u32::from(id.as_raw()), 1),
        Id::Extended(id) => {
            text::push_hex(line, id.as_raw(), 1);
            line.push(b'x');
        }
    }
    let id_len = line.len() - col;
    if id_len < 8 {
        line.splice(col..col, std::iter::repeat_n(b' ', 8 - id_len));
    }
    // Two spaces, the blank symbolic name (32 wide), a space.
    line.extend_from_slice(&[b' '; 35]);
    line.extend_from_slice(if f.brs() { b"1 " } else { b"0 " });
    line.extend_from_slice(if f.esi() { b"1 " } else { b"0 " });
    text::push_hex(line, u32::from(f.dlc()), 1);
    line.push(b' ');
    text::push_u64_right(line, f.payload().len() as u64, 2);
    text::push_spaced_hex(line, f.payload());
    line.extend_from_slice(b"        0    0 ");
    let flags = EDL | if f.brs() { FLAG_BRS } else { 0 } | if f.esi() { FLAG_ESI } else { 0 };
    let col = line.len();
    text::push_hex(line, flags, 1);
    let flags_len = line.len() - col;
    line.splice(col..col, std::iter::repeat_n(b' ', 8 - flags_len));
    line.extend_from_slice(b"        0        0        0        0        0\n");
}

impl<W: Write + Send> Encoder<W> for Writer<W> {
    fn write(&mut self, entry: &Message) -> io::Result<()> {
        Writer::write(self, entry)
    }
    fn flush(&mut self) -> io::Result<()> {
        self.out.flush()
    }
    fn finish(self) -> io::Result<W> {
        Writer::finish(self)
    }
}
