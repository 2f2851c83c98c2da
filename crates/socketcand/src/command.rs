//! Client → server: the commands of socketcand, plus buslab's `buslab_*` extensions.

use core::fmt;

use buslab_can::{Frame, Id};

use crate::{ProtocolError, tokens};

pub use buslab_bus::NodeRef;
use buslab_bus::SlioId;
use buslab_bus::admin::{BoardInput, BoardSwitch, BoardVolts};
use buslab_bus::{BusOffRecovery, Probability, WireFault};

/// One client command.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Command {
    /// `< open BUS >`: attach to a bus (the server answers `< ok >`).
    Open(String),
    /// `< rawmode >`: every frame on the bus is delivered as `< frame … >`.
    RawMode,
    /// `< bcmmode >` (the mode after open).
    BcmMode,
    /// `< controlmode >`.
    ControlMode,
    /// `< isotpmode >`.
    IsotpMode,
    /// `< echo >`: answered with `< echo >`.
    Echo,
    /// `< send ID DLC B… >`. A remote frame is `< send ID R<dlc> >` (buslab), or a DLC above 0
    /// with no bytes (what python-can sends for a remote frame).
    Send(Frame),
    /// A socketcand command buslab understands but does not implement (BCM jobs and filters,
    /// statistics, ISO-TP, bus settings): its name and arguments.
    Unsupported { name: String, args: Vec<String> },
    /// `< buslab_name NAME >`: names this client's node.
    Name(String),
    /// `< buslab_ext >`: received remote frames come as `< frame ID TIME R<dlc> >`.
    Extensions,
    /// `< buslab_own 0|1 >`: also deliver this client's own frames once sent (off by default,
    /// like python-can's `receive_own_messages`).
    ReceiveOwn(bool),
    /// `< buslab_errors 0|1 >`: also deliver the chip's bus errors, lost arbitrations and
    /// state changes as `< error CLASS SEC.USEC >` (SocketCAN error classes).
    ErrorFrames(bool),
    /// `< buslab_nodes >`: list the nodes.
    Nodes,
    /// `< buslab_status [NODE] >`: error state, counters and registers of a node (own if absent).
    Status(Option<NodeRef>),
    /// `< buslab_regs [NODE] >`: a register dump of a node (own if absent).
    Regs(Option<NodeRef>),
    /// `< buslab_flush >`: answered `< buslab_flushed SENT FAILED >` once every frame this
    /// client sent before it was transmitted or given up (SENT and FAILED count since the
    /// client joined).
    Flush,
    /// `< buslab_abort >`: gives up this client's frame being tried and its queued ones
    /// (`< ok >`).
    Abort,
    /// `< buslab_btr BTR0 BTR1 >`: reprogram this client's chip with these bit timing
    /// registers (hex).
    Btr { btr0: u8, btr1: u8 },
    /// `< buslab_fault MS KIND ARGS… >`: puts a fault on the virtual bus's wire for MS
    /// milliseconds (0: until repaired). KIND ARGS: `cut NODE[,NODE…] RATE`,
    /// `disconnect NODE`, `flip NODE|*`, `noise NODE[,NODE…]|* RATE`, `stuck`.
    Fault { fault: WireFault, lasting_ms: u64 },
    /// `< buslab_repair >`: ends every fault on the wire now (`< ok >`).
    Repair,
    /// `< buslab_controller KEY=VALUE… >`: reprogram this client's chip with the parts of a
    /// controller configuration it gives (mode, timing, filter, OCR, CLKOUT; see
    /// [`crate::controller`]).
    Controller(buslab_bus::ControllerSettings),
    /// `< buslab_board SLIO [CHANGE] >`: a SLIO demo board on the virtual bus, after a change
    /// to its inputs: `switch N 0|1` (N 0..3, on P0..P3), `switches H` (the four at once, one
    /// hex digit, bit 0 = P0) or `pot VOLTS` (the potentiometer, 0..5). Answered
    /// `< buslab_board … >` with the board's inputs and outputs.
    Board {
        slio: SlioId,
        change: Option<BoardInput>,
    },
    /// `< buslab_busoff counted|fast|manual >`: how this client's chip comes back after
    /// bus-off (the bus's policy until then; `manual`: it stays bus-off, as a Lawicel CANUSB).
    BusOff(BusOffRecovery),
}

