//! The network side: one thread runs an event loop (mio) around the [`VirtualBus`] and one
//! sans-IO socketcand [`Session`] per TCP client, pacing the bus to the wall clock.
//!
//! The loop sleeps until the next thing that can happen: a client's bytes, the bus's next
//! scheduled activity, a session's timer, the end of a client's frame on the wire
//! ([`VirtualBus::frame_end`], met to the microsecond: a timer a little before it, then a
//! bounded spin, see [`MAX_SPIN`]); while other frames are on the wire it wakes every
//! [`BUSY_SLICE`] so deliveries leave within a fraction of a millisecond. Waits end on a timer
//! in the loop's epoll set (a timerfd counts nanoseconds, epoll's own timeout milliseconds), so
//! a client's bytes wake the loop at once however short the wait.

use std::collections::VecDeque;
use std::io::{self, Read, Write};
use std::net::{SocketAddr, UdpSocket};
use std::os::fd::{AsFd, AsRawFd};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{self, Receiver, Sender};
use std::sync::{Arc, Mutex};
use std::thread::{self, JoinHandle};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use buslab_canbus::{NodeRef, TxReport};
use buslab_sim::Simulation;
use buslab_socketcand::server::{Action, FAULT_RATE, RateLimit, Session, SessionConfig};
use buslab_socketcand::{
    Command, FormattedFrame, ServerMessage, Timestamp, flushed_reply, nodes_reply, refused_reply,
    regs_reply, status_reply,
};
use mio::net::{TcpListener, TcpStream};
use mio::unix::SourceFd;
use mio::{Events, Interest, Poll, Token, Waker};
use nix::sys::time::TimeSpec;
use nix::sys::timerfd::{ClockId, Expiration, TimerFd, TimerFlags, TimerSetTimeFlags};
use tracing::{debug, info, warn};

use crate::bus::{BusEvent, VbusError, VirtualBus};
use crate::node::TimedErrorFrame;
use crate::speed::{Speed, SpeedError};
use buslab_pace::{Pacer, Punctual, Rate, Step, Ticks};

/// Everything `buslab bus serve` can set.
pub struct ServerConfig {
    pub listen: SocketAddr,
    pub bitrate: u32,
    /// The one bus name clients may open.
    pub channel: String,
    /// Virtual seconds per wall-clock second ([`Speed::Times`]; 1.0 is real time, more runs
    /// the bus faster than a real one could), or [`Speed::Max`]: as fast as the CPU allows
    /// (benchmarks; clearly not real time).
    pub speed: Speed,
    /// Frames waiting for one client before newer ones are dropped (counted per node).
    pub client_queue: usize,
    /// TCP connections served at once, joined or not; more are answered
    /// `< error too many connections … >` and closed.
    pub max_connections: usize,
    /// How long a connection may stay without opening the bus.
    pub open_timeout: Duration,
    /// Scenario nodes on the same wire.
    pub scenario: Option<Simulation>,
    /// More simulated nodes on the wire, by name (SLIO boards, the PowerPC node).
    pub devices: Vec<(String, Box<dyn buslab_can::node::BusNode>)>,
    /// Send every client its chip's bus errors, lost arbitrations and state changes as
    /// `< error CLASS SEC.USEC >` (socketcand's `-e`); a client can also ask with
    /// `< buslab_errors 1 >`.
    pub error_frames: bool,
    /// Send socketcand's discovery beacon (UDP, every 3 s) to this address, so python-can's
    /// `detect_beacon()` finds the bus (socketcand broadcasts to port 42000).
    pub beacon: Option<SocketAddr>,
    /// How client chips come back after bus-off: the seed's (the chip counts 128 × 11 recessive
    /// bits, TXERR falling; the default) or Linux's fast restart after 100 ms.
    pub bus_off_recovery: buslab_canbus::BusOffRecovery,
    /// Faults one client may put on the wire (`< buslab_fault … >`); more are answered
    /// `< buslab_refused fault rate … >` with the limit and the wait.
    pub fault_rate: RateLimit,
}

