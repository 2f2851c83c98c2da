//! The SLCAN (Lawicel) ASCII protocol both ways, sans-IO: what a host sends ([`Command`]), what
//! an adapter answers or reports ([`Reply`]), parsed from one line and formatted into bytes.
//!
//! A line ends with CR (`\r`); an adapter's error answer is a lone BEL (`\a`). IDs are 3 hex
//! digits (standard) or 8 (extended), the DLC one digit `0`..`8`, data 2 hex digits a byte
//! (either case in, upper case out). [`LineSplitter`] cuts a byte stream into lines, bounded.
//!
//! CAN FD as CANable 2.0's firmware and python-can's `slcan` interface spell it: `d`/`D` an FD
//! frame without bit-rate switch, `b`/`B` one with it (standard/extended ID), the DLC one hex
//! digit `0`..`F` (lengths 0..8, 12, 16, 20, 24, 32, 48, 64), and `Yn` the data bit rate
//! ([`DATA_BITRATES`]). The protocol has no spelling for ESI: an FD frame with ESI goes out
//! without it.
//! Every parser takes any bytes and gives a value or an error naming what is wrong; none
//! panics (`tests/codec_props.rs`).

use std::fmt;

use buslab_can::{FdFrame, Frame, Id, fd_len_of_dlc};

/// The longest line kept: an extended FD frame with 64 bytes and a timestamp is 142 bytes
/// without its CR (`B`, 8 ID digits, the DLC, 128 data digits, 4 timestamp digits); commands
/// are shorter. Longer lines are garbage.
pub const MAX_LINE: usize = 142;

/// The longest reply line a host keeps ([`LineSplitter::with_limit`]): CANable's answer to `V`
/// is its firmware's `git describe` and repository URL, 50 to 70 characters
/// (`8ca5d39 https://github.com/normaldotcom/canable-fw.git`), longer for forks; and any
/// frame ([`MAX_LINE`]).
pub const MAX_REPLY_LINE: usize = 160;

/// The data bit rates of `Y0`..`Y8`, in bit/s, for CAN FD: the codes CANable 2.0's firmware
/// and its forks document (`Y2` = 2 Mbit/s is the one python-can also sends, with `Y5`).
pub const DATA_BITRATES: [(u8, u32); 7] = [
    (0, 500_000),
    (1, 1_000_000),
    (2, 2_000_000),
    (3, 3_000_000),
    (4, 4_000_000),
    (5, 5_000_000),
    (8, 8_000_000),
];

/// The data bit rate of a `Yn` code.
pub fn data_bitrate(code: u8) -> Option<u32> {
    DATA_BITRATES
        .iter()
        .find(|(c, _)| *c == code)
        .map(|&(_, rate)| rate)
}

/// The bit rates of `S0`..`S8`, in bit/s.
pub const STANDARD_BITRATES: [u32; 9] = [
    10_000, 20_000, 50_000, 100_000, 125_000, 250_000, 500_000, 800_000, 1_000_000,
];

/// Timestamps (`Z1`) count milliseconds and wrap here: `0000`..`EA5F`.
pub const TIMESTAMP_WRAP_MS: u16 = 60_000;

/// The line terminator (an answer "OK" on its own).
pub const CR: u8 = b'\r';
/// The error answer.
pub const BEL: u8 = 0x07;

/// What a host sends an adapter.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Command {
    /// A bare CR: python-can sends one (its empty data-bit-rate code); adapters ignore it.
    Empty,
    /// `Sn`: one of the standard bit rates, [`STANDARD_BITRATES`]`[n]` (n = 0..=8).
    Bitrate(u8),
    /// `sxxyy`: the SJA1000 bus timing registers BTR0 and BTR1.
    Btr { btr0: u8, btr1: u8 },
    /// `sxxyyzz`: an MCP2515 clone's CNF1..CNF3.
    Cnf([u8; 3]),
    /// `O`: open the channel (take part in the bus).
    Open,
    /// `L`: open listen-only (receive, never transmit or acknowledge).
    ListenOnly,
    /// `C`: close the channel.
    Close,
    /// `t`, `T`, `r`, `R`: transmit a frame.
    Transmit(Frame),
    /// `d`, `D`, `b`, `B`: transmit a CAN FD frame (`b`/`B` with BRS).
    TransmitFd(FdFrame),
    /// `Yn`: the CAN FD data bit rate, [`data_bitrate`]`(n)`.
    DataBitrate(u8),
    /// `F`: read the status flags.
    Status,
    /// `V`: hardware and software version.
    Version,
    /// `v`: detailed firmware version (some clones).
    DetailedVersion,
    /// `N`: serial number.
    SerialNumber,
    /// `Z0`/`Z1`: timestamps on received frames off/on.
    Timestamps(bool),
    /// `Mxxxxxxxx`: SJA1000 acceptance code.
    AcceptanceCode(u32),
    /// `mxxxxxxxx`: SJA1000 acceptance mask.
    AcceptanceMask(u32),
    /// Legacy or extension commands with one argument an adapter may accept or refuse: `X`
    /// (auto-poll), `U` (UART rate), `W` (filter mode), `Q` (auto-start), `P`/`A` (poll
    /// one/all). The letter and the text after it.
    Other { letter: u8, argument: String },
}

