//! `buslab bus serve`: the virtual CAN bus server (socketcand protocol, SJA1000 nodes), and the
//! bus URLs every CAN client command (`dump`, `send`, `gen`, `regs`, `status`) takes.

use std::fmt;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::str::FromStr;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use anyhow::{Context, bail};
use buslab_canbus::CanBus;
use buslab_socketcand::{NodeRef, SocketcandBus};

/// The default server address (socketcand's port) and bus.
pub const DEFAULT_BUS: &str = "socketcand://127.0.0.1:29536/vcan0";

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
    /// Run the bus this many times faster than real time (benchmarks only: frame times are
    /// then virtual, not the wall clock).
    #[arg(long, default_value_t = 1.0)]
    pub speed: f64,
    /// Frames queued for one client before newer ones are dropped for it (16..=1048576).
    #[arg(long, default_value_t = 8192)]
    pub client_queue: usize,
    /// Send every client its chip's bus errors, lost arbitrations and state changes as
    /// error frames (`< error CLASS SEC.USEC >`, like socketcand -e).
    #[arg(short = 'e', long)]
    pub error_frames: bool,
    /// Send socketcand's discovery beacon every 3 s (python-can's `detect_beacon()`), to
    /// ADDR, by default 127.0.0.1:42000 when listening on loopback, else the broadcast
    /// address 255.255.255.255:42000.
    #[arg(long, value_name = "ADDR", num_args = 0..=1, default_missing_value = "auto")]
    pub beacon: Option<String>,
}

/// The common `--bus` option.
#[derive(clap::Args, Clone)]
pub struct BusOpt {
    /// The bus: socketcand://HOST[:PORT]/CHANNEL (socketcan:IFACE and slcan:DEVICE later).
    #[arg(long, default_value = DEFAULT_BUS)]
    pub bus: BusUrl,
}

/// Where a CAN client command connects.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum BusUrl {
    Socketcand {
        host: String,
        port: u16,
        channel: String,
    },
    SocketCan {
        interface: String,
    },
    Slcan {
        device: String,
    },
}

impl FromStr for BusUrl {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        if let Some(rest) = s.strip_prefix("socketcand://") {
            let (hostport, channel) = rest.split_once('/').unwrap_or((rest, "vcan0"));
            let channel = if channel.is_empty() { "vcan0" } else { channel };
            if channel.contains(['/', '<', '>', ' ']) {
                return Err(format!(
                    "bus URL {s:?}: channel {channel:?} must be one name"
                ));
            }
            let parse_port = |p: &str| {
                p.parse::<u16>()
                    .ok()
                    .filter(|&p| p != 0)
                    .ok_or_else(|| format!("bus URL {s:?}: port {p:?} must be a number 1..65535"))
            };
            let (host, port) = if let Some(bracketed) = hostport.strip_prefix('[') {
                // An IPv6 address: `[::1]` or `[::1]:PORT`.
                let (h, after) = bracketed
                    .split_once(']')
                    .ok_or_else(|| format!("bus URL {s:?}: unclosed [ in the host"))?;
                let port = match after {
                    "" => 29536,
                    _ => parse_port(after.strip_prefix(':').ok_or_else(|| {
                        format!("bus URL {s:?}: expected :PORT or nothing after ], got {after:?}")
                    })?)?,
                };
                (h, port)
            } else {
                match hostport.rsplit_once(':') {
                    // `fe80::1` without brackets: an IPv6 address on the default port.
                    Some((h, p)) if !h.ends_with(':') => (h, parse_port(p)?),
                    _ => (hostport, 29536),
                }
            };
            if host.is_empty() {
                return Err(format!("bus URL {s:?} has no host"));
            }
            return Ok(BusUrl::Socketcand {
                host: host.to_string(),
                port,
                channel: channel.to_string(),
            });
        }
        if let Some(interface) = s.strip_prefix("socketcan:") {
            return Ok(BusUrl::SocketCan {
                interface: interface.to_string(),
            });
        }
        if let Some(device) = s.strip_prefix("slcan:") {
            return Ok(BusUrl::Slcan {
                device: device.to_string(),
            });
        }
        Err(format!(
            "bus URL {s:?}: expected socketcand://HOST[:PORT]/CHANNEL, socketcan:IFACE or slcan:DEVICE"
        ))
    }
}

impl fmt::Display for BusUrl {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            BusUrl::Socketcand {
                host,
                port,
                channel,
            } if host.contains(':') => write!(f, "socketcand://[{host}]:{port}/{channel}"),
            BusUrl::Socketcand {
                host,
                port,
                channel,
            } => write!(f, "socketcand://{host}:{port}/{channel}"),
            BusUrl::SocketCan { interface } => write!(f, "socketcan:{interface}"),
            BusUrl::Slcan { device } => write!(f, "slcan:{device}"),
        }
    }
}

impl BusUrl {
    /// The channel name shown in candump-like output.
    pub fn channel(&self) -> &str {
        match self {
            BusUrl::Socketcand { channel, .. } => channel,
            BusUrl::SocketCan { interface } => interface,
            BusUrl::Slcan { device } => device,
        }
    }
}

/// An open bus with buslab's extensions when the server has them.
pub struct OpenBus {
    pub bus: SocketcandBus,
    pub extensions: bool,
}

