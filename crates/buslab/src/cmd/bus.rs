//! `buslab bus serve`: the virtual CAN bus server (socketcand protocol, SJA1000 nodes). The bus
//! URLs the client commands take are in `busopt.rs` and `buslab_backends`.

use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::sync::atomic::Ordering;
use std::time::Duration;

use anyhow::Context;
use buslab_bench::serve::ServeError;

#[derive(clap::Args)]
pub struct Args {
    #[command(subcommand)]
    pub command: BusCommand,
}

#[derive(clap::Subcommand)]
pub enum BusCommand {
    /// Serve a simulated CAN bus over TCP (socketcand raw mode); every client gets its own
    /// SJA1000 on the bus.
    Serve(ServeArgs),
}

#[derive(clap::Args)]
pub struct ServeArgs {
    /// Address to listen on (loopback unless told otherwise; port 0 picks a free one).
    #[arg(long, default_value = "127.0.0.1:29536")]
    pub listen: SocketAddr,
    /// Bus bit rate in bit/s.
    #[arg(long, default_value_t = 500_000)]
    pub bitrate: u32,
    /// The bus name clients open (`< open NAME >`).
    #[arg(long, default_value = "vcan0")]
    pub name: String,
    /// Simulated nodes, traffic and faults from a scenario file (`buslab sim` format) on the
    /// same wire; its bit rate must be the bus's.
    #[arg(long, value_name = "SCENARIO")]
    pub nodes: Option<PathBuf>,
    /// Run the bus this many times faster than real time (0.001..=1000000), or `max`: as fast
    /// as the CPU allows, never waiting for the wall clock (benchmarks only: frame times are
    /// then virtual, not the wall clock).
    #[arg(long, default_value = "1", value_name = "N|max")]
    pub speed: buslab_vbus::Speed,
    /// Frames queued for one client before newer ones are dropped for it (16..=1048576).
    #[arg(long, default_value_t = 8192)]
    pub client_queue: usize,
    /// Send every client its chip's bus errors, lost arbitrations and state changes as
    /// error frames (`< error CLASS SEC.USEC >`, like socketcand -e).
    #[arg(short = 'e', long)]
    pub error_frames: bool,
    /// Put SLIO demo boards on the bus with these numbers (0..F, comma-separated, e.g.
    /// 0,3,A): P82C150 nodes that need calibrating (a host such as `buslab slio calibrate
    /// --keep` or python-can sending 0AA#AA04); the bus must run at 20000..125000 bit/s.
    #[arg(long, value_name = "IDS", value_delimiter = ',')]
    pub slio: Vec<buslab_slio::SlioId>,
    /// The SLIO boards' potentiometer (P6, ADC2): VOLTS, const:VOLTS,
    /// sine|triangle|square:FREQ[:AMPLITUDE[:OFFSET]], ramp:FROM:TO:PERIOD or csv:FILE (as the
    /// ZELLE and CPU196 inputs take them); default a 0..5 V sine of 10 s.
    #[arg(long, value_name = "SOURCE", default_value = buslab_bench::board::POTENTIOMETER)]
    pub slio_pot: String,
    /// The SLIO boards' ADC1 input (P5), same grammar; default 1.25 V.
    #[arg(long, value_name = "SOURCE", default_value = buslab_bench::board::ADC1)]
    pub slio_adc1: String,
    /// Put the PowerPC node running MoniCAN on the bus (it calibrates and drives the SLIOs)
    /// and serve its VT100 terminal on a pseudo-terminal (19200 8N1) linked at PATH: open it
    /// with `screen PATH 19200`, `picocom -b 19200 PATH` or minicom.
    #[arg(long, value_name = "PATH")]
    pub ppc: Option<PathBuf>,
    /// With --ppc: keep the PowerPC node's memory (what `buslab load` put there) in this
    /// S-record file, read at start and saved after each load before the node reports it.
    #[arg(long, value_name = "FILE", requires = "ppc")]
    pub ppc_memory: Option<PathBuf>,
    /// With --ppc: answer control lines on this Unix socket (`state`, `load`, `ranges`,
    /// `entry`, `read ADDR LEN`); `buslab load --verify SOCKET` reads the memory back here.
    #[arg(long, value_name = "SOCKET", requires = "ppc")]
    pub ppc_control: Option<PathBuf>,
    /// Send socketcand's discovery beacon every 3 s (python-can's `detect_beacon()`), to
    /// ADDR, by default 127.0.0.1:42000 when listening on loopback, else the broadcast
    /// address 255.255.255.255:42000.
    #[arg(long, value_name = "ADDR", num_args = 0..=1, default_missing_value = "auto")]
    pub beacon: Option<String>,
    /// After bus-off, restart client chips 100 ms later with TXERR := 0 (Linux's restart)
    /// instead of the seed's recovery (the chip counts 128 × 11 recessive bits, TXERR falling).
    #[arg(long)]
    pub fast_restart: bool,
    /// Join this bus to remote buses (repeatable): cannelloni://PEER:PORT?listen=HOST:PORT,
    /// cannelloni+tcp://HOST:PORT[?role=server] or mqtt://BROKER[:PORT]/PREFIX. A gateway node
    /// on this bus sends the remote frames here, where they arbitrate with the local ones, and
    /// the local frames there; its counters (sent, lost, reordered per peer) are printed when
    /// the server stops (docs/transports.md).
    #[arg(long, value_name = "URL", value_parser = parse_join_url)]
    pub join: Vec<buslab_backends::BusUrl>,
}