/// What an adapter sends a host.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Reply {
    /// CR alone: OK.
    Ok,
    /// BEL: error (unknown command, wrong state, malformed).
    Error,
    /// `z` / `Z` then CR: a standard / extended frame was queued (Lawicel, CANUSB).
    Queued { extended: bool },
    /// A received frame, with its timestamp in ms (`0`..`59999`) when timestamps are on.
    Frame {
        frame: Frame,
        timestamp_ms: Option<u16>,
    },
    /// A received CAN FD frame (`d`, `D`, `b`, `B`), with its timestamp as for frames.
    FdFrame {
        frame: FdFrame,
        timestamp_ms: Option<u16>,
    },
    /// `Fxx`: the status flags.
    Status(StatusFlags),
    /// `Vxxxx`: hardware and software version, 2 digits each.
    Version([u8; 4]),
    /// `vxxxx`: detailed version.
    DetailedVersion([u8; 4]),
    /// `Nxxxx`: the serial number, 4 alphanumeric characters.
    SerialNumber([u8; 4]),
    /// A line of printable text with a space in it, which no Lawicel reply has: how CANable's
    /// slcan firmware answers `V` (`<git describe> <repository>`; the CANable 2 fork of
    /// Nakakiyo092 puts `VL2K0 ` before it).
    FirmwareText(String),
}

/// The status flags of the `F` command (Lawicel CAN232/CANUSB).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct StatusFlags(pub u8);

impl StatusFlags {
    pub const RX_FIFO_FULL: u8 = 0x01;
    pub const TX_FIFO_FULL: u8 = 0x02;
    pub const ERROR_WARNING: u8 = 0x04;
    pub const DATA_OVERRUN: u8 = 0x08;
    pub const ERROR_PASSIVE: u8 = 0x20;
    pub const ARBITRATION_LOST: u8 = 0x40;
    pub const BUS_ERROR: u8 = 0x80;

    pub const fn contains(self, flag: u8) -> bool {
        self.0 & flag == flag
    }
}

/// The flags in words, `|`-separated (`-` when none is set).
impl fmt::Display for StatusFlags {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        const WORDS: [(u8, &str); 7] = [
            (StatusFlags::RX_FIFO_FULL, "rx-fifo-full"),
            (StatusFlags::TX_FIFO_FULL, "tx-fifo-full"),
            (StatusFlags::ERROR_WARNING, "error-warning"),
            (StatusFlags::DATA_OVERRUN, "data-overrun"),
            (StatusFlags::ERROR_PASSIVE, "error-passive"),
            (StatusFlags::ARBITRATION_LOST, "arbitration-lost"),
            (StatusFlags::BUS_ERROR, "bus-error"),
        ];
        let mut first = true;
        for (bit, word) in WORDS {
            if self.0 & bit != 0 {
                if !first {
                    f.write_str("|")?;
                }
                f.write_str(word)?;
                first = false;
            }
        }
        if first {
            f.write_str("-")?;
        }
        Ok(())
    }
}

/// Why a line is not a command or a reply. Every variant shows the line (lossy, control
/// characters escaped).
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum CodecError {
    #[error("{line}: unknown command letter {letter:?}")]
    UnknownCommand { line: Shown, letter: char },
    #[error("{line}: not a reply an SLCAN adapter sends")]
    UnknownReply { line: Shown },
    #[error("{line}: {what} must be {expected}")]
    Field {
        line: Shown,
        what: &'static str,
        expected: &'static str,
    },
    #[error("{line}: {problem}")]
    Frame {
        line: Shown,
        problem: buslab_can::ParseError,
    },
    #[error("a line longer than an SLCAN line can be (dropped)")]
    TooLong,
}

/// A line as shown in errors: printable ASCII as is, anything else escaped, at most 40
/// characters.
#[derive(Clone, PartialEq, Eq)]
pub struct Shown(String);

impl Shown {
    pub fn new(line: &[u8]) -> Self {
        let mut text = String::from("\"");
        for &b in line.iter().take(40) {
            text.extend(std::ascii::escape_default(b).map(char::from));
        }
        if line.len() > 40 {
            text.push('…');
        }
        text.push('"');
        Self(text)
    }
}