/// socketcand's commands that buslab does not implement.
const UNSUPPORTED: &[&str] = &[
    "add",
    "update",
    "delete",
    "filter",
    "muxfilter",
    "subscribe",
    "unsubscribe",
    "statistics",
    "isotpconf",
    "sendpdu",
];

impl Command {
    /// Parses an element's inside (`send 123 2 11 22`).
    pub fn parse(inner: &str) -> Result<Self, ProtocolError> {
        // Every frame a client sends, without allocating; the rest token by token.
        match parse_send_fast(inner.as_bytes()) {
            Some(frame) => Ok(Command::Send(frame)),
            None => Self::parse_tokens(inner),
        }
    }

    /// [`Self::parse`] for any command, from its tokens.
    fn parse_tokens(inner: &str) -> Result<Self, ProtocolError> {
        let t = tokens(inner);
        let (&name, args) = t.split_first().ok_or(ProtocolError::Empty)?;
        let no_args = |cmd: Command, command: &'static str| {
            if args.is_empty() {
                Ok(cmd)
            } else {
                Err(ProtocolError::Arguments {
                    command,
                    expected: "no arguments",
                    got: args.join(" "),
                })
            }
        };
        match name {
            "open" => match args {
                [bus] => Ok(Command::Open(bus.to_string())),
                _ => Err(arguments("open", "one bus name", args)),
            },
            "rawmode" => no_args(Command::RawMode, "rawmode"),
            "bcmmode" => no_args(Command::BcmMode, "bcmmode"),
            "controlmode" => no_args(Command::ControlMode, "controlmode"),
            "isotpmode" => no_args(Command::IsotpMode, "isotpmode"),
            "echo" => no_args(Command::Echo, "echo"),
            "send" => parse_send(args).map(Command::Send),
            "buslab_name" => match args {
                [n] if valid_name(n) => Ok(Command::Name(n.to_string())),
                _ => Err(arguments(
                    "buslab_name",
                    "one name of 1..32 of A-Z a-z 0-9 _ - . (not all digits)",
                    args,
                )),
            },
            "buslab_ext" => no_args(Command::Extensions, "buslab_ext"),
            "buslab_own" => match args {
                ["0"] => Ok(Command::ReceiveOwn(false)),
                ["1"] => Ok(Command::ReceiveOwn(true)),
                _ => Err(arguments("buslab_own", "0 or 1", args)),
            },
            "buslab_errors" => match args {
                ["0"] => Ok(Command::ErrorFrames(false)),
                ["1"] => Ok(Command::ErrorFrames(true)),
                _ => Err(arguments("buslab_errors", "0 or 1", args)),
            },
            "buslab_nodes" => no_args(Command::Nodes, "buslab_nodes"),
            "buslab_flush" => no_args(Command::Flush, "buslab_flush"),
            "buslab_abort" => no_args(Command::Abort, "buslab_abort"),
            "buslab_status" | "buslab_regs" => {
                let node = match args {
                    [] => None,
                    [n] => Some(NodeRef::parse(n)),
                    _ => return Err(arguments("buslab_status", "at most one node", args)),
                };
                Ok(if name == "buslab_status" {
                    Command::Status(node)
                } else {
                    Command::Regs(node)
                })
            }
            "buslab_btr" => match args {
                [a, b] => Ok(Command::Btr {
                    btr0: hex_byte(a, "BTR0")?,
                    btr1: hex_byte(b, "BTR1")?,
                }),
                _ => Err(arguments("buslab_btr", "BTR0 BTR1 in hex", args)),
            },
            "buslab_fault" => parse_fault(args),
            "buslab_repair" => no_args(Command::Repair, "buslab_repair"),
            crate::controller::NAME => crate::controller::parse(args).map(Command::Controller),
            "buslab_board" => parse_board(args),
            "buslab_busoff" => match args {
                ["counted"] => Ok(Command::BusOff(BusOffRecovery::Counted)),
                ["fast"] => Ok(Command::BusOff(BusOffRecovery::Fast)),
                ["manual"] => Ok(Command::BusOff(BusOffRecovery::Manual)),
                _ => Err(arguments("buslab_busoff", "counted, fast or manual", args)),
            },
            n if UNSUPPORTED.contains(&n) => Ok(Command::Unsupported {
                name: n.to_string(),
                args: args.iter().map(|s| s.to_string()).collect(),
            }),
            // `< vcan0 B … >` / `< vcan0 C … >`: bus settings before open.
            _ if matches!(args.first(), Some(&"B") | Some(&"C")) => Ok(Command::Unsupported {
                name: name.to_string(),
                args: args.iter().map(|s| s.to_string()).collect(),
            }),
            _ => Err(ProtocolError::UnknownCommand(name.to_string())),
        }
    }
}

