//! `buslab lab`: the whole virtual bench, paced to real time.
//!
//! The bench's CAN bus is a virtual bus server (`buslab bus serve` in-process): simulated
//! nodes exchange periodic and bursty traffic on the bit-level wire, and any socketcand client
//! (python-can, `buslab dump`) can join it. The lab itself joins with a node sending a counter
//! and, with `--frames`, a monitor whose receptions are printed the way `candump` prints them.
//! By default a compact status line tells how the bench is doing. Next to the bus, a ZELLE cell
//! and a CPU196 board are served on pseudo-terminals (`buslab_bench::devices`), and the bus is shown as web
//! pages with a live dashboard (`buslab web`, docs/web.md). The dashboard shows the frames as
//! signals, decoded with the lab's own DBC database (`buslab_bench::lab::LAB_DBC`, written to
//! `DIR/lab.dbc` for the other tools, printed by `--print-dbc`) or the one `--dbc` names.

use std::io::{self, IsTerminal, Write};
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread;
use std::time::{Duration, Instant};

use anyhow::Context;
use buslab_bench::counter::{self, CounterNode};
use buslab_bench::devices::LabDevices;
use buslab_bench::lab::{CHANNEL, LAB_DBC};
use buslab_bench::status::BenchStatus;
use buslab_canbus::CanBus;
use buslab_dbc::Database;
use buslab_vbus::ServerHandle;

use buslab_logs::Message;

use crate::status_line::StatusLine;
use buslab_logs::candump::{Terminal, TimestampMode, View};

#[derive(clap::Args)]
pub struct Args {
    /// Stop after this long (`2s`, `500ms`, `1h`); default: run until Ctrl-C.
    #[arg(long, value_parser = crate::units::duration)]
    pub duration: Option<Duration>,
    /// Bit rate of the simulated CAN bus, in bit/s (the SLIO boards and the PowerPC node
    /// take part at 20000..125000 only).
    #[arg(long, default_value_t = 125_000, value_parser = clap::value_parser!(u32).range(1_000..=1_000_000))]
    pub bitrate: u32,
    /// Seed of the simulation (its random faults and choices).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Print every frame on the bus to stdout, as candump does (by default only a status
    /// line on stderr; `buslab dump` on the printed URL shows them too).
    #[arg(long)]
    pub frames: bool,
    /// With --frames: prefix each frame with the time since the start, as `candump -t z`.
    #[arg(short = 't', long, requires = "frames")]
    pub timestamps: bool,
    /// Where the bus server listens (socketcand); if the default port is taken, a free one is
    /// used. The URL is printed at start.
    #[arg(long, value_name = "ADDR")]
    pub listen: Option<SocketAddr>,
    /// Keep the devices' state here (zelle.toml, cpu196.toml, the PowerPC memory ppc.s37 with its
    /// control socket ppc.sock) and link their ports as
    /// DIR/zelle, DIR/cpu196 and DIR/monican; default: in memory, ports printed at start.
    #[arg(long, value_name = "DIR")]
    pub dir: Option<PathBuf>,
    /// Only the CAN bus: no ZELLE cell or CPU196 board.
    #[arg(long)]
    pub no_devices: bool,
    /// A DBC database the dashboard decodes the bus with instead of the lab's own (which names
    /// its nodes', counter's and SLIO boards' messages and signals; see --print-dbc).
    #[arg(long, value_name = "FILE")]
    pub dbc: Option<PathBuf>,
    /// Print the lab's own DBC database on stdout and exit, for `buslab monitor --dbc` and other
    /// DBC tools (a lab run with --dir also writes it to DIR/lab.dbc).
    #[arg(long, exclusive = true)]
    pub print_dbc: bool,
    #[command(flatten)]
    pub web: WebOptions,
}

/// The lab's web pages (`buslab web` on the lab's bus): the same options in every build; a
/// build without the `web` feature refuses `--web` and `--allow-host`.
#[derive(clap::Args)]
pub struct WebOptions {
    /// Where the web pages and the live dashboard listen (`buslab web`, docs/web.md); by
    /// default 127.0.0.1:8080, or a free port if that one is taken. Writes need the token
    /// printed at start.
    #[arg(
        id = "web",
        long = "web",
        value_name = "ADDR",
        conflicts_with = "no_web"
    )]
    pub listen: Option<SocketAddr>,
    /// No web pages or dashboard.
    #[arg(long)]
    pub no_web: bool,
    #[command(flatten)]
    pub hosts: AllowHost,
}