/// A join transport's URL (`--join`).
fn parse_join_url(text: &str) -> Result<buslab_backends::BusUrl, String> {
    let url: buslab_backends::BusUrl = text.parse().map_err(|e| format!("{e}"))?;
    match url {
        buslab_backends::BusUrl::Cannelloni { .. } | buslab_backends::BusUrl::Mqtt { .. } => {
            Ok(url)
        }
        _ => Err(format!(
            "{url} is not a join transport: expected cannelloni://PEER:PORT?listen=HOST:PORT, cannelloni+tcp://HOST:PORT[?role=server] or mqtt://BROKER[:PORT]/PREFIX (to copy frames to another kind of bus, use `buslab bridge`)"
        )),
    }
}

pub fn run(args: Args) -> anyhow::Result<()> {
    match args.command {
        BusCommand::Serve(a) => serve(a),
    }
}

fn serve(args: ServeArgs) -> anyhow::Result<()> {
    let mut config = buslab_vbus::ServerConfig::new(args.listen, args.bitrate);
    config.channel = args.name.clone();
    config.speed = args.speed;
    config.client_queue = args.client_queue;
    config.error_frames = args.error_frames;
    if args.fast_restart {
        config.bus_off_recovery = buslab_canbus::BusOffRecovery::Fast;
    }
    config.beacon = match args.beacon.as_deref() {
        None => None,
        Some("auto") if args.listen.ip().is_loopback() => Some(([127, 0, 0, 1], 42000).into()),
        Some("auto") => Some(([255, 255, 255, 255], 42000).into()),
        Some(addr) => Some(
            addr.parse()
                .map_err(|_| anyhow::anyhow!("beacon address {addr:?} must be IP:PORT"))?,
        ),
    };
    let mut bench = buslab_bench::serve::ServeBench {
        slios: args.slio.clone(),
        ppc: args.ppc.is_some(),
        ..Default::default()
    };
    if !args.slio.is_empty() {
        bench.adc1 = board_source("--slio-adc1", &args.slio_adc1)?;
        bench.potentiometer = board_source("--slio-pot", &args.slio_pot)?;
    }
    if let Some(path) = &args.nodes {
        let text = super::sim::read_scenario(path)?;
        let scenario = buslab_bench::Scenario::from_toml(&text)
            .with_context(|| format!("bad scenario {}", path.display()))?;
        bench.scenario = Some(scenario);
    }
    // The option that put it there.
    bench.install(&mut config).map_err(|e| {
        let option = match &e {
            ServeError::Slio { id, .. } => format!("--slio {id}"),
            ServeError::Ppc(_) => "--ppc".to_string(),
            ServeError::ScenarioBitrate { .. } | ServeError::Scenario(_) => {
                let path = args.nodes.as_deref().unwrap_or(Path::new(""));
                format!("--nodes {}", path.display())
            }
        };
        anyhow::Error::new(e).context(option)
    })?;
    let stop = super::interrupted()?;
    let server = buslab_vbus::spawn(config)?;
    let terminal = match &args.ppc {
        Some(path) => Some(
            buslab_served::ppc::serve(
                buslab_bench::ppc::NAME,
                server.poster(),
                buslab_served::ppc::PpcOptions {
                    link: Some(path.clone()),
                    memory: args.ppc_memory.clone(),
                    control: args.ppc_control.clone(),
                },
            )
            .context("cannot serve the PowerPC node")?,
        ),
        None => None,
    };
    // Each gateway is a client node of this bus, on its loopback side.
    let mut local = server.local_addr();
    if local.ip().is_unspecified() {
        local.set_ip(std::net::Ipv4Addr::LOCALHOST.into());
    }
    let mut gateways = Vec::new();
    for url in &args.join {
        let remote = buslab_backends::open_join(url, &super::busopt::open_options())
            .with_context(|| format!("--join {url}"))?;
        let mut node = buslab_backends::open(&format!("socketcand://{local}/{}", args.name))
            .context("the gateway cannot join this bus")?;
        if let Some(admin) = node.admin() {
            admin.set_name(&format!("join-{}", url.scheme().replace('+', "-")))?;
        }
        gateways.push((
            url.clone(),
            buslab_backends::Gateway::spawn(url.scheme(), node, remote)?,
        ));
    }
    // The URL on stdout (tests and scripts read it when the port was 0).
    println!("socketcand://{}/{}", server.local_addr(), args.name);
    if let (Some(path), Some(t)) = (&args.ppc, &terminal) {
        tracing::info!(
            "MoniCAN's terminal on {} ({}, 19200 8N1): screen {} 19200",
            path.display(),
            t.path().display(),
            path.display()
        );
        if let Some(control) = t.control_socket() {
            tracing::info!("PowerPC control socket on {}", control.display());
        }
    }
    tracing::info!("Ctrl-C to stop");
    while !stop.load(Ordering::SeqCst) {
        std::thread::sleep(Duration::from_millis(50));
    }
    // Each join's counters on stdout (what a script checks after stopping the server).
    for (url, gateway) in gateways {
        println!("joined {url}: {}", gateway.stop());
    }
    server.shutdown();
    Ok(())
}

/// An analog source in buslab's one spelling (a CSV replay file read here).
fn board_source(what: &str, spec: &str) -> anyhow::Result<buslab_analog::Source> {
    let spec = buslab_analog::SourceSpec::parse(spec).context(what.to_string())?;
    buslab_served::analog::load_source(spec).context(what.to_string())
}