const FAULT_ARGS: &str = "MS then cut NODE[,NODE…] RATE, disconnect NODE, flip NODE|*, noise NODE[,NODE…]|* RATE, or stuck";

fn parse_fault(args: &[&str]) -> Result<Command, ProtocolError> {
    let bad = || arguments("buslab_fault", FAULT_ARGS, args);
    let [ms, kind, rest @ ..] = args else {
        return Err(bad());
    };
    let lasting_ms: u64 = ms
        .parse()
        .ok()
        .filter(|_| ms.bytes().all(|b| b.is_ascii_digit()))
        .ok_or_else(bad)?;
    let nodes = |list: &str| -> Result<Vec<NodeRef>, ProtocolError> {
        if list == "*" {
            return Ok(Vec::new());
        }
        list.split(',')
            .map(|n| {
                if n.is_empty() {
                    Err(bad())
                } else {
                    Ok(NodeRef::parse(n))
                }
            })
            .collect()
    };
    let rate = |text: &str| -> Result<Probability, ProtocolError> {
        let p: f64 = text.parse().map_err(|_| bad())?;
        Probability::new(p).map_err(|e| ProtocolError::Arguments {
            command: "buslab_fault",
            expected: "a rate per bit 0..=1",
            got: e.to_string(),
        })
    };
    let fault = match (*kind, rest) {
        ("cut", [list, r]) if *list != "*" => WireFault::Cut {
            far_side: nodes(list)?,
            error_rate: rate(r)?,
        },
        ("disconnect", [node]) if *node != "*" => WireFault::Disconnect {
            node: NodeRef::parse(node),
        },
        ("flip", [node]) => WireFault::Flip {
            node: (*node != "*").then(|| NodeRef::parse(node)),
        },
        ("noise", [list, r]) => WireFault::Noise {
            nodes: nodes(list)?,
            rate: rate(r)?,
        },
        ("stuck", []) => WireFault::StuckDominant,
        _ => return Err(bad()),
    };
    Ok(Command::Fault { fault, lasting_ms })
}

const BOARD_ARGS: &str = "SLIO (one hex digit 0..F), then nothing, switch N 0|1 (N 0..3), switches H (one hex digit: bit 0 is P0) or pot VOLTS (0..5)";

fn parse_board(args: &[&str]) -> Result<Command, ProtocolError> {
    let bad = || arguments("buslab_board", BOARD_ARGS, args);
    let [slio, rest @ ..] = args else {
        return Err(bad());
    };
    let slio: SlioId = one_hex_digit(slio)
        .and_then(|n| SlioId::new(n).ok())
        .ok_or_else(bad)?;
    let change = match rest {
        [] => None,
        ["switch", n, level] => {
            let switch = n
                .parse::<u8>()
                .ok()
                .filter(|_| n.len() == 1 && n.bytes().all(|b| b.is_ascii_digit()))
                .ok_or_else(bad)?;
            let switch = BoardSwitch::new(switch).map_err(|e| ProtocolError::Arguments {
                command: "buslab_board",
                expected: BOARD_ARGS,
                got: e.to_string(),
            })?;
            let on = match *level {
                "0" => false,
                "1" => true,
                _ => return Err(bad()),
            };
            Some(BoardInput::Switch { switch, on })
        }
        ["switches", bits] => Some(BoardInput::Switches(one_hex_digit(bits).ok_or_else(bad)?)),
        ["pot", volts] => {
            // Digits and one point only: `f64::from_str` would take `inf`, `NaN`, `1e3`, `+2`.
            let plain = !volts.is_empty()
                && volts.bytes().all(|b| b.is_ascii_digit() || b == b'.')
                && volts.bytes().filter(|&b| b == b'.').count() <= 1
                && volts.len() <= 32;
            let v: f64 = volts.parse().ok().filter(|_| plain).ok_or_else(bad)?;
            let v = BoardVolts::new(v).map_err(|e| ProtocolError::Arguments {
                command: "buslab_board",
                expected: BOARD_ARGS,
                got: e.to_string(),
            })?;
            Some(BoardInput::Potentiometer(v))
        }
        _ => return Err(bad()),
    };
    Ok(Command::Board { slio, change })
}

