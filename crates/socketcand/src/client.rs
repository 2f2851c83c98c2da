//! A [`CanBus`] over a socketcand TCP connection in raw mode (the IO adapter around the codec),
//! with buslab's extensions as a [`BusAdmin`] when the server has them.

pub mod inbound;

use std::io::{self, Read, Write};
use std::net::{TcpStream, ToSocketAddrs};
use std::os::fd::AsFd;
use std::sync::Arc;
use std::time::{Duration, Instant};

use buslab_bus::admin::FaultLimit;
use buslab_bus::bus::Human;
use buslab_bus::{
    BusAdmin, BusError, BusOffRecovery, CanBus, ControllerSettings, ErrorState, FdSupport, Filter,
    Message, NoFd, NodeInfo, NodeRef, NodeRegisters, NodeStatus, RecvWaker, TxReport, WireFault,
};
use buslab_can::Frame;

use crate::command::Command;
use crate::element::ElementError;
use crate::message::ServerMessage;
use crate::reply::{self, ReplyError};
use crate::{ProtocolError, sanitize};
use buslab_link::wake::{WakeLine, wait_readable};
use inbound::Inbound;
pub use inbound::MAX_INBOX;

/// Deadlines of a client.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ClientOptions {
    /// How long to wait for the TCP connection.
    pub connect_timeout: Duration,
    /// How long to wait for the answer to a request (the handshake, status, registers…).
    pub reply_timeout: Duration,
}

