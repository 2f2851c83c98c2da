//! The network side: a TCP listener, one reader and one writer thread per client, and the bus
//! thread that paces the [`VirtualBus`] to the wall clock.

use std::fmt::Write as _;
use std::io::{self, Read, Write};
use std::net::{Shutdown, SocketAddr, TcpListener, TcpStream, UdpSocket};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError, Sender, SyncSender, TrySendError};
use std::thread::{self, JoinHandle};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use buslab_can::Frame;
use buslab_canbus::CanMode;
use buslab_sim::Simulation;
use buslab_socketcand::message::format_frame;
use buslab_socketcand::{Command, Deframer, NodeRef, ServerMessage, Timestamp};

use crate::bus::{TX_QUEUE, VbusError, VirtualBus};

/// Everything `buslab bus serve` can set.
pub struct ServerConfig {
    pub listen: SocketAddr,
    pub bitrate: u32,
    /// The one bus name clients may open.
    pub channel: String,
    /// Virtual seconds per wall-clock second: 1.0 is real time; more runs the bus faster
    /// than a real one could (for benchmarks, clearly not real time).
    pub speed: f64,
    /// Frames waiting for one client before newer ones are dropped (counted per node).
    pub client_queue: usize,
    /// TCP connections served at once, joined or not (each costs two threads and its queue);
    /// more are answered `< error too many connections … >` and closed.
    pub max_connections: usize,
    /// Scenario nodes on the same wire.
    pub scenario: Option<Simulation>,
    /// Send every client its chip's bus errors, lost arbitrations and state changes as
    /// `< error CLASS SEC.USEC >` (socketcand's `-e`); a client can also ask with
    /// `< buslab_errors 1 >`.
    pub error_frames: bool,
    /// Send socketcand's discovery beacon (UDP, every 3 s) to this address, so python-can's
    /// `detect_beacon()` finds the bus (socketcand broadcasts to port 42000).
    pub beacon: Option<SocketAddr>,
    /// Where log lines go.
    pub log: Arc<dyn Fn(&str) + Send + Sync>,
}

impl ServerConfig {
    pub fn new(listen: SocketAddr, bitrate: u32) -> Self {
        Self {
            listen,
            bitrate,
            channel: "vcan0".to_string(),
            speed: 1.0,
            client_queue: 8192,
            max_connections: 256,
            scenario: None,
            error_frames: false,
            beacon: None,
            log: Arc::new(|line| eprintln!("{line}")),
        }
    }
}

/// Why the server could not start.
#[derive(Debug, thiserror::Error)]
pub enum ServerError {
    #[error("cannot listen on {addr}: {source}")]
    Listen { addr: SocketAddr, source: io::Error },
    #[error("{0}")]
    Bus(#[from] VbusError),
    #[error("speed {0} must be a positive number 0.001..=1000000 (times real time)")]
    Speed(f64),
    #[error("client queue {0} must be 16..=1048576 frames")]
    ClientQueue(usize),
    #[error("bus name {0:?} must be 1..=64 of A-Z a-z 0-9 _ - . : (one token clients can open)")]
    Channel(String),
    #[error("cannot start a server thread: {0}")]
    Thread(io::Error),
    #[error("cannot send the beacon to {target}: {source}")]
    Beacon {
        target: SocketAddr,
        source: io::Error,
    },
}

/// A running server; dropping it does not stop it (call [`ServerHandle::shutdown`]).
pub struct ServerHandle {
    addr: SocketAddr,
    stop: Arc<AtomicBool>,
    threads: Vec<JoinHandle<()>>,
}

impl ServerHandle {
    /// The address clients connect to (with the real port when 0 was asked for).
    pub fn local_addr(&self) -> SocketAddr {
        self.addr
    }

    /// Stops accepting, stops the bus and waits for the server threads.
    pub fn shutdown(self) {
        self.stop.store(true, Ordering::SeqCst);
        // Wake the accept loop.
        let _ = TcpStream::connect(self.addr);
        for t in self.threads {
            let _ = t.join();
        }
    }

