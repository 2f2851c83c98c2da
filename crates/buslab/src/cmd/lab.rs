//! `buslab lab`: the whole virtual bench, paced to real time.
//!
//! The bench's CAN bus is a virtual bus server (`buslab bus serve` in-process): simulated
//! nodes exchange periodic and bursty traffic on the bit-level wire, and any socketcand client
//! (python-can, `buslab dump`) can join it. The lab itself joins with two clients: a monitor
//! whose receptions are printed the way `candump` prints them, and a node sending a counter.
//! Next to the bus, a ZELLE cell and a CPU196 board are served on pseudo-terminals
//! ([`Devices`]).

use std::io::{self, Write};
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::{self, JoinHandle};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use anyhow::Context;
use buslab_can::controller::ControllerConfig;
use buslab_can::{Frame, Id};
use buslab_canbus::CanBus;
use buslab_sim::{BitTime, Simulation, Span, Traffic};
use buslab_socketcand::SocketcandBus;
use buslab_vbus::{ServerConfig, ServerError, ServerHandle};

use super::dump::Candump;

#[derive(clap::Args)]
pub struct Args {
    /// Stop after this long (`2s`, `500ms`); default: run until Ctrl-C.
    #[arg(long)]
    pub duration: Option<Span>,
    /// Bit rate of the simulated CAN bus.
    #[arg(long, default_value_t = 500_000, value_parser = clap::value_parser!(u32).range(1_000..=1_000_000))]
    pub bitrate: u32,
    /// Seed of the simulation.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Prefix each frame with the time since the start, as `candump -t z`.
    #[arg(short = 't', long)]
    pub timestamps: bool,
    /// Where the bus server listens (socketcand); if the default port is taken, a free one is
    /// used. The URL is printed at start.
    #[arg(long, value_name = "ADDR")]
    pub listen: Option<SocketAddr>,
    /// Keep the devices' state here (zelle.toml, cpu196.toml) and link their ports as
    /// DIR/zelle and DIR/cpu196; default: in memory, ports printed at start.
    #[arg(long, value_name = "DIR")]
    pub dir: Option<PathBuf>,
    /// Only the CAN bus: no ZELLE cell or CPU196 board.
    #[arg(long)]
    pub no_devices: bool,
}

/// The bus name clients open.
const CHANNEL: &str = "vcan0";
/// The lab's counter node: `200#` with a 32-bit little-endian counter.
const COUNTER_ID: u16 = 0x200;
const COUNTER_PERIOD: Duration = Duration::from_millis(50);

pub fn run(args: Args) -> anyhow::Result<()> {
    // A reader that goes away (`| head`) ends the run quietly, as for other Unix tools.
    match run_lab(args) {
        Err(e)
            if e.downcast_ref::<io::Error>()
                .is_some_and(|e| e.kind() == io::ErrorKind::BrokenPipe) =>
        {
            Ok(())
        }
        other => other,
    }
}

fn run_lab(args: Args) -> anyhow::Result<()> {
    let stop = Arc::new(AtomicBool::new(false));
    {
        let stop = stop.clone();
        ctrlc::set_handler(move || stop.store(true, Ordering::SeqCst))
            .context("cannot install the Ctrl-C handler")?;
    }
    let devices = if args.no_devices {
        None
    } else {
        Some(Devices::start(args.dir.as_deref())?)
    };
    let (scenario, names) = lab_nodes(args.bitrate, args.seed);
    // Frame times are the server's start plus virtual time: `-t` counts from here.
    let start_unix = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0.0, |d| d.as_secs_f64());
    let server = start_server(args.listen, args.bitrate, scenario)?;
    let addr = server.local_addr();
    eprintln!(
        "buslab lab: CAN bus socketcand://{addr}/{CHANNEL} at {} bit/s, nodes: {}, counter",
        args.bitrate,
        names.join(", ")
    );
    if let Some(devices) = &devices {
        devices.describe();
    }
    eprintln!("Ctrl-C to stop");

    let counter = spawn_counter(addr, stop.clone())?;
    let result = monitor(addr, &args, start_unix, &stop);
    stop.store(true, Ordering::SeqCst);
    let counted = counter.join();
    server.shutdown();
    if let Some(devices) = devices {
        devices.stop()?;
    }
    result?;
    counted.map_err(|_| anyhow::anyhow!("the counter node panicked"))?
}