impl ServerConfig {
    pub fn new(listen: SocketAddr, bitrate: u32) -> Self {
        Self {
            listen,
            bitrate,
            channel: "vcan0".to_string(),
            speed: Speed::default(),
            client_queue: 8192,
            max_connections: 256,
            open_timeout: Duration::from_secs(30),
            scenario: None,
            devices: Vec::new(),
            error_frames: false,
            beacon: None,
            bus_off_recovery: buslab_canbus::BusOffRecovery::default(),
            fault_rate: FAULT_RATE,
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
    #[error("{0}")]
    Speed(#[from] SpeedError),
    #[error("client queue {0} must be 16..=1048576 frames")]
    ClientQueue(usize),
    #[error("a fault rate of {max} per {per:?} must be at least 1 per 1 ms .. 1 h")]
    FaultRate { max: u32, per: Duration },
    #[error("bus name {0:?} must be 1..=64 of A-Z a-z 0-9 _ - . : (one token clients can open)")]
    Channel(String),
    #[error("the scenario runs at {scenario} bit/s but the bus at {bus} bit/s")]
    ScenarioBitrate { scenario: u32, bus: u32 },
    #[error("cannot start the server: {0}")]
    Io(io::Error),
    #[error("cannot send the beacon to {target}: {source}")]
    Beacon {
        target: SocketAddr,
        source: io::Error,
    },
}

/// Work for the bus thread, run between two slices of bus time.
type Job = Box<dyn FnOnce(&mut VirtualBus) + Send>;

/// How far the server's virtual time fell behind the wall clock.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Lag {
    /// The worst lag after catching up, since the start.
    pub worst: Duration,
    /// Time spent more than [`LAG_WARNING`] behind.
    pub behind_for: Duration,
    /// Wall time the bus skipped rather than catch up in one burst: stalls of the host
    /// longer than [`BUS_CREDIT`] with the bus busy.
    pub skipped: Duration,
}

/// Posts work to a running server's bus thread without waiting for it (clonable, e.g. for a
/// device's terminal thread).
#[derive(Clone)]
pub struct Poster {
    jobs: Sender<Job>,
    waker: Arc<Waker>,
}

impl Poster {
    /// Runs `job` on the bus thread between two slices of bus time; `false` if the server has
    /// stopped.
    pub fn post(&self, job: impl FnOnce(&mut VirtualBus) + Send + 'static) -> bool {
        self.jobs.send(Box::new(job)).is_ok() && self.waker.wake().is_ok()
    }
}

/// A running server; dropping it does not stop it (call [`ServerHandle::shutdown`]).
pub struct ServerHandle {
    addr: SocketAddr,
    stop: Arc<AtomicBool>,
    waker: Arc<Waker>,
    jobs: Sender<Job>,
    lag: Arc<Mutex<Lag>>,
    thread: Option<JoinHandle<()>>,
}

impl ServerHandle {
    /// The address clients connect to (with the real port when 0 was asked for).
    pub fn local_addr(&self) -> SocketAddr {
        self.addr
    }

    /// Runs `job` on the bus thread between two slices of bus time and returns its result
    /// (`None` if the server has stopped).
    pub fn with_bus<R: Send + 'static>(
        &self,
        job: impl FnOnce(&mut VirtualBus) -> R + Send + 'static,
    ) -> Option<R> {
        let (tx, rx) = mpsc::channel();
        self.jobs
            .send(Box::new(move |bus| {
                let _ = tx.send(job(bus));
            }))
            .ok()?;
        self.waker.wake().ok()?;
        rx.recv().ok()
    }

    /// A handle that posts work to the bus thread without waiting.
    pub fn poster(&self) -> Poster {
        Poster {
            jobs: self.jobs.clone(),
            waker: self.waker.clone(),
        }
    }

    /// How far virtual time fell behind the wall clock so far.
    pub fn lag(&self) -> Lag {
        *lock(&self.lag)
    }

    /// Stops accepting, disconnects the clients, stops the bus and waits for the thread.
    pub fn shutdown(mut self) {
        self.stop.store(true, Ordering::SeqCst);
        let _ = self.waker.wake();
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }

    /// Waits until the server stops (it runs until shut down).
    pub fn wait(mut self) {
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|p| p.into_inner())
}

/// A bus name a client can `< open >` (one token) and the beacon can carry (no XML quoting).
fn valid_channel(name: &str) -> bool {
    (1..=64).contains(&name.len())
        && name
            .bytes()
            .all(|b| b.is_ascii_alphanumeric() || matches!(b, b'_' | b'-' | b'.' | b':'))
}

const LISTENER: Token = Token(0);
const WAKER: Token = Token(1);
const TIMER: Token = Token(2);
/// Client tokens start here.
const FIRST_CLIENT: usize = 3;

/// Starts the server: binds, then runs the bus and serves clients in a background thread.
pub fn spawn(mut config: ServerConfig) -> Result<ServerHandle, ServerError> {
    config.speed.check()?;
    if !(16..=1_048_576).contains(&config.client_queue) {
        return Err(ServerError::ClientQueue(config.client_queue));
    }
    if !valid_channel(&config.channel) {
        return Err(ServerError::Channel(config.channel));
    }
    let RateLimit { max, per } = config.fault_rate;
    if max == 0 || !(Duration::from_millis(1)..=Duration::from_secs(3600)).contains(&per) {
        return Err(ServerError::FaultRate { max, per });
    }
    let mut bus = VirtualBus::new(config.bitrate)?;
    bus.set_error_frames(config.error_frames);
    bus.set_bus_off_recovery(config.bus_off_recovery);
    if let Some(sim) = config.scenario.take() {
        if sim.bitrate() != config.bitrate {
            return Err(ServerError::ScenarioBitrate {
                scenario: sim.bitrate(),
                bus: config.bitrate,
            });
        }
        bus = bus.with_scenario(sim);
    }
    for (name, device) in std::mem::take(&mut config.devices) {
        bus.add_node(&name, device)?;
    }
    let mut listener = TcpListener::bind(config.listen).map_err(|source| ServerError::Listen {
        addr: config.listen,
        source,
    })?;
    let addr = listener
        .local_addr()
        .map_err(|source| ServerError::Listen {
            addr: config.listen,
            source,
        })?;
    let poll = Poll::new().map_err(ServerError::Io)?;
    poll.registry()
        .register(&mut listener, LISTENER, Interest::READABLE)
        .map_err(ServerError::Io)?;
    let waker = Arc::new(Waker::new(poll.registry(), WAKER).map_err(ServerError::Io)?);
    let timer = TimerFd::new(
        ClockId::CLOCK_MONOTONIC,
        TimerFlags::TFD_NONBLOCK | TimerFlags::TFD_CLOEXEC,
    )
    .map_err(|e| ServerError::Io(e.into()))?;
    poll.registry()
        .register(
            &mut SourceFd(&timer.as_fd().as_raw_fd()),
            TIMER,
            Interest::READABLE,
        )
        .map_err(ServerError::Io)?;
    let beacon = match config.beacon {
        None => None,
        Some(target) => {
            let socket = UdpSocket::bind(if target.is_ipv4() {
                "0.0.0.0:0"
            } else {
                "[::]:0"
            })
            .and_then(|s| s.set_broadcast(true).map(|()| s))
            .map_err(|source| ServerError::Beacon { target, source })?;
            let text = beacon_text(beacon_url_addr(addr, target), &config.channel);
            info!("beacon to {target} every 3 s");
            Some(Beacon {
                socket,
                target,
                text,
                next: Instant::now(),
            })
        }
    };
    info!(
        "{} at {} bit/s on {addr}{}",
        config.channel,
        config.bitrate,
        match config.speed {
            s if s.is_real_time() => String::new(),
            Speed::Max => ", AS FAST AS THE CPU ALLOWS (virtual time, not the wall clock)".into(),
            Speed::Times(f) => format!(", {f}x FASTER THAN REAL TIME"),
        }
    );
    let stop = Arc::new(AtomicBool::new(false));
    let lag = Arc::new(Mutex::new(Lag::default()));
    let (jobs_tx, jobs) = mpsc::channel();
    // `max` is never paced; its factor only keeps the conversions defined.
    let factor = match config.speed {
        Speed::Times(f) => f,
        Speed::Max => *crate::speed::PACED.end(),
    };
    let pacer = Pacer::new(
        Rate::per_second(bus.bitrate() as u64).times(factor),
        BUS_CREDIT,
    );
    let mut session_config = SessionConfig::new(config.channel.clone());
    // A raw-mode frame line is typically 40 to 50 bytes.
    session_config.max_output = config.client_queue * 48;
    session_config.open_timeout_ns = buslab_can::Nanos::from(config.open_timeout);
    session_config.fault_rate = config.fault_rate;
    let server = Server {
        poll,
        timer,
        listener,
        clients: Vec::new(),
        next_client: 0,
        open: 0,
        bus,
        session_config,
        max_connections: config.max_connections,
        speed: config.speed,
        jobs,
        stop: stop.clone(),
        lag: lag.clone(),
        beacon,
        epoch: Instant::now(),
        pacer,
        punctual: Punctual::new(MAX_SPIN),
        read_buf: vec![0; READ_CHUNK],
        taken: Vec::new(),
        unix0: SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .unwrap_or_default()
            .as_nanos(),
        lag_state: LagState::default(),
        last_summary: Instant::now(),
        summarised: (0, 0),
        send_buffer_warned: false,
        accept_failed: false,
    };
    let thread = thread::Builder::new()
        .name("vbus".into())
        .spawn(move || server.run())
        .map_err(ServerError::Io)?;
    Ok(ServerHandle {
        addr,
        stop,
        waker,
        jobs: jobs_tx,
        lag,
        thread: Some(thread),
    })
}

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

struct Beacon {
    socket: UdpSocket,
    target: SocketAddr,
    text: String,
    next: Instant,
}

/// Kernel send buffer per client (the kernel doubles it): a few thousand frames, so the
/// per-client queue is what decides when its frames are dropped. Not less: on loopback a
/// segment can be 64 KiB, and a client's kernel acknowledges at once only when more than one
/// segment's worth is unacknowledged. A buffer of about one segment (32 KiB was) waits for
/// its delayed acknowledgement, 40 ms each time it fills, which at `--speed max` made some
/// runs four times slower than others (docs/bus.md).
const SEND_BUFFER: usize = 128 * 1024;
const _: () = assert!(2 * SEND_BUFFER >= 4 * LOOPBACK_SEGMENT);
/// The largest TCP segment on Linux's loopback (its MTU is 64 KiB).
const LOOPBACK_SEGMENT: usize = 64 * 1024;
/// While frames are on the wire and the bus cannot tell when they end, the loop wakes at least
/// this often (wall clock).
pub const BUSY_SLICE: Duration = Duration::from_micros(100);
/// The longest the loop spins before a client's frame ends on the wire, so that it is awake
/// at the end although timers wake it late (20–35 µs at the median on a 2-core VM, see
/// `buslab_pace::Punctual`); only while such a frame is on the wire, never on an idle bus.
pub const MAX_SPIN: Duration = Duration::from_micros(50);
/// The most bytes read from a client at once.
const READ_CHUNK: usize = 16 * 1024;
/// The longest wall time spent simulating before the loop looks at the clients again, and
/// serving clients before the bus runs again (it matters when the host cannot keep up).
const MAX_RUN: Duration = Duration::from_millis(2);
// The longest classic frame on the wire with its worst stuffing, error-free, and the
// intermission after it.
use buslab_can::wire::LONGEST_FRAME;
use buslab_can::{BitTime, Nanos};
/// At `max`: a receiver that has not read for this long no longer holds the bus (its frames
/// are dropped as at any speed).
const STALLED_AFTER: Duration = Duration::from_secs(1);
/// The fewest bit-times between two frames a receiver is handed: the shortest frame (a
/// standard data frame without data bytes, SOF to the end of EOF). `k` times as many
/// bit-times hand it at most `k + 1`.
const SHORTEST_FRAME: BitTime = BitTime::new(44);
/// With error frames on, a receiver may be handed several at one bit-time (an error, the
/// state change it causes, a lost arbitration beside a frame): budgeted as at most this many
/// items in any [`ERROR_WINDOW`] (an error flag and its delimiter), twice what the
/// driver's events give on a bus stuck at dominant.
const ERROR_ITEMS_PER_WINDOW: u64 = 8;
const ERROR_WINDOW: BitTime = BitTime::new(6 + 8);
/// The longest line a frame or an error frame takes in a client's output (a raw-mode frame
/// with an extended ID, 8 data bytes and a ten-digit timestamp is 53 bytes).
const LONGEST_LINE: usize = 64;
/// How often a failed accept is tried again (the connection waits in the listen queue).
const ACCEPT_RETRY: Duration = Duration::from_millis(100);
/// At `max`: rounds of feeding the bus from the clients per loop turn (see
/// [`Server::feed_flat_out`]).
const FEED_ROUNDS: usize = 8;
/// Elements handled per client per round of serving, so one client cannot starve the others
/// or the bus.
const ACTIONS_PER_TURN: usize = 256;
/// The most wall time's worth of bus time a paced server catches up at once when the bus had
/// work (its credit, see `buslab_pace`): a loop that wakes late runs the bus up to the wall
/// clock; after a longer stall (the process was stopped) the rest is skipped rather than sent
/// to the clients as one burst of frames, and virtual time stays that much behind the wall.
pub const BUS_CREDIT: Duration = Duration::from_secs(2);
/// Virtual time this far behind the wall clock, after catching up, means clients see frames
/// late: worth a warning.
pub const LAG_WARNING: Duration = Duration::from_millis(50);
/// While the lag lasts, a summary at most this often.
const LAG_SUMMARY_EVERY: Duration = Duration::from_secs(60);
/// How often the bus's load is summarised (only when something changed).
const SUMMARY_EVERY: Duration = Duration::from_secs(5);

struct Client {
    stream: TcpStream,
    peer: SocketAddr,
    session: Session,
    /// When it connected (ns since the server started).
    accepted: buslab_can::Nanos,
    /// Readiness not used up yet (mio is edge-triggered).
    readable: bool,
    writable: bool,
    /// The peer closed or reset the connection, or writing to it failed: nothing reaches it
    /// any more, its node departs (see [`client_left`]), and what it sent before is still read.
    left: bool,
    /// Its last byte has been read (end of stream, or a failed read).
    input_ended: bool,
    /// A frame the node's full queue could not take yet.
    backlog: Option<buslab_can::Frame>,
    /// `< buslab_flush >`es: each answered once the node has done this many frames.
    flushes: VecDeque<u64>,
    dropped_reported: u64,
    /// When its output was last empty or a write made progress: a receiver that reads holds
    /// the bus at `max` when its output piles up (see [`Server::receiver_behind`]).
    drained_at: Instant,
}

#[derive(Default)]
struct LagState {
    /// When the current stretch of lag started.
    since: Option<Instant>,
    warned: bool,
    last_summary: Option<Instant>,
    worst_in_stretch: Duration,
}

struct Server {
    poll: Poll,
    /// Ends the loop's waits (see [`Server::wait`]).
    timer: TimerFd,
    listener: TcpListener,
    clients: Vec<Option<Client>>,
    /// The client slot the next turn starts with.
    next_client: usize,
    open: usize,
    bus: VirtualBus,
    session_config: SessionConfig,
    max_connections: usize,
    speed: Speed,
    jobs: Receiver<Job>,
    stop: Arc<AtomicBool>,
    lag: Arc<Mutex<Lag>>,
    beacon: Option<Beacon>,
    epoch: Instant,
    /// Bus time (bit-times) against the wall clock since `epoch`.
    pacer: Pacer,
    /// Waits that end at a client's frame's end on the wire (see [`Server::wait_punctually`]).
    punctual: Punctual,
    /// What a client sent, read into one buffer allocated once ([`READ_CHUNK`]).
    read_buf: Vec<u8>,
    /// A client's deliveries of one round: their bit-times and places in the round's
    /// formatted frames (allocated once).
    taken: Vec<(BitTime, usize)>,
    unix0: u128,
    lag_state: LagState,
    last_summary: Instant,
    summarised: (u64, u64),
    /// The kernel gave a client less send buffer than asked (said once).
    send_buffer_warned: bool,
    /// The last accept failed (e.g. out of file descriptors): tried again every
    /// [`ACCEPT_RETRY`].
    accept_failed: bool,
}

impl Server {
    fn run(mut self) {
        let mut events = Events::with_capacity(256);
        while !self.stop.load(Ordering::SeqCst) {
            while let Ok(job) = self.jobs.try_recv() {
                job(&mut self.bus);
            }
            self.note_empty_outputs();
            // The bus first catches up with the wall clock, so what clients send now enters
            // the bus now (not at the instant the loop last ran it, maybe long ago).
            self.advance_bus();
            let busy_io = match self.speed {
                Speed::Times(_) => self.serve_clients(),
                // A receiver behind: its frames would be dropped, so nobody is read until it
                // catches up (or is seen not to read at all).
                Speed::Max if self.receiver_behind() => {
                    // Timers still run: a deadline left in the past would end every wait at
                    // once while the receiver is waited for.
                    self.handle_timeouts();
                    false
                }
                Speed::Max => {
                    let busy_io = self.serve_clients();
                    self.feed_flat_out(busy_io)
                }
            };
            self.deliver();
            self.flush_all();
            self.reap();
            self.housekeeping();
            let timeout = if busy_io {
                Some(Duration::ZERO)
            } else if self.speed == Speed::Max {
                self.sleep_for_flat_out()
            } else {
                self.sleep_for()
            };
            let frame_end = match self.speed {
                Speed::Times(_) if !busy_io => self.frame_end_wall(),
                _ => None,
            };
            if let Err(e) = self.wait(&mut events, timeout, frame_end)
                && e.kind() != io::ErrorKind::Interrupted
            {
                warn!("the server's event loop failed: {e}");
                break;
            }
            for event in events.iter() {
                match event.token() {
                    LISTENER => self.accept(),
                    WAKER | TIMER => {}
                    Token(t) => {
                        if let Some(Some(c)) = self.clients.get_mut(t - FIRST_CLIENT) {
                            c.readable |= event.is_readable();
                            c.writable |= event.is_writable();
                            if event.is_read_closed() || event.is_write_closed() || event.is_error()
                            {
                                client_left(c, &mut self.bus);
                            }
                        }
                    }
                }
            }
            if self.accept_failed {
                self.accept();
            }
        }
        for slot in self.clients.iter_mut() {
            if let Some(c) = slot.take()
                && let Some(n) = c.session.node()
            {
                self.bus.leave(n);
            }
        }
        // Departed clients' nodes still sending.
        for n in self.bus.departing() {
            self.bus.leave(n);
        }
        self.log_bus_events();
        let lag = *lock(&self.lag);
        if lag.worst >= LAG_WARNING {
            warn!(
                "the host was too slow: virtual time fell up to {} ms behind the wall clock, for {:.1} s in all",
                lag.worst.as_millis(),
                lag.behind_for.as_secs_f64()
            );
        }
        if !lag.skipped.is_zero() {
            warn!(
                "{:.1} s of bus time were skipped in all (the host more than {} s behind)",
                lag.skipped.as_secs_f64(),
                BUS_CREDIT.as_secs()
            );
        }
    }