    /// Waits until the server stops (it runs until shut down).
    pub fn wait(self) {
        for t in self.threads {
            let _ = t.join();
        }
    }
}

/// What the bus thread is asked to do.
enum Control {
    Join {
        out: SyncSender<Out>,
        frames: Receiver<Frame>,
        reply: Sender<Result<u32, String>>,
    },
    Leave(u32),
    Request {
        node: u32,
        command: Command,
        reply: Sender<ServerMessage>,
    },
}

/// To a client's writer thread.
enum Out {
    Text(String),
    Frame(Frame, Timestamp),
    ErrorFrame(u32, Timestamp),
    /// From now on frames are delivered; `true`: remote frames as `R<dlc>`.
    Raw(bool),
    /// Remote frames in buslab's form from now on.
    Extensions,
}

/// A bus name a client can `< open >` (one token) and the beacon can carry (no XML quoting).
fn valid_channel(name: &str) -> bool {
    (1..=64).contains(&name.len())
        && name
            .bytes()
            .all(|b| b.is_ascii_alphanumeric() || matches!(b, b'_' | b'-' | b'.' | b':'))
}

/// Starts the server: binds, then runs the bus and accepts clients in background threads.
pub fn spawn(mut config: ServerConfig) -> Result<ServerHandle, ServerError> {
    // Outside this range the pacing arithmetic overflows `Duration`.
    if !(0.001..=1_000_000.0).contains(&config.speed) {
        return Err(ServerError::Speed(config.speed));
    }
    // The queue is allocated whole for each client, and must hold a few replies.
    if !(16..=1_048_576).contains(&config.client_queue) {
        return Err(ServerError::ClientQueue(config.client_queue));
    }
    if !valid_channel(&config.channel) {
        return Err(ServerError::Channel(config.channel));
    }
    let mut bus = VirtualBus::new(config.bitrate)?;
    bus.set_error_frames(config.error_frames);
    if let Some(sim) = config.scenario.take() {
        bus = bus.with_scenario(sim);
    }
    let listener = TcpListener::bind(config.listen).map_err(|source| ServerError::Listen {
        addr: config.listen,
        source,
    })?;
    let addr = listener
        .local_addr()
        .map_err(|source| ServerError::Listen {
            addr: config.listen,
            source,
        })?;
    let stop = Arc::new(AtomicBool::new(false));
    let (control_tx, control_rx) = mpsc::channel();
    let log = config.log.clone();
    log(&format!(
        "buslab bus serve: {} at {} bit/s on {addr}{}",
        config.channel,
        config.bitrate,
        if config.speed == 1.0 {
            String::new()
        } else {
            format!(", {}x FASTER THAN REAL TIME", config.speed)
        }
    ));
    let bus_thread = {
        let stop = stop.clone();
        let log = log.clone();
        let speed = config.speed;
        thread::Builder::new()
            .name("vbus-bus".into())
            .spawn(move || run_bus(bus, control_rx, stop, log, speed))
            .map_err(ServerError::Thread)?
    };
    let accept_thread = {
        let stop = stop.clone();
        let channel = config.channel.clone();
        let queue = config.client_queue;
        let max_connections = config.max_connections;
        let log = log.clone();
        thread::Builder::new()
            .name("vbus-accept".into())
            .spawn(move || {
                // Without a bound, a flood of idle connections exhausts threads and memory.
                let open = Arc::new(AtomicUsize::new(0));
                for conn in listener.incoming() {
                    if stop.load(Ordering::SeqCst) {
                        break;
                    }
                    let Ok(mut stream) = conn else { continue };
                    if open.load(Ordering::SeqCst) >= max_connections {
                        let refusal = ServerMessage::Error(format!(
                            "too many connections ({max_connections} open); try again later"
                        ));
                        let _ = stream.write_all(refusal.to_string().as_bytes());
                        continue;
                    }
                    open.fetch_add(1, Ordering::SeqCst);
                    let control = control_tx.clone();
                    let channel = channel.clone();
                    let log = log.clone();
                    let slot = open.clone();
                    let spawned =
                        thread::Builder::new()
                            .name("vbus-client".into())
                            .spawn(move || {
                                session(stream, control, channel, queue, log);
                                slot.fetch_sub(1, Ordering::SeqCst);
                            });
                    if spawned.is_err() {
                        open.fetch_sub(1, Ordering::SeqCst);
                    }
                }
            })
            .map_err(ServerError::Thread)?
    };
    let mut threads = vec![accept_thread, bus_thread];
    if let Some(target) = config.beacon {
        let socket = UdpSocket::bind(if target.is_ipv4() {
            "0.0.0.0:0"
        } else {
            "[::]:0"
        })
        .and_then(|s| s.set_broadcast(true).map(|()| s))
        .map_err(|source| ServerError::Beacon { target, source })?;
        let text = beacon_text(beacon_url_addr(addr, target), &config.channel);
        let stop = stop.clone();
        let log = log.clone();
        log(&format!("beacon to {target} every 3 s"));
        threads.push(
            thread::Builder::new()
                .name("vbus-beacon".into())
                .spawn(move || {
                    let mut next = Instant::now();
                    while !stop.load(Ordering::SeqCst) {
                        if Instant::now() >= next {
                            if let Err(e) = socket.send_to(text.as_bytes(), target) {
                                log(&format!("beacon to {target}: {e}"));
                            }
                            next += BEACON_EVERY;
                        }
                        thread::sleep(Duration::from_millis(50));
                    }
                })
                .map_err(ServerError::Thread)?,
        );
    }
    Ok(ServerHandle {
        addr,
        stop,
        threads,
    })
}

/// How long frames wait after the rawmode `< ok >` (see `writer`).
const RAW_HOLD: Duration = Duration::from_millis(50);

/// socketcand sends its beacon about every 3 s.
const BEACON_EVERY: Duration = Duration::from_secs(3);

/// The address the beacon announces: the listening one, or, when listening on every
/// interface (`0.0.0.0`, `::`), the address of the interface the beacon leaves from (as
/// socketcand names its interface's address; `0.0.0.0` would send a client to itself).
pub fn beacon_url_addr(listen: SocketAddr, target: SocketAddr) -> SocketAddr {
    if !listen.ip().is_unspecified() {
        return listen;
    }
    let local = UdpSocket::bind(SocketAddr::new(listen.ip(), 0))
        .and_then(|probe| {
            probe.set_broadcast(true)?;
            probe.connect(target)?;
            probe.local_addr()
        })
        .map(|a| a.ip());
    match local {
        Ok(ip) if !ip.is_unspecified() => SocketAddr::new(ip, listen.port()),
        _ => listen,
    }
}

/// socketcand's discovery beacon: a `CANBeacon` element with the server's URL and its bus.
pub fn beacon_text(addr: SocketAddr, channel: &str) -> String {
    format!(
        "<CANBeacon name=\"buslab\" type=\"SocketCAN\" description=\"buslab bus serve\">\n<URL>can://{addr}</URL><Bus name=\"{channel}\"/></CANBeacon>"
    )
}

/// Kernel send buffer per client (the kernel doubles it): a few thousand frames.
const SEND_BUFFER: usize = 32 * 1024;

/// Longest stretch simulated without looking at clients (bit-times = bitrate / this).
const SLICES_PER_SECOND: u64 = 2000;
/// Virtual time more than this behind the wall clock is reported.
const LAG_REPORT: Duration = Duration::from_millis(20);

/// One client's queues on the bus thread.
struct Link {
    number: u32,
    out: SyncSender<Out>,
    frames: Receiver<Frame>,
    dropped_reported: u64,
}

fn run_bus(
    mut bus: VirtualBus,
    control: Receiver<Control>,
    stop: Arc<AtomicBool>,
    log: Arc<dyn Fn(&str) + Send + Sync>,
    speed: f64,
) {
    let bitrate = bus.bitrate() as f64;
    let start = Instant::now();
    let unix0 = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .unwrap_or_default()
        .as_nanos();
    let slice = (bus.bitrate() as u64 / SLICES_PER_SECOND).max(1);
    let mut links: Vec<Link> = Vec::new();
    let mut last_lag_report = Instant::now() - Duration::from_secs(10);
    let mut max_lag = Duration::ZERO;
    let mut last_summary = Instant::now();
    let mut last_frames = 0u64;
    while !stop.load(Ordering::SeqCst) {
        // Clients first, so their frames start as soon as possible.
        while let Ok(c) = control.try_recv() {
            handle_control(&mut bus, &mut links, c);
        }
        for link in &links {
            if let Ok(node) = bus.node_mut(&NodeRef::Number(link.number)) {
                while node.tx.len() < TX_QUEUE {
                    match link.frames.try_recv() {
                        Ok(f) => node.tx.push_back(f),
                        Err(_) => break,
                    }
                }
            }
        }
        let elapsed = start.elapsed();
        let target = (elapsed.as_secs_f64() * speed * bitrate) as u64;
        let now = bus.now();
        if target > now {
            let behind = Duration::from_secs_f64((target - now) as f64 / bitrate / speed);
            if behind > LAG_REPORT {
                max_lag = max_lag.max(behind);
                if last_lag_report.elapsed() >= Duration::from_secs(1) {
                    log(&format!(
                        "warning: the host is too slow: virtual time is {:.1} ms behind the wall clock (worst {:.1} ms)",
                        behind.as_secs_f64() * 1e3,
                        max_lag.as_secs_f64() * 1e3
                    ));
                    last_lag_report = Instant::now();
                }
            }
            bus.run_until(target.min(now + slice));
            deliver(&mut bus, &mut links, unix0, &*log);
            for line in bus.take_log() {
                log(&line);
            }
        } else {
            // Ahead of nothing: wait for a client or for the next slice of wall time.
            let wait = Duration::from_secs_f64(slice as f64 / bitrate / speed);
            match control.recv_timeout(wait) {
                Ok(c) => handle_control(&mut bus, &mut links, c),
                Err(RecvTimeoutError::Timeout) => {}
                Err(RecvTimeoutError::Disconnected) => break,
            }
        }
        if last_summary.elapsed() >= Duration::from_secs(5) {
            let load = bus.load();
            if load.frames != last_frames || load.errors > 0 {
                let mut line = format!(
                    "bus: load {:.1} % (last second), {} frames/s, {} frames, {} bus errors",
                    load.last_second_percent(),
                    load.frames_last_second(),
                    load.frames,
                    load.errors
                );
                for n in bus.nodes() {
                    line.push_str(&format!(
                        "; {} {} {}",
                        n.number,
                        n.name,
                        crate::bus::state_word(n.state())
                    ));
                }
                log(&line);
                last_frames = load.frames;
            }
            last_summary = Instant::now();
        }
    }
}

/// Virtual bit-time → Unix time for frame timestamps.
fn stamp(unix0: u128, time: u64, bitrate: u32) -> Timestamp {
    Timestamp::from_nanos(unix0 + time as u128 * 1_000_000_000 / bitrate as u128)
}

/// Moves received frames to the clients' writer queues; a full queue loses the frame for
/// that client only.
fn deliver(bus: &mut VirtualBus, links: &mut [Link], unix0: u128, log: &dyn Fn(&str)) {
    let bitrate = bus.bitrate();
    for link in links.iter_mut() {
        let Ok(node) = bus.node_mut(&NodeRef::Number(link.number)) else {
            continue;
        };
        for e in node.errors.drain(..) {
            match link
                .out
                .try_send(Out::ErrorFrame(e.class, stamp(unix0, e.time, bitrate)))
            {
                Ok(()) => {}
                Err(TrySendError::Full(_)) => node.counters.rx_lost += 1,
                Err(TrySendError::Disconnected(_)) => {}
            }
        }
        for d in node.rx.drain(..) {
            match link
                .out
                .try_send(Out::Frame(d.frame, stamp(unix0, d.time, bitrate)))
            {
                Ok(()) => {}
                Err(TrySendError::Full(_)) => node.counters.rx_lost += 1,
                Err(TrySendError::Disconnected(_)) => {}
            }
        }
        let lost = node.counters.rx_lost;
        if lost > link.dropped_reported
            && (link.dropped_reported == 0 || lost >= link.dropped_reported * 2)
        {
            log(&format!(
                "node {} ({}): the client does not keep up: {lost} frames dropped for it so far",
                node.number, node.name
            ));
            link.dropped_reported = lost;
        }
    }
}

fn handle_control(bus: &mut VirtualBus, links: &mut Vec<Link>, control: Control) {
    match control {
        Control::Join { out, frames, reply } => {
            let r = bus.join();
            if let Ok(number) = r {
                links.push(Link {
                    number,
                    out,
                    frames,
                    dropped_reported: 0,
                });
            }
            let _ = reply.send(r.map_err(|e| e.to_string()));
        }
        Control::Leave(number) => {
            bus.leave(number);
            links.retain(|l| l.number != number);
        }
        Control::Request {
            node,
            command,
            reply,
        } => {
            let _ = reply.send(answer(bus, node, command));
        }
    }
}

/// The reply to an extension command from node `me`.
fn answer(bus: &mut VirtualBus, me: u32, command: Command) -> ServerMessage {
    let own = NodeRef::Number(me);
    let result: Result<ServerMessage, VbusError> = match command {
        Command::Name(name) => bus.rename(me, &name).map(|()| ServerMessage::Ok),
        Command::ReceiveOwn(on) => bus.node_mut(&own).map(|n| {
            n.receive_own = on;
            ServerMessage::Ok
        }),
        Command::ErrorFrames(on) => bus.node_mut(&own).map(|n| {
            n.error_frames = on;
            if !on {
                n.errors.clear();
            }
            ServerMessage::Ok
        }),
        Command::Btr { btr0, btr1 } => bus.set_btr(me, btr0, btr1).map(|()| ServerMessage::Ok),
        Command::Nodes => Ok(ServerMessage::Other {
            name: "buslab_nodes".into(),
            args: bus
                .nodes()
                .iter()
                .map(|n| format!("{}:{}", n.number, n.name))
                .collect(),
        }),
        Command::Status(node) => {
            bus.status(node.as_ref().unwrap_or(&own))
                .map(|(number, name, fields)| {
                    let mut args = vec![number.to_string(), name];
                    args.extend(fields.into_iter().map(|(k, v)| format!("{k}={v}")));
                    ServerMessage::Other {
                        name: "buslab_status".into(),
                        args,
                    }
                })
        }
        Command::Regs(node) => {
            bus.regs(node.as_ref().unwrap_or(&own))
                .map(|(number, name, dump)| {
                    let mut args = vec![
                        number.to_string(),
                        name,
                        match dump.mode {
                            CanMode::Peli => "peli",
                            CanMode::Basic => "basic",
                        }
                        .into(),
                        if dump.reset_mode {
                            "reset"
                        } else {
                            "operating"
                        }
                        .into(),
                    ];
                    args.extend(
                        dump.values
                            .iter()
                            .map(|v| v.map_or("--".to_string(), |v| format!("{v:02X}"))),
                    );
                    ServerMessage::Other {
                        name: "buslab_regs".into(),
                        args,
                    }
                })
        }
        other => Ok(ServerMessage::Error(format!(
            "{other} is not an extension command"
        ))),
    };
    result.unwrap_or_else(|e| ServerMessage::Error(e.to_string()))
}

/// Where a client is in socketcand's state machine.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Mode {
    NoBus,
    Bcm,
    Raw,
}