/// Prints what the monitor's node receives until `stop` or the end of `--duration`.
fn monitor(
    addr: SocketAddr,
    args: &Args,
    start_unix: f64,
    stop: &AtomicBool,
) -> anyhow::Result<()> {
    let mut bus = join(addr, "monitor")?;
    let started = Instant::now();
    let end = args
        .duration
        .map(|d| Duration::from_secs_f64(d.to_bits(args.bitrate) as f64 / args.bitrate as f64));
    let stdout = io::stdout();
    let mut out = stdout.lock();
    let mut candump = Candump::default();
    while !stop.load(Ordering::SeqCst) {
        let left = end.map(|end| end.saturating_sub(started.elapsed()));
        if left == Some(Duration::ZERO) {
            break;
        }
        let wait = left.map_or(Duration::from_millis(100), |l| {
            l.min(Duration::from_millis(100))
        });
        if let Some(m) = bus.recv(Some(wait))? {
            let since_start = args.timestamps.then(|| (m.timestamp - start_unix).max(0.0));
            candump.line(&mut out, since_start, CHANNEL, &m.frame)?;
            out.flush()?;
        }
    }
    Ok(())
}

/// The counter node: a socketcand client sending `200#` + counter every 50 ms.
fn spawn_counter(
    addr: SocketAddr,
    stop: Arc<AtomicBool>,
) -> anyhow::Result<JoinHandle<anyhow::Result<()>>> {
    let mut bus = join(addr, "counter")?;
    let id = Id::standard(COUNTER_ID).expect("valid ID");
    Ok(thread::spawn(move || {
        let mut value = 0u32;
        let mut next = Instant::now();
        while !stop.load(Ordering::SeqCst) {
            let frame = Frame::data(id, &value.to_le_bytes()).expect("4 bytes");
            bus.send(&frame).context("counter node")?;
            value = value.wrapping_add(1);
            next += COUNTER_PERIOD;
            thread::sleep(next.saturating_duration_since(Instant::now()));
        }
        Ok(())
    }))
}

/// Joins the lab's bus as a named node.
fn join(addr: SocketAddr, name: &str) -> anyhow::Result<SocketcandBus> {
    let mut bus = SocketcandBus::connect(addr, CHANNEL)
        .with_context(|| format!("the {name} cannot join the lab's bus at {addr}"))?;
    if bus.enable_extensions()? {
        bus.set_name(name)?;
    }
    Ok(bus)
}

/// Starts the bus server; on the default address, a taken port falls back to a free one.
fn start_server(
    listen: Option<SocketAddr>,
    bitrate: u32,
    scenario: Simulation,
) -> anyhow::Result<ServerHandle> {
    let config = |addr, scenario| ServerConfig {
        channel: CHANNEL.to_string(),
        scenario: Some(scenario),
        log: Arc::new(|line: &str| {
            // The server's routine log would drown the frames; keep its warnings.
            if line.starts_with("warning") {
                eprintln!("{line}");
            }
        }),
        ..ServerConfig::new(addr, bitrate)
    };
    let default: SocketAddr = ([127, 0, 0, 1], 29536).into();
    match buslab_vbus::spawn(config(listen.unwrap_or(default), scenario)) {
        Err(ServerError::Listen { source, .. })
            if listen.is_none() && source.kind() == io::ErrorKind::AddrInUse =>
        {
            let (scenario, _) = lab_nodes(bitrate, 0);
            buslab_vbus::spawn(config(([127, 0, 0, 1], 0).into(), scenario))
                .context("starting the lab's bus server")
        }
        other => other.context("starting the lab's bus server"),
    }
}