/// `--allow-host`, shared with `buslab web`.
#[derive(clap::Args, Clone, Debug, Default)]
pub struct AllowHost {
    /// A host name the pages answer to besides IP addresses and localhost (repeatable):
    /// requests naming any other host are refused with 403, so that a page of another site
    /// cannot read the bus by pointing its name at this machine (DNS rebinding).
    #[arg(long = "allow-host", value_name = "NAME")]
    pub allow_host: Vec<String>,
}

/// `quiet` (the global `-q`): no status line.
pub fn run(args: Args, quiet: bool) -> anyhow::Result<()> {
    // A reader that goes away (`| head`) ends the run quietly, as for other Unix tools.
    match run_lab(args, quiet) {
        Err(e)
            if e.downcast_ref::<io::Error>()
                .is_some_and(|e| e.kind() == io::ErrorKind::BrokenPipe) =>
        {
            Ok(())
        }
        other => other,
    }
}

fn run_lab(args: Args, quiet: bool) -> anyhow::Result<()> {
    if args.print_dbc {
        let mut out = io::stdout().lock();
        out.write_all(LAB_DBC.as_bytes())?;
        out.flush()?;
        return Ok(());
    }
    // A bad database is named before anything starts.
    let dbc = match &args.dbc {
        Some(path) => crate::dbc::load(path)?,
        None => Arc::new(Database::parse(LAB_DBC).context("the lab's own DBC database")?),
    };
    let stop = super::interrupted()?;
    let devices = if args.no_devices {
        None
    } else {
        Some(LabDevices::start(
            args.dir.as_deref(),
            super::cpu196::DEFAULT_BAUD,
        )?)
    };
    // Frame times are the server's start plus virtual time: `-t` counts from here.
    let start_unix = buslab_canbus::wall_clock();
    let slio_bench = SlioBench(buslab_bench::lab::SlioBench::new(args.bitrate));
    let server =
        buslab_bench::lab::start_server(args.listen, args.bitrate, args.seed, &slio_bench.0)?;
    let addr = server.local_addr();
    let terminal = slio_bench
        .start_terminal(&server, args.dir.as_deref())
        .context("starting the PowerPC node's terminal")?;
    eprintln!(
        "buslab lab: CAN bus socketcand://{addr}/{CHANNEL} at {} bit/s, nodes: {}, counter",
        args.bitrate,
        buslab_bench::lab::SIMULATED
            .iter()
            .map(ToString::to_string)
            .chain(slio_bench.0.names())
            .collect::<Vec<_>>()
            .join(", ")
    );
    let url = format!("socketcand://{addr}/{CHANNEL}");
    let hints = Hints::new(&url);
    if addr.port() != buslab_backends::SOCKETCAND_PORT && args.listen.is_none() {
        eprintln!(
            "  port {} is taken (another lab, a socketcand?): this bus is on port {}; the commands below name it",
            buslab_backends::SOCKETCAND_PORT,
            addr.port()
        );
    }
    eprintln!("  watch it:   {}", hints.command("dump", "", true));
    slio_bench.describe(terminal.as_ref(), args.dir.as_deref(), &hints);
    if let Some(devices) = &devices {
        describe_devices(devices, &hints);
    }
    let lab_dbc = args.dir.as_deref().map(|dir| dir.join("lab.dbc"));
    if let Some(path) = &lab_dbc {
        write_lab_dbc(path)?;
    }
    describe_dbc(&args, lab_dbc.as_deref(), &hints);
    let web = super::web::lab_pages(
        &args.web,
        &url,
        slio_bench.0.ids(),
        devices.as_ref().map(|d| (d.zelle.path(), d.cpu196.path())),
        dbc,
    )?;
    // The lab's bus for scripts (`export BUSLAB_BUS=$(cat DIR/bus)`): written last, so that
    // it is there once everything else is.
    let bus_file = args.dir.as_deref().map(|dir| dir.join("bus"));
    if let Some(path) = &bus_file {
        buslab_link::fs::write_atomic(path, format!("{url}\n").as_bytes())
            .with_context(|| format!("cannot write the lab's bus URL to {}", path.display()))?;
    }
    if !quiet {
        eprintln!("Ctrl-C to stop");
    }

    let counter = CounterNode::spawn(addr, stop.clone())?;
    let end = args.duration.map(|d| Instant::now() + d);
    let result = if args.frames {
        monitor(addr, &args, end, start_unix, &stop)
    } else {
        status_lines(&server, end, &stop, quiet)
    };
    stop.store(true, Ordering::SeqCst);
    if let Some(web) = web {
        web.stop();
    }
    let counted = counter.join();
    if let Some(path) = &bus_file {
        // A stopped lab's URL would send the next script to whatever takes the port.
        let _ = std::fs::remove_file(path);
    }
    drop(terminal);
    server.shutdown();
    if let Some(devices) = devices {
        devices.stop()?;
    }
    result?;
    Ok(counted?)
}

