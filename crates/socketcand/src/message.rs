//! Server → client: greetings, acknowledgements, frames, errors, and buslab's replies.

use core::fmt;

use buslab_can::{Frame, Id};

#[cfg(test)]
use crate::command::IdText;
use crate::command::parse_id;
use crate::hex::{HEX, NOT_HEX, fast_id, hex_digit};
use crate::{ProtocolError, tokens};

pub use buslab_can::Timestamp;

/// A frame time as socketcand writes it: seconds and 1..6 digits of microseconds
/// (`23.424242`; `1.5` is 1.500000 s).
pub fn parse_timestamp(text: &str) -> Result<Timestamp, ProtocolError> {
    let bad = || ProtocolError::BadTimestamp {
        text: text.to_string(),
    };
    let (s, us) = text.split_once('.').ok_or_else(bad)?;
    let digits = |t: &str| !t.is_empty() && t.bytes().all(|b| b.is_ascii_digit());
    if !digits(s) || !digits(us) || us.len() > 6 {
        return Err(bad());
    }
    let secs = s.parse().map_err(|_| bad())?;
    // At most 6 digits (checked above).
    let micros = us.parse::<u32>().map_err(|_| bad())? * 10u32.pow(6 - us.len() as u32);
    Ok(Timestamp::from_secs_micros(secs, micros))
}

/// One server message.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum ServerMessage {
    /// `< hi >`: the greeting.
    Hi,
    /// `< ok >`: a command was accepted.
    Ok,
    /// `< echo >`: the answer to `< echo >`.
    Echo,
    /// `< frame ID SEC.USEC DATA >`: a frame seen on the bus (raw mode: packed data; the BCM
    /// layout with one byte per token is read too). With buslab's extensions a remote frame
    /// reads `< frame ID SEC.USEC R<dlc> >`.
    Frame { frame: Frame, timestamp: Timestamp },
    /// `< error CLASS SEC.USEC [DD …] >`: an error frame.
    ErrorFrame {
        class: u32,
        timestamp: Timestamp,
        data: Vec<u8>,
    },
    /// `< error TEXT >`: a command failed.
    Error(String),
    /// `< stat RBYTES RPACKETS TBYTES TPACKETS >`.
    Stat([u64; 4]),
    /// A buslab reply (`buslab_status`, `buslab_regs`, `buslab_nodes`) or any other element:
    /// its name and tokens.
    Other { name: String, args: Vec<String> },
}

impl ServerMessage {
    /// A frame message for the bus's frame.
    pub fn frame(frame: Frame, timestamp: Timestamp) -> Self {
        ServerMessage::Frame { frame, timestamp }
    }

    /// Parses an element's inside.
    pub fn parse(inner: &str) -> Result<Self, ProtocolError> {
        // Every frame a client receives, without allocating; the rest token by token.
        match parse_frame_fast(inner.as_bytes()) {
            Some((frame, timestamp)) => Ok(ServerMessage::Frame { frame, timestamp }),
            None => Self::parse_tokens(inner),
        }
    }