    /// Waits for socket events or `timeout`. epoll counts whole milliseconds (mio rounds a
    /// timeout up), so a frame on the wire would be delivered up to a millisecond late: the
    /// wait ends on the timerfd in the same epoll set instead (nanoseconds, and no timer slack,
    /// unlike a sleep), and a client's bytes still end it at once. A wait that ends at
    /// `frame_end` (wall time since the epoch: a client's frame leaves the wire then) is
    /// punctual ([`Server::wait_punctually`]).
    fn wait(
        &mut self,
        events: &mut Events,
        timeout: Option<Duration>,
        frame_end: Option<Duration>,
    ) -> io::Result<()> {
        let timeout = match timeout {
            _ if !self.accept_failed => timeout,
            Some(t) => Some(t.min(ACCEPT_RETRY)),
            None => Some(ACCEPT_RETRY),
        };
        let now = self.epoch.elapsed();
        if let (Some(end), Some(t)) = (frame_end, timeout)
            && end <= now + t
        {
            return self.wait_punctually(events, end);
        }
        match timeout {
            Some(t) if !t.is_zero() => {
                self.set_timer(t)?;
                self.poll.poll(events, None)
            }
            _ => self.poll.poll(events, timeout),
        }
    }

    /// Waits for socket events or the wall time `deadline` (since the epoch), awake at it: a
    /// timer wakes the loop a little before it (timers wake late), and the rest, at most
    /// [`MAX_SPIN`], is spun in polls that do not block. So a client's frame reaches its
    /// receivers the moment it ends on the wire, with one timer wake-up per frame (before, the
    /// loop slept until the end and woke 20–35 µs after it, p50 0.21 ms for a frame of 0.09 ms
    /// against 0.14 ms through a bare TCP relay).
    fn wait_punctually(&mut self, events: &mut Events, deadline: Duration) -> io::Result<()> {
        loop {
            let now = self.epoch.elapsed();
            match self.punctual.plan(now, deadline) {
                Step::Due => return self.poll.poll(events, Some(Duration::ZERO)),
                Step::Spin { .. } => {
                    self.poll.poll(events, Some(Duration::ZERO))?;
                    // An expiry of an earlier timer ends no spin.
                    if events.iter().any(|e| e.token() != TIMER) {
                        return Ok(());
                    }
                    std::hint::spin_loop();
                }
                Step::Sleep { until } => {
                    self.set_timer(until - now)?;
                    self.poll.poll(events, None)?;
                    if events.iter().any(|e| e.token() != TIMER) {
                        return Ok(());
                    }
                    if !events.is_empty() {
                        self.punctual.woke(until, self.epoch.elapsed());
                    }
                }
            }
        }
    }