/// One client: the reader loop (this thread) and a writer thread.
fn session(
    stream: TcpStream,
    control: Sender<Control>,
    channel: String,
    queue: usize,
    log: Arc<dyn Fn(&str) + Send + Sync>,
) {
    let peer = stream
        .peer_addr()
        .map_or_else(|_| "?".to_string(), |a| a.to_string());
    let _ = stream.set_nodelay(true);
    // Bound what the kernel holds for a client that does not read, so the per-client queue is
    // what decides when its frames are dropped (not megabytes of socket buffer).
    let _ = nix::sys::socket::setsockopt(&stream, nix::sys::socket::sockopt::SndBuf, &SEND_BUFFER);
    let (out_tx, out_rx) = mpsc::sync_channel::<Out>(queue.max(16));
    let Ok(write_half) = stream.try_clone() else {
        return;
    };
    let writer = thread::spawn(move || writer(write_half, out_rx));
    let _ = out_tx.send(Out::Text(ServerMessage::Hi.to_string()));
    let mut reader = stream;
    let mut deframer = Deframer::new();
    let mut buf = [0u8; 16 * 1024];
    let mut mode = Mode::NoBus;
    let mut node: Option<(u32, SyncSender<Frame>)> = None;
    let reply = |msg: ServerMessage| {
        let _ = out_tx.send(Out::Text(msg.to_string()));
    };
    'conn: loop {
        let n = match reader.read(&mut buf) {
            Ok(0) | Err(_) => break,
            Ok(n) => n,
        };
        deframer.push(&buf[..n]);
        while let Some(element) = deframer.next_element() {
            let element = match element {
                Ok(e) => e,
                Err(e) => {
                    reply(ServerMessage::Error(e.to_string()));
                    continue;
                }
            };
            let command = match Command::parse(&element) {
                Ok(c) => c,
                Err(e) => {
                    reply(ServerMessage::Error(e.to_string()));
                    continue;
                }
            };
            match (mode, command) {
                (_, Command::Echo) => reply(ServerMessage::Echo),
                (Mode::NoBus, Command::Open(bus)) => {
                    if bus != channel {
                        // As socketcand: refuse and close.
                        reply(ServerMessage::Error("could not open bus".into()));
                        break 'conn;
                    }
                    let (frames_tx, frames_rx) = mpsc::sync_channel(TX_QUEUE);
                    let (r_tx, r_rx) = mpsc::channel();
                    let joined = control
                        .send(Control::Join {
                            out: out_tx.clone(),
                            frames: frames_rx,
                            reply: r_tx,
                        })
                        .ok()
                        .and_then(|()| r_rx.recv().ok());
                    match joined {
                        Some(Ok(number)) => {
                            node = Some((number, frames_tx));
                            mode = Mode::Bcm;
                            log(&format!("client {peer} is node {number}"));
                            reply(ServerMessage::Ok);
                        }
                        Some(Err(e)) => {
                            reply(ServerMessage::Error(e));
                            break 'conn;
                        }
                        None => break 'conn,
                    }
                }
                (Mode::NoBus, _) => reply(ServerMessage::Error(
                    "open a bus first: < open BUS >".into(),
                )),
                (Mode::Bcm, Command::RawMode) => {
                    mode = Mode::Raw;
                    reply(ServerMessage::Ok);
                    let _ = out_tx.send(Out::Raw(true));
                }
                (Mode::Raw, Command::RawMode) => {
                    reply(ServerMessage::Error("already in raw mode".into()))
                }
                (_, Command::Open(_)) => reply(ServerMessage::Error(
                    "a bus is already open on this connection".into(),
                )),
                (_, Command::BcmMode | Command::ControlMode | Command::IsotpMode) => reply(
                    ServerMessage::Error("buslab serves raw mode only (send rawmode)".into()),
                ),
                (_, Command::Unsupported { name, .. }) => reply(ServerMessage::Error(format!(
                    "{name} is not supported by buslab (raw mode only)"
                ))),
                (_, Command::Send(frame)) => {
                    if let Some((_, frames)) = &node {
                        // Blocks when the node's queue is full: only this client waits
                        // (TCP pushes back on it), the bus goes on.
                        if frames.send(frame).is_err() {
                            break 'conn;
                        }
                    }
                }
                (_, Command::Extensions) => {
                    let _ = out_tx.send(Out::Extensions);
                    reply(ServerMessage::Ok);
                }
                (_, command) => {
                    let Some((number, _)) = &node else { continue };
                    let (r_tx, r_rx) = mpsc::channel();
                    if control
                        .send(Control::Request {
                            node: *number,
                            command,
                            reply: r_tx,
                        })
                        .is_err()
                    {
                        break 'conn;
                    }
                    match r_rx.recv() {
                        Ok(msg) => reply(msg),
                        Err(_) => break 'conn,
                    }
                }
            }
        }
    }
    if let Some((number, _)) = node {
        let _ = control.send(Control::Leave(number));
        log(&format!("client {peer} (node {number}) disconnected"));
    }
    // The writer sends what is queued (e.g. the last error), then the connection closes.
    drop(out_tx);
    let _ = writer.join();
    let _ = reader.shutdown(Shutdown::Both);
}

