//! A [`CanBus`] over a socketcand TCP connection in raw mode (the IO adapter around the codec).

use std::collections::VecDeque;
use std::fmt;
use std::io::{self, Read, Write};
use std::net::{TcpStream, ToSocketAddrs};
use std::time::{Duration, Instant};

use buslab_can::Frame;
use buslab_canbus::bus::matches_any;
use buslab_canbus::{
    Alc, BusError, BusState, CanBus, CanMode, Ecc, ErrorRegisters, Filter, Message, RegisterDump,
    Status,
};

use crate::command::{Command, NodeRef};
use crate::element::{Deframer, ElementError};
use crate::message::ServerMessage;
use crate::{ProtocolError, sanitize};

/// How long the client waits for the answer to a request.
const REPLY_TIMEOUT: Duration = Duration::from_secs(5);

/// Why talking to a socketcand server failed.
#[derive(Debug, thiserror::Error)]
pub enum ClientError {
    #[error("{0}")]
    Io(#[from] io::Error),
    #[error("the server closed the connection")]
    Closed,
    #[error("handshake: expected {expected}, got {got}")]
    Handshake { expected: &'static str, got: String },
    #[error("the server answered: {0}")]
    Server(String),
    #[error("no answer to {0} within 5 s")]
    Timeout(String),
    #[error("bad message from the server: {0}")]
    Protocol(#[from] ProtocolError),
    #[error("bad data from the server: {0}")]
    Element(#[from] ElementError),
    #[error("bad {what} reply: {text}")]
    Reply { what: &'static str, text: String },
}

impl From<ClientError> for BusError {
    fn from(e: ClientError) -> Self {
        match e {
            ClientError::Io(e) => BusError::Io(e),
            ClientError::Closed => BusError::Closed,
            ClientError::Protocol(_) | ClientError::Element(_) | ClientError::Reply { .. } => {
                BusError::Protocol(e.to_string())
            }
            other => BusError::Other(other.to_string()),
        }
    }
}

/// A node's status as a buslab server reports it (`< buslab_status … >`).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct NodeStatus {
    pub number: u32,
    pub name: String,
    /// Every `key=value` pair in the order the server sent them.
    pub fields: Vec<(String, String)>,
}

impl NodeStatus {
    pub fn get(&self, key: &str) -> Option<&str> {
        self.fields
            .iter()
            .find(|(k, _)| k == key)
            .map(|(_, v)| v.as_str())
    }

    fn hex(&self, key: &str) -> Option<u8> {
        self.get(key).and_then(|v| u8::from_str_radix(v, 16).ok())
    }

    fn num(&self, key: &str) -> Option<u64> {
        self.get(key).and_then(|v| v.parse().ok())
    }

    /// SR.
    pub fn status(&self) -> Option<Status> {
        self.hex("sr").map(Status)
    }

    /// RXERR, TXERR and the last captured ALC and ECC.
    pub fn error_registers(&self) -> ErrorRegisters {
        ErrorRegisters {
            alc: self.hex("alc").map(Alc),
            ecc: self.hex("ecc").map(Ecc),
            rxerr: self.num("rxerr").unwrap_or(0) as u8,
            txerr: self.num("txerr").unwrap_or(0) as u8,
        }
    }

    pub fn state(&self) -> BusState {
        match self.get("state") {
            Some("bus-off") => BusState::BusOff,
            Some("error-passive") => BusState::Passive,
            _ => BusState::Active,
        }
    }
}

/// Several lines: the node, its state, SR in words, the counters, ALC and ECC in words, and
/// the server's other counters.
impl fmt::Display for NodeStatus {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fn row(f: &mut fmt::Formatter<'_>, label: &str, value: impl fmt::Display) -> fmt::Result {
            writeln!(f, "{:<18}{value}", format!("{label}:"))
        }
        writeln!(f, "node {} ({})", self.number, self.name)?;
        row(f, "state", self.get("state").unwrap_or("?"))?;
        if let Some(sr) = self.status() {
            row(f, "STATUS", sr)?;
        }
        let e = self.error_registers();
        row(f, "TXERR", e.txerr)?;
        row(f, "RXERR", e.rxerr)?;
        match e.alc {
            Some(alc) => row(f, "ALC", format_args!("0x{:02X} {alc}", alc.0))?,
            None => row(f, "ALC", "none captured")?,
        }
        match e.ecc {
            Some(ecc) => row(f, "ECC", format_args!("0x{:02X} {ecc}", ecc.0))?,
            None => row(f, "ECC", "none captured")?,
        }
        for (k, v) in &self.fields {
            if !matches!(
                k.as_str(),
                "state" | "sr" | "txerr" | "rxerr" | "alc" | "ecc"
            ) {
                row(f, k, v)?;
            }
        }
        Ok(())
    }
}

/// A connection to a socketcand server, in raw mode on one bus.
#[derive(Debug)]
pub struct SocketcandBus {
    stream: TcpStream,
    deframer: Deframer,
    inbox: VecDeque<Message>,
    error_frames: VecDeque<(u32, f64)>,
    channel: String,
    filters: Vec<Filter>,
    extensions: bool,
    buf: Vec<u8>,
}

impl SocketcandBus {
    /// Connects, checks `< hi >`, opens `channel` and switches to raw mode (python-can's
    /// sequence).
    pub fn connect(addr: impl ToSocketAddrs, channel: &str) -> Result<Self, ClientError> {
        let stream = TcpStream::connect(addr)?;
        stream.set_nodelay(true)?;
        let mut bus = Self {
            stream,
            deframer: Deframer::new(),
            inbox: VecDeque::new(),
            error_frames: VecDeque::new(),
            channel: channel.to_string(),
            filters: Vec::new(),
            extensions: false,
            buf: vec![0; 64 * 1024],
        };
        let deadline = Instant::now() + REPLY_TIMEOUT;
        match bus.next_message(Some(deadline))? {
            Some(ServerMessage::Hi) => {}
            other => return Err(handshake("< hi >", other)),
        }
        bus.write(&Command::Open(channel.to_string()))?;
        bus.expect_ok("< ok > after open")?;
        bus.write(&Command::RawMode)?;
        bus.expect_ok("< ok > after rawmode")?;
        Ok(bus)
    }

    fn expect_ok(&mut self, expected: &'static str) -> Result<(), ClientError> {
        let deadline = Instant::now() + REPLY_TIMEOUT;
        match self.next_message(Some(deadline))? {
            Some(ServerMessage::Ok) => Ok(()),
            other => Err(handshake(expected, other)),
        }
    }

    /// Turns on buslab's extensions (remote frames as `R<dlc>`); `false` if the server is a
    /// plain socketcand that does not know them.
    pub fn enable_extensions(&mut self) -> Result<bool, ClientError> {
        match self.request(&Command::Extensions, None) {
            Ok(_) => {
                self.extensions = true;
                Ok(true)
            }
            Err(ClientError::Server(_)) => Ok(false),
            Err(e) => Err(e),
        }
    }

    /// Names this client's node (buslab servers).
    pub fn set_name(&mut self, name: &str) -> Result<(), ClientError> {
        self.request(&Command::Name(name.to_string()), None)
            .map(drop)
    }

    /// Also receive this client's own frames once they were sent.
    pub fn receive_own(&mut self, on: bool) -> Result<(), ClientError> {
        self.request(&Command::ReceiveOwn(on), None).map(drop)
    }

    /// Also receive error frames (buslab servers; a socketcand started with `-e` sends them
    /// anyway): they are collected for [`Self::take_error_frames`].
    pub fn enable_error_frames(&mut self, on: bool) -> Result<(), ClientError> {
        self.request(&Command::ErrorFrames(on), None).map(drop)
    }

    /// The error frames received so far: `(SocketCAN error class, timestamp)`.
    pub fn take_error_frames(&mut self) -> Vec<(u32, f64)> {
        self.error_frames.drain(..).collect()
    }

    /// Reprograms this client's chip with BTR0/BTR1 (buslab servers).
    pub fn set_btr(&mut self, btr0: u8, btr1: u8) -> Result<(), ClientError> {
        self.request(&Command::Btr { btr0, btr1 }, None).map(drop)
    }

    /// The nodes on the bus: `(number, name)`.
    pub fn nodes(&mut self) -> Result<Vec<(u32, String)>, ClientError> {
        let args = self.request(&Command::Nodes, Some("buslab_nodes"))?;
        args.iter()
            .map(|a| {
                a.split_once(':')
                    .and_then(|(n, name)| Some((n.parse().ok()?, name.to_string())))
                    .ok_or_else(|| ClientError::Reply {
                        what: "buslab_nodes",
                        text: a.clone(),
                    })
            })
            .collect()
    }

    /// A node's status (own node if `None`).
    pub fn node_status(&mut self, node: Option<NodeRef>) -> Result<NodeStatus, ClientError> {
        let args = self.request(&Command::Status(node), Some("buslab_status"))?;
        let bad = |args: &[String]| ClientError::Reply {
            what: "buslab_status",
            text: args.join(" "),
        };
        let [number, name, fields @ ..] = args.as_slice() else {
            return Err(bad(&args));
        };
        let fields = fields
            .iter()
            .map(|f| {
                f.split_once('=')
                    .map(|(k, v)| (k.to_string(), v.to_string()))
            })
            .collect::<Option<Vec<_>>>()
            .ok_or_else(|| bad(&args))?;
        Ok(NodeStatus {
            number: number.parse().map_err(|_| bad(&args))?,
            name: name.clone(),
            fields,
        })
    }

    /// A node's register dump (own node if `None`): `(number, name, dump)`.
    pub fn register_dump(
        &mut self,
        node: Option<NodeRef>,
    ) -> Result<(u32, String, RegisterDump), ClientError> {
        let args = self.request(&Command::Regs(node), Some("buslab_regs"))?;
        let bad = || ClientError::Reply {
            what: "buslab_regs",
            text: args.join(" "),
        };
        let [number, name, mode, state, values @ ..] = args.as_slice() else {
            return Err(bad());
        };
        let mode = match mode.as_str() {
            "peli" => CanMode::Peli,
            "basic" => CanMode::Basic,
            _ => return Err(bad()),
        };
        let values = values
            .iter()
            .map(|v| match v.as_str() {
                "--" => Ok(None),
                v => u8::from_str_radix(v, 16).map(Some),
            })
            .collect::<Result<Vec<_>, _>>()
            .map_err(|_| bad())?;
        Ok((
            number.parse().map_err(|_| bad())?,
            name.clone(),
            RegisterDump {
                mode,
                reset_mode: state == "reset",
                values,
            },
        ))
    }

    /// Sends `cmd` and waits for `< ok >`, for the reply element called `reply`, or for
    /// `< error … >`. Frames that arrive meanwhile are kept for [`CanBus::recv`].
    fn request(&mut self, cmd: &Command, reply: Option<&str>) -> Result<Vec<String>, ClientError> {
        self.write(cmd)?;
        let deadline = Instant::now() + REPLY_TIMEOUT;
        loop {
            match self.next_message(Some(deadline))? {
                None => return Err(ClientError::Timeout(cmd.to_string())),
                Some(ServerMessage::Ok) if reply.is_none() => return Ok(Vec::new()),
                Some(ServerMessage::Other { name, args }) if Some(name.as_str()) == reply => {
                    return Ok(args);
                }
                Some(ServerMessage::Error(text)) => return Err(ClientError::Server(text)),
                Some(_) => {}
            }
        }
    }

    fn write(&mut self, cmd: &Command) -> Result<(), ClientError> {
        self.stream.write_all(cmd.to_string().as_bytes())?;
        Ok(())
    }

    /// The next server message other than a frame (frames go to the inbox), or `None` at the
    /// deadline. `None` deadline: wait forever.
    fn next_message(
        &mut self,
        deadline: Option<Instant>,
    ) -> Result<Option<ServerMessage>, ClientError> {
        loop {
            match self.pump(deadline)? {
                Pumped::Message(m) => return Ok(Some(m)),
                Pumped::Frames => {}
                Pumped::Deadline => return Ok(None),
            }
        }
    }

    /// Handles what is buffered, reading once if nothing is: a message, or the news that
    /// frames arrived (now in the inbox), or the deadline.
    fn pump(&mut self, deadline: Option<Instant>) -> Result<Pumped, ClientError> {
        loop {
            let mut frames = false;
            while let Some(element) = self.deframer.next_element() {
                let msg = ServerMessage::parse(&element?)?;
                match msg {
                    ServerMessage::Frame { frame, timestamp } => {
                        frames = true;
                        self.inbox.push_back(Message::rx(
                            timestamp.as_secs_f64(),
                            self.channel.clone(),
                            frame,
                        ));
                    }
                    ServerMessage::ErrorFrame {
                        class, timestamp, ..
                    } => {
                        frames = true;
                        self.error_frames
                            .push_back((class, timestamp.as_secs_f64()));
                    }
                    other => return Ok(Pumped::Message(other)),
                }
            }
            if frames {
                return Ok(Pumped::Frames);
            }
            if !self.fill(deadline)? {
                return Ok(Pumped::Deadline);
            }
        }
    }

    /// Reads more bytes; `false` at the deadline.
    fn fill(&mut self, deadline: Option<Instant>) -> Result<bool, ClientError> {
        let timeout = match deadline {
            None => None,
            Some(d) => {
                let left = d.saturating_duration_since(Instant::now());
                if left.is_zero() {
                    return Ok(false);
                }
                Some(left)
            }
        };
        self.stream.set_read_timeout(timeout)?;
        match self.stream.read(&mut self.buf) {
            Ok(0) => Err(ClientError::Closed),
            Ok(n) => {
                self.deframer.push(&self.buf[..n]);
                Ok(true)
            }
            Err(e)
                if matches!(
                    e.kind(),
                    io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut
                ) =>
            {
                Ok(false)
            }
            Err(e) if e.kind() == io::ErrorKind::Interrupted => Ok(true),
            Err(e) => Err(e.into()),
        }
    }

    /// The next received message that passes the filters.
    fn pop_matching(&mut self) -> Option<Message> {
        while let Some(m) = self.inbox.pop_front() {
            if matches_any(&self.filters, &m.frame) {
                return Some(m);
            }
        }
        None
    }
}

/// What [`SocketcandBus::pump`] found.
enum Pumped {
    Message(ServerMessage),
    Frames,
    Deadline,
}

fn handshake(expected: &'static str, got: Option<ServerMessage>) -> ClientError {
    ClientError::Handshake {
        expected,
        got: got.map_or_else(
            || "nothing within 5 s".to_string(),
            |m| sanitize(&m.to_string()),
        ),
    }
}

impl CanBus for SocketcandBus {
    fn send(&mut self, frame: &Frame) -> Result<(), BusError> {
        self.write(&Command::Send(*frame))?;
        Ok(())
    }

    fn recv(&mut self, timeout: Option<Duration>) -> Result<Option<Message>, BusError> {
        let deadline = timeout.map(|t| Instant::now() + t);
        loop {
            if let Some(m) = self.pop_matching() {
                return Ok(Some(m));
            }
            match self.pump(deadline)? {
                Pumped::Deadline => return Ok(None),
                // An error sent without a request (e.g. for a refused command): report it.
                Pumped::Message(ServerMessage::Error(text)) => {
                    return Err(BusError::Rejected(text));
                }
                _ => {}
            }
        }
    }

    fn set_filters(&mut self, filters: &[Filter]) -> Result<(), BusError> {
        self.filters = filters.to_vec();
        Ok(())
    }

    fn state(&mut self) -> Result<BusState, BusError> {
        if !self.extensions {
            return Ok(BusState::Active);
        }
        Ok(self.node_status(None)?.state())
    }

    fn channel_info(&self) -> String {
        match self.stream.peer_addr() {
            Ok(addr) => format!("socketcand://{addr}/{}", self.channel),
            Err(_) => format!("socketcand {}", self.channel),
        }
    }
}