    /// Arms the loop's timer to expire `after` from now (setting it also clears an expiry
    /// nobody waited for).
    fn set_timer(&self, after: Duration) -> io::Result<()> {
        self.timer
            .set(
                Expiration::OneShot(TimeSpec::from_duration(after)),
                TimerSetTimeFlags::empty(),
            )
            .map_err(io::Error::from)
    }

    /// The wall time (since the epoch) at which the client's frame on the wire ends, if the bus
    /// knows it ([`VirtualBus::frame_end`]).
    fn frame_end_wall(&self) -> Option<Duration> {
        self.bus
            .frame_end()
            .map(|end| self.pacer.wall_at(Ticks(end.get())))
    }

    /// Nanoseconds since the server started (the sessions' clock).
    fn now_ns(&self) -> buslab_can::Nanos {
        buslab_can::Nanos::from(self.epoch.elapsed())
    }

    /// The bit-time the bus should have reached by now.
    fn target_bits(&self) -> BitTime {
        BitTime::new(self.pacer.ticks_at(self.epoch.elapsed()).0)
    }

    fn bits_to_wall(&self, bits: BitTime) -> Duration {
        self.pacer.wall_of(Ticks(bits.get()))
    }

    /// Where the bus has work: now while a frame is on the wire, else its next activity.
    fn bus_due(&self) -> Option<Ticks> {
        if self.bus.is_idle() {
            let next = self.bus.next_activity();
            (next != BitTime::MAX).then_some(Ticks(next.get()))
        } else {
            Some(Ticks(self.bus.now().get()))
        }
    }

    /// Runs the bus: up to the wall clock when paced, as far as it has work at `max`.
    fn advance_bus(&mut self) {
        match self.speed {
            Speed::Times(_) => self.advance_paced(),
            Speed::Max => {
                self.advance_flat_out();
                // Into the outputs before the clients are served: their replies then count
                // against the room the next stretch of the bus is given, not these frames.
                self.deliver();
            }
        }
    }

    /// At `max`: runs the bus while it has work, at most [`MAX_RUN`] of wall time at once so
    /// clients keep being served. An idle bus skips to its next activity (scenario traffic, a
    /// node's timer) at once, or stays where it is when nothing is scheduled.
    fn advance_flat_out(&mut self) {
        let started = Instant::now();
        while started.elapsed() < MAX_RUN {
            // No further than what every receiver that reads can take before the next
            // delivery: a burst larger than its output would drop frames for it, hold or not.
            let budget = self.delivery_budget();
            if budget == BitTime::ZERO {
                break;
            }
            let now = self.bus.now();
            if self.bus.is_idle() {
                let next = self.bus.next_activity();
                if next == BitTime::MAX {
                    break;
                }
                self.bus
                    .run_until(next.max(now + BitTime::ONE).min(now.saturating_add(budget)));
                continue;
            }
            // Far enough that the queued client frames end inside the stretch (a frame split
            // by its end would be simulated bit by bit, the whole-frame path needs it whole);
            // if they end sooner, the idle rest is skipped at once.
            let queued: u64 = self
                .bus
                .clients_mut()
                .map(|(_, c)| c.tx_queued() as u64)
                .sum();
            let stretch = (LONGEST_FRAME * (queued + 1))
                .max(Nanos::from_millis(10).bit_times_at(self.bus.bitrate()));
            self.bus.run_until(now + stretch.min(budget));
        }
    }

    /// At `max`: how many bit-times the bus may run before the loop next delivers, so that no
    /// receiver that reads (see [`reads`]) is handed more than its output takes: the least
    /// over such receivers of the room left in its output, less what its node holds for it
    /// already, in bit-times (see [`SHORTEST_FRAME`], [`ERROR_ITEMS_PER_WINDOW`]). A
    /// receiver with nothing waiting at all lets the bus run at least one shortest frame,
    /// however small its queue. 0: a receiver must read first; [`BitTime::MAX`]: nobody limits.
    fn delivery_budget(&self) -> BitTime {
        let all_room = self.session_config.max_output.div_ceil(LONGEST_LINE) as u64;
        self.clients
            .iter()
            .flatten()
            .filter(|c| !c.left && reads(c))
            .filter_map(|c| {
                let room = c.session.frame_room(LONGEST_LINE)? as u64;
                let node = self.bus.client(c.session.node()?).ok()?;
                let waiting = node.deliveries_waiting() as u64;
                // Nothing waiting for it anywhere (frames held after `rawmode` count too).
                let empty = waiting == 0 && room == all_room;
                let room = room.saturating_sub(waiting);
                let budget = if node.error_frames {
                    ERROR_WINDOW
                        * (room.saturating_sub(ERROR_ITEMS_PER_WINDOW) / ERROR_ITEMS_PER_WINDOW)
                } else {
                    SHORTEST_FRAME * room.saturating_sub(1)
                };
                Some(if empty {
                    budget.max(SHORTEST_FRAME)
                } else {
                    budget
                })
            })
            .min()
            .unwrap_or(BitTime::MAX)
    }

    /// Clients with nothing to write now have not fallen behind, however long the loop slept:
    /// [`Client::drained_at`] is now for them (before this turn's deliveries fill outputs).
    fn note_empty_outputs(&mut self) {
        let now = Instant::now();
        for c in self.clients.iter_mut().flatten() {
            if !c.session.has_output() {
                c.drained_at = now;
            }
        }
    }