/// The banner's commands, written so that they work when pasted: the program as the shell
/// finds it, and the lab's bus named unless it is already the tools' default.
struct Hints {
    /// `buslab` when the shell finds this very program under that name, else its path (after
    /// `cargo run`, before `cargo install`).
    program: String,
    url: String,
    /// The tools' default bus (`bus` in buslab.toml or $BUSLAB_BUS, else vcan0) is this one.
    is_default: bool,
}

impl Hints {
    fn new(url: &str) -> Self {
        let default = buslab_backends::resolve(&crate::config::get().bus_name)
            .map(|u| u.to_string())
            .ok();
        Self {
            program: program_name(),
            url: url.to_string(),
            is_default: default.as_deref() == Some(url),
        }
    }

    /// ` --bus URL`, or nothing when the default is this bus and `always` is not asked.
    fn bus_option(&self, always: bool) -> String {
        if self.is_default && !always {
            String::new()
        } else {
            format!(" --bus {}", self.url)
        }
    }

    /// `buslab GROUP --bus URL REST` (`slio` takes `--bus` before its subcommand).
    fn command(&self, group: &str, rest: &str, always_bus: bool) -> String {
        let rest = if rest.is_empty() {
            String::new()
        } else {
            format!(" {rest}")
        };
        format!(
            "{} {group}{}{rest}",
            self.program,
            self.bus_option(always_bus)
        )
    }
}

/// How a shell reaches this program: `buslab` if that name on the PATH is this executable,
/// else its path (relative to the current folder when inside it).
fn program_name() -> String {
    let Ok(exe) = std::env::current_exe().and_then(std::fs::canonicalize) else {
        return "buslab".to_string();
    };
    let on_path = std::env::var_os("PATH").is_some_and(|paths| {
        std::env::split_paths(&paths)
            .filter_map(|dir| std::fs::canonicalize(dir.join("buslab")).ok())
            .next()
            .is_some_and(|found| found == exe)
    });
    if on_path {
        return "buslab".to_string();
    }
    let shown = std::env::current_dir()
        .ok()
        .and_then(|cwd| exe.strip_prefix(cwd).ok().map(Path::to_path_buf))
        .unwrap_or_else(|| exe.clone());
    let text = shown.display().to_string();
    if text.contains(char::is_whitespace) {
        format!("'{text}'")
    } else {
        text
    }
}

/// How often the status line is refreshed on a terminal, and written as a new line otherwise.
const STATUS_ON_TERMINAL: Duration = Duration::from_secs(1);
const STATUS_IN_LOG: Duration = Duration::from_secs(10);

/// The bench in one line (stderr) until `stop` or `end`: on a terminal updated in place every
/// second, otherwise a new line every 10 s; and once more at the end.
fn status_lines(
    server: &ServerHandle,
    end: Option<Instant>,
    stop: &AtomicBool,
    quiet: bool,
) -> anyhow::Result<()> {
    if quiet {
        while !stop.load(Ordering::SeqCst) && end.is_none_or(|e| Instant::now() < e) {
            thread::sleep(Duration::from_millis(100));
        }
        return Ok(());
    }
    let terminal = io::stderr().is_terminal();
    let every = if terminal {
        STATUS_ON_TERMINAL
    } else {
        STATUS_IN_LOG
    };
    let mut next = Instant::now() + every;
    while !stop.load(Ordering::SeqCst) && end.is_none_or(|e| Instant::now() < e) {
        let wake = end.map_or(next, |e| e.min(next));
        thread::sleep(
            wake.saturating_duration_since(Instant::now())
                .min(Duration::from_millis(100)),
        );
        if Instant::now() < next {
            continue;
        }
        next += every;
        let Some(fields) = server.with_bus(|bus| status_fields(&BenchStatus::of(bus))) else {
            break;
        };
        let line = fit(&fields, status_width(terminal));
        if terminal {
            StatusLine::show(&line)?;
        } else {
            let mut err = io::stderr().lock();
            writeln!(err, "{line}")?;
            err.flush()?;
        }
    }
    // The last word, on its own line.
    match server.with_bus(|bus| status_fields(&BenchStatus::of(bus))) {
        Some(fields) => StatusLine::finish(&fit(&fields, status_width(terminal)))?,
        None => StatusLine::clear()?,
    }
    Ok(())
}