    /// [`Self::parse`] for any message, from its tokens.
    fn parse_tokens(inner: &str) -> Result<Self, ProtocolError> {
        let t = tokens(inner);
        let (&name, args) = t.split_first().ok_or(ProtocolError::Empty)?;
        match (name, args) {
            ("hi", []) => Ok(ServerMessage::Hi),
            ("ok", []) => Ok(ServerMessage::Ok),
            ("echo", []) => Ok(ServerMessage::Echo),
            ("frame", [id, ts, data @ ..]) => {
                let id = parse_id(id)?;
                let timestamp = parse_timestamp(ts)?;
                let frame = match data {
                    [r] if r.starts_with(['R', 'r']) => {
                        let dlc: u8 = r[1..].parse().map_err(|_| ProtocolError::BadDlc {
                            text: r.to_string(),
                        })?;
                        Frame::remote(id, dlc).map_err(|_| ProtocolError::BadDlc {
                            text: r.to_string(),
                        })?
                    }
                    _ => {
                        let bytes = parse_data(data)?;
                        Frame::data(id, &bytes).map_err(|_| ProtocolError::DataLength {
                            count: bytes.len(),
                            dlc: 8,
                        })?
                    }
                };
                Ok(ServerMessage::Frame { frame, timestamp })
            }
            ("frame", _) => Err(ProtocolError::Arguments {
                command: "frame",
                expected: "ID SEC.USEC DATA",
                got: args.join(" "),
            }),
            ("error", [class, ts, data @ ..])
                if parse_timestamp(ts).is_ok()
                    && u32::from_str_radix(class, 16).is_ok()
                    && !class.starts_with('+') =>
            {
                Ok(ServerMessage::ErrorFrame {
                    class: u32::from_str_radix(class, 16).unwrap_or(0) & 0x1FFF_FFFF,
                    timestamp: parse_timestamp(ts)?,
                    data: parse_data(data)?,
                })
            }
            ("error", _) => Ok(ServerMessage::Error(error_text(args))),
            ("stat", [a, b, c, d]) => {
                let mut v = [0u64; 4];
                for (slot, text) in v.iter_mut().zip([a, b, c, d]) {
                    *slot = text.parse().map_err(|_| ProtocolError::Arguments {
                        command: "stat",
                        expected: "four decimal counters",
                        got: args.join(" "),
                    })?;
                }
                Ok(ServerMessage::Stat(v))
            }
            _ => Ok(ServerMessage::Other {
                name: name.to_string(),
                args: args.iter().map(|s| s.to_string()).collect(),
            }),
        }
    }
}

/// A frame element's inside exactly as servers write every frame (` frame ID SECS.USECS DATA `:
/// one space around each field, data packed hex of at most 8 bytes, or none), read from the
/// bytes without allocating. `None` for anything else, even a frame in another layout or a bad
/// one: [`ServerMessage::parse`] reads those (and names what is wrong). What this accepts,
/// `parse` reads the same (tests compare them).
pub(crate) fn parse_frame_fast(inner: &[u8]) -> Option<(Frame, Timestamp)> {
    let fields = inner.strip_prefix(b" frame ")?.strip_suffix(b" ")?;
    let (id, fields) = split_at_space(fields)?;
    let (time, data) = split_at_space(fields)?;
    let id = fast_id(id)?;
    let timestamp = fast_timestamp(time)?;
    let mut bytes = [0u8; 8];
    let len = fast_data(data, &mut bytes)?;
    Some((Frame::data(id, &bytes[..len]).ok()?, timestamp))
}

/// What comes before the first space and what after it.
fn split_at_space(text: &[u8]) -> Option<(&[u8], &[u8])> {
    let space = text.iter().position(|&b| b == b' ')?;
    Some((&text[..space], &text[space + 1..]))
}

/// Decimal digits as a u64 (`None` for anything else, or beyond u64).
fn decimal(text: &[u8]) -> Option<u64> {
    if text.is_empty() {
        return None;
    }
    if text.len() > 19 {
        // Might not fit: checked digit by digit.
        return text.iter().try_fold(0u64, |value, &b| {
            let digit = b.is_ascii_digit().then(|| u64::from(b - b'0'))?;
            value.checked_mul(10)?.checked_add(digit)
        });
    }
    // 19 digits always fit.
    let (value, bad) = text.iter().fold((0u64, false), |(value, bad), &b| {
        let digit = b.wrapping_sub(b'0');
        // (Wrapping: a value with a bad digit is dropped anyway.)
        let value = value.wrapping_mul(10).wrapping_add(u64::from(digit));
        (value, bad | (digit > 9))
    });
    (!bad).then_some(value)
}

