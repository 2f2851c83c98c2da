//! can-utils' candump formats.
//!
//! The **log line** (candump `-l`/`-L`, read by canplayer, log2asc and python-can):
//!
//! ```text
//! (1700000000.123456) vcan0 123#1122334455667788
//! (1700000000.200000) can0 7FF#R
//! (1700000000.300000) can0 321##1112233                  <- CAN FD: `##`, flags, data
//! (1700000000.400000) can0 20000088#0000000000000000     <- an error frame
//! (1700000000.500000) can0 123#112233 T                  <- with candump -x: R or T
//! ```
//!
//! A CAN FD frame's flags nibble holds BRS (1) and ESI (2); can-utils v2025.01 and later also
//! set FDF (4), so readers mask it: any hex digit is read, its two low bits kept. Written as
//! python-can and older can-utils write it, `0`..`3`.
//!
//! [`parse_line`] reads one (never panics, whatever the text), [`format_line`] writes one;
//! [`Reader`] and [`Writer`] stream them. The **terminal layout** (candump without `-L`) is
//! [`Terminal`], with candump's views: `-t a|d|z` timestamps, `-a` ASCII, `-x` direction,
//! `-e` error frames in words.

use std::io::{self, BufRead, Write};
use std::time::Duration;

use buslab_bus::ErrorFrame;
use buslab_bus::error_frame::ERROR_FLAG;
use buslab_can::{FD_MAX_LEN, FdFrame, Frame, Id};

use crate::codec::{Encoder, LogReader};
pub use crate::error::LineError;
use crate::text::{self, Lines, TooLong};
use crate::{Direction, Location, Message, ReadError, Record, Timestamp};

/// The longest line [`Reader`] takes (a classic CAN line is under 80 characters).
pub const MAX_LINE: usize = text::MAX_LINE;