/// One hex digit (`A`, `f`).
fn one_hex_digit(text: &str) -> Option<u8> {
    let [b] = text.as_bytes() else { return None };
    (*b as char).to_digit(16).map(|d| d as u8)
}

/// A node list as `buslab_fault` writes it: `a,b`, or `*` for none (every node).
fn node_list(nodes: &[NodeRef]) -> String {
    if nodes.is_empty() {
        return "*".into();
    }
    nodes
        .iter()
        .map(ToString::to_string)
        .collect::<Vec<_>>()
        .join(",")
}

/// A node name: 1..32 of `A-Z a-z 0-9 _ - .`, not all digits (those are node numbers).
pub fn valid_name(name: &str) -> bool {
    (1..=32).contains(&name.len())
        && name
            .bytes()
            .all(|b| b.is_ascii_alphanumeric() || matches!(b, b'_' | b'-' | b'.'))
        && !name.bytes().all(|b| b.is_ascii_digit())
}

fn arguments(command: &'static str, expected: &'static str, args: &[&str]) -> ProtocolError {
    ProtocolError::Arguments {
        command,
        expected,
        got: args.join(" "),
    }
}

fn hex_byte(text: &str, what: &'static str) -> Result<u8, ProtocolError> {
    let digits = text
        .strip_prefix("0x")
        .or_else(|| text.strip_prefix("0X"))
        .unwrap_or(text);
    // Hex digits only: `from_str_radix` would take a sign (`+f`).
    if digits.is_empty() || digits.len() > 2 || !digits.bytes().all(|b| b.is_ascii_hexdigit()) {
        return Err(ProtocolError::BadHex {
            what,
            text: text.to_string(),
        });
    }
    u8::from_str_radix(digits, 16).map_err(|_| ProtocolError::BadHex {
        what,
        text: text.to_string(),
    })
}

/// An ID as socketcand reads it: hex; 8 characters mean extended, anything else standard.
pub(crate) fn parse_id(text: &str) -> Result<Id, ProtocolError> {
    if text.len() > 8 && text.bytes().all(|b| b.is_ascii_hexdigit()) {
        return Err(ProtocolError::BadId {
            text: text.to_string(),
            reason: "an ID is 1..8 hex digits (8 digits: extended, 00000000..1FFFFFFF; fewer: standard, 000..7FF)".to_string(),
        });
    }
    let raw = u32::from_str_radix(text, 16)
        .ok()
        .filter(|_| !text.is_empty() && text.len() <= 8 && !text.starts_with('+'))
        .ok_or_else(|| ProtocolError::BadHex {
            what: "ID",
            text: text.to_string(),
        })?;
    let id = if text.len() == 8 {
        Id::extended(raw)
    } else {
        u16::try_from(raw)
            .map_err(|_| buslab_can::ParseError::IdOutOfRange {
                value: raw,
                max: 0x7FF,
                extended: false,
            })
            .and_then(Id::standard)
    };
    id.map_err(|e| ProtocolError::BadId {
        text: text.to_string(),
        reason: e.to_string(),
    })
}

/// A `send` element's inside as buslab's client and python-can write every frame (` send ID
/// DLC B… `: one space around each field, a DLC of 0..8 and as many bytes of one or two hex
/// digits), read from the bytes without allocating. `None` for anything else, even a frame in
/// another layout or a bad one: [`Command::parse`] reads those token by token (and names what
/// is wrong). What this accepts, the tokens read the same (tests compare them).
fn parse_send_fast(inner: &[u8]) -> Option<Frame> {
    let fields = inner.strip_prefix(b" send ")?.strip_suffix(b" ")?;
    let mut parts = fields.split(|&b| b == b' ');
    let id = crate::hex::fast_id(parts.next()?)?;
    let dlc = match parts.next()? {
        [digit @ b'0'..=b'8'] => usize::from(digit - b'0'),
        _ => return None,
    };
    let mut data = [0u8; 8];
    let mut len = 0;
    for part in parts {
        let slot = data.get_mut(len).filter(|_| len < dlc)?;
        *slot = crate::hex::fast_byte(part)?;
        len += 1;
    }
    if len != dlc {
        return None;
    }
    Frame::data(id, &data[..len]).ok()
}