/// `SECS.USECS` as [`parse_timestamp`] reads it (1..6 digits of microseconds).
fn fast_timestamp(text: &[u8]) -> Option<Timestamp> {
    let dot = text.iter().position(|&b| b == b'.')?;
    let (secs, micros) = (&text[..dot], &text[dot + 1..]);
    if micros.len() > 6 {
        return None;
    }
    let secs = decimal(secs)?;
    // At most 6 digits: fits, and "1.5" means 1.500000 s.
    let micros = decimal(micros)? as u32 * 10u32.pow(6 - micros.len() as u32);
    Some(Timestamp::from_secs_micros(secs, micros))
}

/// Packed hex data (pairs of digits, at most 8 bytes, or none) into `out`; the bytes written.
fn fast_data(text: &[u8], out: &mut [u8; 8]) -> Option<usize> {
    if !text.len().is_multiple_of(2) || text.len() > 16 {
        return None;
    }
    let mut bad = 0;
    for (slot, pair) in out.iter_mut().zip(text.chunks_exact(2)) {
        let (high, low) = (HEX[usize::from(pair[0])], HEX[usize::from(pair[1])]);
        *slot = (high << 4) | (low & 15);
        bad |= high | low;
    }
    (bad & NOT_HEX == 0).then_some(text.len() / 2)
}

/// A server's error text as the user will see it: control characters (a terminal escape sent
/// by a hostile server) and what an element cannot carry replaced, spaces collapsed, so it
/// also prints as it was read.
fn error_text(args: &[&str]) -> String {
    let text = crate::sanitize(&args.join(" "));
    text.split_ascii_whitespace().collect::<Vec<_>>().join(" ")
}

/// Data as packed hex (`1A2203`) or one byte per token (`1A 22 03`).
fn parse_data(tokens: &[&str]) -> Result<Vec<u8>, ProtocolError> {
    let mut out = Vec::with_capacity(8);
    for t in tokens {
        if t.len() % 2 != 0 && tokens.len() == 1 {
            return Err(ProtocolError::BadHex {
                what: "data",
                text: t.to_string(),
            });
        }
        if tokens.len() > 1 && t.len() > 2 {
            return Err(ProtocolError::BadByte {
                text: t.to_string(),
            });
        }
        if !t.bytes().all(|b| b.is_ascii_hexdigit()) {
            return Err(ProtocolError::BadHex {
                what: "data",
                text: t.to_string(),
            });
        }
        if tokens.len() == 1 {
            // Pairs of hex digits (both checked above): every frame a client receives.
            for pair in t.as_bytes().chunks_exact(2) {
                out.push((hex_digit(pair[0]) << 4) | hex_digit(pair[1]));
            }
        } else {
            out.push(
                u8::from_str_radix(t, 16).map_err(|_| ProtocolError::BadByte {
                    text: t.to_string(),
                })?,
            );
        }
    }
    if out.len() > 8 {
        return Err(ProtocolError::DataLength {
            count: out.len(),
            dlc: 8,
        });
    }
    Ok(out)
}

/// Writes a frame in raw-mode layout; remote frames as `R<dlc>` if `remote_as_r`, else with
/// no data (python-can cannot represent them; socketcand drops them).
///
/// By hand into a buffer on the stack and appended at once, not through `write!`: a frame
/// line is formatted for every frame a bus delivers (`write!` with its formatter took about
/// 1 300 instructions a line; `format_frame_is_what_write_gives` pins the layout).
pub fn format_frame(
    out: &mut String,
    frame: &Frame,
    timestamp: Timestamp,
    remote_as_r: bool,
) -> fmt::Result {
    let mut line = Line::default();
    line.push(b"< frame ");
    // socketcand's ID text: `%03X` standard, `%08X` extended (the IDs fit those widths).
    match frame.id() {
        Id::Standard(id) => line.hex(u32::from(id.as_raw()), 3),
        Id::Extended(id) => line.hex(id.as_raw(), 8),
    }
    line.push(b" ");
    // Seconds with six decimals, truncated as candump prints them (see `Timestamp`).
    let (secs, micros) = timestamp.secs_and_micros();
    line.decimal(secs, 1);
    line.push(b".");
    line.decimal(u64::from(micros), 6);
    line.push(b" ");
    // Empty data still leaves the data field: `< frame 123 1.000000  >`, as socketcand
    // writes it and python-can splits it (it needs the third field, even empty).
    if frame.is_remote() {
        if remote_as_r {
            line.push(b"R");
            line.decimal(u64::from(frame.dlc()), 1);
        }
    } else {
        line.hex_bytes(frame.payload());
    }
    line.push(b" >");
    out.push_str(line.as_str());
    Ok(())
}

