//! PEAK TRC trace files (text, CRLF, `;` comments), as PCAN-View and python-can write them.
//!
//! Version 1.1 (no bus column, offsets in ms with one decimal):
//!
//! ```text
//! ;$FILEVERSION=1.1
//! ;$STARTTIME=44548.6028595139
//!      1)     17535.4  Tx     00000100  8  00 00 00 00 00 00 00 00
//!      2)     48937.6  Rx         0704  1  RTR
//! ```
//!
//! Version 2.1 (columns named in the header, offsets with three decimals, the bus):
//!
//! ```text
//! ;$FILEVERSION=2.1
//! ;$STARTTIME=44548.6028595139
//! ;$COLUMNS=N,O,T,B,I,d,R,L,D
//!       1     17535.400 DT 1  00000100 Tx -  8    00 00 00 00 00 00 00 00
//!       2     48937.600 RR 1      0704 Rx -  1
//! ```
//!
//! `$STARTTIME` is days since 1899-12-30 (UTC, as python-can reads and writes it); buslab
//! writes it with 15 decimals, the first entry's time to the nanosecond. IDs have 4 hex digits
//! (standard) or 8 (extended). CAN FD frames are 2.x records of type `FD` (neither flag), `FB`
//! (BRS), `FE` (ESI) or `BI` (BRS and ESI) whose `L` column is the DLC (0..15) and `l` column,
//! when a file has it, the data length; version 1.x has no CAN FD, so a 1.1 writer refuses an
//! FD frame by name. The writer leaves error frames out (TRC's error records are
//! not SocketCAN's; python-can leaves them out too), counted by `left_out`. The reader takes
//! versions 1.0 to 2.1 and skips status, error-counter and event records. The bit rates of a
//! PCAN-View header's connection table (`;   1    Connection1   TestNet@pcan_usb   CAN   500
//! kBit/s`) are the buses' ([`LogReader::bit_rate`]).

use std::io::{self, BufRead, Write};
use std::time::Duration;

use buslab_can::{FD_MAX_LEN, FdFrame, Frame, Id, fd_len_of_dlc};

use crate::LogBitRate;
use crate::bitrate::HeaderRates;
use crate::channel::{ChannelMap, channel_of, set_channel_name};
use crate::codec::{Encoder, LogReader};
use crate::error::{Problem, ReadError, excerpt};
use crate::text::{self, Lines, TooLong, field};
use crate::time;
use crate::{Direction, Location, Message, Record, Timestamp};

/// The TRC version a writer writes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Version {
    V1_1,
    V2_1,
}

/// The layout of a file's records, from its header.
#[derive(Clone, Debug, PartialEq, Eq)]
enum Layout {
    /// 1.0: `N) O I L D`.
    V1_0,
    /// 1.1: `N) O T I L D`.
    V1_1,
    /// 1.2 and 1.3: `N) O B T I [R] L D`.
    V1_3,
    /// 2.x: the `$COLUMNS` letters.
    V2(Vec<u8>),
}

/// Reads a TRC file.
pub struct Reader<R> {
    lines: Lines<R>,
    state: State,
}

struct State {
    layout: Layout,
    start: Duration,
    /// The bit rates of the header's connection table.
    rates: HeaderRates,
}