/// Connects to the bus behind `url`.
pub fn open(url: &BusUrl) -> anyhow::Result<OpenBus> {
    match url {
        BusUrl::Socketcand {
            host,
            port,
            channel,
        } => {
            let mut bus = SocketcandBus::connect((host.as_str(), *port), channel)
                .with_context(|| format!("cannot join {url}"))?;
            let extensions = bus.enable_extensions().context("buslab_ext")?;
            Ok(OpenBus { bus, extensions })
        }
        BusUrl::SocketCan { .. } => {
            bail!("{url}: the socketcan backend is not available yet (use socketcand://)")
        }
        BusUrl::Slcan { .. } => {
            bail!("{url}: the slcan backend is not available yet (use socketcand://)")
        }
    }
}

/// Waits until this client's node has sent `count` frames (a socketcand `send` has no
/// confirmation; leaving earlier would pull the node off the bus with frames still queued).
pub fn wait_sent(open: &mut OpenBus, count: u64, timeout: Duration) -> anyhow::Result<()> {
    if !open.extensions {
        return Ok(());
    }
    let deadline = Instant::now() + timeout;
    loop {
        let st = open.bus.node_status(None)?;
        let sent = st.counters.sent;
        let failed = st.counters.tx_failed;
        if sent + failed >= count {
            if failed > 0 {
                bail!("{failed} of {count} frames were not sent; the node's status:\n{st}");
            }
            return Ok(());
        }
        if Instant::now() >= deadline {
            bail!(
                "only {sent} of {count} frames were sent within {} (no other node to acknowledge them, or a bit rate mismatch?); the node's status:\n{st}",
                crate::units::Human(timeout)
            );
        }
        // Drain frames meanwhile so the server never has to drop ours.
        let _ = open.bus.recv(Some(Duration::from_millis(5)));
    }
}

/// `--node` as the server names nodes.
pub fn node_ref(text: &str) -> NodeRef {
    NodeRef::parse(text)
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
    config.beacon = match args.beacon.as_deref() {
        None => None,
        Some("auto") if args.listen.ip().is_loopback() => Some(([127, 0, 0, 1], 42000).into()),
        Some("auto") => Some(([255, 255, 255, 255], 42000).into()),
        Some(addr) => Some(
            addr.parse()
                .map_err(|_| anyhow::anyhow!("beacon address {addr:?} must be IP:PORT"))?,
        ),
    };
    if let Some(path) = &args.nodes {
        let text = super::sim::read_scenario(path)?;
        let scenario = buslab_sim::Scenario::from_toml(&text)
            .with_context(|| format!("bad scenario {}", path.display()))?;
        if scenario.bitrate != args.bitrate {
            bail!(
                "scenario {} runs at {} bit/s but the bus at {} bit/s (--bitrate)",
                path.display(),
                scenario.bitrate,
                args.bitrate
            );
        }
        let mut sim = scenario.build();
        sim.set_record_events(false);
        config.scenario = Some(sim);
    }
    let stop = Arc::new(AtomicBool::new(false));
    {
        let stop = stop.clone();
        ctrlc::set_handler(move || stop.store(true, Ordering::SeqCst))
            .context("cannot install the Ctrl-C handler")?;
    }
    let server = buslab_vbus::spawn(config)?;
    // The URL on stdout (tests and scripts read it when the port was 0).
    println!("socketcand://{}/{}", server.local_addr(), args.name);
    eprintln!("Ctrl-C to stop");
    while !stop.load(Ordering::SeqCst) {
        std::thread::sleep(Duration::from_millis(50));
    }
    server.shutdown();
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn urls() {
        let u: BusUrl = "socketcand://127.0.0.1:29537/can1".parse().unwrap();
        assert_eq!(
            u,
            BusUrl::Socketcand {
                host: "127.0.0.1".into(),
                port: 29537,
                channel: "can1".into()
            }
        );
        assert_eq!(u.to_string(), "socketcand://127.0.0.1:29537/can1");
        let u: BusUrl = "socketcand://localhost".parse().unwrap();
        assert_eq!(u.to_string(), "socketcand://localhost:29536/vcan0");
        let u: BusUrl = "socketcand://[::1]:5/x".parse().unwrap();
        assert_eq!(u.to_string(), "socketcand://[::1]:5/x");
        // A bracketed IPv6 host without a port takes the default one.
        let u: BusUrl = "socketcand://[::1]/x".parse().unwrap();
        assert_eq!(u.to_string(), "socketcand://[::1]:29536/x");
        let u: BusUrl = "socketcand://[fe80::1]".parse().unwrap();
        assert_eq!(u.to_string(), "socketcand://[fe80::1]:29536/vcan0");
        for (bad, want) in [
            ("socketcand://[::1/x", "unclosed ["),
            ("socketcand://[::1]x/x", "after ]"),
            ("socketcand://h:0/x", "port \"0\" must be a number 1..65535"),
        ] {
            let err = bad.parse::<BusUrl>().unwrap_err();
            assert!(err.contains(want), "{bad}: {err}");
        }
        assert_eq!(
            "socketcan:can0".parse::<BusUrl>().unwrap(),
            BusUrl::SocketCan {
                interface: "can0".into()
            }
        );
        assert!("slcan:/dev/ttyACM0".parse::<BusUrl>().is_ok());
        for bad in [
            "http://x",
            "socketcand://:1/x",
            "socketcand://h:99999/x",
            "socketcand://h:1/a b",
            "",
        ] {
            assert!(bad.parse::<BusUrl>().is_err(), "{bad}");
        }
    }
}