/// Reads one log line: `(SEC.FRACTION) IFACE FRAME [R|T]`. Runs of spaces separate the
/// fields (candump right-aligns interface names to the longest one).
pub fn parse_line(line: &str) -> Result<Message, LineError> {
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
    Ok(Message {
        at: Timestamp::since_epoch(timestamp),
        channel: interface.to_string(),
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

/// A frame in can-utils syntax, a CAN FD frame (`123##1…`), or an error frame (`20000088#…`:
/// 8 digits with the error flag).
pub(crate) fn parse_record(text: &str) -> Result<Record, LineError> {
    if let Some((_, fd)) = text.split_once('#')
        && fd.starts_with('#')
    {
        return Ok(Record::Fd(text.parse::<FdFrame>()?));
    }
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

/// Reads one log line into `entry`, reusing its interface's allocation: the reader's hot path
/// (no allocation for an ordinary line). Same result as [`parse_line`] on any input.
pub fn parse_line_into(line: &[u8], entry: &mut Message) -> Result<(), LineError> {
    if parse_fast(line, entry).is_some() {
        return Ok(());
    }
    let text = std::str::from_utf8(line).map_err(|_| LineError::NotText)?;
    *entry = parse_line(text)?;
    Ok(())
}

/// `!` to `~`: one comparison.
#[inline]
fn is_graphic(b: u8) -> bool {
    b.wrapping_sub(0x21) < 0x5E
}

#[inline]
fn is_blank(b: u8) -> bool {
    b == b' ' || b == b'\t'
}

const POW10: [u32; 10] = [
    1_000_000_000,
    100_000_000,
    10_000_000,
    1_000_000,
    100_000,
    10_000,
    1_000,
    100,
    10,
    1,
];

/// The common shape of a line, parsed byte by byte: `(SECS.FRAC) IFACE ID#DATA [R|T]` with a
/// 3- or 8-digit ID and plain hex data or `R[dlc]`, or `ID##FDATA` (CAN FD). `None` for
/// anything else (then [`parse_line`] decides, with its precise error).
#[inline]
fn parse_fast(line: &[u8], entry: &mut Message) -> Option<()> {
    let n = line.len();
    // candump's own `(%010u.%06u) ` in one go.
    if let Some((secs, micros)) = candump_time(line) {
        return parse_after_time(line, 19, secs, micros * 1000, entry);
    }
    let mut i = 0;
    while i < n && is_blank(line[i]) {
        i += 1;
    }
    if *line.get(i)? != b'(' {
        return None;
    }
    i += 1;
    let start = i;
    let mut secs: u64 = 0;
    while i < n && line[i].is_ascii_digit() {
        secs = secs
            .wrapping_mul(10)
            .wrapping_add(u64::from(line[i] - b'0'));
        i += 1;
    }
    if i == start || i - start > 19 || *line.get(i)? != b'.' {
        return None;
    }
    i += 1;
    let start = i;
    let mut frac: u32 = 0;
    while i < n && line[i].is_ascii_digit() && i - start < 9 {
        frac = frac * 10 + u32::from(line[i] - b'0');
        i += 1;
    }
    let decimals = i - start;
    if decimals == 0 || *line.get(i)? != b')' {
        return None;
    }
    frac *= POW10[decimals];
    parse_after_time(line, i + 1, secs, frac, entry)
}

/// Eight ASCII digits as a number (SWAR: all eight at once), or `None`.
#[inline]
fn eight_digits(b: &[u8]) -> Option<u32> {
    let v = u64::from_le_bytes(b.get(..8)?.try_into().ok()?);
    let digits = (v & 0xF0F0_F0F0_F0F0_F0F0)
        | (((v.wrapping_add(0x0606_0606_0606_0606)) & 0xF0F0_F0F0_F0F0_F0F0) >> 4);
    if digits != 0x3333_3333_3333_3333 {
        return None;
    }
    let v = v - 0x3030_3030_3030_3030;
    let v = v * 10 + (v >> 8);
    let v = ((v & 0x0000_00FF_0000_00FF).wrapping_mul(100 + (1_000_000 << 32))
        + ((v >> 16) & 0x0000_00FF_0000_00FF).wrapping_mul(1 + (10_000 << 32)))
        >> 32;
    Some(v as u32)
}

/// `(SSSSSSSSSS.UUUUUU) ` exactly (candump's layout): seconds and microseconds.
#[inline]
fn candump_time(line: &[u8]) -> Option<(u64, u32)> {
    if line.len() < 21 || line[0] != b'(' || line[11] != b'.' || line[18] != b')' {
        return None;
    }
    if !is_blank(line[19]) {
        return None;
    }
    let high = eight_digits(&line[1..9])?;
    let (d9, d10) = (line[9].wrapping_sub(b'0'), line[10].wrapping_sub(b'0'));
    if d9 > 9 || d10 > 9 {
        return None;
    }
    let secs = u64::from(high) * 100 + u64::from(d9) * 10 + u64::from(d10);
    let mut micros = 0u32;
    for &b in &line[12..18] {
        let d = b.wrapping_sub(b'0');
        if d > 9 {
            return None;
        }
        micros = micros * 10 + u32::from(d);
    }
    Some((secs, micros))
}

/// The rest of a line after its timestamp, from `i` on.
#[inline]
fn parse_after_time(
    line: &[u8],
    mut i: usize,
    secs: u64,
    frac: u32,
    entry: &mut Message,
) -> Option<()> {
    let n = line.len();
    // interface
    let start = i;
    while i < n && is_blank(line[i]) {
        i += 1;
    }
    if i == start {
        return None;
    }
    // Graphic ASCII up to a space or tab (anything else: the reference parser decides).
    let start = i;
    while i < n && is_graphic(line[i]) {
        i += 1;
    }
    let interface = &line[start..i];
    if interface.is_empty() || (i < n && !is_blank(line[i])) {
        return None;
    }
    // frame
    let start = i;
    while i < n && is_blank(line[i]) {
        i += 1;
    }
    if i == start {
        return None;
    }
    let start = i;
    while i < n && is_graphic(line[i]) {
        i += 1;
    }
    if i < n && !is_blank(line[i]) {
        return None;
    }
    let text = &line[start..i];
    while i < n && is_blank(line[i]) {
        i += 1;
    }
    let direction = if i < n {
        let d = match line[i] {
            b'R' => Direction::Rx,
            b'T' => Direction::Tx,
            _ => return None,
        };
        i += 1;
        while i < n && is_blank(line[i]) {
            i += 1;
        }
        if i != n {
            return None;
        }
        Some(d)
    } else {
        None
    };
    // Classic frames first, stored in place: an FD frame costs them one branch.
    match fast_frame(text) {
        Some(frame) => entry.record = Record::Frame(frame),
        None => entry.record = Record::Fd(fast_fd_frame(text)?),
    }
    entry.at = Timestamp::since_epoch(Duration::new(secs, frac));
    // Mostly the same interface as the line before: then nothing to copy.
    if entry.channel.as_bytes() != interface {
        entry.channel.clear();
        // The interface bytes are ASCII graphic characters (checked above).
        entry
            .channel
            .extend(interface.iter().map(|&b| char::from(b)));
    }
    entry.direction = direction;
    Some(())
}

#[inline]
fn fast_frame(text: &[u8]) -> Option<Frame> {
    // The ID has 3 or 8 digits: the '#' is right after them.
    let hash = match text.get(3) {
        Some(b'#') => 3,
        _ if text.get(8) == Some(&b'#') => 8,
        _ => return None,
    };
    let (id, rest) = (&text[..hash], &text[hash + 1..]);
    let raw = text::hex_u32(id)?;
    let id = match hash {
        3 if raw <= 0x7FF => Id::standard(raw as u16).ok()?,
        8 if raw <= 0x1FFF_FFFF => Id::extended(raw).ok()?,
        _ => return None,
    };
    match rest {
        [b'R' | b'r'] => return Frame::remote(id, 0).ok(),
        [b'R' | b'r', d @ b'0'..=b'8'] => return Frame::remote(id, d - b'0').ok(),
        _ => {}
    }
    if rest.len() % 2 != 0 || rest.len() > 16 {
        return None;
    }
    let mut data = [0u8; 8];
    let mut bad = 0u8;
    for (k, pair) in rest.chunks_exact(2).enumerate() {
        let (hi, lo) = (text::hex_digit(pair[0]), text::hex_digit(pair[1]));
        bad |= hi | lo;
        data[k] = (hi << 4) | (lo & 15);
    }
    if bad > 15 {
        return None;
    }
    Frame::data(id, &data[..rest.len() / 2]).ok()
}

/// `ID##FDATA`: a 3- or 8-digit ID, the flags digit, plain hex data of an FD length.
fn fast_fd_frame(text: &[u8]) -> Option<FdFrame> {
    let hash = match text.get(3..5) {
        Some(b"##") => 3,
        _ if text.get(8..10) == Some(b"##") => 8,
        _ => return None,
    };
    let raw = text::hex_u32(&text[..hash])?;
    let id = match hash {
        3 if raw <= 0x7FF => Id::standard(raw as u16).ok()?,
        8 if raw <= 0x1FFF_FFFF => Id::extended(raw).ok()?,
        _ => return None,
    };
    let (&flags, rest) = text[hash + 2..].split_first()?;
    let flags = text::hex_digit(flags);
    if flags > 15 || rest.len() % 2 != 0 || rest.len() > 2 * FD_MAX_LEN {
        return None;
    }
    let mut data = [0u8; FD_MAX_LEN];
    let mut bad = 0u8;
    for (k, pair) in rest.chunks_exact(2).enumerate() {
        let (hi, lo) = (text::hex_digit(pair[0]), text::hex_digit(pair[1]));
        bad |= hi | lo;
        data[k] = (hi << 4) | (lo & 15);
    }
    if bad > 15 {
        return None;
    }
    let frame = FdFrame::new(id, &data[..rest.len() / 2]).ok()?;
    Some(frame.with_brs(flags & 1 != 0).with_esi(flags & 2 != 0))
}

/// Appends one log line without the newline: `(%010u.%06u) IFACE FRAME` (microseconds, cut
/// as candump does; nanoseconds with `nanos`), then ` R`/` T` if `direction` and the entry has
/// one (candump `-x`).
pub fn write_line(out: &mut Vec<u8>, entry: &Message, direction: bool, nanos: bool) {
    let t = entry.at.since_epoch_duration();
    out.push(b'(');
    text::push_u64_zeros(out, t.as_secs(), 10);
    out.push(b'.');
    if nanos {
        text::push_u64_zeros(out, u64::from(t.subsec_nanos()), 9);
    } else {
        text::push_u64_zeros(out, u64::from(t.subsec_micros()), 6);
    }
    out.extend_from_slice(b") ");
    out.extend_from_slice(entry.channel.as_bytes());
    out.push(b' ');
    push_record(out, &entry.record);
    if direction {
        match entry.direction {
            Some(Direction::Rx) => out.extend_from_slice(b" R"),
            Some(Direction::Tx) => out.extend_from_slice(b" T"),
            None => {}
        }
    }
}

/// A frame or error frame in can-utils syntax (`123#1122`, `12345678#R3`,
/// `20000088#0000020A00000000`: an error frame's class with the error flag, and as many data
/// bytes as it has).
pub(crate) fn push_record(out: &mut Vec<u8>, record: &Record) {
    match record {
        Record::Frame(f) => push_frame(out, f),
        Record::Fd(f) => push_fd_frame(out, f),
        Record::Error(e) => {
            let (class, data) = e.encode();
            text::push_hex(out, ERROR_FLAG | class, 8);
            out.push(b'#');
            for &b in &data[..e.data_len()] {
                text::push_hex_byte(out, b);
            }
        }
    }
}

/// Appends an FD frame in can-utils syntax: `123##1112233` (the flags nibble: BRS = 1,
/// ESI = 2): the text of [`FdFrame`]'s `Display`.
pub fn push_fd_frame(out: &mut Vec<u8>, f: &FdFrame) {
    match f.id() {
        Id::Standard(id) => out.extend_from_slice(&text::hex_fixed::<3>(u32::from(id.as_raw()))),
        Id::Extended(id) => out.extend_from_slice(&text::hex_fixed::<8>(id.as_raw())),
    }
    out.extend_from_slice(b"##");
    out.push(b"0123456789ABCDEF"[usize::from(f.flags())]);
    for &b in f.payload() {
        out.extend_from_slice(&text::hex_pair(b));
    }
}

/// Appends a frame in can-utils syntax (`123#1122`, `12345678#R3`): the text of
/// [`Frame`]'s `Display`, built on the stack and copied once.
pub fn push_frame(out: &mut Vec<u8>, f: &Frame) {
    // 8 ID digits, `#`, 16 data digits.
    let mut buf = [0u8; 25];
    let mut n = match f.id() {
        Id::Standard(id) => {
            buf[..3].copy_from_slice(&text::hex_fixed::<3>(u32::from(id.as_raw())));
            3
        }
        Id::Extended(id) => {
            buf[..8].copy_from_slice(&text::hex_fixed::<8>(id.as_raw()));
            8
        }
    };
    buf[n] = b'#';
    n += 1;
    if f.is_remote() {
        buf[n] = b'R';
        n += 1;
        if f.dlc() > 0 {
            buf[n] = b'0' + f.dlc();
            n += 1;
        }
    } else {
        for &b in f.payload() {
            buf[n..n + 2].copy_from_slice(&text::hex_pair(b));
            n += 2;
        }
    }
    out.extend_from_slice(&buf[..n]);
}

/// One log line without the newline; the direction (` R`/` T`) only if `direction` is set
/// and the entry has one (candump `-x`).
pub fn format_line(entry: &Message, direction: bool) -> String {
    let mut out = Vec::with_capacity(64);
    write_line(&mut out, entry, direction, false);
    String::from_utf8_lossy(&out).into_owned()
}

/// Reads a candump log line by line. Like canplayer it skips lines that do not start with
/// `(` (blank lines, `DROPCOUNT: …` notes) and counts them; a bad line is an error naming
/// its number, after which reading goes on with the next line.
pub struct Reader<R> {
    lines: Lines<R>,
    skipped: u64,
}

impl<R: BufRead> Reader<R> {
    pub fn new(input: R) -> Self {
        Self {
            lines: Lines::new(input),
            skipped: 0,
        }
    }

    /// Lines skipped so far because they do not start with `(`.
    pub fn skipped(&self) -> u64 {
        self.skipped
    }

    /// Reads the next entry into `entry`; `Ok(false)` at the end.
    pub fn read_into(&mut self, entry: &mut Message) -> Result<bool, ReadError> {
        loop {
            let step = self.lines.next(|number, line| {
                let at = Location::Line(number);
                let line = match line {
                    Ok(line) => line,
                    Err(TooLong) => return Some(Err(ReadError::bad(at, LineError::TooLong))),
                };
                let first = line.iter().position(|b| !b.is_ascii_whitespace());
                if first.is_none_or(|i| line[i] != b'(') {
                    if std::str::from_utf8(line).is_err() {
                        return Some(Err(ReadError::bad(at, LineError::NotText)));
                    }
                    return None;
                }
                Some(parse_line_into(line, entry).map_err(|e| ReadError::bad(at, e)))
            })?;
            match step {
                None => return Ok(false),
                Some(None) => self.skipped += 1,
                Some(Some(result)) => return result.map(|()| true),
            }
        }
    }
}

impl<R: BufRead + Send> LogReader for Reader<R> {
    fn read_into(&mut self, entry: &mut Message) -> Result<bool, ReadError> {
        Reader::read_into(self, entry)
    }
}

impl<R: BufRead> Iterator for Reader<R> {
    type Item = Result<Message, ReadError>;

    fn next(&mut self) -> Option<Self::Item> {
        let mut entry = Message::default();
        match self.read_into(&mut entry) {
            Ok(true) => Some(Ok(entry)),
            Ok(false) => None,
            Err(e) => Some(Err(e)),
        }
    }
}

/// Writes candump log lines.
pub struct Writer<W> {
    out: W,
    direction: bool,
    nanos: bool,
    line: Vec<u8>,
}

impl<W: Write> Writer<W> {
    pub fn new(out: W) -> Self {
        Self {
            out,
            direction: false,
            nanos: false,
            line: Vec::with_capacity(128),
        }
    }

    /// Also write ` R`/` T` after each frame (candump `-x`).
    pub fn with_direction(mut self, on: bool) -> Self {
        self.direction = on;
        self
    }

    /// Nine decimals (nanoseconds, candump `-N`) instead of six.
    pub fn with_nanos(mut self, on: bool) -> Self {
        self.nanos = on;
        self
    }

    pub fn write(&mut self, entry: &Message) -> io::Result<()> {
        self.line.clear();
        write_line(&mut self.line, entry, self.direction, self.nanos);
        self.line.push(b'\n');
        self.out.write_all(&self.line)
    }

    pub fn flush(&mut self) -> io::Result<()> {
        self.out.flush()
    }

    pub fn into_inner(self) -> W {
        self.out
    }
}

impl<W: Write + Send> Encoder<W> for Writer<W> {
    fn write(&mut self, entry: &Message) -> io::Result<()> {
        Writer::write(self, entry)
    }
    fn flush(&mut self) -> io::Result<()> {
        Writer::flush(self)
    }
    fn finish(mut self) -> io::Result<W> {
        self.out.flush()?;
        Ok(self.out)
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
    pub fn with_zero(mut self, zero: Timestamp) -> Self {
        self.first = Some(zero.since_epoch_duration());
        self
    }

    /// One entry's text without the final newline (with `-e` an error frame takes several
    /// lines).
    pub fn line(&mut self, entry: &Message) -> String {
        let mut out = Vec::with_capacity(80);
        self.write_line(&mut out, entry);
        String::from_utf8_lossy(&out).into_owned()
    }

    /// Appends [`Self::line`]'s text to `out`, without allocating.
    pub fn write_line(&mut self, out: &mut Vec<u8>, entry: &Message) {
        out.push(b' ');
        if let Some(mode) = self.view.timestamps {
            self.timestamp(out, mode, entry.at.since_epoch_duration());
        }
        out.push(b' ');
        out.extend_from_slice(entry.channel.as_bytes());
        if self.view.extra {
            out.extend_from_slice(match entry.direction {
                Some(Direction::Tx) => b"  TX - -",
                _ => b"  RX - -",
            });
        }
        out.extend_from_slice(b"  ");
        match &entry.record {
            Record::Frame(frame) => self.frame(out, frame),
            Record::Fd(frame) => self.fd_frame(out, frame),
            Record::Error(e) => {
                let (class, data) = e.encode();
                let len = e.data_len();
                text::push_hex(out, ERROR_FLAG | class, 8);
                out.extend_from_slice(b"   [");
                text::push_u64(out, len as u64);
                out.extend_from_slice(b"] ");
                text::push_spaced_hex(out, &data[..len]);
                out.extend_from_slice(b"   ERRORFRAME");
                if self.view.error_words {
                    out.extend_from_slice(b"\n\t");
                    out.extend_from_slice(e.describe("\n\t").as_bytes());
                }
            }
        }
    }

    fn timestamp(&mut self, out: &mut Vec<u8>, mode: TimestampMode, t: Duration) {
        let (shown, width) = match mode {
            TimestampMode::Absolute => (t, 10),
            TimestampMode::Delta => {
                let since = t.saturating_sub(self.last.unwrap_or(t));
                self.last = Some(t);
                (since, 3)
            }
            TimestampMode::Zero => (t.saturating_sub(*self.first.get_or_insert(t)), 3),
        };
        out.push(b'(');
        text::push_u64_zeros(out, shown.as_secs(), width);
        out.push(b'.');
        text::push_u64_zeros(out, u64::from(shown.subsec_micros()), 6);
        out.extend_from_slice(b") ");
    }

    /// candump's FD line: the length in two digits (`[03]`, `[64]`), the bytes.
    fn fd_frame(&mut self, out: &mut Vec<u8>, frame: &FdFrame) {
        self.id(out, frame.id());
        let payload = frame.payload();
        out.extend_from_slice(b"  [");
        text::push_u64_zeros(out, payload.len() as u64, 2);
        out.extend_from_slice(b"] ");
        text::push_spaced_hex(out, payload);
    }

    fn id(&mut self, out: &mut Vec<u8>, id: Id) {
        self.extended_seen |= id.is_extended();
        match id {
            Id::Extended(id) => out.extend_from_slice(&text::hex_fixed::<8>(id.as_raw())),
            Id::Standard(id) => {
                if self.extended_seen {
                    out.extend_from_slice(b"     ");
                }
                out.extend_from_slice(&text::hex_fixed::<3>(u32::from(id.as_raw())));
            }
        }
    }

    fn frame(&mut self, out: &mut Vec<u8>, frame: &Frame) {
        self.id(out, frame.id());
        out.extend_from_slice(b"   [");
        out.push(b'0' + frame.dlc());
        out.extend_from_slice(b"] ");
        if frame.is_remote() {
            out.extend_from_slice(b" remote request");
            return;
        }
        let payload = frame.payload();
        text::push_spaced_hex(out, payload);
        if self.view.ascii {
            // At a fixed column after the bytes, as candump puts it.
            let pad = 3 * (8 - payload.len()) + 3;
            out.extend_from_slice(&b"                           "[..pad]);
            out.push(b'\'');
            out.extend(
                payload
                    .iter()
                    .map(|&b| if (0x20..0x7F).contains(&b) { b } else { b'.' }),
            );
            out.push(b'\'');
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::collection::vec;
    use proptest::prelude::*;

    fn entry(frame: &str, t: f64) -> Message {
        Message {
            at: Timestamp::from_secs_f64(t),
            channel: "vcan0".into(),
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

    /// The terminal layout as it was written before it was made allocation-free (with
    /// `format!`), kept as the reference the fast writer must match byte for byte.
    #[derive(Default)]
    struct Reference {
        view: View,
        extended_seen: bool,
        first: Option<Duration>,
        last: Option<Duration>,
    }

    impl Reference {
        fn line(&mut self, entry: &Message) -> String {
            use std::fmt::Write as _;
            let mut out = String::from(" ");
            if let Some(mode) = self.view.timestamps {
                let t = entry.at.since_epoch_duration();
                let shown = match mode {
                    TimestampMode::Absolute => None,
                    TimestampMode::Delta => {
                        let since = t.saturating_sub(self.last.unwrap_or(t));
                        self.last = Some(t);
                        Some(since)
                    }
                    TimestampMode::Zero => Some(t.saturating_sub(*self.first.get_or_insert(t))),
                };
                match shown {
                    None => write!(out, "({:010}.{:06}) ", t.as_secs(), t.subsec_micros()),
                    Some(d) => write!(out, "({:03}.{:06}) ", d.as_secs(), d.subsec_micros()),
                }
                .unwrap();
            }
            out.push(' ');
            out.push_str(&entry.channel);
            if self.view.extra {
                out.push_str(match entry.direction {
                    Some(Direction::Tx) => "  TX - -",
                    _ => "  RX - -",
                });
            }
            out.push_str("  ");
            match &entry.record {
                Record::Frame(frame) => {
                    self.extended_seen |= frame.is_extended();
                    let id = frame.id().to_string();
                    if self.extended_seen && !frame.is_extended() {
                        write!(out, "{id:>8}").unwrap();
                    } else {
                        out.push_str(&id);
                    }
                    write!(out, "   [{}] ", frame.dlc()).unwrap();
                    if frame.is_remote() {
                        out.push_str(" remote request");
                        return out;
                    }
                    for b in frame.payload() {
                        write!(out, " {b:02X}").unwrap();
                    }
                    if self.view.ascii {
                        let width = 3 * (8 - frame.payload().len()) + 4;
                        write!(out, "{:>width$}", "'").unwrap();
                        for &b in frame.payload() {
                            let printable = (0x20..0x7F).contains(&b);
                            out.push(if printable { b as char } else { '.' });
                        }
                        out.push('\'');
                    }
                }
                Record::Fd(frame) => {
                    self.extended_seen |= frame.is_extended();
                    let id = frame.id().to_string();
                    if self.extended_seen && !frame.is_extended() {
                        write!(out, "{id:>8}").unwrap();
                    } else {
                        out.push_str(&id);
                    }
                    write!(out, "  [{:02}] ", frame.payload().len()).unwrap();
                    for b in frame.payload() {
                        write!(out, " {b:02X}").unwrap();
                    }
                }
                Record::Error(e) => {
                    let (class, data) = e.encode();
                    let len = e.data_len();
                    write!(out, "{:08X}   [{len}] ", ERROR_FLAG | class).unwrap();
                    for b in &data[..len] {
                        write!(out, " {b:02X}").unwrap();
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
    }

    fn any_frame() -> impl Strategy<Value = Frame> {
        let id = prop_oneof![
            (0u16..=0x7FF).prop_map(|v| Id::standard(v).unwrap()),
            (0u32..=0x1FFF_FFFF).prop_map(|v| Id::extended(v).unwrap()),
        ];
        (id, any::<bool>(), vec(any::<u8>(), 0..=8), 0u8..=8).prop_map(|(id, remote, data, dlc)| {
            if remote {
                Frame::remote(id, dlc).unwrap()
            } else {
                Frame::data(id, &data).unwrap()
            }
        })
    }

    fn any_entry() -> impl Strategy<Value = Message> {
        let fd = (
            any_frame(),
            prop::sample::select(buslab_can::FD_LENGTHS.to_vec()),
            vec(any::<u8>(), 64),
            any::<bool>(),
            any::<bool>(),
        )
            .prop_map(|(f, len, data, brs, esi)| {
                let fd = FdFrame::new(f.id(), &data[..len]).unwrap();
                Record::Fd(fd.with_brs(brs).with_esi(esi))
            });
        let record = prop_oneof![
            4 => any_frame().prop_map(Record::Frame),
            1 => fd,
            1 => (prop_oneof![0u32..=0x3FF, 0u32..=0x1FFF_FFFF], vec(any::<u8>(), 0..=8))
                .prop_map(|(class, data)| Record::Error(ErrorFrame::decode(class, &data).unwrap())),
        ];
        let direction = prop_oneof![
            Just(None),
            Just(Some(Direction::Rx)),
            Just(Some(Direction::Tx))
        ];
        (
            0u64..20_000_000_000,
            0u32..1_000_000_000,
            "[a-z0-9]{1,8}",
            record,
            direction,
        )
            .prop_map(|(secs, nanos, channel, record, direction)| Message {
                at: Timestamp::since_epoch(Duration::new(secs, nanos)),
                channel,
                record,
                direction,
            })
    }

    proptest! {
        /// The terminal lines are the reference's, byte for byte, in every view, over runs of
        /// entries (the `-t d`/`-t z` and extended-ID state carries from line to line).
        #[test]
        fn terminal_lines_are_the_references(
            entries in vec(any_entry(), 1..12),
            mode in prop_oneof![
                Just(None),
                Just(Some(TimestampMode::Absolute)),
                Just(Some(TimestampMode::Delta)),
                Just(Some(TimestampMode::Zero)),
            ],
            ascii in any::<bool>(),
            extra in any::<bool>(),
            error_words in any::<bool>(),
        ) {
            let view = View { timestamps: mode, ascii, extra, error_words };
            let mut fast = Terminal::new(view);
            let mut reference = Reference { view, ..Reference::default() };
            for e in &entries {
                prop_assert_eq!(fast.line(e), reference.line(e));
            }
        }

        /// A frame's log text is its `Display` (can-utils' compact syntax).
        #[test]
        fn pushed_fd_frames_are_their_display(e in any_entry()) {
            if let Record::Fd(f) = e.record {
                let mut out = Vec::new();
                push_fd_frame(&mut out, &f);
                prop_assert_eq!(String::from_utf8(out).unwrap(), f.to_string());
            }
        }

        /// A frame's log text is its `Display` (can-utils' compact syntax).
        #[test]
        fn pushed_frames_are_their_display(f in any_frame()) {
            let mut out = Vec::new();
            push_frame(&mut out, &f);
            prop_assert_eq!(String::from_utf8(out).unwrap(), f.to_string());
        }

        /// An entry's log line reads back as the entry (microseconds), FD frames included.
        #[test]
        fn written_lines_read_back(e in any_entry()) {
            let line = format_line(&e, true);
            let mut fast = Message::default();
            parse_line_into(line.as_bytes(), &mut fast).unwrap();
            let mut want = e.clone();
            want.at = Timestamp::from_micros(e.at.since_epoch_duration().as_micros() as u64);
            prop_assert_eq!(fast, want);
        }
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
        .with_zero(Timestamp::from_secs_f64(9.5));
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
        let e = Message {
            at: Timestamp::since_epoch(Duration::ZERO),
            channel: "vcan0".into(),
            // Linux's frame for a bus error without details (CAN_ERR_DLC: 8 bytes).
            record: Record::Error(ErrorFrame::decode(0x088, &[0; 8]).unwrap()),
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
        // A frame of fewer bytes shows them, as candump shows a frame's length.
        let short = Message {
            record: Record::Error(ErrorFrame::decode(0x004, &[0, 0x04]).unwrap()),
            ..e
        };
        assert_eq!(
            Terminal::default().line(&short),
            "  vcan0  20000004   [2]  00 04   ERRORFRAME"
        );
        assert_eq!(
            format_line(&short, false),
            "(0000000000.000000) vcan0 20000004#0004"
        );
    }
}