fn parse_send(args: &[&str]) -> Result<Frame, ProtocolError> {
    let [id, dlc, bytes @ ..] = args else {
        return Err(arguments("send", "ID DLC BYTES…", args));
    };
    let id = parse_id(id)?;
    let bad_dlc = || ProtocolError::BadDlc {
        text: dlc.to_string(),
    };
    if let Some(n) = dlc.strip_prefix(['R', 'r']) {
        if !bytes.is_empty() {
            return Err(arguments("send", "no bytes after R<dlc>", bytes));
        }
        let n: u8 = n.parse().map_err(|_| bad_dlc())?;
        return Frame::remote(id, n).map_err(|_| bad_dlc());
    }
    if dlc.is_empty() || !dlc.bytes().all(|b| b.is_ascii_digit()) {
        return Err(bad_dlc());
    }
    let n: u8 = dlc.parse().map_err(|_| bad_dlc())?;
    if n > 8 {
        return Err(bad_dlc());
    }
    if bytes.is_empty() && n > 0 {
        // python-can's way of sending a remote frame (socketcand itself rejects it).
        return Frame::remote(id, n).map_err(|_| bad_dlc());
    }
    if bytes.len() != n as usize {
        return Err(ProtocolError::DataLength {
            count: bytes.len(),
            dlc: n,
        });
    }
    let mut data = [0u8; 8];
    for (slot, b) in data.iter_mut().zip(bytes) {
        if b.is_empty() || b.len() > 2 || !b.bytes().all(|c| c.is_ascii_hexdigit()) {
            return Err(ProtocolError::BadByte {
                text: b.to_string(),
            });
        }
        // One or two hex digits, checked above: no `from_str_radix` (every frame a client
        // sends comes through here).
        *slot = b.bytes().fold(0, |value, digit| {
            (value << 4) | crate::hex::hex_digit(digit)
        });
    }
    Frame::data(id, &data[..n as usize]).map_err(|_| bad_dlc())
}

/// socketcand's ID text: `%03X` standard, `%08X` extended.
pub(crate) struct IdText(pub Id);

impl fmt::Display for IdText {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.0 {
            Id::Standard(id) => write!(f, "{:03X}", id.as_raw()),
            Id::Extended(id) => write!(f, "{:08X}", id.as_raw()),
        }
    }
}