    /// Runs the bus up to the wall clock, at most [`MAX_RUN`] of wall time's worth at once so
    /// clients keep being served when the host is slow; records the lag.
    fn advance_paced(&mut self) {
        let started = Instant::now();
        // A stall beyond the credit with the bus busy: the rest is skipped (the pacer's clock
        // slips), not caught up in one burst.
        let plan = self.pacer.plan(
            self.epoch.elapsed(),
            Ticks(self.bus.now().get()),
            self.bus_due(),
        );
        if !plan.skipped.is_zero() {
            let mut lag = lock(&self.lag);
            if lag.skipped.is_zero() {
                warn!(
                    "the host fell more than {} s behind the bus: {} ms of bus time skipped rather than sent to the clients at once (said once; the total at the end)",
                    BUS_CREDIT.as_secs(),
                    plan.skipped.as_millis()
                );
            }
            lag.skipped += plan.skipped;
        }
        // Busy bus time is simulated in chunks of this many bit-times, so the wall time spent
        // is checked often enough; idle bus time is skipped in one go.
        let chunk = Nanos::from_micros(500)
            .bit_times_at(self.bus.bitrate())
            .max(BitTime::ONE);
        loop {
            let target = self.target_bits();
            let now = self.bus.now();
            if now >= target || started.elapsed() >= MAX_RUN {
                break;
            }
            // An idle bus jumps to its next activity at once (nothing to look at meanwhile).
            let step = if self.bus.is_idle() {
                target - now
            } else {
                chunk
            };
            self.bus.run_until(target.min(now + step));
        }
        let behind = self
            .pacer
            .behind(self.epoch.elapsed(), Ticks(self.bus.now().get()));
        self.track_lag(behind);
    }

    fn track_lag(&mut self, behind: Duration) {
        let now = Instant::now();
        let mut lag = lock(&self.lag);
        lag.worst = lag.worst.max(behind);
        let state = &mut self.lag_state;
        if behind < LAG_WARNING {
            if let Some(since) = state.since.take() {
                lag.behind_for += now - since;
            }
            return;
        }
        state.worst_in_stretch = state.worst_in_stretch.max(behind);
        let since = *state.since.get_or_insert(now);
        if !state.warned {
            state.warned = true;
            state.last_summary = Some(now);
            warn!(
                "the host is too slow: virtual time is {} ms behind the wall clock, so clients get frames late (said once; a summary follows while it lasts)",
                behind.as_millis()
            );
        } else if state
            .last_summary
            .is_none_or(|t| now - t >= LAG_SUMMARY_EVERY)
        {
            state.last_summary = Some(now);
            warn!(
                "the host is still too slow: up to {} ms behind for the last {:.0} s",
                state.worst_in_stretch.as_millis(),
                (now - since).as_secs_f64()
            );
            state.worst_in_stretch = Duration::ZERO;
        }
    }

    /// How long the loop may sleep: until the bus has something to do, a session's timer, the
    /// beacon, or (frames on the wire) the end of a client's frame, else one [`BUSY_SLICE`].
    fn sleep_for(&self) -> Option<Duration> {
        // Input its full output kept unread: the flush just emptied the output.
        if self.input_ready() {
            return Some(Duration::ZERO);
        }
        let mut wait = if self.bus.is_idle() {
            let next = self.bus.next_activity();
            let wall_of_next = self.bits_to_wall(next.saturating_sub(self.bus.now()));
            // The bus is at the wall clock: sleep until its next activity.
            Some(wall_of_next)
        } else if let Some(end) = self.bus.frame_end() {
            // The frame's deliveries leave the moment the bus has run up to its end.
            let wall = self.epoch.elapsed();
            self.pacer
                .wake_at(wall, Some(Ticks(end.get())))
                .map(|at| at.saturating_sub(wall))
        } else {
            Some(BUSY_SLICE)
        };
        let now_ns = self.now_ns();
        for c in self.clients.iter().flatten() {
            if let Some(d) = c.session.next_deadline() {
                let d = d.saturating_sub(now_ns).as_duration();
                wait = Some(wait.map_or(d, |w| w.min(d)));
            }
            // Room in the node's queue and finished frames come with frames ending on the wire.
            if (c.backlog.is_some() || !c.flushes.is_empty()) && self.bus.frame_end().is_none() {
                wait = Some(wait.map_or(BUSY_SLICE, |w| w.min(BUSY_SLICE)));
            }
        }
        if let Some(b) = &self.beacon {
            let d = b.next.saturating_duration_since(Instant::now());
            wait = Some(wait.map_or(d, |w| w.min(d)));
        }
        // The bus's statistics window closes every virtual second.
        let second = self.bits_to_wall(Nanos::from_secs(1).bit_times_at(self.bus.bitrate()));
        wait.map(|w| w.min(second).min(SUMMARY_EVERY))
    }

    /// At `max`: while a client's node queue is full and more of its frames wait, runs the
    /// bus and serves the clients again (each round fair as ever), up to [`FEED_ROUNDS`] or
    /// [`MAX_RUN`], before frames are delivered: fewer, larger writes to the receivers, each of
    /// which wakes a receiver. Returns whether some client still has work ready.
    fn feed_flat_out(&mut self, mut busy_io: bool) -> bool {
        let started = Instant::now();
        for _ in 1..FEED_ROUNDS {
            let waiting = self.clients.iter().flatten().any(|c| c.backlog.is_some());
            if !(waiting || busy_io) || started.elapsed() >= MAX_RUN {
                break;
            }
            self.advance_bus();
            busy_io = self.serve_clients();
        }
        busy_io
    }

    /// At `max`: whether a receiver has half its output limit waiting and has read within
    /// [`STALLED_AFTER`]. The bus would run ahead of it and drop its frames; a client that does
    /// not read at all holds nobody up for longer than that.
    fn receiver_behind(&self) -> bool {
        let limit = self.session_config.max_output / 2;
        self.clients.iter().flatten().any(|c| {
            let (a, b) = c.session.output();
            a.len() + b.len() >= limit && reads(c) && !c.left
        })
    }

    /// At `max`: no sleep while the bus has work (or a scheduled activity to skip to);
    /// otherwise until a session's timer, the beacon or the summary.
    fn sleep_for_flat_out(&self) -> Option<Duration> {
        // Work the bus may do now: none while a receiver must read first (see
        // `advance_flat_out`), which holds the bus as a receiver behind does: its write event,
        // or its stall, ends the wait.
        let must_read = self.delivery_budget() == BitTime::ZERO;
        let bus_has_work =
            (!self.bus.is_idle() || self.bus.next_activity() != BitTime::MAX) && !must_read;
        // A client not read because a receiver held the turn: the flush may since have
        // released the hold. Likewise a frame that waited for room in its node's queue: the
        // bus may have emptied the queue during the hold, and no event comes for that.
        let input_ready = self.input_ready() || self.backlog_fits();
        let now_ns = self.now_ns();
        let mut next = self
            .clients
            .iter()
            .flatten()
            .filter_map(|c| c.session.next_deadline())
            .map(|d| d.saturating_sub(now_ns).as_duration())
            .min();
        if let Some(b) = &self.beacon {
            let d = b.next.saturating_duration_since(Instant::now());
            next = Some(next.map_or(d, |n| n.min(d)));
        }
        Some(flat_out_wait(
            bus_has_work,
            self.receiver_behind() || must_read,
            input_ready,
            next,
        ))
    }

