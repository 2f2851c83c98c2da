//! Server → client: greetings, acknowledgements, frames, errors, and buslab's replies.

use core::fmt;

use buslab_can::Frame;

use crate::command::{IdText, parse_id};
use crate::{ProtocolError, tokens};

/// A frame time as socketcand writes it: seconds and microseconds (`23.424242`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Timestamp {
    pub secs: u64,
    pub micros: u32,
}

impl Timestamp {
    /// From nanoseconds (truncated to microseconds, as socketcand's `%06ld`).
    pub fn from_nanos(nanos: u128) -> Self {
        Self {
            secs: (nanos / 1_000_000_000) as u64,
            micros: ((nanos % 1_000_000_000) / 1000) as u32,
        }
    }

    pub fn as_secs_f64(self) -> f64 {
        self.secs as f64 + self.micros as f64 * 1e-6
    }

    pub fn parse(text: &str) -> Result<Self, ProtocolError> {
        let bad = || ProtocolError::BadTimestamp {
            text: text.to_string(),
        };
        let (s, us) = text.split_once('.').ok_or_else(bad)?;
        let digits = |t: &str| !t.is_empty() && t.bytes().all(|b| b.is_ascii_digit());
        if !digits(s) || !digits(us) || us.len() > 6 {
            return Err(bad());
        }
        let secs = s.parse().map_err(|_| bad())?;
        // "1.5" means 1.500000 s (at most 6 digits, checked above).
        let micros = us.parse::<u32>().map_err(|_| bad())? * 10u32.pow(6 - us.len() as u32);
        Ok(Self { secs, micros })
    }
}

impl fmt::Display for Timestamp {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}.{:06}", self.secs, self.micros)
    }
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
        let t = tokens(inner);
        let (&name, args) = t.split_first().ok_or(ProtocolError::Empty)?;
        match (name, args) {
            ("hi", []) => Ok(ServerMessage::Hi),
            ("ok", []) => Ok(ServerMessage::Ok),
            ("echo", []) => Ok(ServerMessage::Echo),
            ("frame", [id, ts, data @ ..]) => {
                let id = parse_id(id)?;
                let timestamp = Timestamp::parse(ts)?;
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
                if Timestamp::parse(ts).is_ok()
                    && u32::from_str_radix(class, 16).is_ok()
                    && !class.starts_with('+') =>
            {
                Ok(ServerMessage::ErrorFrame {
                    class: u32::from_str_radix(class, 16).unwrap_or(0) & 0x1FFF_FFFF,
                    timestamp: Timestamp::parse(ts)?,
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

/// A server's error text as the user will see it: control characters (a terminal escape sent
/// by a hostile server) and what an element cannot carry replaced, spaces collapsed, so it
/// also prints as it was read.
fn error_text(args: &[&str]) -> String {
    let text = crate::sanitize(&args.join(" "));
    text.split_ascii_whitespace().collect::<Vec<_>>().join(" ")
}

/// The value of a hex digit (checked by the caller).
fn hex_digit(b: u8) -> u8 {
    match b {
        b'0'..=b'9' => b - b'0',
        b'a'..=b'f' => b - b'a' + 10,
        b'A'..=b'F' => b - b'A' + 10,
        _ => 0,
    }
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
pub fn format_frame(
    out: &mut String,
    frame: &Frame,
    timestamp: Timestamp,
    remote_as_r: bool,
) -> fmt::Result {
    use fmt::Write;
    // Empty data still leaves the data field: `< frame 123 1.000000  >`, as socketcand
    // writes it and python-can splits it (it needs the third field, even empty).
    write!(out, "< frame {} {} ", IdText(frame.id()), timestamp)?;
    if frame.is_remote() {
        if remote_as_r {
            write!(out, "R{}", frame.dlc())?;
        }
    } else {
        // By table: a frame line is formatted for every frame a client gets.
        const HEX: &[u8; 16] = b"0123456789ABCDEF";
        for &b in frame.payload() {
            out.push(HEX[usize::from(b >> 4)] as char);
            out.push(HEX[usize::from(b & 15)] as char);
        }
    }
    out.push_str(" >");
    Ok(())
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
            let mut text = String::with_capacity(48);
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