/// The status line's parts, most telling first; [`fit`] leaves out the last ones that do not
/// fit the terminal. Nodes are the bench's own and the clients that joined (the lab's counter,
/// its web pages, every `dump` or python-can script).
fn status_fields(status: &BenchStatus) -> Vec<String> {
    let last = &status.last_second;
    let mut states = vec![format!("{} active", status.active)];
    for (n, word) in [(status.passive, "passive"), (status.bus_off, "bus-off")] {
        if n > 0 {
            states.push(format!("{n} {word}"));
        }
    }
    vec![
        format!("load {:.1} %", 100.0 * last.load()),
        format!("{} frames/s", last.frames),
        format!("{} errors/s", last.errors),
        format!(
            "{} nodes + {} client{}: {}",
            status.simulated,
            status.clients,
            if status.clients == 1 { "" } else { "s" },
            states.join(", ")
        ),
        format!(
            "{} frames, {} errors in all",
            status.total.frames, status.total.errors
        ),
    ]
}

/// The status line in at most `width` columns (a terminal wraps a longer one, and an update
/// in place then becomes a new line): whole parts in order while they fit, then nothing.
fn fit(fields: &[String], width: usize) -> String {
    let mut line = String::new();
    for field in fields {
        let gap = if line.is_empty() { 0 } else { 2 };
        if line.chars().count() + gap + field.chars().count() > width {
            break;
        }
        if gap > 0 {
            line.push_str("  ");
        }
        line.push_str(field);
    }
    line
}

/// Columns the status line may take: the width of the terminal stderr is on, less one (a line
/// that fills the last column wraps on some terminals), 80 when it cannot be known; a log file
/// takes whole lines.
fn status_width(terminal: bool) -> usize {
    if !terminal {
        return usize::MAX;
    }
    let columns = console::Term::stderr()
        .size_checked()
        .map_or(80, |(_, columns)| usize::from(columns));
    columns.saturating_sub(1).max(20)
}

/// Prints what the monitor's node receives until `stop` or `end`.
fn monitor(
    addr: SocketAddr,
    args: &Args,
    end: Option<Instant>,
    start_unix: buslab_canbus::Timestamp,
    stop: &AtomicBool,
) -> anyhow::Result<()> {
    let mut bus = counter::join(addr, "monitor")?;
    let stdout = io::stdout();
    let mut out = stdout.lock();
    // candump's layout; `-t`: seconds since the lab started, as `candump -t z`.
    let mut terminal = Terminal::new(View {
        timestamps: args.timestamps.then_some(TimestampMode::Zero),
        ..View::default()
    })
    .with_zero(start_unix);
    while !stop.load(Ordering::SeqCst) {
        let left = end.map(|end| end.saturating_duration_since(Instant::now()));
        if left == Some(Duration::ZERO) {
            break;
        }
        let wait = left.map_or(Duration::from_millis(100), |l| {
            l.min(Duration::from_millis(100))
        });
        if let Some(m) = bus.recv(Some(wait))? {
            let entry = Message {
                channel: CHANNEL.to_string(),
                direction: None,
                ..m.into_record()
            };
            writeln!(out, "{}", terminal.line(&entry))?;
            out.flush()?;
        }
    }
    Ok(())
}

/// The SLIO bench's side in the binary: the PowerPC node's terminal and the banner's lines.
struct SlioBench(buslab_bench::lab::SlioBench);

impl SlioBench {
    /// The PowerPC node's terminal, linked as DIR/monican.
    fn start_terminal(
        &self,
        server: &ServerHandle,
        dir: Option<&Path>,
    ) -> anyhow::Result<Option<buslab_served::ppc::ServedPpc>> {
        if self.0.is_empty() {
            return Ok(None);
        }
        if let Some(dir) = dir {
            // `--no-devices` leaves the folder to the PowerPC node.
            std::fs::create_dir_all(dir)
                .with_context(|| format!("cannot create the lab folder {}", dir.display()))?;
        }
        let options = buslab_served::ppc::PpcOptions {
            link: dir.map(|d| d.join("monican")),
            memory: dir.map(|d| d.join("ppc.s37")),
            control: dir.map(|d| d.join("ppc.sock")),
        };
        Ok(Some(buslab_served::ppc::serve(
            buslab_bench::ppc::NAME,
            server.poster(),
            options,
        )?))
    }