const HEX_DIGITS: &[u8; 16] = b"0123456789ABCDEF";

/// `00` to `99`: two decimal digits in one load.
static DEC_PAIRS: [[u8; 2]; 100] = {
    let mut table = [[0u8; 2]; 100];
    let mut i = 0;
    while i < 100 {
        table[i] = [b'0' + (i / 10) as u8, b'0' + (i % 10) as u8];
        i += 1;
    }
    table
};

/// `00` to `FF`: a byte's two hex digits in one load.
static HEX_PAIRS: [[u8; 2]; 256] = {
    let mut table = [[0u8; 2]; 256];
    let mut i = 0;
    while i < 256 {
        table[i] = [HEX_DIGITS[i >> 4], HEX_DIGITS[i & 15]];
        i += 1;
    }
    table
};

/// The longest frame line: `< frame `, 8 ID digits, a space, 20 digits of seconds, a point,
/// 6 digits, a space, 16 data digits, ` >` (63 bytes).
const LONGEST_FRAME_LINE: usize = 64;

/// A frame line being written: ASCII only, never longer than [`LONGEST_FRAME_LINE`].
struct Line {
    bytes: [u8; LONGEST_FRAME_LINE],
    len: usize,
}

impl Default for Line {
    fn default() -> Self {
        Self {
            bytes: [0; LONGEST_FRAME_LINE],
            len: 0,
        }
    }
}

impl Line {
    /// `text` at once (one look at the room left, one copy).
    #[inline(always)]
    fn push(&mut self, text: &[u8]) {
        if let Some(room) = self.bytes.get_mut(self.len..self.len + text.len()) {
            room.copy_from_slice(text);
            self.len += text.len();
        }
    }

    /// The low `width` hex digits of `value`, upper case (the widths fit the values: 3
    /// digits for a standard ID, 8 for an extended one).
    #[inline(always)]
    fn hex(&mut self, value: u32, width: usize) {
        let mut digits = [0u8; 8];
        for (k, digit) in digits.iter_mut().rev().enumerate() {
            *digit = HEX_DIGITS[((value >> (4 * k)) & 15) as usize];
        }
        self.push(&digits[8 - width.min(8)..]);
    }

    /// Each byte as two upper-case hex digits (up to 8 bytes: a classic frame's data).
    #[inline(always)]
    fn hex_bytes(&mut self, bytes: &[u8]) {
        let mut digits = [0u8; 16];
        for (pair, &b) in digits.chunks_exact_mut(2).zip(bytes) {
            pair.copy_from_slice(&HEX_PAIRS[usize::from(b)]);
        }
        self.push(&digits[..2 * bytes.len().min(8)]);
    }

    /// `value` in decimal, at least `width` digits (zero-padded, up to 20).
    fn decimal(&mut self, value: u64, width: usize) {
        // Two digits a step (a Unix time's seconds have ten).
        let mut digits = [b'0'; 20];
        let mut start = digits.len();
        let mut rest = value;
        while rest >= 10 {
            start -= 2;
            digits[start..start + 2].copy_from_slice(&DEC_PAIRS[(rest % 100) as usize]);
            rest /= 100;
        }
        if rest > 0 {
            start -= 1;
            digits[start] = b'0' + rest as u8;
        }
        self.push(&digits[start.min(20 - width.min(20))..]);
    }

    fn as_str(&self) -> &str {
        // Only ASCII digits and the layout's ASCII are pushed.
        std::str::from_utf8(&self.bytes[..self.len]).unwrap_or_default()
    }
}