impl Default for ClientOptions {
    fn default() -> Self {
        Self {
            connect_timeout: Duration::from_secs(10),
            reply_timeout: Duration::from_secs(5),
        }
    }
}

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
    #[error("no answer to {request} within {}", Human(*after))]
    Timeout { request: String, after: Duration },
    #[error("bad message from the server: {0}")]
    Protocol(#[from] ProtocolError),
    #[error("bad data from the server: {0}")]
    Element(#[from] ElementError),
    #[error("bad reply from the server: {0}")]
    Reply(#[from] ReplyError),
    #[error("{0} needs a buslab server (this one has no buslab extensions)")]
    NoExtensions(&'static str),
    /// A limit of the server refused the request (`< buslab_refused … >`).
    #[error("the server refused: {0}")]
    Refused(FaultLimit),
}

impl From<ClientError> for BusError {
    fn from(e: ClientError) -> Self {
        match e {
            ClientError::Io(e) => BusError::Io(e),
            ClientError::Closed => BusError::Closed,
            ClientError::Timeout { request, after } => BusError::Timeout {
                what: format!("answer to {request}"),
                after,
            },
            ClientError::Protocol(_) | ClientError::Element(_) | ClientError::Reply(_) => {
                BusError::Protocol(Box::new(e))
            }
            ClientError::Refused(limit) => BusError::FaultRefused(limit),
            other => BusError::Other(Box::new(other)),
        }
    }
}

/// How this client learns that its frames were sent.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum FlushMode {
    /// Not tried yet.
    Unknown,
    /// `< buslab_flush >`, answered when done.
    Event,
    /// FALLBACK for buslab servers older than `buslab_flush`: poll `buslab_status`.
    Polling,
}

/// A connection to a socketcand server, in raw mode on one bus.
#[derive(Debug)]
pub struct SocketcandBus {
    stream: TcpStream,
    /// What was received and not handed out yet.
    inbound: Inbound,
    channel: String,
    extensions: bool,
    flush: FlushMode,
    /// Frames written since the connection opened (the node's counters start there too).
    sent: u64,
    /// Replies still owed for requests that timed out, by reply name (`ok` for `< ok >`):
    /// dropped when they come, so they cannot answer a later request.
    late: Vec<&'static str>,
    options: ClientOptions,
    buf: Vec<u8>,
    /// Ends a wait for frames from another thread, once [`CanBus::recv_waker`] asked for it.
    wake: Option<WakeLine>,
}

impl SocketcandBus {
    /// Connects, checks `< hi >`, opens `channel` and switches to raw mode (python-can's
    /// sequence), with the default deadlines.
    pub fn connect(addr: impl ToSocketAddrs, channel: &str) -> Result<Self, ClientError> {
        Self::connect_with(addr, channel, ClientOptions::default())
    }

    /// [`Self::connect`] with other deadlines.
    pub fn connect_with(
        addr: impl ToSocketAddrs,
        channel: &str,
        options: ClientOptions,
    ) -> Result<Self, ClientError> {
        let stream = connect_any(addr, options.connect_timeout)?;
        stream.set_nodelay(true)?;
        let mut bus = Self {
            stream,
            inbound: Inbound::new(channel),
            channel: channel.to_string(),
            extensions: false,
            flush: FlushMode::Unknown,
            sent: 0,
            late: Vec::new(),
            options,
            buf: vec![0; 64 * 1024],
            wake: None,
        };
        let deadline = Instant::now() + options.reply_timeout;
        match bus.next_message(Some(deadline))? {
            Some(ServerMessage::Hi) => {}
            other => return Err(bus.handshake("< hi >", other)),
        }
        bus.write(&Command::Open(channel.to_string()))?;
        bus.expect_ok("< ok > after open")?;
        bus.write(&Command::RawMode)?;
        bus.expect_ok("< ok > after rawmode")?;
        tracing::debug!("joined {}", bus.channel_info());
        Ok(bus)
    }

    fn expect_ok(&mut self, expected: &'static str) -> Result<(), ClientError> {
        let deadline = Instant::now() + self.options.reply_timeout;
        match self.next_message(Some(deadline))? {
            Some(ServerMessage::Ok) => Ok(()),
            other => Err(self.handshake(expected, other)),
        }
    }

    fn handshake(&self, expected: &'static str, got: Option<ServerMessage>) -> ClientError {
        ClientError::Handshake {
            expected,
            got: got.map_or_else(
                || format!("nothing within {}", Human(self.options.reply_timeout)),
                |m| sanitize(&m.to_string()),
            ),
        }
    }

    /// Turns on buslab's extensions (remote frames as `R<dlc>`, status, registers, flush);
    /// `false` if the server is a plain socketcand that does not know them.
    pub fn enable_extensions(&mut self) -> Result<bool, ClientError> {
        match self.request(&Command::Extensions, None, self.options.reply_timeout) {
            Ok(_) => {
                self.extensions = true;
                Ok(true)
            }
            Err(ClientError::Server(text)) => {
                tracing::debug!("no buslab extensions: the server answered {text:?}");
                Ok(false)
            }
            Err(e) => Err(e),
        }
    }

    /// Whether [`Self::enable_extensions`] found them.
    pub fn has_extensions(&self) -> bool {
        self.extensions
    }

    fn need_extensions(&self, what: &'static str) -> Result<(), ClientError> {
        if self.extensions {
            Ok(())
        } else {
            Err(ClientError::NoExtensions(what))
        }
    }

    /// Names this client's node (buslab servers).
    pub fn set_name(&mut self, name: &str) -> Result<(), ClientError> {
        self.need_extensions("naming a node")?;
        self.request(
            &Command::Name(name.to_string()),
            None,
            self.options.reply_timeout,
        )
        .map(drop)
    }

    /// Also receive this client's own frames once they were sent (buslab servers).
    pub fn receive_own(&mut self, on: bool) -> Result<(), ClientError> {
        self.need_extensions("receiving own frames")?;
        self.request(&Command::ReceiveOwn(on), None, self.options.reply_timeout)
            .map(drop)
    }

    /// Gives up this client's frame being tried and the queued ones (buslab servers).
    pub fn abort(&mut self) -> Result<(), ClientError> {
        self.need_extensions("aborting a transmission")?;
        self.request(&Command::Abort, None, self.options.reply_timeout)
            .map(drop)
    }

    /// Reprograms this client's chip with BTR0/BTR1 (buslab servers).
    pub fn set_btr(&mut self, btr0: u8, btr1: u8) -> Result<(), ClientError> {
        self.need_extensions("setting the bit timing")?;
        self.request(
            &Command::Btr { btr0, btr1 },
            None,
            self.options.reply_timeout,
        )
        .map(drop)
    }

    /// Reprograms this client's chip with the parts of a controller configuration that are
    /// given (buslab servers: `< buslab_controller … >`).
    pub fn configure(&mut self, settings: &ControllerSettings) -> Result<(), ClientError> {
        self.need_extensions("controller settings")?;
        self.request(
            &Command::Controller(*settings),
            None,
            self.options.reply_timeout,
        )
        .map(drop)
    }

    /// How this client's chip comes back after bus-off (buslab servers).
    pub fn set_bus_off_recovery(&mut self, recovery: BusOffRecovery) -> Result<(), ClientError> {
        self.need_extensions("choosing the bus-off recovery")?;
        self.request(&Command::BusOff(recovery), None, self.options.reply_timeout)
            .map(drop)
    }

    /// Puts a fault on the virtual bus's wire for `lasting` (until repaired if `None`;
    /// buslab servers).
    pub fn inject_fault(
        &mut self,
        fault: &WireFault,
        lasting: Option<Duration>,
    ) -> Result<(), ClientError> {
        self.need_extensions("fault injection")?;
        // 0 means "until repaired": a lasting fault is at least 1 ms.
        let lasting_ms = lasting.map_or(0, |d| d.as_millis().clamp(1, u64::MAX as u128) as u64);
        self.request(
            &Command::Fault {
                fault: fault.clone(),
                lasting_ms,
            },
            None,
            self.options.reply_timeout,
        )
        .map(drop)
    }

    /// Ends every fault on the virtual bus's wire (buslab servers).
    pub fn repair(&mut self) -> Result<(), ClientError> {
        self.need_extensions("fault injection")?;
        self.request(&Command::Repair, None, self.options.reply_timeout)
            .map(drop)
    }

    /// A SLIO demo board on the virtual bus, after `change` to its inputs (buslab servers).
    pub fn demo_board(
        &mut self,
        slio: buslab_bus::SlioId,
        change: Option<buslab_bus::admin::BoardInput>,
    ) -> Result<buslab_bus::admin::BoardState, ClientError> {
        self.need_extensions("demo boards")?;
        let args = self.request(
            &Command::Board { slio, change },
            Some(reply::BOARD),
            self.options.reply_timeout,
        )?;
        Ok(reply::parse_board(&args)?)
    }

    /// The nodes on the bus.
    pub fn nodes(&mut self) -> Result<Vec<NodeInfo>, ClientError> {
        self.need_extensions("listing nodes")?;
        let args = self.request(
            &Command::Nodes,
            Some(reply::NODES),
            self.options.reply_timeout,
        )?;
        Ok(reply::parse_nodes(&args)?)
    }

    /// A node's status (own node if `None`).
    pub fn node_status(&mut self, node: Option<&NodeRef>) -> Result<NodeStatus, ClientError> {
        self.need_extensions("node status")?;
        let args = self.request(
            &Command::Status(node.cloned()),
            Some(reply::STATUS),
            self.options.reply_timeout,
        )?;
        Ok(reply::parse_status(&args)?)
    }

    /// A node's register dump (own node if `None`).
    pub fn register_dump(&mut self, node: Option<&NodeRef>) -> Result<NodeRegisters, ClientError> {
        self.need_extensions("register dumps")?;
        let args = self.request(
            &Command::Regs(node.cloned()),
            Some(reply::REGS),
            self.options.reply_timeout,
        )?;
        Ok(reply::parse_regs(&args)?)
    }

    /// Waits until every frame this client sent so far was transmitted or given up
    /// (`< buslab_flush >`); frames received meanwhile are kept for `recv`.
    pub fn flush(&mut self, timeout: Duration) -> Result<TxReport, ClientError> {
        self.need_extensions("confirming sent frames")?;
        if self.flush == FlushMode::Polling {
            return self.flush_by_polling(timeout);
        }
        match self.request(&Command::Flush, Some(reply::FLUSHED), timeout) {
            Ok(args) => {
                self.flush = FlushMode::Event;
                Ok(reply::parse_flushed(&args)?)
            }
            Err(ClientError::Server(text))
                if self.flush == FlushMode::Unknown && unknown_command(&text) =>
            {
                tracing::debug!(
                    "the server does not know buslab_flush ({text:?}): polling buslab_status instead"
                );
                self.flush = FlushMode::Polling;
                self.flush_by_polling(timeout)
            }
            Err(e) => Err(e),
        }
    }

    /// FALLBACK, only for buslab servers that answer `buslab_flush` as an unknown command
    /// (before issue 8): polls this node's status every 5 ms until its sent and failed
    /// counters account for every frame this client wrote.
    fn flush_by_polling(&mut self, timeout: Duration) -> Result<TxReport, ClientError> {
        let deadline = Instant::now() + timeout;
        loop {
            let st = self.node_status(None)?;
            let report = TxReport {
                sent: st.counters.sent,
                failed: st.counters.tx_failed,
            };
            if report.sent + report.failed >= self.sent {
                return Ok(report);
            }
            let now = Instant::now();
            if now >= deadline {
                return Err(ClientError::Timeout {
                    request: Command::Flush.to_string(),
                    after: timeout,
                });
            }
            // Take in frames meanwhile so the server never has to drop ours.
            let pause = deadline.min(now + Duration::from_millis(5));
            while let Some(m) = self.next_message(Some(pause))? {
                self.unsolicited(m);
            }
        }
    }

    /// Sends `cmd` and waits up to `timeout` for `< ok >` (`reply` = `None`), for the reply
    /// element called `reply`, or for `< error … >`. Frames that arrive meanwhile are kept
    /// for [`CanBus::recv`].
    fn request(
        &mut self,
        cmd: &Command,
        reply: Option<&'static str>,
        timeout: Duration,
    ) -> Result<Vec<String>, ClientError> {
        self.write(cmd)?;
        let deadline = Instant::now() + timeout;
        loop {
            let Some(m) = self.next_message(Some(deadline))? else {
                self.late.push(reply.unwrap_or("ok"));
                return Err(ClientError::Timeout {
                    request: cmd.to_string(),
                    after: timeout,
                });
            };
            match m {
                ServerMessage::Ok if reply.is_none() => return Ok(Vec::new()),
                ServerMessage::Other { name, args } if Some(name.as_str()) == reply => {
                    return Ok(args);
                }
                ServerMessage::Error(text) => return Err(ClientError::Server(text)),
                ServerMessage::Other { name, args } if name == reply::REFUSED => {
                    return Err(ClientError::Refused(reply::parse_refused(&args)?));
                }
                other => self.unsolicited(other),
            }
        }
    }

    /// A message nobody waits for: logged.
    fn unsolicited(&mut self, m: ServerMessage) {
        tracing::debug!(
            "unsolicited message from the server: {}",
            sanitize(&m.to_string())
        );
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
            match self.pump(deadline, Wakeable::No)? {
                Pumped::Message(m) => return Ok(Some(m)),
                Pumped::Frames => {}
                Pumped::Deadline => return Ok(None),
            }
        }
    }

    /// Handles what is buffered, reading once if nothing is: a message, or the news that
    /// frames arrived (now in the inbox), or the deadline (or a wake, when `wakeable`).
    fn pump(
        &mut self,
        deadline: Option<Instant>,
        wakeable: Wakeable,
    ) -> Result<Pumped, ClientError> {
        loop {
            let received = self.inbound.received();
            while let Some(other) = self.inbound.next_message()? {
                if let Some(i) = self.late.iter().position(|&r| owed(r, &other)) {
                    self.late.remove(i);
                    tracing::debug!("a late reply dropped: {}", sanitize(&other.to_string()));
                    continue;
                }
                return Ok(Pumped::Message(other));
            }
            if self.inbound.received() != received {
                return Ok(Pumped::Frames);
            }
            if !self.fill(deadline, wakeable)? {
                return Ok(Pumped::Deadline);
            }
        }
    }

    /// Reads more bytes; `false` at the deadline (or woken, when `wakeable`).
    fn fill(&mut self, deadline: Option<Instant>, wakeable: Wakeable) -> Result<bool, ClientError> {
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
        match self.readable(timeout, wakeable) {
            Ok(true) => {}
            Ok(false) => return Ok(false),
            // A signal: as an interrupted read, the caller waits again until its deadline.
            Err(e) if e.kind() == io::ErrorKind::Interrupted => return Ok(true),
            Err(e) => return Err(e.into()),
        }
        match self.stream.read(&mut self.buf) {
            Ok(0) => Err(ClientError::Closed),
            Ok(n) => {
                self.inbound.push(&self.buf[..n]);
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

    /// Waits until the connection has bytes (or was closed); `false` after `timeout` or when
    /// woken (see [`wait_readable`]).
    fn readable(&self, timeout: Option<Duration>, wakeable: Wakeable) -> io::Result<bool> {
        let wake = self.wake.as_ref().filter(|_| wakeable == Wakeable::Yes);
        wait_readable(self.stream.as_fd(), wake, timeout)
    }

    /// The next event (see [`Inbound::pop`]) or `None` after `timeout`.
    fn next_event(
        &mut self,
        timeout: Option<Duration>,
        with_errors: bool,
    ) -> Result<Option<Message>, BusError> {
        // Read the clock only when waiting: most calls on a busy bus find an event kept.
        let mut deadline = None;
        loop {
            if let Some(event) = self.inbound.pop(with_errors) {
                return Ok(Some(event));
            }
            let deadline = *deadline.get_or_insert_with(|| timeout.map(|t| Instant::now() + t));
            match self.pump(deadline, Wakeable::Yes)? {
                Pumped::Deadline => return Ok(None),
                // An error sent without a request (e.g. for a refused command): report it.
                Pumped::Message(ServerMessage::Error(text)) => {
                    return Err(BusError::Rejected(text.into()));
                }
                Pumped::Message(other) => self.unsolicited(other),
                Pumped::Frames => {}
            }
        }
    }
}

/// Whether `m` is the reply a timed-out request named `reply` still owes.
fn owed(reply: &str, m: &ServerMessage) -> bool {
    match m {
        ServerMessage::Ok => reply == "ok",
        ServerMessage::Other { name, .. } => name == reply,
        _ => false,
    }
}

/// socketcand's `< error unknown command >`, and what buslab servers before `buslab_flush`
/// answered it (`( buslab_flush ) is not an extension command`).
fn unknown_command(text: &str) -> bool {
    text.contains("unknown command") || text.contains("is not an extension command")
}

/// Connects to the first address that answers within `timeout`.
fn connect_any(addr: impl ToSocketAddrs, timeout: Duration) -> io::Result<TcpStream> {
    let mut last = None;
    for a in addr.to_socket_addrs()? {
        match TcpStream::connect_timeout(&a, timeout) {
            Ok(s) => return Ok(s),
            Err(e) => last = Some(e),
        }
    }
    Err(last.unwrap_or_else(|| {
        io::Error::new(io::ErrorKind::InvalidInput, "the host name has no address")
    }))
}

/// Whether a wait ends when the client is woken ([`CanBus::recv_waker`]): a wait for frames
/// does; a wait for the answer to a request does not (the wake is kept for the next wait).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Wakeable {
    Yes,
    No,
}

/// What [`SocketcandBus::pump`] found.
enum Pumped {
    Message(ServerMessage),
    Frames,
    Deadline,
}

impl CanBus for SocketcandBus {
    /// Never: socketcand's protocol has no FD frames (an unmerged branch of socketcand adds
    /// `< sendfd … >` without flags; docs/decisions.md), and a buslab server's bus is the
    /// bit-level one, classic CAN. [`CanBus::send_fd`] refuses with this reason.
    fn fd_support(&self) -> FdSupport {
        FdSupport::Classic(if self.extensions {
            NoFd::BitLevelBus
        } else {
            NoFd::Socketcand
        })
    }

    fn send(&mut self, frame: &Frame) -> Result<(), BusError> {
        self.write(&Command::Send(*frame))?;
        self.sent += 1;
        Ok(())
    }

    /// One write for all the frames.
    fn send_all(&mut self, frames: &[Frame]) -> Result<(), BusError> {
        use std::fmt::Write as _;
        let mut text = String::with_capacity(frames.len() * 40);
        for frame in frames {
            let _ = write!(text, "{}", Command::Send(*frame));
        }
        self.stream
            .write_all(text.as_bytes())
            .map_err(ClientError::from)?;
        self.sent += frames.len() as u64;
        Ok(())
    }

    fn recv(&mut self, timeout: Option<Duration>) -> Result<Option<Message<Frame>>, BusError> {
        Ok(self
            .next_event(timeout, false)?
            .and_then(Message::into_frame))
    }

    fn recv_event(&mut self, timeout: Option<Duration>) -> Result<Option<Message>, BusError> {
        self.next_event(timeout, true)
    }

    /// On a buslab server `< buslab_errors 0|1 >`; a plain socketcand sends error frames only
    /// when it was started with `-e`, so there this just keeps or drops what comes.
    fn set_error_frames(&mut self, on: bool) -> Result<(), BusError> {
        if self.extensions {
            self.request(&Command::ErrorFrames(on), None, self.options.reply_timeout)?;
        } else if on {
            tracing::info!(
                "{}: a plain socketcand sends error frames only when started with -e",
                self.channel_info()
            );
        }
        self.inbound.set_error_frames(on);
        Ok(())
    }

    fn set_filters(&mut self, filters: &[Filter]) -> Result<(), BusError> {
        self.inbound.set_filters(filters);
        Ok(())
    }

    fn state(&mut self) -> Result<ErrorState, BusError> {
        if !self.extensions {
            return Ok(ErrorState::Active);
        }
        Ok(self.node_status(None)?.state)
    }

    fn channel_info(&self) -> String {
        match self.stream.peer_addr() {
            Ok(addr) => format!("socketcand://{addr}/{}", self.channel),
            Err(_) => format!("socketcand {}", self.channel),
        }
    }

    fn admin(&mut self) -> Option<&mut dyn BusAdmin> {
        if self.extensions { Some(self) } else { None }
    }

    fn recv_waker(&mut self) -> Option<Arc<dyn RecvWaker>> {
        let bus = self.channel_info();
        WakeLine::opened_waker(&mut self.wake, &bus)
    }
}

/// buslab's extensions, typed (the wire's text is parsed in [`crate::reply`]).
impl BusAdmin for SocketcandBus {
    fn nodes(&mut self) -> Result<Vec<NodeInfo>, BusError> {
        Ok(SocketcandBus::nodes(self)?)
    }

    fn node_status(&mut self, node: Option<&NodeRef>) -> Result<NodeStatus, BusError> {
        Ok(SocketcandBus::node_status(self, node)?)
    }

    fn register_dump(&mut self, node: Option<&NodeRef>) -> Result<NodeRegisters, BusError> {
        Ok(SocketcandBus::register_dump(self, node)?)
    }

    fn set_name(&mut self, name: &str) -> Result<(), BusError> {
        Ok(SocketcandBus::set_name(self, name)?)
    }

    fn set_btr(&mut self, btr0: u8, btr1: u8) -> Result<(), BusError> {
        Ok(SocketcandBus::set_btr(self, btr0, btr1)?)
    }

    fn configure(&mut self, settings: &ControllerSettings) -> Result<(), BusError> {
        Ok(SocketcandBus::configure(self, settings)?)
    }

    fn flush(&mut self, timeout: Duration) -> Result<TxReport, BusError> {
        Ok(SocketcandBus::flush(self, timeout)?)
    }

    fn abort(&mut self) -> Result<(), BusError> {
        Ok(SocketcandBus::abort(self)?)
    }

    fn set_bus_off_recovery(&mut self, recovery: BusOffRecovery) -> Result<(), BusError> {
        Ok(SocketcandBus::set_bus_off_recovery(self, recovery)?)
    }

    fn inject_fault(
        &mut self,
        fault: &WireFault,
        lasting: Option<Duration>,
    ) -> Result<(), BusError> {
        Ok(SocketcandBus::inject_fault(self, fault, lasting)?)
    }

    fn repair(&mut self) -> Result<(), BusError> {
        Ok(SocketcandBus::repair(self)?)
    }

    fn demo_board(
        &mut self,
        slio: buslab_bus::SlioId,
        change: Option<buslab_bus::admin::BoardInput>,
    ) -> Result<buslab_bus::admin::BoardState, BusError> {
        Ok(SocketcandBus::demo_board(self, slio, change)?)
    }
}