    fn describe(
        &self,
        terminal: Option<&buslab_served::ppc::ServedPpc>,
        dir: Option<&Path>,
        hints: &Hints,
    ) {
        let Some(terminal) = terminal else {
            eprintln!(
                "  no SLIO boards: they follow 20000..125000 bit/s (the lab's default is 125000)"
            );
            return;
        };
        let ids: Vec<String> = self.0.ids().iter().map(ToString::to_string).collect();
        eprintln!(
            "  SLIO boards  {} (demo boards; MoniCAN calibrates and drives them; try: {})",
            ids.join(", "),
            hints.command("slio", "list", false)
        );
        let pty = terminal.path().display();
        let link = dir.map(|d| d.join("monican"));
        let path = link
            .as_deref()
            .map_or_else(|| pty.to_string(), |l| l.display().to_string());
        eprintln!(
            "  MoniCAN      on {pty}  (19200 8N1, VT100; open it: screen {path} 19200, or picocom -b 19200 {path}; Ctrl-L redraws)"
        );
        if let (Some(memory), Some(control)) = (terminal.memory_file(), terminal.control_socket()) {
            eprintln!(
                "  PowerPC      memory in {}, control socket {} (load a program: {})",
                memory.display(),
                control.display(),
                hints.command(
                    "load",
                    &format!("PROG.s37 --verify {}", control.display()),
                    false
                ),
            );
        }
    }
}

/// Writes the lab's own DBC to `path` (atomically; its folder made if need be).
fn write_lab_dbc(path: &Path) -> anyhow::Result<()> {
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir)
            .with_context(|| format!("cannot create the lab folder {}", dir.display()))?;
    }
    buslab_link::fs::write_atomic(path, LAB_DBC.as_bytes())
        .with_context(|| format!("cannot write the lab's DBC to {}", path.display()))
}

/// The banner's line for the DBC database: which one the dashboard decodes with, and where
/// the lab's own is for the other tools.
fn describe_dbc(args: &Args, lab_dbc: Option<&Path>, hints: &Hints) {
    let shown = if args.web.no_web {
        ""
    } else {
        "the dashboard shows its signals; "
    };
    let line = match (&args.dbc, lab_dbc) {
        (Some(file), own) => format!(
            "{} ({shown}try: {}){}",
            file.display(),
            hints.command("monitor", &format!("--dbc {}", file.display()), false),
            own.map_or(String::new(), |p| format!(
                "; the lab's own in {}",
                p.display()
            ))
        ),
        (None, Some(own)) => format!(
            "the lab's own in {} ({shown}try: {})",
            own.display(),
            hints.command("monitor", &format!("--dbc {}", own.display()), false)
        ),
        (None, None) => format!(
            "the lab's own ({shown}for other tools: {} lab --print-dbc > lab.dbc)",
            hints.program
        ),
    };
    eprintln!("  DBC          {line}");
}

/// The banner's lines for the serial devices.
fn describe_devices(devices: &LabDevices, hints: &Hints) {
    eprintln!(
        "  ZELLE cell   on {}  (9600 8N2; try: {} zelle --port {} analog 1)",
        devices.zelle.path().display(),
        hints.program,
        devices.zelle_port.display()
    );
    eprintln!(
        "  CPU196 board on {}  ({} 8N1; try: {} cpu196 --port {} info)",
        devices.cpu196.path().display(),
        super::cpu196::DEFAULT_BAUD,
        hints.program,
        devices.cpu196_port.display()
    );
}

#[cfg(test)]
mod tests {
    use super::fit;

    fn fields() -> Vec<String> {
        [
            "load 100.0 %",
            "8120 frames/s",
            "16466 errors/s",
            "8 nodes + 2 clients: 7 active, 2 passive, 1 bus-off",
            "123456789 frames, 1234567 errors in all",
        ]
        .map(String::from)
        .to_vec()
    }

    #[test]
    fn the_status_line_keeps_whole_parts_within_the_width() {
        let all = fit(&fields(), usize::MAX);
        assert_eq!(
            all,
            "load 100.0 %  8120 frames/s  16466 errors/s  8 nodes + 2 clients: 7 active, 2 passive, 1 bus-off  123456789 frames, 1234567 errors in all"
        );
        let line = fit(&fields(), 79);
        assert_eq!(line, "load 100.0 %  8120 frames/s  16466 errors/s");
        for width in 20..200 {
            assert!(fit(&fields(), width).chars().count() <= width, "{width}");
        }
    }
}