impl<R: BufRead> Reader<R> {
    pub fn new(input: R) -> Self {
        Self {
            lines: Lines::new(input),
            state: State {
                layout: Layout::V1_0,
                start: Duration::ZERO,
                rates: HeaderRates::default(),
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
                if line.is_empty() {
                    return None;
                }
                if let Some(comment) = line.strip_prefix(b";") {
                    state.header(comment);
                    return None;
                }
                match state.record(line, entry) {
                    Ok(true) => Some(Ok(())),
                    Ok(false) => None,
                    Err(p) => Some(Err(ReadError::bad(at, p))),
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
    fn header(&mut self, comment: &[u8]) {
        let text = String::from_utf8_lossy(comment);
        let Some((key, value)) = text.trim().split_once('=') else {
            self.rates.comment(&text);
            return;
        };
        match key.trim() {
            "$FILEVERSION" => {
                self.layout = match value.trim() {
                    "1.1" => Layout::V1_1,
                    "1.2" | "1.3" => Layout::V1_3,
                    v if v.starts_with('2') => match &self.layout {
                        Layout::V2(cols) => Layout::V2(cols.clone()),
                        _ => Layout::V2(b"NOTBIdRLD".to_vec()),
                    },
                    _ => Layout::V1_0,
                }
            }
            "$STARTTIME" => match time::parse_ole_days(value) {
                Some(t) => self.start = t,
                None => tracing::warn!("TRC $STARTTIME={value} not understood: times count from 0"),
            },
            "$COLUMNS" => {
                let cols: Vec<u8> = value
                    .split(',')
                    .filter_map(|c| c.trim().bytes().next())
                    .collect();
                self.layout = Layout::V2(cols);
            }
            _ => {}
        }
    }

    /// One record: `Ok(false)` for a record that is not a frame (status, errors, events).
    fn record(&mut self, line: &[u8], entry: &mut Message) -> Result<bool, Problem> {
        let mut rest = line;
        let mut next = || {
            let (w, r) = field(rest);
            rest = r;
            w
        };
        let mut ty: &[u8] = b"DT";
        let mut id: &[u8] = b"";
        let mut dlc: &[u8] = b"";
        let mut bus: &[u8] = b"1";
        let mut dir: &[u8] = b"Rx";
        let mut offset: &[u8] = b"";
        let mut length_is_dlc = true;
        match &self.layout {
            Layout::V2(cols) => {
                for &c in cols {
                    if c == b'D' {
                        break;
                    }
                    let w = next();
                    match c {
                        b'O' => offset = w,
                        b'T' => ty = w,
                        b'B' => bus = w,
                        b'I' => id = w,
                        b'd' => dir = w,
                        b'L' => dlc = w,
                        b'l' => {
                            dlc = w;
                            length_is_dlc = false;
                        }
                        _ => {}
                    }
                }
                match ty {
                    b"DT" | b"RR" | b"FD" | b"FB" | b"FE" | b"BI" => {}
                    _ => return Ok(false),
                }
            }
            layout => {
                let _number = next();
                offset = next();
                if *layout == Layout::V1_3 {
                    bus = next();
                }
                if *layout != Layout::V1_0 {
                    dir = next();
                    ty = b"DT";
                }
                id = next();
                let mut w = next();
                if *layout == Layout::V1_3 && w == b"-" {
                    w = next();
                }
                dlc = w;
                if *layout != Layout::V1_0 && !matches!(dir, b"Rx" | b"Tx") {
                    return Ok(false); // Warng, Error, …
                }
                if id == b"FFFFFFFF" || text::trim(rest).starts_with(b"ERROR") {
                    return Ok(false);
                }
                if text::trim(rest) == b"RTR" {
                    ty = b"RR";
                    rest = b"";
                }
            }
        }
        let offset =
            text::decimal_duration(offset, buslab_can::Nanos::from_millis(1)).ok_or_else(|| {
                Problem::Expected {
                    expected: "a time offset in milliseconds",
                    found: excerpt(offset),
                }
            })?;
        let raw = text::hex_u32(id).ok_or_else(|| Problem::Expected {
            expected: "a CAN ID in hex (4 digits standard, 8 extended)",
            found: excerpt(id),
        })?;
        let id = if id.len() > 4 {
            Id::extended(raw)?
        } else {
            Id::standard(raw as u16)?
        };
        // BRS and ESI of a CAN FD record's type.
        let fd = match ty {
            b"FD" => Some((false, false)),
            b"FB" => Some((true, false)),
            b"FE" => Some((false, true)),
            b"BI" => Some((true, true)),
            _ => None,
        };
        let len = data_length(dlc, fd.is_some(), length_is_dlc, &self.layout)?;
        let direction = match dir {
            b"Rx" => Direction::Rx,
            b"Tx" => Direction::Tx,
            other => {
                return Err(Problem::Expected {
                    expected: "Rx or Tx",
                    found: excerpt(other),
                });
            }
        };
        let bus = text::dec_u64(bus)
            .and_then(|b| u16::try_from(b).ok())
            .ok_or_else(|| Problem::Expected {
                expected: "a bus number",
                found: excerpt(bus),
            })?;
        let record = if ty == b"RR" {
            Record::Frame(Frame::remote(id, len as u8)?)
        } else {
            let mut data = [0u8; FD_MAX_LEN];
            let mut words = rest;
            for slot in data.iter_mut().take(len) {
                let (w, r) = field(words);
                words = r;
                *slot = match w {
                    [a, b] if text::hex_digit(*a) < 16 && text::hex_digit(*b) < 16 => {
                        (text::hex_digit(*a) << 4) | text::hex_digit(*b)
                    }
                    _ => {
                        return Err(Problem::Expected {
                            expected: "as many data bytes (2 hex digits each) as the length",
                            found: excerpt(w),
                        });
                    }
                };
            }
            match fd {
                Some((brs, esi)) => {
                    Record::Fd(FdFrame::new(id, &data[..len])?.with_brs(brs).with_esi(esi))
                }
                None => Record::Frame(Frame::data(id, &data[..len])?),
            }
        };
        entry.at = Timestamp::since_epoch(self.start + offset);
        set_channel_name(&mut entry.channel, bus);
        entry.record = record;
        entry.direction = Some(direction);
        Ok(true)
    }
}

/// A record's data length: a classic record's 0..8; a CAN FD record's from its DLC (0..15,
/// the `L` column) or its length (the `l` column).
fn data_length(
    text: &[u8],
    fd: bool,
    length_is_dlc: bool,
    layout: &Layout,
) -> Result<usize, Problem> {
    let value = text::dec_u64(text);
    let bad = |expected| Problem::Expected {
        expected,
        found: excerpt(text),
    };
    match (fd, value) {
        (false, Some(n @ 0..=8)) => Ok(n as usize),
        (false, _) if matches!(layout, Layout::V2(_)) => Err(bad(
            "a data length 0..8 (a CAN FD record's type is FD, FB, FE or BI)",
        )),
        (false, _) => Err(bad("a data length 0..8 (TRC 1.x has no CAN FD)")),
        (true, Some(dlc)) if length_is_dlc => u8::try_from(dlc)
            .ok()
            .and_then(fd_len_of_dlc)
            .ok_or_else(|| bad("a CAN FD DLC 0..15")),
        (true, Some(n)) if n <= FD_MAX_LEN as u64 => Ok(n as usize),
        (true, _) => Err(bad(
            "a CAN FD data length 0..8, 12, 16, 20, 24, 32, 48 or 64",
        )),
    }
}

impl<R: BufRead + Send> LogReader for Reader<R> {
    fn read_into(&mut self, entry: &mut Message) -> Result<bool, ReadError> {
        Reader::read_into(self, entry)
    }
    fn bit_rate(&self, channel: &str) -> Option<LogBitRate> {
        self.state.rates.rate(channel_of(channel)?)
    }
}

/// Writes a TRC file of version 1.1 or 2.1 (the header with the first entry).
pub struct Writer<W> {
    out: W,
    version: Version,
    channels: ChannelMap,
    start: Option<Duration>,
    number: u64,
    left_out: u64,
    line: Vec<u8>,
}

impl<W: Write> Writer<W> {
    pub fn new(out: W, version: Version) -> Self {
        Self {
            out,
            version,
            channels: ChannelMap::new(),
            start: None,
            number: 0,
            left_out: 0,
            line: Vec::with_capacity(128),
        }
    }

    fn header(&mut self, start: Duration) -> io::Result<()> {
        let days = time::ole_days(start);
        let lines: &[&str] = match self.version {
            Version::V1_1 => &[
                ";$FILEVERSION=1.1",
                &format!(";$STARTTIME={days}"),
                ";",
                ";   Generated by buslab",
                ";",
                ";   Message Number",
                ";   |         Time Offset (ms)",
                ";   |         |        Type",
                ";   |         |        |        ID (hex)",
                ";   |         |        |        |     Data Length",
                ";   |         |        |        |     |   Data Bytes (hex) ...",
                ";   |         |        |        |     |   |",
                ";---+--   ----+----  --+--  ----+---  +  -+ -- -- -- -- -- -- --",
            ],
            Version::V2_1 => &[
                ";$FILEVERSION=2.1",
                &format!(";$STARTTIME={days}"),
                ";$COLUMNS=N,O,T,B,I,d,R,L,D",
                ";",
                ";   Generated by buslab",
                ";-------------------------------------------------------------------------------",
                ";   Message   Time    Type    ID     Rx/Tx",
                ";   Number    Offset  |  Bus  [hex]  |  Reserved",
                ";   |         [ms]    |  |    |      |  |  Data Length Code",
                ";   |         |       |  |    |      |  |  |    Data [hex] ...",
                ";   |         |       |  |    |      |  |  |    |",
                ";---+-- ------+------ +- +- --+----- +- +- +--- +- -- -- -- -- -- -- --",
            ],
        };
        for l in lines {
            self.out.write_all(l.as_bytes())?;
            self.out.write_all(b"\r\n")?;
        }
        self.start = Some(start);
        Ok(())
    }

    /// Writes one entry. An error frame is left out (counted); an FD frame in a 1.1 file is
    /// refused with [`io::ErrorKind::InvalidInput`] and nothing is written.
    pub fn write(&mut self, entry: &Message) -> io::Result<()> {
        let frame = match &entry.record {
            Record::Frame(f) => TrcFrame::Classic(f),
            Record::Fd(f) if self.version == Version::V2_1 => TrcFrame::Fd(f),
            Record::Fd(_) => {
                return Err(io::Error::new(
                    io::ErrorKind::InvalidInput,
                    "TRC 1.1 has no CAN FD records: write TRC 2.1 (.trc, --to trc21) or another format that carries CAN FD (candump, ASC, BLF, pcap, pcapng)",
                ));
            }
            Record::Error(_) => {
                if self.left_out == 0 {
                    tracing::warn!(
                        "TRC files hold no SocketCAN error frames: they are left out (as python-can does)"
                    );
                }
                self.left_out += 1;
                return Ok(());
            }
        };
        let start = match self.start {
            Some(s) => s,
            None => {
                self.header(entry.at.since_epoch_duration())?;
                entry.at.since_epoch_duration()
            }
        };
        self.number += 1;
        let offset = entry.at.since_epoch_duration().saturating_sub(start);
        let bus = self.channels.number(&entry.channel);
        let line = &mut self.line;
        line.clear();
        let dir: &[u8] = match entry.direction {
            Some(Direction::Tx) => b"Tx",
            _ => b"Rx",
        };
        let mut id = Vec::with_capacity(8);
        match frame.id() {
            Id::Standard(i) => text::push_hex(&mut id, u32::from(i.as_raw()), 4),
            Id::Extended(i) => text::push_hex(&mut id, i.as_raw(), 8),
        }
        match self.version {
            Version::V1_1 => {
                // `{n:>6}) {ms:>11.1}  {type:<5}  {id:>8}  {dlc}  {data}`
                let tenths = offset.as_micros() / 100;
                text::push_u64_right(line, self.number, 6);
                line.extend_from_slice(b") ");
                let col = line.len();
                text::push_u64(line, (tenths / 10) as u64);
                line.push(b'.');
                text::push_u64(line, (tenths % 10) as u64);
                right_align(line, col, 11);
                line.extend_from_slice(b"  ");
                line.extend_from_slice(dir);
                line.extend_from_slice(b"     ");
                let col = line.len();
                line.extend_from_slice(&id);
                right_align(line, col, 8);
                line.extend_from_slice(b"  ");
                text::push_u64(line, u64::from(frame.dlc()));
                line.extend_from_slice(b"  ");
                if frame.is_remote() {
                    line.extend_from_slice(b"RTR");
                }
            }
            Version::V2_1 => {
                // `{n:>7} {ms:>13.3} {type} {bus:<2} {id:>8} {dir} -  {dlc:<4} {data}`
                let micros = offset.as_micros();
                text::push_u64_right(line, self.number, 7);
                line.push(b' ');
                let col = line.len();
                text::push_u64(line, (micros / 1000) as u64);
                line.push(b'.');
                text::push_u64_zeros(line, (micros % 1000) as u64, 3);
                right_align(line, col, 13);
                line.extend_from_slice(frame.kind());
                let col = line.len();
                text::push_u64(line, u64::from(bus));
                text::pad_to(line, col, 2);
                line.push(b' ');
                let col = line.len();
                line.extend_from_slice(&id);
                right_align(line, col, 8);
                line.push(b' ');
                line.extend_from_slice(dir);
                line.extend_from_slice(b" -  ");
                let col = line.len();
                text::push_u64(line, u64::from(frame.dlc()));
                text::pad_to(line, col, 4);
                line.push(b' ');
            }
        }
        for (i, &b) in frame.payload().iter().enumerate() {
            if i > 0 {
                line.push(b' ');
            }
            text::push_hex_byte(line, b);
        }
        while line.last() == Some(&b' ') {
            line.pop();
        }
        line.extend_from_slice(b"\r\n");
        self.out.write_all(line)
    }

    /// Writes the header of a log without entries.
    pub fn finish(mut self) -> io::Result<W> {
        if self.start.is_none() {
            let now = std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .unwrap_or_default();
            self.header(now)?;
        }
        self.out.flush()?;
        Ok(self.out)
    }
}

/// A frame a TRC record holds: classic, or CAN FD (2.x only).
enum TrcFrame<'a> {
    Classic(&'a Frame),
    Fd(&'a FdFrame),
}

impl TrcFrame<'_> {
    fn id(&self) -> Id {
        match self {
            TrcFrame::Classic(f) => f.id(),
            TrcFrame::Fd(f) => f.id(),
        }
    }
    /// The `L` column: a classic frame's DLC 0..8, an FD frame's 0..15.
    fn dlc(&self) -> u8 {
        match self {
            TrcFrame::Classic(f) => f.dlc(),
            TrcFrame::Fd(f) => f.dlc(),
        }
    }
    fn is_remote(&self) -> bool {
        matches!(self, TrcFrame::Classic(f) if f.is_remote())
    }
    fn payload(&self) -> &[u8] {
        match self {
            TrcFrame::Classic(f) => f.payload(),
            TrcFrame::Fd(f) => f.payload(),
        }
    }
    /// The 2.x type column, with a space on each side.
    fn kind(&self) -> &'static [u8] {
        match self {
            TrcFrame::Classic(f) if f.is_remote() => b" RR ",
            TrcFrame::Classic(_) => b" DT ",
            TrcFrame::Fd(f) => match (f.brs(), f.esi()) {
                (false, false) => b" FD ",
                (true, false) => b" FB ",
                (false, true) => b" FE ",
                (true, true) => b" BI ",
            },
        }
    }
}

/// Right-aligns what was pushed since `col` to `width` columns.
fn right_align(line: &mut Vec<u8>, col: usize, width: usize) {
    let len = line.len() - col;
    if len < width {
        line.splice(col..col, std::iter::repeat_n(b' ', width - len));
    }
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
    fn left_out(&self) -> u64 {
        self.left_out
    }
}