/// The element, with `<` and `>`, as buslab's client sends it.
impl fmt::Display for Command {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Command::Open(bus) => write!(f, "< open {bus} >"),
            Command::RawMode => f.write_str("< rawmode >"),
            Command::BcmMode => f.write_str("< bcmmode >"),
            Command::ControlMode => f.write_str("< controlmode >"),
            Command::IsotpMode => f.write_str("< isotpmode >"),
            Command::Echo => f.write_str("< echo >"),
            Command::Send(frame) => {
                write!(f, "< send {} ", IdText(frame.id()))?;
                if frame.is_remote() {
                    write!(f, "R{} >", frame.dlc())
                } else {
                    write!(f, "{}", frame.dlc())?;
                    for b in frame.payload() {
                        write!(f, " {b:02X}")?;
                    }
                    f.write_str(" >")
                }
            }
            Command::Unsupported { name, args } => {
                write!(f, "< {name}")?;
                for a in args {
                    write!(f, " {a}")?;
                }
                f.write_str(" >")
            }
            Command::Name(name) => write!(f, "< buslab_name {name} >"),
            Command::Extensions => f.write_str("< buslab_ext >"),
            Command::ReceiveOwn(on) => write!(f, "< buslab_own {} >", *on as u8),
            Command::ErrorFrames(on) => write!(f, "< buslab_errors {} >", *on as u8),
            Command::Nodes => f.write_str("< buslab_nodes >"),
            Command::Flush => f.write_str("< buslab_flush >"),
            Command::Abort => f.write_str("< buslab_abort >"),
            Command::Status(None) => f.write_str("< buslab_status >"),
            Command::Status(Some(n)) => write!(f, "< buslab_status {n} >"),
            Command::Regs(None) => f.write_str("< buslab_regs >"),
            Command::Regs(Some(n)) => write!(f, "< buslab_regs {n} >"),
            Command::Btr { btr0, btr1 } => write!(f, "< buslab_btr {btr0:02X} {btr1:02X} >"),
            Command::Fault { fault, lasting_ms } => {
                write!(f, "< buslab_fault {lasting_ms} {}", fault.name())?;
                match fault {
                    WireFault::Cut {
                        far_side,
                        error_rate,
                    } => write!(f, " {} {error_rate}", node_list(far_side))?,
                    WireFault::Disconnect { node } => write!(f, " {node}")?,
                    WireFault::Flip { node: Some(node) } => write!(f, " {node}")?,
                    WireFault::Flip { node: None } => f.write_str(" *")?,
                    WireFault::Noise { nodes, rate } => write!(f, " {} {rate}", node_list(nodes))?,
                    WireFault::StuckDominant => {}
                }
                f.write_str(" >")
            }
            Command::Repair => f.write_str("< buslab_repair >"),
            Command::Controller(settings) => write!(
                f,
                "< {} {} >",
                crate::controller::NAME,
                crate::controller::Args(settings)
            ),
            Command::Board { slio, change } => {
                write!(f, "< buslab_board {slio}")?;
                match change {
                    None => {}
                    Some(BoardInput::Switch { switch, on }) => {
                        write!(f, " switch {switch} {}", u8::from(*on))?
                    }
                    Some(BoardInput::Switches(bits)) => write!(f, " switches {:X}", bits & 0xF)?,
                    // Rust's shortest text that reads back as the same number.
                    Some(BoardInput::Potentiometer(v)) => write!(f, " pot {}", v.get())?,
                }
                f.write_str(" >")
            }
            Command::BusOff(recovery) => write!(
                f,
                "< buslab_busoff {} >",
                match recovery {
                    BusOffRecovery::Counted => "counted",
                    BusOffRecovery::Fast => "fast",
                    BusOffRecovery::Manual => "manual",
                }
            ),
        }
    }
}

#[cfg(test)]
mod tests {
    use proptest::prelude::*;

    use super::*;

    /// Element insides near the `send` layout: names, IDs, DLCs and bytes slightly off.
    fn send_like() -> impl Strategy<Value = String> {
        let name = prop_oneof!["send", "sen", "sends", "Send", "open"];
        let space = "[ \t\n]{1,2}";
        let id = "[0-9a-fA-F+gR -]{0,10}";
        let dlc = "[0-9Rr+ -]{0,3}";
        let bytes = prop::collection::vec("[0-9a-fA-Fg+]{0,3}", 0..10);
        let gap = prop_oneof![
            Just(" ".to_string()),
            Just("  ".to_string()),
            Just("\t".to_string())
        ];
        (space, name, " {1,2}", id, " {1,2}", dlc, bytes, gap, space).prop_map(
            |(a, name, b, id, c, dlc, bytes, gap, e)| {
                let mut text = format!("{a}{name}{b}{id}{c}{dlc}");
                for byte in bytes {
                    text += &gap;
                    text += &byte;
                }
                text + &e
            },
        )
    }

    proptest! {
        /// What the fast path reads, the tokens read the same; it never refuses for them.
        #[test]
        fn the_fast_send_path_reads_as_the_tokens_do(inner in send_like()) {
            if let Some(frame) = parse_send_fast(inner.as_bytes()) {
                prop_assert_eq!(Command::parse_tokens(&inner), Ok(Command::Send(frame)));
            }
            prop_assert_eq!(Command::parse(&inner), Command::parse_tokens(&inner));
        }

        /// Every data frame buslab's client sends takes the fast path.
        #[test]
        fn sent_data_frames_take_the_fast_path(
            raw in 0u32..0x2000_0000,
            extended: bool,
            data in prop::collection::vec(any::<u8>(), 0..=8),
        ) {
            let id = if extended {
                Id::extended(raw).unwrap()
            } else {
                Id::standard((raw & 0x7FF) as u16).unwrap()
            };
            let frame = Frame::data(id, &data).unwrap();
            let text = Command::Send(frame).to_string();
            let inner = &text[1..text.len() - 1];
            prop_assert_eq!(parse_send_fast(inner.as_bytes()), Some(frame));
        }
    }

