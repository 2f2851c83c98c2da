//! `buslab web --bus URL [--listen ADDR] [--token [TOKEN]] [--dbc FILE]`: the bus as web pages
//! (the seed's CAN WebServer) and a live dashboard (docs/web.md), with a DBC database's signals.

use std::net::{Ipv4Addr, SocketAddr};
use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::time::Duration;

use anyhow::Context;
use buslab_dbc::Database;
use buslab_slio::SlioId;
use buslab_web::{DeviceConfig, Timeouts, WebConfig, WebError, WebServer, generate_token};

use super::busopt::{BusOpt, open};
use super::lab::{AllowHost, WebOptions};
use crate::dbc::DbcArg;

#[derive(clap::Args)]
pub struct Args {
    #[command(flatten)]
    pub bus: BusOpt,
    /// Where to listen. Loopback by default: another address lets other machines read the
    /// bus (and write, with the token).
    #[arg(long, value_name = "ADDR", default_value = "127.0.0.1:8080")]
    pub listen: SocketAddr,
    /// Allow writes (send frames, inject faults) to requests carrying this token in the
    /// X-Buslab-Token header; `--token` alone makes a random one and prints it. Read-only
    /// without it.
    #[arg(long, value_name = "TOKEN", num_args = 0..=1, default_missing_value = "")]
    pub token: Option<String>,
    /// The bus's bit rate, to estimate the load on buses that do not report it (a buslab
    /// bus does).
    #[arg(long, value_name = "BIT/S", value_parser = clap::value_parser!(u32).range(1_000..=1_000_000))]
    pub bitrate: Option<u32>,
    /// Connections served at once; further ones get 503.
    #[arg(long, value_name = "N", default_value_t = 64, value_parser = clap::value_parser!(u32).range(1..=10_000))]
    pub max_connections: u32,
    #[command(flatten)]
    pub hosts: AllowHost,
    #[command(flatten)]
    pub dbc: DbcArg,
    /// How long a client may take to send a request's head, then its body, and may leave a
    /// kept-alive connection idle (for tests; docs/web.md).
    #[arg(long, value_name = "DURATION", value_parser = crate::units::duration, hide = true)]
    pub request_timeout: Option<Duration>,
}

/// `quiet` (the global `-q`): no `Ctrl-C to stop`.
pub fn run(args: Args, quiet: bool) -> anyhow::Result<()> {
    let token = match args.token.as_deref() {
        None => None,
        Some("") => Some(generate_token()?),
        Some(t) => Some(t.to_string()),
    };
    let url = &args.bus.bus;
    let dbc = args.dbc.load()?;
    // A joined bus keeps its counters for the overview page.
    let (bus, join): (buslab_backends::DynBus, _) = match url {
        buslab_backends::BusUrl::Cannelloni { .. } | buslab_backends::BusUrl::Mqtt { .. } => {
            let bus = buslab_backends::open_join(url, &super::busopt::open_options())?;
            let join = bus.sender();
            (Box::new(bus), Some(join))
        }
        _ => (open(url)?, None),
    };
    let server = WebServer::start(
        bus,
        WebConfig {
            listen: args.listen,
            token,
            max_connections: args.max_connections as usize,
            bitrate: args.bitrate,
            allowed_hosts: args.hosts.allow_host,
            timeouts: Timeouts {
                request: args.request_timeout.unwrap_or(Timeouts::default().request),
                ..Timeouts::default()
            },
            dbc,
            join,
            ..WebConfig::default()
        },
    )
    .with_context(|| format!("buslab web on {url}"))?;
    // The URL on stdout alone (scripts and tests read it), the rest for people on stderr.
    println!("{}", server.url());
    // The banner in one write: a reader (or a kill right after its last line) never sees a
    // part of it (a test killed the server between "writes allowed" and "Ctrl-C to stop").
    let mut banner = format!("buslab web: {url} at {}\n", server.url());
    match server.token() {
        Some(token) => {
            // The token in the fragment: the dashboard takes it from there (the part after `#`
            // never leaves the browser), as the lab prints it.
            banner += &format!(
                "  live dashboard: {}dashboard#token={token}\n",
                server.url()
            );
            banner += &format!("  writes allowed with the header X-Buslab-Token: {token}\n");
        }
        None => {
            banner += &format!("  live dashboard: {}dashboard\n", server.url());
            banner += "  read-only (start with --token to allow sending and faults)\n";
        }
    }
    if !quiet {
        banner += "Ctrl-C to stop\n";
    }
    eprint!("{banner}");
    let stop = super::interrupted()?;
    while !stop.load(Ordering::SeqCst) {
        if let Some(why) = server.bus_failure() {
            server.stop();
            anyhow::bail!("{url}: the bus failed: {why}");
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    server.stop();
    Ok(())
}

/// Where the lab's web pages listen unless told otherwise.
const LAB_DEFAULT: SocketAddr =
    SocketAddr::V4(std::net::SocketAddrV4::new(Ipv4Addr::LOCALHOST, 8080));

/// The lab's web pages on its bus `url`, with a fresh write token (the dashboard injects
/// faults), panels for its SLIO boards and its ZELLE and CPU196 ports, and the signals of
/// `dbc`; none with `--no-web`. The addresses are printed for the banner.
pub fn lab_pages(
    options: &WebOptions,
    url: &str,
    slios: &[SlioId],
    ports: Option<(&Path, &Path)>,
    dbc: Arc<Database>,
) -> anyhow::Result<Option<WebServer>> {
    if options.no_web {
        return Ok(None);
    }
    let devices = DeviceConfig {
        slios: slios.to_vec(),
        zelle: ports.map(|(zelle, _)| zelle.to_path_buf()),
        cpu196: ports.map(|(_, cpu196)| (cpu196.to_path_buf(), super::cpu196::DEFAULT_BAUD)),
    };
    let token = generate_token()?;
    let start = |listen: SocketAddr| -> anyhow::Result<Result<WebServer, WebError>> {
        let bus = buslab_backends::open(url)
            .with_context(|| format!("the web pages cannot join the lab's bus {url}"))?;
        let config = WebConfig {
            listen,
            token: Some(token.clone()),
            devices: devices.clone(),
            allowed_hosts: options.hosts.allow_host.clone(),
            dbc: Some(dbc.clone()),
            ..WebConfig::default()
        };
        Ok(WebServer::start(bus, config))
    };
    let web = match start(options.listen.unwrap_or(LAB_DEFAULT))? {
        Ok(web) => web,
        // The usual port is taken (another lab?): any free one will do.
        Err(WebError::Listen { .. }) if options.listen.is_none() => {
            start(SocketAddr::from((Ipv4Addr::LOCALHOST, 0)))??
        }
        Err(e) => return Err(e.into()),
    };
    eprintln!(
        "  web pages:  {} (no JavaScript needed; devices: {}devices)",
        web.url(),
        web.url()
    );
    if let Some(token) = web.token() {
        eprintln!("  dashboard:  {}dashboard#token={token}", web.url());
    }
    Ok(Some(web))
}