/// A frame from the bus formatted once in raw-mode layout, for every session that delivers it
/// ([`crate::server::Session::deliver_formatted`]): a bus with many clients formats each frame
/// once rather than once per client.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FormattedFrame {
    /// As every client gets it (a remote frame without data).
    plain: String,
    /// A remote frame as `R<dlc>` for clients with buslab's extensions.
    remote_as_r: Option<String>,
}

impl FormattedFrame {
    pub fn new(frame: &Frame, timestamp: Timestamp) -> Self {
        let format = |remote_as_r| {
            let mut text = String::with_capacity(LONGEST_FRAME_LINE);
            let _ = format_frame(&mut text, frame, timestamp, remote_as_r);
            text
        };
        Self {
            plain: format(false),
            remote_as_r: frame.is_remote().then(|| format(true)),
        }
    }

    /// The text for a client that asked for remote frames as `R<dlc>`, or not.
    pub fn text(&self, remote_as_r: bool) -> &str {
        match (&self.remote_as_r, remote_as_r) {
            (Some(r), true) => r,
            _ => &self.plain,
        }
    }
}

/// The element as a server sends it (raw layout; remote frames in buslab's `R<dlc>` form).
impl fmt::Display for ServerMessage {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ServerMessage::Hi => f.write_str("< hi >"),
            ServerMessage::Ok => f.write_str("< ok >"),
            ServerMessage::Echo => f.write_str("< echo >"),
            ServerMessage::Frame { frame, timestamp } => {
                let mut s = String::new();
                format_frame(&mut s, frame, *timestamp, true)?;
                f.write_str(&s)
            }
            ServerMessage::ErrorFrame {
                class,
                timestamp,
                data,
            } => {
                write!(f, "< error {class:03X} {timestamp}")?;
                for b in data {
                    write!(f, " {b:02X}")?;
                }
                f.write_str(" >")
            }
            ServerMessage::Error(text) => write!(f, "< error {} >", crate::sanitize(text)),
            ServerMessage::Stat([a, b, c, d]) => write!(f, "< stat {a} {b} {c} {d} >"),
            ServerMessage::Other { name, args } => {
                write!(f, "< {name}")?;
                for a in args {
                    write!(f, " {a}")?;
                }
                f.write_str(" >")
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use proptest::prelude::*;

    use super::*;

    /// Element insides near the frame layout: names, IDs, times and data slightly off.
    fn frame_like() -> impl Strategy<Value = String> {
        let name = prop_oneof!["frame", "fram", "frames", "Frame", "error"];
        let space = "[ \t\n\r\x0b\x0c]{1,2}";
        let id = "[0-9a-fA-F+gR -]{0,10}";
        let time = "[0-9.+-]{0,24}";
        let data = "[0-9a-fA-FRrxé <]{0,20}";
        (
            space,
            name,
            "[ \t]{1,2}",
            id,
            " {1,2}",
            time,
            " {0,2}",
            data,
            space,
        )
            .prop_map(|(a, name, b, id, c, time, d, data, e)| {
                format!("{a}{name}{b}{id}{c}{time}{d}{data}{e}")
            })
    }

    proptest! {
        /// What the fast path reads, the general parser reads the same; it never refuses
        /// for the general parser.
        #[test]
        fn the_fast_frame_path_reads_as_the_tokens_do(inner in frame_like()) {
            if let Some((frame, timestamp)) = parse_frame_fast(inner.as_bytes()) {
                prop_assert_eq!(
                    ServerMessage::parse_tokens(&inner),
                    Ok(ServerMessage::Frame { frame, timestamp })
                );
            }
            prop_assert_eq!(ServerMessage::parse(&inner), ServerMessage::parse_tokens(&inner));
        }

        #[test]
        fn any_text_parses_as_the_tokens_do(inner in "\\PC{0,40}") {
            prop_assert_eq!(ServerMessage::parse(&inner), ServerMessage::parse_tokens(&inner));
        }

        /// Every data frame a server writes takes the fast path.
        #[test]
        fn served_data_frames_take_the_fast_path(
            raw in 0u32..0x2000_0000,
            extended: bool,
            data in prop::collection::vec(any::<u8>(), 0..=8),
            secs: u64,
            micros in 0u32..1_000_000,
        ) {
            let id = if extended {
                Id::extended(raw).unwrap()
            } else {
                Id::standard((raw & 0x7FF) as u16).unwrap()
            };
            let frame = Frame::data(id, &data).unwrap();
            let timestamp = Timestamp::from_secs_micros(secs, micros);
            let text = FormattedFrame::new(&frame, timestamp).text(true).to_string();
            let inner = &text[1..text.len() - 1];
            prop_assert_eq!(parse_frame_fast(inner.as_bytes()), Some((frame, timestamp)));
        }

        /// The line written by hand is the one `write!` gives with socketcand's widths
        /// (`%03X`/`%08X`, seconds, six decimals, upper-case data, `R<dlc>` or nothing).
        #[test]
        fn format_frame_is_what_write_gives(
            raw in 0u32..0x2000_0000,
            extended: bool,
            remote: bool,
            remote_as_r: bool,
            data in prop::collection::vec(any::<u8>(), 0..=8),
            dlc in 0u8..=15,
            secs: u64,
            micros in 0u32..1_000_000,
        ) {
            let id = if extended {
                Id::extended(raw).unwrap()
            } else {
                Id::standard((raw & 0x7FF) as u16).unwrap()
            };
            let frame = if remote {
                Frame::remote(id, dlc.min(8)).unwrap()
            } else {
                Frame::data(id, &data).unwrap()
            };
            let timestamp = Timestamp::from_secs_micros(secs, micros);
            let mut written = String::new();
            format_frame(&mut written, &frame, timestamp, remote_as_r).unwrap();
            let mut expected = format!("< frame {} {secs}.{micros:06} ", IdText(frame.id()));
            if remote && remote_as_r {
                expected += &format!("R{}", frame.dlc());
            } else if !remote {
                for b in frame.payload() {
                    expected += &format!("{b:02X}");
                }
            }
            expected += " >";
            prop_assert_eq!(written, expected);
        }
    }

    #[test]
    fn frames_just_off_the_fast_layout_are_read_or_refused_as_before() {
        for inner in [
            " frame 123 1.000001 R8 ",
            " frame 123 1.000001 r2 ",
            " frame 123 1.000001 01 02 03 ",
            " frame 123 1.000001 ",
            " frame 12345678 1.000001 01 ",
            " frame 123 18446744073709551615.5 01 ",
            " frame 123 18446744073709551616.5 01 ",
            " frame 123 1.1234567 01 ",
            " frame 123 1. 01 ",
            " frame 123 .5 01 ",
            " frame 123 1.5.5 01 ",
            " frame +12 1.5 01 ",
            " frame 800 1.5 01 ",
            " frame 20000000 1.5 01 ",
            " frame 123456789 1.5 01 ",
            " frame 123 1.5 0102030405060708 ",
            " frame 123 1.5 010203040506070809 ",
            " frame 123 1.5 010 ",
            " frame 123 1.5 0g ",
            " frame 123 1.5 01 extra ",
            " frame 123 ++++++++++++++++++++.5 01 ",
            " frame 123 1234567890123456789.5 01 ",
            " frame 123 00000000000000000000001.5 01 ",
            "\x0bframe 123 1.5 01 ",
            " frame\x0b123 1.5 01 ",
        ] {
            let fast = parse_frame_fast(inner.as_bytes())
                .map(|(frame, timestamp)| ServerMessage::Frame { frame, timestamp });
            let general = ServerMessage::parse_tokens(inner);
            if let Some(fast) = fast {
                assert_eq!(Ok(fast), general, "{inner:?}");
            }
            assert_eq!(ServerMessage::parse(inner), general, "{inner:?}");
        }
    }
}