    #[test]
    fn python_can_s_send_layout_takes_the_fast_path() {
        // python-can's socketcand interface: bytes in lower-case hex without padding.
        let frame = Frame::data(Id::standard(0x12).unwrap(), &[0x1, 0xab]).unwrap();
        assert_eq!(parse_send_fast(b" send 12 2 1 ab "), Some(frame));
        assert_eq!(
            parse_send_fast(b" send 12 0 "),
            Some(Frame::data(Id::standard(0x12).unwrap(), &[]).unwrap())
        );
        // Not this layout: the tokens decide (a remote frame, a bad count, spaces).
        for inner in [
            " send 12 2 ",
            " send 12 R2 ",
            " send 12 1 1 2 ",
            " send  12 0 ",
            " send 12 9 ",
        ] {
            assert_eq!(parse_send_fast(inner.as_bytes()), None, "{inner:?}");
        }
    }

    fn slio(n: u8) -> SlioId {
        SlioId::new(n).unwrap()
    }

    #[test]
    fn board_commands_round_trip_through_their_text() {
        let switch = |n, on| BoardInput::Switch {
            switch: BoardSwitch::new(n).unwrap(),
            on,
        };
        let pot = |v| BoardInput::Potentiometer(BoardVolts::new(v).unwrap());
        for (command, text) in [
            ((slio(3), None), "< buslab_board 3 >"),
            (
                (slio(3), Some(switch(2, true))),
                "< buslab_board 3 switch 2 1 >",
            ),
            (
                (slio(10), Some(switch(0, false))),
                "< buslab_board A switch 0 0 >",
            ),
            (
                (slio(15), Some(BoardInput::Switches(0x5))),
                "< buslab_board F switches 5 >",
            ),
            ((slio(0), Some(pot(2.5))), "< buslab_board 0 pot 2.5 >"),
            ((slio(0), Some(pot(5.0))), "< buslab_board 0 pot 5 >"),
            (
                (slio(0), Some(pot(1.0 / 3.0))),
                "< buslab_board 0 pot 0.3333333333333333 >",
            ),
        ] {
            let (slio, change) = command;
            let command = Command::Board { slio, change };
            assert_eq!(command.to_string(), text);
            let inner = text.strip_prefix("< ").unwrap().strip_suffix(" >").unwrap();
            assert_eq!(Command::parse(inner).unwrap(), command, "{text}");
        }
        // A switch is on with 1, a SLIO is one hex digit either case.
        assert_eq!(
            Command::parse("buslab_board a switch 3 1").unwrap(),
            Command::Board {
                slio: slio(10),
                change: Some(switch(3, true)),
            }
        );
    }

    #[test]
    fn bad_board_commands_name_what_is_wrong() {
        for (text, named) in [
            ("buslab_board", "SLIO (one hex digit 0..F)"),
            ("buslab_board 10", "got \"10\""),
            ("buslab_board G", "got \"G\""),
            (
                "buslab_board 3 switch 4 1",
                "switch 4: a demo board has input switches 0..=3",
            ),
            ("buslab_board 3 switch 1 on", "got \"3 switch 1 on\""),
            ("buslab_board 3 switch +1 1", "got \"3 switch +1 1\""),
            ("buslab_board 3 switches 10", "got \"3 switches 10\""),
            (
                "buslab_board 3 pot 5.5",
                "5.5 V: a demo board's analog inputs take 0..=5 V",
            ),
            ("buslab_board 3 pot -1", "got \"3 pot -1\""),
            ("buslab_board 3 pot NaN", "got \"3 pot NaN\""),
            ("buslab_board 3 pot inf", "got \"3 pot inf\""),
            ("buslab_board 3 pot 1e0", "got \"3 pot 1e0\""),
            ("buslab_board 3 pot 1.2.3", "got \"3 pot 1.2.3\""),
            ("buslab_board 3 pot", "got \"3 pot\""),
            ("buslab_board 3 led 7 1", "got \"3 led 7 1\""),
        ] {
            let e = Command::parse(text).unwrap_err().to_string();
            assert!(e.contains(named), "{text}: {e}");
            assert!(e.contains("buslab_board"), "{text}: {e}");
        }
    }
}