    fn accept(&mut self) {
        loop {
            let (mut stream, peer) = match self.listener.accept() {
                Ok(s) => s,
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => return,
                Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                Err(e) => {
                    // Out of file descriptors and the like. The listener's readiness is
                    // edge-triggered: the connection waiting now brings no second event, so
                    // the loop tries again every ACCEPT_RETRY until it gets through.
                    if !self.accept_failed {
                        warn!("cannot accept a connection: {e}; trying again");
                    }
                    self.accept_failed = true;
                    return;
                }
            };
            self.accept_failed = false;
            if self.open >= self.max_connections && !self.evict_idle() {
                let refusal = ServerMessage::Error(format!(
                    "too many connections ({} open); try again later",
                    self.max_connections
                ));
                let _ = stream.write(refusal.to_string().as_bytes());
                debug!("refused {peer}: {} connections open", self.open);
                continue;
            }
            let _ = stream.set_nodelay(true);
            self.set_send_buffer(&stream);
            let slot = match self.clients.iter().position(Option::is_none) {
                Some(i) => i,
                None => {
                    self.clients.push(None);
                    self.clients.len() - 1
                }
            };
            if let Err(e) = self.poll.registry().register(
                &mut stream,
                Token(FIRST_CLIENT + slot),
                Interest::READABLE | Interest::WRITABLE,
            ) {
                debug!("cannot watch {peer}: {e}");
                continue;
            }
            let now_ns = self.now_ns();
            let session = Session::new(self.session_config.clone(), now_ns);
            self.clients[slot] = Some(Client {
                stream,
                peer,
                session,
                accepted: now_ns,
                readable: true,
                writable: true,
                left: false,
                input_ended: false,
                backlog: None,
                flushes: VecDeque::new(),
                dropped_reported: 0,
                drained_at: Instant::now(),
            });
            self.open += 1;
            debug!("{peer} connected");
        }
    }

    /// Makes room for a new connection when all places are taken: the oldest connection that
    /// has not opened the bus is told why and closed (it may be one of many an attacker holds
    /// open; a real client opens the bus right after the greeting). `false` if every
    /// connection has opened the bus.
    fn evict_idle(&mut self) -> bool {
        let oldest = self
            .clients
            .iter()
            .enumerate()
            .filter_map(|(slot, c)| c.as_ref().map(|c| (slot, c)))
            .filter(|(_, c)| c.session.node().is_none() && !c.session.is_closing())
            .min_by_key(|(_, c)| c.accepted)
            .map(|(slot, _)| slot);
        let Some(mut c) = oldest.and_then(|slot| self.clients[slot].take()) else {
            return false;
        };
        let notice = ServerMessage::Error(format!(
            "closed: all {} places are taken and this connection had not opened the bus",
            self.max_connections
        ));
        let _ = c.stream.write(notice.to_string().as_bytes());
        let _ = self.poll.registry().deregister(&mut c.stream);
        let _ = c.stream.shutdown(std::net::Shutdown::Both);
        self.open -= 1;
        debug!("closed {} to make room: it had not opened the bus", c.peer);
        true
    }

    /// Reads what clients sent and carries out their sessions' actions. Returns whether some
    /// client still has work ready (its turn's budget ran out).
    fn serve_clients(&mut self) -> bool {
        let mut more = false;
        let now_ns = self.now_ns();
        let started = Instant::now();
        let count = self.clients.len();
        // Round robin from where the last turn stopped: when the turn's time runs out, the
        // clients not served yet go first next time.
        for k in 0..count {
            let slot = (self.next_client + k) % count;
            if k > 0 && started.elapsed() >= MAX_RUN {
                self.next_client = slot;
                return true;
            }
            let Some(mut c) = self.clients[slot].take() else {
                continue;
            };
            if let Some(action) = c.session.handle_timeout(now_ns) {
                self.act(&mut c, action);
            }
            more |= self.serve(&mut c);
            self.clients[slot] = Some(c);
        }
        self.next_client = 0;
        more
    }

    /// Gives a client [`SEND_BUFFER`]; says once if the kernel caps it lower
    /// (`net.core.wmem_max`), which brings back waits for delayed acknowledgements.
    fn set_send_buffer(&mut self, stream: &TcpStream) {
        use nix::sys::socket::{getsockopt, setsockopt, sockopt::SndBuf};
        let result =
            setsockopt(stream, SndBuf, &SEND_BUFFER).and_then(|()| getsockopt(stream, SndBuf));
        // Linux reports twice what was set (its bookkeeping overhead included).
        let got = match result {
            Ok(doubled) if doubled >= 2 * SEND_BUFFER => return,
            Ok(doubled) => format!("{} bytes", doubled / 2),
            Err(e) => e.to_string(),
        };
        if !std::mem::replace(&mut self.send_buffer_warned, true) {
            warn!(
                "a client's send buffer is {got}, not {SEND_BUFFER} bytes (net.core.wmem_max?): \
                 frames to fast readers may wait for delayed acknowledgements"
            );
        }
    }

    /// Sessions' timers only (an unopened connection's time-out, the end of a hold on
    /// frames), for turns in which the clients are not read.
    fn handle_timeouts(&mut self) {
        let now_ns = self.now_ns();
        for slot in 0..self.clients.len() {
            let Some(mut c) = self.clients[slot].take() else {
                continue;
            };
            if let Some(action) = c.session.handle_timeout(now_ns) {
                self.act(&mut c, action);
            }
            self.clients[slot] = Some(c);
        }
    }

    /// Whether a client has input that [`Server::serve`] would read now. Readiness is
    /// edge-triggered: a client left readable (a turn that did not read it, or whose output
    /// was full until the flush after it) gets no second event, so the loop must not wait
    /// for one. A frame waiting for room in its node's queue waits for the bus instead.
    fn input_ready(&self) -> bool {
        self.clients
            .iter()
            .flatten()
            .any(|c| c.readable && c.backlog.is_none() && c.session.wants_input())
    }

    /// Whether a client's frame that waited for room in its node's queue would go in now.
    fn backlog_fits(&self) -> bool {
        self.clients.iter().flatten().any(|c| {
            c.backlog.is_some() && c.session.node().is_some_and(|n| self.bus.takes_frame(n))
        })
    }

    fn serve(&mut self, c: &mut Client) -> bool {
        // Borrowed from the server for the turn (a fresh one zeroed 16 KiB per client per
        // turn).
        let mut buf = std::mem::take(&mut self.read_buf);
        let more = self.serve_from(c, &mut buf);
        self.read_buf = buf;
        more
    }

    /// [`Server::serve`] with the read buffer.
    fn serve_from(&mut self, c: &mut Client, buf: &mut [u8]) -> bool {
        let mut budget = ACTIONS_PER_TURN;
        loop {
            // A frame waiting for room in the node's queue holds up everything behind it.
            if let Some(frame) = c.backlog.take()
                && !self.submit(c, frame)
            {
                return false;
            }
            while budget > 0 {
                let Some(action) = c.session.poll_action(self.now_ns()) else {
                    break;
                };
                budget -= 1;
                self.act(c, action);
                if c.backlog.is_some() {
                    return false;
                }
            }
            if budget == 0 {
                return true;
            }
            if !(c.readable && c.session.wants_input()) {
                return false;
            }
            // A client that left is read to the end of its stream: the kernel keeps what it
            // sent before its FIN, and before its RST too (the read after the last byte fails).
            match c.stream.read(buf) {
                Ok(0) => self.input_ended(c),
                Ok(n) => {
                    self.idle_bus_to_the_wall_clock();
                    c.session.receive(&buf[..n]);
                }
                // After the peer closed, nothing more can come.
                Err(e) if e.kind() == io::ErrorKind::WouldBlock && c.left => self.input_ended(c),
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => {
                    c.readable = false;
                    return false;
                }
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                Err(e) => {
                    debug!("reading from {}: {e}", c.peer);
                    self.input_ended(c);
                }
            }
        }
    }

    /// Paced, an idle bus catches up with the wall clock now that bytes were read: a frame
    /// among them starts no earlier than they came (they may have come after the turn ran
    /// the bus), so it ends no earlier than its wire time after it was sent. Not later
    /// either: the clock is read before they are parsed.
    fn idle_bus_to_the_wall_clock(&mut self) {
        if matches!(self.speed, Speed::Times(_)) && self.bus.is_idle() {
            let target = self.target_bits();
            if self.bus.now() < target {
                self.bus.run_until(target);
            }
        }
    }

    /// The client's last byte was read: the session hands out the rest of what it sent.
    fn input_ended(&mut self, c: &mut Client) {
        c.input_ended = true;
        c.session.finish_input();
        client_left(c, &mut self.bus);
    }