/// The simulated nodes of the bench and their traffic.
fn lab_nodes(bitrate: u32, seed: u64) -> (Simulation, Vec<&'static str>) {
    let mut bus = Simulation::new(bitrate, seed);
    let ms = |m: u64| m * bitrate as u64 / 1000;
    let f = |text: &str| -> Frame { text.parse().expect("built-in frame") };
    let plain = ControllerConfig::default();
    let brakes = bus.add_node("brakes", plain);
    bus.add_traffic(brakes, periodic(f("080#0140"), ms(20), 0));
    let engine = bus.add_node("engine", plain);
    bus.add_traffic(engine, periodic(f("0C0#0FA0003C00000000"), ms(10), ms(1)));
    let body = bus.add_node("body", plain);
    bus.add_traffic(body, periodic(f("18FF0010#A5"), ms(100), ms(3)));
    let dash = bus.add_node("dash", plain);
    bus.add_traffic(
        dash,
        Traffic::Burst {
            frame: f("300#D1D2D3D4"),
            count: 4,
            period: ms(250),
            start: ms(5),
        },
    );
    (bus, vec!["brakes", "engine", "body", "dash"])
}

fn periodic(frame: Frame, period: BitTime, start: BitTime) -> Traffic {
    Traffic::Periodic {
        frame,
        period,
        start,
        count: None,
    }
}

/// The serial devices of the bench, each served on a pseudo-terminal by its own thread (and
/// stopped, with its state saved, when the bench stops).
struct Devices {
    zelle: buslab_served::zelle::ServedCell,
    cpu196: buslab_link::Served<buslab_cpu196::Board>,
    /// What the banner tells tools to open: the stable links when there is a folder, else the
    /// PTYs.
    zelle_port: PathBuf,
    cpu196_port: PathBuf,
}

impl Devices {
    fn start(dir: Option<&Path>) -> anyhow::Result<Self> {
        if let Some(dir) = dir {
            std::fs::create_dir_all(dir)
                .with_context(|| format!("cannot create the lab folder {}", dir.display()))?;
        }
        let file = |name: &str| dir.map(|d| d.join(name));
        // Two sine waves on the cell's first channels, so a measurement shows something.
        let sine = |amplitude, offset| buslab_zelle::analog::Source::Wave {
            shape: buslab_zelle::analog::Shape::Sine,
            hz: 0.5,
            amplitude,
            offset,
        };
        let zelle = buslab_served::zelle::ServedCell::spawn(buslab_served::zelle::CellOptions {
            state: file("zelle.toml"),
            link: file("zelle"),
            analog: vec![(1, sine(2.0, 2.5)), (2, sine(1.0, 2.5))],
        })
        .context("starting the ZELLE cell")?;
        let cpu196 = buslab_served::cpu196::spawn_board(buslab_served::cpu196::BoardOptions {
            image: file("cpu196.toml"),
            link: file("cpu196"),
            baud: super::cpu196::DEFAULT_BAUD,
            inputs: buslab_cpu196::source::Inputs::default(),
            peer: buslab_cpu196::pic::Peer::default(),
        })
        .context("starting the CPU196 board")?;
        Ok(Self {
            zelle_port: file("zelle").unwrap_or_else(|| zelle.path().to_path_buf()),
            cpu196_port: file("cpu196").unwrap_or_else(|| cpu196.path().to_path_buf()),
            zelle,
            cpu196,
        })
    }

    fn describe(&self) {
        eprintln!(
            "  ZELLE cell   on {}  (9600 8N2; try: buslab zelle --port {} analog 1)",
            self.zelle.path().display(),
            self.zelle_port.display()
        );
        eprintln!(
            "  CPU196 board on {}  ({} 8N1; try: buslab cpu196 --port {} info)",
            self.cpu196.path().display(),
            super::cpu196::DEFAULT_BAUD,
            self.cpu196_port.display()
        );
    }

    fn stop(self) -> anyhow::Result<()> {
        self.zelle.stop().context("stopping the ZELLE cell")?;
        self.cpu196.stop().context("stopping the CPU196 board")?;
        Ok(())
    }
}