impl fmt::Display for Shown {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl fmt::Debug for Shown {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

/// Parses one command line (without its CR).
pub fn parse_command(line: &[u8]) -> Result<Command, CodecError> {
    let field = |what, expected| CodecError::Field {
        line: Shown::new(line),
        what,
        expected,
    };
    let Some((&letter, arg)) = line.split_first() else {
        return Ok(Command::Empty);
    };
    let no_argument = |command: Command| {
        if arg.is_empty() {
            Ok(command)
        } else {
            Err(field("the command", "one letter without arguments"))
        }
    };
    match letter {
        b'S' => match arg {
            [d @ b'0'..=b'8'] => Ok(Command::Bitrate(d - b'0')),
            _ => Err(field(
                "the bit rate code",
                "one digit 0..8 (S6 = 500 kbit/s)",
            )),
        },
        b's' => match hex_bytes(arg).as_deref() {
            Some([btr0, btr1]) => Ok(Command::Btr {
                btr0: *btr0,
                btr1: *btr1,
            }),
            Some([a, b, c]) => Ok(Command::Cnf([*a, *b, *c])),
            _ => Err(field(
                "the timing registers",
                "4 hex digits BTR0 BTR1 (or 6 for CNF1..3)",
            )),
        },
        b'O' => no_argument(Command::Open),
        b'L' => no_argument(Command::ListenOnly),
        b'C' => no_argument(Command::Close),
        b'F' => no_argument(Command::Status),
        b'V' => no_argument(Command::Version),
        b'v' => no_argument(Command::DetailedVersion),
        b'N' => no_argument(Command::SerialNumber),
        // A host sends no timestamp: 4 more digits are too much data.
        b't' | b'T' | b'r' | b'R' => match parse_frame(line)? {
            (frame, None) => Ok(Command::Transmit(frame)),
            (_, Some(_)) => Err(field("the data", "2 hex digits per byte of the DLC")),
        },
        b'd' | b'D' | b'b' | b'B' => match parse_fd_frame(line)? {
            (frame, None) => Ok(Command::TransmitFd(frame)),
            (_, Some(_)) => Err(field("the data", "2 hex digits per byte of the FD DLC")),
        },
        b'Y' => match arg {
            [d @ b'0'..=b'9'] if data_bitrate(d - b'0').is_some() => {
                Ok(Command::DataBitrate(d - b'0'))
            }
            _ => Err(field(
                "the data bit rate code",
                "one of 0, 1, 2, 3, 4, 5, 8 (Y2 = 2 Mbit/s)",
            )),
        },
        b'Z' => match arg {
            b"0" => Ok(Command::Timestamps(false)),
            b"1" => Ok(Command::Timestamps(true)),
            _ => Err(field("the timestamp switch", "0 or 1")),
        },
        b'M' | b'm' => {
            let value = (arg.len() == 8)
                .then(|| hex_value(arg))
                .flatten()
                .ok_or_else(|| field("the acceptance code or mask", "8 hex digits"))?;
            Ok(if letter == b'M' {
                Command::AcceptanceCode(value)
            } else {
                Command::AcceptanceMask(value)
            })
        }
        b'X' | b'U' | b'W' | b'Q' | b'P' | b'A' => {
            if arg.len() > 8 || !arg.iter().all(u8::is_ascii_alphanumeric) {
                return Err(field("the argument", "up to 8 letters or digits"));
            }
            Ok(Command::Other {
                letter,
                argument: String::from_utf8_lossy(arg).into_owned(),
            })
        }
        _ => Err(CodecError::UnknownCommand {
            line: Shown::new(line),
            letter: char::from(letter),
        }),
    }
}

/// Parses one reply line: its text without the terminator, and whether the terminator was
/// BEL (an error answer; anything before a BEL is ignored, as python-can and the kernel do).
pub fn parse_reply(line: &[u8], bell: bool) -> Result<Reply, CodecError> {
    if bell {
        return Ok(Reply::Error);
    }
    let field = |what, expected| CodecError::Field {
        line: Shown::new(line),
        what,
        expected,
    };
    let four = |arg: &[u8], what| -> Result<[u8; 4], CodecError> {
        match <[u8; 4]>::try_from(arg) {
            Ok(a) if a.iter().all(u8::is_ascii_alphanumeric) => Ok(a),
            _ => Err(field(what, "4 letters or digits")),
        }
    };
    if line.contains(&b' ') && line.iter().all(|b| (b' '..=b'~').contains(b)) {
        return Ok(Reply::FirmwareText(
            String::from_utf8_lossy(line).into_owned(),
        ));
    }
    match line {
        [] => Ok(Reply::Ok),
        [b'z'] => Ok(Reply::Queued { extended: false }),
        [b'Z'] => Ok(Reply::Queued { extended: true }),
        [b'F', arg @ ..] => match hex_bytes(arg).as_deref() {
            Some([flags]) => Ok(Reply::Status(StatusFlags(*flags))),
            _ => Err(field("the status flags", "2 hex digits")),
        },
        [b'V', arg @ ..] => Ok(Reply::Version(four(arg, "the version")?)),
        [b'v', arg @ ..] => Ok(Reply::DetailedVersion(four(arg, "the version")?)),
        [b'N', arg @ ..] => Ok(Reply::SerialNumber(four(arg, "the serial number")?)),
        [b't' | b'T' | b'r' | b'R', ..] => {
            let (frame, timestamp_ms) = parse_frame(line)?;
            Ok(Reply::Frame {
                frame,
                timestamp_ms,
            })
        }
        [b'd' | b'D' | b'b' | b'B', ..] => {
            let (frame, timestamp_ms) = parse_fd_frame(line)?;
            Ok(Reply::FdFrame {
                frame,
                timestamp_ms,
            })
        }
        _ => Err(CodecError::UnknownReply {
            line: Shown::new(line),
        }),
    }
}

/// `tIIIL…`, `TIIIIIIIIL…`, `rIIIL`, `RIIIIIIIIL`, with an optional 4-hex-digit timestamp
/// after the data (`Z1`), which must be below 60000.
fn parse_frame(line: &[u8]) -> Result<(Frame, Option<u16>), CodecError> {
    let field = |what, expected| CodecError::Field {
        line: Shown::new(line),
        what,
        expected,
    };
    let frame_error = |problem| CodecError::Frame {
        line: Shown::new(line),
        problem,
    };
    let (kind, id, dlc, rest) = frame_head(line)?;
    let dlc = match dlc {
        d @ b'0'..=b'8' => d - b'0',
        _ => return Err(field("the DLC", "one digit 0..8")),
    };
    let remote = matches!(kind, b'r' | b'R');
    let data_len = if remote { 0 } else { usize::from(dlc) };
    let (data, timestamp_ms) = frame_tail(
        line,
        rest,
        data_len,
        "2 hex digits per byte of the DLC, then nothing or a 4-digit timestamp",
    )?;
    let frame = if remote {
        Frame::remote(id, dlc)
    } else {
        Frame::data(id, &data)
    }
    .map_err(frame_error)?;
    Ok((frame, timestamp_ms))
}

/// `dIIIL…`, `DIIIIIIIIL…`, `bIIIL…`, `BIIIIIIIIL…` (`b`/`B` with BRS), the DLC one hex
/// digit, with an optional timestamp as for frames.
fn parse_fd_frame(line: &[u8]) -> Result<(FdFrame, Option<u16>), CodecError> {
    let (kind, id, dlc, rest) = frame_head(line)?;
    let len = char::from(dlc)
        .to_digit(16)
        .and_then(|d| fd_len_of_dlc(d as u8))
        .ok_or_else(|| CodecError::Field {
            line: Shown::new(line),
            what: "the FD DLC",
            expected: "one hex digit 0..F",
        })?;
    let (data, timestamp_ms) = frame_tail(
        line,
        rest,
        len,
        "2 hex digits per byte of the FD DLC's length, then nothing or a 4-digit timestamp",
    )?;
    let frame = FdFrame::new(id, &data)
        .map_err(|problem| CodecError::Frame {
            line: Shown::new(line),
            problem,
        })?
        .with_brs(matches!(kind, b'b' | b'B'));
    Ok((frame, timestamp_ms))
}

/// A frame line's kind letter, ID (3 hex digits for a lower-case letter, 8 for upper case),
/// DLC character, and what follows it.
fn frame_head(line: &[u8]) -> Result<(u8, Id, u8, &[u8]), CodecError> {
    let field = |what, expected| CodecError::Field {
        line: Shown::new(line),
        what,
        expected,
    };
    let (&kind, rest) = line
        .split_first()
        .ok_or_else(|| field("the line", "a frame"))?;
    let extended = kind.is_ascii_uppercase();
    let id_len = if extended { 8 } else { 3 };
    if rest.len() < id_len + 1 {
        return Err(field(
            "the frame",
            if extended {
                "8 hex digits of ID and a DLC digit"
            } else {
                "3 hex digits of ID and a DLC digit"
            },
        ));
    }
    let (id_text, rest) = rest.split_at(id_len);
    let raw = hex_value(id_text).ok_or_else(|| field("the ID", "hexadecimal"))?;
    let id = if extended {
        Id::extended(raw)
    } else {
        Id::standard(raw as u16)
    }
    .map_err(|problem| CodecError::Frame {
        line: Shown::new(line),
        problem,
    })?;
    Ok((kind, id, rest[0], &rest[1..]))
}

/// `len` data bytes (2 hex digits each) and the optional 4-digit timestamp after them;
/// `expected` says what the data must be when it does not fit.
fn frame_tail(
    line: &[u8],
    rest: &[u8],
    len: usize,
    expected: &'static str,
) -> Result<(Vec<u8>, Option<u16>), CodecError> {
    let field = |what, expected| CodecError::Field {
        line: Shown::new(line),
        what,
        expected,
    };
    let data_len = 2 * len;
    let (data_text, stamp) = match rest.len() {
        n if n == data_len => (rest, None),
        n if n == data_len + 4 => (&rest[..data_len], Some(&rest[data_len..])),
        _ => return Err(field("the data", expected)),
    };
    let data = hex_bytes(data_text).ok_or_else(|| field("the data", "hexadecimal"))?;
    let timestamp_ms = match stamp {
        None => None,
        Some(text) => Some(
            hex_value(text)
                .filter(|&t| t < u32::from(TIMESTAMP_WRAP_MS))
                .ok_or_else(|| field("the timestamp", "4 hex digits 0000..EA5F"))?
                as u16,
        ),
    };
    Ok((data, timestamp_ms))
}

/// Appends a command with its CR.
pub fn format_command(command: &Command, out: &mut Vec<u8>) {
    use std::io::Write;
    let _ = match command {
        Command::Empty => Ok(()),
        Command::Bitrate(n) => write!(out, "S{n}"),
        Command::Btr { btr0, btr1 } => write!(out, "s{btr0:02X}{btr1:02X}"),
        Command::Cnf([a, b, c]) => write!(out, "s{a:02X}{b:02X}{c:02X}"),
        Command::Open => write!(out, "O"),
        Command::ListenOnly => write!(out, "L"),
        Command::Close => write!(out, "C"),
        Command::Transmit(frame) => {
            format_frame(frame, None, out);
            Ok(())
        }
        Command::TransmitFd(frame) => {
            format_fd_frame(frame, None, out);
            Ok(())
        }
        Command::DataBitrate(code) => write!(out, "Y{code}"),
        Command::Status => write!(out, "F"),
        Command::Version => write!(out, "V"),
        Command::DetailedVersion => write!(out, "v"),
        Command::SerialNumber => write!(out, "N"),
        Command::Timestamps(on) => write!(out, "Z{}", u8::from(*on)),
        Command::AcceptanceCode(v) => write!(out, "M{v:08X}"),
        Command::AcceptanceMask(v) => write!(out, "m{v:08X}"),
        Command::Other { letter, argument } => {
            out.push(*letter);
            out.extend_from_slice(argument.as_bytes());
            Ok(())
        }
    };
    out.push(CR);
}

/// Appends a reply with its terminator (a lone BEL for [`Reply::Error`]).
pub fn format_reply(reply: &Reply, out: &mut Vec<u8>) {
    match reply {
        Reply::Ok => {}
        Reply::Error => {
            out.push(BEL);
            return;
        }
        Reply::Queued { extended } => out.push(if *extended { b'Z' } else { b'z' }),
        Reply::Frame {
            frame,
            timestamp_ms,
        } => format_frame(frame, *timestamp_ms, out),
        Reply::FdFrame {
            frame,
            timestamp_ms,
        } => format_fd_frame(frame, *timestamp_ms, out),
        Reply::Status(flags) => {
            out.push(b'F');
            push_hex(out, u32::from(flags.0), 2);
        }
        Reply::Version(text) => {
            out.push(b'V');
            out.extend_from_slice(text);
        }
        Reply::DetailedVersion(text) => {
            out.push(b'v');
            out.extend_from_slice(text);
        }
        Reply::SerialNumber(text) => {
            out.push(b'N');
            out.extend_from_slice(text);
        }
        Reply::FirmwareText(text) => out.extend_from_slice(text.as_bytes()),
    }
    out.push(CR);
}

/// A frame's text without a terminator: `t1232AABB`, `T1ABCDEF00`, `r7FF2`, and the timestamp
/// (taken modulo 60000) when given.
pub fn format_frame(frame: &Frame, timestamp_ms: Option<u16>, out: &mut Vec<u8>) {
    let kind = match (frame.is_remote(), frame.is_extended()) {
        (false, false) => b't',
        (false, true) => b'T',
        (true, false) => b'r',
        (true, true) => b'R',
    };
    out.push(kind);
    push_hex(
        out,
        frame.id().as_raw(),
        if frame.is_extended() { 8 } else { 3 },
    );
    out.push(b'0' + frame.dlc());
    for &b in frame.payload() {
        push_hex(out, u32::from(b), 2);
    }
    if let Some(t) = timestamp_ms {
        push_hex(out, u32::from(t % TIMESTAMP_WRAP_MS), 4);
    }
}

/// An FD frame's text without a terminator: `d1233112233`, `B1ABCDEF09` followed by 12 bytes,
/// and the timestamp (taken modulo 60000) when given. ESI has no spelling and is left out.
pub fn format_fd_frame(frame: &FdFrame, timestamp_ms: Option<u16>, out: &mut Vec<u8>) {
    let kind = match (frame.brs(), frame.is_extended()) {
        (false, false) => b'd',
        (false, true) => b'D',
        (true, false) => b'b',
        (true, true) => b'B',
    };
    out.push(kind);
    push_hex(
        out,
        frame.id().as_raw(),
        if frame.is_extended() { 8 } else { 3 },
    );
    push_hex(out, u32::from(frame.dlc()), 1);
    for &b in frame.payload() {
        push_hex(out, u32::from(b), 2);
    }
    if let Some(t) = timestamp_ms {
        push_hex(out, u32::from(t % TIMESTAMP_WRAP_MS), 4);
    }
}

fn push_hex(out: &mut Vec<u8>, value: u32, digits: u32) {
    const HEX: &[u8; 16] = b"0123456789ABCDEF";
    for i in (0..digits).rev() {
        out.push(HEX[(value >> (4 * i)) as usize & 0xF]);
    }
}

/// Hex digits (1..=8 of them) as a number.
fn hex_value(text: &[u8]) -> Option<u32> {
    if text.is_empty() || text.len() > 8 {
        return None;
    }
    text.iter()
        .try_fold(0u32, |acc, &d| Some(acc << 4 | char::from(d).to_digit(16)?))
}

/// Pairs of hex digits as bytes (at most 64 bytes, an FD frame's).
fn hex_bytes(text: &[u8]) -> Option<Vec<u8>> {
    if !text.len().is_multiple_of(2) || text.len() > 128 {
        return None;
    }
    text.chunks(2)
        .map(|pair| hex_value(pair).map(|v| v as u8))
        .collect()
}

/// A line cut from the stream by [`LineSplitter`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Line<'a> {
    /// Text that ended with CR.
    Text(&'a [u8]),
    /// Text (usually none) that ended with BEL.
    Bell(&'a [u8]),
    /// A line longer than [`MAX_LINE`] ended here; its text was dropped.
    TooLong,
}

/// Cuts a byte stream into lines at CR or BEL, keeping at most [`MAX_LINE`] bytes (or the
/// limit given). A LF right after a terminator (a terminal's CR LF) is ignored.
#[derive(Clone, Debug)]
pub struct LineSplitter {
    buf: Vec<u8>,
    limit: usize,
    too_long: bool,
    /// The previous call ended a line: its bytes are dropped on the next push.
    ended: bool,
}

impl Default for LineSplitter {
    fn default() -> Self {
        Self::with_limit(MAX_LINE)
    }
}

impl LineSplitter {
    pub fn new() -> Self {
        Self::default()
    }

    /// A splitter that keeps lines of up to `limit` bytes ([`MAX_REPLY_LINE`] for replies).
    pub fn with_limit(limit: usize) -> Self {
        Self {
            buf: Vec::new(),
            limit,
            too_long: false,
            ended: false,
        }
    }

    /// Takes one byte; gives the line it ends, if it ends one.
    pub fn push(&mut self, byte: u8) -> Option<Line<'_>> {
        if self.ended {
            self.buf.clear();
            self.ended = false;
            if byte == b'\n' {
                return None;
            }
        }
        match byte {
            CR | BEL => {
                self.ended = true;
                if std::mem::take(&mut self.too_long) {
                    return Some(Line::TooLong);
                }
                Some(if byte == CR {
                    Line::Text(&self.buf)
                } else {
                    Line::Bell(&self.buf)
                })
            }
            _ if self.too_long => None,
            _ if self.buf.len() >= self.limit => {
                self.too_long = true;
                self.buf.clear();
                None
            }
            _ => {
                self.buf.push(byte);
                None
            }
        }
    }

    /// Bytes of an unfinished line.
    pub fn pending(&self) -> usize {
        if self.ended { 0 } else { self.buf.len() }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(text: &str) -> Frame {
        text.parse().unwrap()
    }

    fn command(text: &str) -> Command {
        parse_command(text.as_bytes()).unwrap_or_else(|e| panic!("{text}: {e}"))
    }

    #[test]
    fn python_can_opening_sequence_parses() {
        // What python-can 4.6.1 writes with bitrate=500000 (facts §2.4), CRs removed.
        let got: Vec<Command> = ["C", "S6", "", "O", "O", "V", "N"]
            .into_iter()
            .map(command)
            .collect();
        use Command::*;
        assert_eq!(
            got,
            [Close, Bitrate(6), Empty, Open, Open, Version, SerialNumber]
        );
        assert_eq!(
            command("t1233010203"),
            Transmit(frame("123#010203")),
            "standard data"
        );
        assert_eq!(command("T1ABCDEF02DEAD"), Transmit(frame("1ABCDEF0#DEAD")));
        assert_eq!(command("r7FF2"), Transmit(frame("7FF#R2")));
        assert_eq!(command("R000001230"), Transmit(frame("00000123#R")));
        assert_eq!(
            command("s031C"),
            Btr {
                btr0: 3,
                btr1: 0x1C
            }
        );
        assert_eq!(command("Z1"), Timestamps(true));
        assert_eq!(command("MFFFFFFFF"), AcceptanceCode(0xFFFF_FFFF));
        assert_eq!(command("Y2"), DataBitrate(2));
    }

    /// What python-can 4.6.1's slcan interface writes for FD messages (its `send`: the FD
    /// DLC as one hex digit, `b`/`B` with bitrate_switch) and reads back.
    #[test]
    fn python_can_fd_lines_parse_both_ways() {
        let fd = |text: &str| -> FdFrame { text.parse().unwrap() };
        for (line, want) in [
            ("d1233112233", fd("123##0112233")),
            ("b1233112233", fd("123##1112233")),
            ("D1ABCDEF00", fd("1ABCDEF0##0")),
            (
                "B1ABCDEF09112233445566778899AABBCC",
                fd("1ABCDEF0##1112233445566778899AABBCC"),
            ),
            (
                &format!("d7FFF{}", "5A".repeat(64)),
                fd(&format!("7FF##0{}", "5A".repeat(64))),
            ),
        ] {
            assert_eq!(command(line), Command::TransmitFd(want), "{line}");
            let mut out = Vec::new();
            format_command(&Command::TransmitFd(want), &mut out);
            assert_eq!(out, format!("{line}\r").as_bytes());
            assert_eq!(
                parse_reply(line.as_bytes(), false),
                Ok(Reply::FdFrame {
                    frame: want,
                    timestamp_ms: None
                })
            );
        }
        // Lower-case hex in, a timestamp after the data from an adapter with Z1.
        assert_eq!(
            parse_reply(b"b123911223344556677889900aabbEA5F", false),
            Ok(Reply::FdFrame {
                frame: fd("123##111223344556677889900AABB"),
                timestamp_ms: Some(59_999)
            })
        );
        // ESI has no SLCAN spelling: it is left out.
        let mut out = Vec::new();
        format_fd_frame(&fd("123##3AA"), None, &mut out);
        assert_eq!(out, b"b1231AA");
        // The longest line fits in MAX_LINE.
        let mut out = Vec::new();
        format_reply(
            &Reply::FdFrame {
                frame: fd(&format!("1FFFFFFF##1{}", "00".repeat(64))),
                timestamp_ms: Some(0),
            },
            &mut out,
        );
        assert_eq!(out.len(), MAX_LINE + 1);
    }

    #[test]
    fn commands_round_trip() {
        for text in [
            "S0",
            "S8",
            "s031C",
            "s010203",
            "O",
            "L",
            "C",
            "F",
            "V",
            "v",
            "N",
            "Z0",
            "Z1",
            "M00000000",
            "mFFFFFFFF",
            "t1230",
            "t7FF81122334455667788",
            "T1FFFFFFF0",
            "r1238",
            "R000000000",
            "X1",
            "U1",
            "Y5",
            "d1230",
            "B1FFFFFFFF00112233445566778899AABBCCDDEEFF00112233445566778899AABBCCDDEEFF00112233445566778899AABBCCDDEEFF00112233445566778899AABBCCDDEEFF",
            "",
        ] {
            let mut out = Vec::new();
            format_command(&command(text), &mut out);
            assert_eq!(out, format!("{text}\r").as_bytes(), "{text}");
        }
    }

    #[test]
    fn replies_round_trip() {
        for (text, reply) in [
            ("\r", Reply::Ok),
            ("z\r", Reply::Queued { extended: false }),
            ("Z\r", Reply::Queued { extended: true }),
            ("F0C\r", Reply::Status(StatusFlags(0x0C))),
            ("V1013\r", Reply::Version(*b"1013")),
            ("NB001\r", Reply::SerialNumber(*b"B001")),
            // CANable's answers to V: its firmware's git description and repository.
            (
                "8ca5d39 https://github.com/normaldotcom/canable-fw.git\r",
                Reply::FirmwareText(
                    "8ca5d39 https://github.com/normaldotcom/canable-fw.git".into(),
                ),
            ),
            (
                "VL2K0 v2.0.0-16-g1a2b3c4 github.com/Nakakiyo092/canable2-fw.git\r",
                Reply::FirmwareText(
                    "VL2K0 v2.0.0-16-g1a2b3c4 github.com/Nakakiyo092/canable2-fw.git".into(),
                ),
            ),
            (
                "t12320102EA5F\r",
                Reply::Frame {
                    frame: frame("123#0102"),
                    timestamp_ms: Some(59_999),
                },
            ),
            (
                "T1111222281122334455667788\r",
                Reply::Frame {
                    frame: frame("11112222#1122334455667788"),
                    timestamp_ms: None,
                },
            ),
        ] {
            let line = &text.as_bytes()[..text.len() - 1];
            assert_eq!(parse_reply(line, false), Ok(reply.clone()), "{text:?}");
            let mut out = Vec::new();
            format_reply(&reply, &mut out);
            assert_eq!(out, text.as_bytes());
        }
        assert_eq!(parse_reply(b"", true), Ok(Reply::Error));
        let mut out = Vec::new();
        format_reply(&Reply::Error, &mut out);
        assert_eq!(out, [BEL]);
    }

    #[test]
    fn garbage_is_named_not_accepted() {
        for (bad, want) in [
            ("S9", "\"S9\": the bit rate code must be one digit 0..8"),
            ("Shello", "the bit rate code"),
            ("s03", "the timing registers must be 4 hex digits"),
            ("Ox", "one letter without arguments"),
            ("t12", "3 hex digits of ID and a DLC digit"),
            ("t8001", "standard ID 0x800 is out of range"),
            ("t1239", "the DLC must be one digit 0..8"),
            ("t1232AA", "2 hex digits per byte of the DLC"),
            ("t1231GG", "the data must be hexadecimal"),
            ("T2000000000", "extended ID 0x20000000 is out of range"),
            (
                "d1239AA",
                "the data must be 2 hex digits per byte of the FD DLC's length",
            ),
            ("d123G", "the FD DLC must be one hex digit 0..F"),
            ("b12", "3 hex digits of ID and a DLC digit"),
            ("D20000000000", "extended ID 0x20000000 is out of range"),
            (
                "Y6",
                "the data bit rate code must be one of 0, 1, 2, 3, 4, 5, 8",
            ),
            ("Y", "the data bit rate code"),
            ("Z2", "the timestamp switch must be 0 or 1"),
            ("M123", "8 hex digits"),
            ("?", "unknown command letter '?'"),
            ("\u{1b}[A", "unknown command letter '\\u{1b}'"),
        ] {
            let err = parse_command(bad.as_bytes()).unwrap_err().to_string();
            assert!(err.contains(want), "{bad:?}: {err}");
        }
        assert!(
            parse_reply(b"t1230FFFF", false)
                .unwrap_err()
                .to_string()
                .contains("the timestamp must be 4 hex digits 0000..EA5F")
        );
        assert!(matches!(
            parse_reply(b"hello", false),
            Err(CodecError::UnknownReply { .. })
        ));
        // A space makes a version text only among printable characters.
        assert!(matches!(
            parse_reply(b"t123 \x1b[2J", false),
            Err(CodecError::Field { .. })
        ));
    }

    #[test]
    fn the_splitter_cuts_at_cr_and_bel_and_bounds_lines() {
        let mut s = LineSplitter::new();
        let mut lines = Vec::new();
        for &b in b"O\r\x07t1230\r\nV\r".iter() {
            if let Some(line) = s.push(b) {
                lines.push(format!("{line:?}"));
            }
        }
        assert_eq!(
            lines,
            [
                "Text([79])",
                "Bell([])",
                "Text([116, 49, 50, 51, 48])",
                "Text([86])"
            ]
        );
        let mut too_long = 0;
        for _ in 0..1000 {
            assert!(s.push(b'x').is_none());
        }
        assert!(s.pending() <= MAX_LINE);
        if let Some(Line::TooLong) = s.push(CR) {
            too_long += 1;
        }
        assert_eq!(too_long, 1);
        assert_eq!(s.push(b'F'), None);
        assert_eq!(s.push(CR), Some(Line::Text(b"F")));
    }

    #[test]
    fn status_flags_in_words() {
        assert_eq!(StatusFlags(0).to_string(), "-");
        assert_eq!(StatusFlags(0x28).to_string(), "data-overrun|error-passive");
    }
}