    /// Hands a client's frame to its node; `false` (frame kept back) when the queue is full.
    fn submit(&mut self, c: &mut Client, frame: buslab_can::Frame) -> bool {
        let Some(number) = c.session.node() else {
            return true;
        };
        match self.bus.submit(number, frame) {
            Ok(Ok(())) | Err(_) => true,
            Ok(Err(frame)) => {
                c.backlog = Some(frame);
                false
            }
        }
    }

    fn act(&mut self, c: &mut Client, action: Action) {
        match action {
            Action::Join => {
                let result = self.bus.join().map_err(|e| e.to_string());
                if let Ok(number) = result {
                    info!("client {} is node {number}", c.peer);
                    // It sent `< open … >` and more, then left before the answer: its node
                    // sends what followed.
                    if c.left {
                        let _ = self.bus.depart(number);
                    }
                }
                if let Some(Action::Close) = c.session.joined(result) {
                    // The session closes itself once its last words are written.
                }
            }
            Action::Send(frame) => {
                self.submit(c, frame);
            }
            Action::Request(command) => {
                let Some(me) = c.session.node() else {
                    c.session.reply(&ServerMessage::Error(
                        "open a bus first: < open BUS >".into(),
                    ));
                    return;
                };
                match command {
                    // Nobody to tell.
                    Command::Flush if c.left => {}
                    Command::Flush => match self.bus.client_mut(me) {
                        Ok(node) => c.flushes.push_back(node.submitted()),
                        Err(e) => c.session.reply(&ServerMessage::Error(e.to_string())),
                    },
                    other => {
                        let reply = answer(&mut self.bus, me, other);
                        c.session.reply(&reply);
                    }
                }
            }
            Action::Close => {}
            Action::Unfinished { excerpt, bytes } => warn!(
                "client {}{} closed in the middle of an element: {bytes} bytes discarded ({excerpt:?})",
                c.peer,
                c.session
                    .node()
                    .map_or(String::new(), |n| format!(" (node {n})"))
            ),
        }
    }

    /// Moves frames and error frames from the client nodes to their sessions, and answers
    /// flushes whose frames are done.
    fn deliver(&mut self) {
        let bitrate = self.bus.bitrate();
        let unix0 = self.unix0;
        let stamp = |time: BitTime| {
            let ns = unix0 + u128::from(time.at_bitrate(bitrate).get());
            Timestamp::from_nanos(u64::try_from(ns).unwrap_or(u64::MAX))
        };
        let now_ns = self.now_ns();
        // Every receiver gets the same frames in the same order: each is formatted once.
        let mut formatted = FormattedFrames::default();
        let taken = &mut self.taken;
        for c in self.clients.iter_mut().flatten() {
            let Some(number) = c.session.node() else {
                continue;
            };
            let Ok(node) = self.bus.client_mut(number) else {
                continue;
            };
            // Frames and error frames in the order they happened.
            let errors: Vec<_> = node.take_error_frames().collect();
            let mut errors = errors.into_iter().peekable();
            let mut lost = 0;
            formatted.rewind();
            taken.clear();
            taken.extend(
                node.take_deliveries()
                    .map(|d| (d.time, formatted.find(d.time, &d.frame, &stamp))),
            );
            // The run of frames every receiver gets, and nothing else: in one piece.
            let whole = errors.peek().is_none()
                && formatted
                    .run(taken)
                    .is_some_and(|lines| c.session.deliver_formatted_lines(lines, now_ns));
            for &(time, at) in taken.iter().filter(|_| !whole) {
                while let Some(e) = errors.next_if(|e| e.time <= time) {
                    lost += !deliver_error(&mut c.session, &e, stamp(e.time), now_ns) as u64;
                }
                lost += !c.session.deliver_formatted(formatted.text(at), now_ns) as u64;
            }
            for e in errors {
                lost += !deliver_error(&mut c.session, &e, stamp(e.time), now_ns) as u64;
            }
            node.counters.rx_lost += lost;
            while c
                .flushes
                .front()
                .is_some_and(|&target| node.done() >= target)
            {
                c.flushes.pop_front();
                c.session.reply(&flushed_reply(&TxReport {
                    sent: node.counters.sent,
                    failed: node.counters.tx_failed,
                }));
            }
            let lost = node.counters.rx_lost;
            if lost > c.dropped_reported
                && (c.dropped_reported == 0 || lost >= c.dropped_reported * 2)
            {
                warn!(
                    "node {number} ({}): the client does not keep up: {lost} frames dropped for it so far",
                    c.peer
                );
                c.dropped_reported = lost;
            }
        }
    }

    fn flush_all(&mut self) {
        let now_ns = self.now_ns();
        for c in self.clients.iter_mut().flatten() {
            if !c.session.has_output() {
                c.drained_at = Instant::now();
            }
            while c.writable && c.session.has_output() {
                let (a, b) = c.session.output();
                let first = if a.is_empty() { b } else { a };
                match c.stream.write(first) {
                    Ok(0) => client_left(c, &mut self.bus),
                    Ok(n) => {
                        c.session.consumed(n, now_ns);
                        c.drained_at = Instant::now();
                    }
                    Err(e) if e.kind() == io::ErrorKind::WouldBlock => c.writable = false,
                    Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                    Err(e) => {
                        debug!("writing to {}: {e}", c.peer);
                        client_left(c, &mut self.bus);
                    }
                }
            }
        }
    }

    /// Drops connections that are over: the session closed and its last words are out, or
    /// the peer left and everything it sent has been handed over (its node stays until its
    /// frames are sent or given up: [`VirtualBus::depart`]).
    fn reap(&mut self) {
        for slot in self.clients.iter_mut() {
            let over = slot.as_ref().is_some_and(|c| {
                (c.session.is_closing() && !c.session.has_output())
                    || (c.input_ended && c.session.is_drained() && c.backlog.is_none())
            });
            if !over {
                continue;
            }
            let Some(mut c) = slot.take() else { continue };
            let _ = self.poll.registry().deregister(&mut c.stream);
            let _ = c.stream.shutdown(std::net::Shutdown::Both);
            self.open -= 1;
            match c.session.node() {
                Some(number) => {
                    if c.session.is_closing() {
                        self.bus.leave(number);
                    } else {
                        self.bus.input_ended(number);
                    }
                    debug!("client {} (node {number}) disconnected", c.peer);
                }
                None => debug!("{} disconnected", c.peer),
            }
        }
    }

    /// The beacon, the bus's log, the periodic summary.
    fn housekeeping(&mut self) {
        if let Some(b) = &mut self.beacon {
            let now = Instant::now();
            if now >= b.next {
                if let Err(e) = b.socket.send_to(b.text.as_bytes(), b.target) {
                    debug!("beacon to {}: {e}", b.target);
                }
                b.next = now + BEACON_EVERY;
            }
        }
        self.log_bus_events();
        if self.last_summary.elapsed() >= SUMMARY_EVERY {
            self.last_summary = Instant::now();
            let stats = *self.bus.stats();
            if (stats.frames, stats.errors) != self.summarised {
                self.summarised = (stats.frames, stats.errors);
                let last = self.bus.last_second();
                info!(
                    "bus: load {:.1} % (last second), {} frames/s, {} frames, {} errors",
                    100.0 * last.load(),
                    last.frames,
                    stats.frames,
                    stats.errors
                );
            }
        }
    }