/// Writes everything queued for one client, batching what is already waiting.
fn writer(mut stream: TcpStream, out: Receiver<Out>) {
    let mut raw = false;
    let mut remote_as_r = false;
    let mut text = String::with_capacity(64 * 1024);
    while let Ok(first) = out.recv() {
        text.clear();
        let mut item = Some(first);
        while let Some(o) = item.take() {
            match o {
                Out::Text(t) => {
                    // Handshake replies go out alone: python-can compares each whole recv.
                    if !text.is_empty() {
                        if stream.write_all(text.as_bytes()).is_err() {
                            return;
                        }
                        text.clear();
                    }
                    if stream.write_all(t.as_bytes()).is_err() {
                        return;
                    }
                }
                Out::Raw(on) => {
                    raw = on;
                    // python-can reads the rawmode `< ok >` with one recv() and compares it
                    // whole: frames must not share that read. They wait in the queue.
                    thread::sleep(RAW_HOLD);
                }
                Out::Extensions => remote_as_r = true,
                Out::Frame(frame, ts) => {
                    if raw {
                        let _ = format_frame(&mut text, &frame, ts, remote_as_r);
                    }
                }
                Out::ErrorFrame(class, ts) => {
                    if raw {
                        // Raw mode's layout: the class, the time, no data (socketcand -e).
                        let _ = write!(text, "< error {class:03X} {ts} >");
                    }
                }
            }
            if text.len() < 60 * 1024 {
                item = out.try_recv().ok();
            }
        }
        if !text.is_empty() && stream.write_all(text.as_bytes()).is_err() {
            return;
        }
    }
}