    fn log_bus_events(&mut self) {
        let bitrate = self.bus.bitrate();
        for (time, event) in self.bus.take_events() {
            let t = time.secs_f64_at(bitrate);
            if event.is_warning() {
                warn!("({t:.6}) {event}");
            } else if matches!(event, BusEvent::Node { .. }) {
                debug!("({t:.6}) {event}");
            } else {
                info!("({t:.6}) {event}");
            }
        }
    }
}

/// The client closed or reset its connection, or writing to it failed: nothing reaches it any
/// more, and its node departs (it sends what the client handed over, then leaves:
/// [`VirtualBus::depart`]) while what the client sent before is still read. At the end of a
/// stream reads never block again, so the client stays readable.
fn client_left(c: &mut Client, bus: &mut VirtualBus) {
    if std::mem::replace(&mut c.left, true) {
        return;
    }
    c.readable = true;
    c.session.close_output();
    c.flushes.clear();
    if let Some(number) = c.session.node() {
        debug!("client {} (node {number}) left", c.peer);
        let _ = bus.depart(number);
    }
}

/// The frames of one delivery round, formatted once: receivers look them up in the order they
/// got them (a receiver misses its own frames, so a few places ahead are looked at; what is
/// not found is formatted and added). Their lines are also kept one after another, so that a
/// receiver that gets a run of them in order takes the run in one piece.
#[derive(Default)]
struct FormattedFrames {
    frames: Vec<(BitTime, buslab_can::Frame, FormattedFrame)>,
    /// The frames' lines as every client gets them, one after another; frame `k`'s ends at
    /// `ends[k]`.
    lines: String,
    ends: Vec<usize>,
    cursor: usize,
}

/// How far ahead of the expected place a receiver's frame is looked for.
const LOOK_AHEAD: usize = 4;

impl FormattedFrames {
    /// The next receiver starts at the first frame.
    fn rewind(&mut self) {
        self.cursor = 0;
    }

    /// Where the frame is (formatted now if it is new).
    fn find(
        &mut self,
        time: BitTime,
        frame: &buslab_can::Frame,
        stamp: &impl Fn(BitTime) -> Timestamp,
    ) -> usize {
        let end = self.frames.len().min(self.cursor + LOOK_AHEAD);
        let found = self.frames[self.cursor.min(end)..end]
            .iter()
            .position(|(t, f, _)| *t == time && f == frame)
            .map(|k| self.cursor + k);
        match found {
            Some(at) => {
                self.cursor = at + 1;
                at
            }
            None => {
                let text = FormattedFrame::new(frame, stamp(time));
                self.lines.push_str(text.text(false));
                self.ends.push(self.lines.len());
                self.frames.push((time, *frame, text));
                self.frames.len() - 1
            }
        }
    }

    fn text(&self, at: usize) -> &FormattedFrame {
        &self.frames[at].2
    }

    /// The lines of frames `taken` (places from [`Self::find`]) in one piece, if they are
    /// consecutive, none of them is a remote frame (a client may take those as `R<dlc>`),
    /// and there is at least one.
    fn run(&self, taken: &[(BitTime, usize)]) -> Option<&str> {
        let (&(_, first), &(_, last)) = (taken.first()?, taken.last()?);
        if !taken.windows(2).all(|w| w[1].1 == w[0].1 + 1) {
            return None;
        }
        let plain = self.frames[first..=last]
            .iter()
            .all(|(_, f, _)| !f.is_remote());
        let start = first.checked_sub(1).map_or(0, |k| self.ends[k]);
        plain.then(|| &self.lines[start..self.ends[last]])
    }
}

/// An error frame in socketcand's raw layout (its data bytes only for clients with buslab's
/// extensions; socketcand -e sends the class alone, without the counters bit).
fn deliver_error(
    session: &mut Session,
    e: &TimedErrorFrame,
    timestamp: Timestamp,
    now_ns: buslab_can::Nanos,
) -> bool {
    let (class, data) = e.frame.encode();
    session.deliver_error_frame(class, &data, timestamp, now_ns)
}

/// Whether a client reads what it is sent: its output is empty, or a write of it made
/// progress within [`STALLED_AFTER`]. One that does not holds nobody up at `max` (its frames
/// are dropped and counted, as at any speed).
fn reads(c: &Client) -> bool {
    !c.session.has_output() || c.drained_at.elapsed() < STALLED_AFTER
}

/// At `max`: how long the loop may wait for an event. No wait while the bus has work (or a
/// scheduled activity to skip to), nor while a client's input is there to be read (or its
/// frame that waited for room in its node's queue would now go in) and no receiver holds the
/// bus; held by a receiver, until it reads (a write event) or is seen
/// stalled; otherwise until the next deadline (a session's timer, the beacon) or the summary.
fn flat_out_wait(
    bus_has_work: bool,
    receiver_behind: bool,
    input_ready: bool,
    next_deadline: Option<Duration>,
) -> Duration {
    if bus_has_work || (input_ready && !receiver_behind) {
        return Duration::ZERO;
    }
    let wait = if receiver_behind {
        STALLED_AFTER
    } else {
        SUMMARY_EVERY
    };
    next_deadline.map_or(wait, |d| wait.min(d))
}

/// The reply to an extension command from node `me`.
fn answer(bus: &mut VirtualBus, me: u32, command: Command) -> ServerMessage {
    let own = NodeRef::Number(me);
    let result: Result<ServerMessage, VbusError> = match command {
        Command::Name(name) => bus.rename(me, &name).map(|()| ServerMessage::Ok),
        Command::ReceiveOwn(on) => bus.client_mut(me).map(|n| {
            n.receive_own = on;
            ServerMessage::Ok
        }),
        Command::ErrorFrames(on) => bus.client_mut(me).map(|n| {
            n.set_error_frames(on);
            ServerMessage::Ok
        }),
        Command::Btr { btr0, btr1 } => bus.set_btr(me, btr0, btr1).map(|()| ServerMessage::Ok),
        Command::Controller(settings) => bus.configure(me, &settings).map(|()| ServerMessage::Ok),
        Command::BusOff(recovery) => bus.client_mut(me).map(|n| {
            n.set_bus_off_recovery(recovery);
            ServerMessage::Ok
        }),
        Command::Abort => bus.client_mut(me).map(|n| {
            n.abort();
            ServerMessage::Ok
        }),
        Command::Fault { fault, lasting_ms } => {
            let lasting = (lasting_ms > 0).then(|| Duration::from_millis(lasting_ms));
            bus.inject_fault(&fault, lasting)
                .map(|()| ServerMessage::Ok)
        }
        Command::Repair => {
            bus.repair();
            Ok(ServerMessage::Ok)
        }
        Command::Board { slio, change } => bus
            .demo_board(slio, change)
            .map(|board| buslab_socketcand::reply::board_reply(&board)),
        Command::Nodes => Ok(nodes_reply(&bus.nodes())),
        Command::Status(node) => bus
            .status(node.as_ref().unwrap_or(&own))
            .map(|status| status_reply(&status)),
        Command::Regs(node) => bus
            .regs(node.as_ref().unwrap_or(&own))
            .map(|regs| regs_reply(&regs)),
        other => Ok(ServerMessage::Error(format!(
            "{other} is not an extension command"
        ))),
    };
    result.unwrap_or_else(|e| match e {
        VbusError::FaultRefused(limit) => refused_reply(&limit),
        e => ServerMessage::Error(e.to_string()),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A sender's input seen while a receiver held the turn is read as soon as the hold ends:
    /// the event that reported it will not come again. (Before, the loop slept until the
    /// 5 s summary with the sender's frames unread, and python-can receivers waiting with a
    /// 2 s timeout gave up: bench/vbus_speed.py.)
    #[test]
    fn at_max_input_already_reported_is_read_without_waiting() {
        assert_eq!(flat_out_wait(false, false, true, None), Duration::ZERO);
        // Held: the receiver's write event ends the wait, or it is seen stalled.
        assert_eq!(flat_out_wait(false, true, true, None), STALLED_AFTER);
        assert_eq!(flat_out_wait(true, true, true, None), Duration::ZERO);
        // Nothing to do: until the next deadline or the summary.
        assert_eq!(flat_out_wait(false, false, false, None), SUMMARY_EVERY);
        let soon = Duration::from_millis(3);
        assert_eq!(flat_out_wait(false, false, false, Some(soon)), soon);
        assert_eq!(flat_out_wait(false, true, false, Some(soon)), soon);
    }
}
