//! `buslab zelle`: serve the ZELLE cell model on a pseudo-terminal, or talk to a cell (the
//! model or a real one) as its host.

use std::fs;
use std::io::{self, BufRead, BufReader, Write};
use std::os::unix::net::{UnixListener, UnixStream};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{self, Sender};
use std::thread::{self, JoinHandle};
use std::time::Duration;

use anyhow::{Context, bail};
use buslab_link::{Control, Pty};
use buslab_zelle::analog::{Source, SourceSpec, to_volts};
use buslab_zelle::client::{Client, Measurement, Progress, SeriesParams, Transfer};
use buslab_zelle::control::{self, ControlCommand, parse_duration_ns, parse_number};
use buslab_zelle::timing::LINE;
use buslab_zelle::{BatteryRam, Cell, DATA_AREA, PARAMS_LEN};

/// `println!` through [`print_stdout`]: a reader that went away (`| head`) ends the output
/// quietly instead of a panic.
macro_rules! say {
    ($($arg:tt)*) => {
        print_stdout(&format!("{}\n", format_args!($($arg)*)))?
    };
}

#[derive(clap::Args)]
pub struct Args {
    /// Serial port of the cell: a real port (/dev/ttyUSB0) or the PTY `zelle serve` printed.
    #[arg(long, short, global = true, value_name = "PATH")]
    pub port: Option<PathBuf>,
    /// How long to wait for each answer from the cell (`500ms`, `2s`).
    #[arg(long, global = true, default_value = "500ms", value_parser = duration)]
    pub timeout: Duration,
    #[command(subcommand)]
    pub command: ZelleCommand,
}

#[derive(clap::Subcommand)]
pub enum ZelleCommand {
    /// Serve the cell model on a pseudo-terminal, paced to real time at 9600 8N2.
    Serve(ServeArgs),
    /// Bring the cell to the ready state (ten zeros, 2 ms apart).
    Reset,
    /// Read an analog channel (command 7; with --repeat, command 4).
    Analog {
        /// Channel 1..4.
        channel: u8,
        /// Read this many times in one command-4 exchange (1..1000000).
        #[arg(long, value_parser = clap::value_parser!(u32).range(1..=1_000_000))]
        repeat: Option<u32>,
    },
    /// Run a measurement series and write it as CSV (time, one column per channel).
    Measure(MeasureArgs),
    /// Read the data area from 0800h: the 8 parameter bytes, then the values (command 2).
    Dump {
        /// Bytes to read; default: 8 plus the value count of the last series.
        #[arg(long)]
        len: Option<usize>,
        /// Write the raw bytes to this file instead of a hex listing on stdout.
        #[arg(long, short)]
        output: Option<PathBuf>,
        /// Wait for each byte before asking for the next (slow; for comparison).
        #[arg(long)]
        stop_and_wait: bool,
    },
    /// Write a file's bytes into the data area from 0800h (command 3).
    Upload {
        file: PathBuf,
        #[arg(long)]
        stop_and_wait: bool,
    },
    /// Read a RAM byte (command 18). Addresses: 2048, 0x800 or 0800h.
    Peek { addr: String },
    /// Write a RAM byte (command 19).
    Poke { addr: String, value: String },
    /// Read port 1 (command 12), or write it (command 11).
    Port1 { value: Option<String> },
    /// Read P2.6 (command 15), or write it (command 14).
    P26 { value: Option<String> },
    /// Read the START key (command 13).
    Key,
    /// Read an internal RAM register 0..127 (command 16), or write it (command 17).
    Reg { addr: String, value: Option<String> },
    /// Read a parallel-bus address 0..127, or write it (command 8).
    Bus { addr: String, value: Option<String> },
    /// Load a program (raw binary, or Intel HEX with addresses in 0400h..07FFh) (command 5).
    Load {
        file: PathBuf,
        #[arg(long)]
        stop_and_wait: bool,
    },
    /// Run the program at 0400h (command 6).
    Run,
    /// START the next block of an armed series (command 9).
    Start,
    /// Arm a series with the parameters already at 0800h (command 10).
    Repeat,
    /// Send one 0: stop a running series or program.
    Stop,
}

#[derive(clap::Args)]
pub struct ServeArgs {
    /// Keep the battery-backed RAM in this file (read at start, written atomically on
    /// changes, power-off and exit).
    #[arg(long, value_name = "FILE")]
    pub state: Option<PathBuf>,
    /// Also make this symlink to the PTY.
    #[arg(long, value_name = "PATH")]
    pub link: Option<PathBuf>,
    /// Feed an analog input: CH=SOURCE, e.g. 1=sine:1Hz:2V:2.5V, 2=3.3V, 3=csv:in.csv.
    #[arg(long, value_name = "CH=SOURCE")]
    pub analog: Vec<String>,
    /// Accept control lines on this unix socket too (as on stdin).
    #[arg(long, value_name = "PATH")]
    pub control: Option<PathBuf>,
}

#[derive(clap::Args)]
pub struct MeasureArgs {
    /// Channels, in slot order (up to four of 1..4).
    #[arg(long, short, value_delimiter = ',', default_value = "1")]
    pub channels: Vec<u8>,
    /// Time between scan cycles (`10ms`, `1s`; at least 1 ms per channel).
    #[arg(long, short, default_value = "10ms", value_parser = duration)]
    pub interval: Duration,
    /// Scan cycles per block (the seed's "block length").
    #[arg(long, default_value_t = 100)]
    pub cycles: u16,
    /// Blocks to run, each started by the host (command 9).
    #[arg(long, default_value_t = 1)]
    pub blocks: u32,
    /// Write the CSV here instead of stdout.
    #[arg(long, short)]
    pub output: Option<PathBuf>,
    /// Write volts instead of raw readings 0..255.
    #[arg(long)]
    pub volts: bool,
    /// Draw the series in the terminal (on stderr).
    #[arg(long)]
    pub plot: bool,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let port_path = match args.command {
        ZelleCommand::Serve(serve_args) => return serve(serve_args),
        _ => args.port.clone().context(
            "--port PATH is required: the cell's serial port, or the PTY `buslab zelle serve` printed",
        )?,
    };
    let serial = buslab_link::open_serial(&port_path, LINE, args.timeout)
        .with_context(|| format!("opening the cell at {}", port_path.display()))?;
    let mut cell = Client::with_timeout(serial, args.timeout)?;
    let mode = |saw: bool| {
        if saw {
            Transfer::StopAndWait
        } else {
            Transfer::Pipelined
        }
    };
    match args.command {
        ZelleCommand::Serve(_) => unreachable!(),
        ZelleCommand::Reset => {
            cell.reset()?;
            say!("ready");
        }
        ZelleCommand::Analog { channel, repeat } => {
            let values = match repeat {
                None => vec![cell.analog(channel)?],
                Some(n) => cell.analog_repeat(&vec![channel; n as usize])?,
            };
            let lines: String = values
                .iter()
                .map(|&v| format!("ch{channel} {v} {:.3} V\n", to_volts(v)))
                .collect();
            print_stdout(&lines)?;
        }
        ZelleCommand::Measure(m) => measure(&mut cell, m)?,
        ZelleCommand::Dump {
            len,
            output,
            stop_and_wait,
        } => {
            let len = match len {
                Some(len) => len,
                None => usize::from(PARAMS_LEN) + usize::from(cell.value_count()?),
            };
            let data = cell.read_data(len, mode(stop_and_wait))?;
            match output {
                Some(path) => write_atomically(&path, &data)?,
                None => print_hex(DATA_AREA, &data)?,
            }
        }
        ZelleCommand::Upload {
            file,
            stop_and_wait,
        } => {
            let data = fs::read(&file).with_context(|| format!("reading {}", file.display()))?;
            cell.write_data(&data, mode(stop_and_wait))?;
            say!("wrote {} bytes from 0800h", data.len());
        }
        ZelleCommand::Peek { addr } => {
            let addr = number(&addr, "address", 0xFFFF)? as u16;
            say!("{:#04x}", cell.peek(addr)?);
        }
        ZelleCommand::Poke { addr, value } => {
            let addr = number(&addr, "address", 0xFFFF)? as u16;
            cell.poke(addr, number(&value, "value", 0xFF)? as u8)?;
        }
        ZelleCommand::Port1 { value: None } => say!("{:#010b}", cell.read_port1()?),
        ZelleCommand::Port1 { value: Some(v) } => {
            cell.write_port1(number(&v, "port value", 0xFF)? as u8)?
        }
        ZelleCommand::P26 { value: None } => say!("{}", u8::from(cell.read_p26()?)),
        ZelleCommand::P26 { value: Some(v) } => {
            cell.write_p26(number(&v, "P2.6 level", 1)? == 1)?
        }
        ZelleCommand::Key => say!(
            "{}",
            if cell.key_pressed()? {
                "pressed"
            } else {
                "released"
            }
        ),
        ZelleCommand::Reg { addr, value } => {
            let addr = number(&addr, "register address", 127)? as u8;
            match value {
                None => say!("{:#04x}", cell.read_register(addr)?),
                Some(v) => cell.write_register(addr, number(&v, "value", 0xFF)? as u8)?,
            }
        }
        ZelleCommand::Bus { addr, value } => {
            let addr = number(&addr, "bus address", 127)? as u8;
            match value {
                None => say!("{:#04x}", cell.bus_read(addr)?),
                Some(v) => cell.bus_write(addr, number(&v, "value", 0xFF)? as u8)?,
            }
        }
        ZelleCommand::Load {
            file,
            stop_and_wait,
        } => {
            let contents =
                fs::read(&file).with_context(|| format!("reading {}", file.display()))?;
            let image = buslab_zelle::program::image_from_file(&contents)
                .with_context(|| format!("{}", file.display()))?;
            cell.load_program(&image, mode(stop_and_wait))?;
            say!(
                "loaded {} bytes at 0400h; `run` starts it (so do reset and power-on)",
                image.len()
            );
        }
        ZelleCommand::Run => cell.run_program()?,
        ZelleCommand::Start => cell.start_block()?,
        ZelleCommand::Repeat => cell.repeat_series()?,
        ZelleCommand::Stop => cell.interrupt()?,
    }
    Ok(())
}

fn measure<P: buslab_zelle::client::Port>(
    cell: &mut Client<P>,
    m: MeasureArgs,
) -> anyhow::Result<()> {
    let interval_ms = u32::try_from(m.interval.as_millis())
        .ok()
        .filter(|_| m.interval.subsec_nanos().is_multiple_of(1_000_000))
        .with_context(|| format!("interval {:?} must be a whole number of ms", m.interval))?;
    let params = SeriesParams::new(&m.channels, m.cycles, interval_ms)?;
    let bar = indicatif::ProgressBar::new(1000);
    bar.set_style(
        indicatif::ProgressStyle::with_template("{msg:>10} [{bar:40}] {percent:>3}%")
            .expect("a valid template"),
    );
    let result = cell.measure(&params, m.blocks, |p| match p {
        Progress::Measuring {
            block,
            blocks,
            done_ns,
            total_ns,
        } => {
            bar.set_message(format!("block {}/{blocks}", block + 1));
            bar.set_position(done_ns * 900 / total_ns.max(1));
        }
        Progress::Reading { done, total } => {
            bar.set_message("reading");
            bar.set_position(900 + (done * 100 / total.max(1)) as u64);
        }
    });
    bar.finish_and_clear();
    let series = result?;
    let csv = series.to_csv(m.volts);
    match &m.output {
        Some(path) => {
            write_atomically(path, csv.as_bytes())?;
            eprintln!(
                "{} cycles of {} channel(s) written to {}",
                series.rows.len(),
                series.channels.len(),
                path.display()
            );
        }
        None => print_stdout(&csv)?,
    }
    if m.plot {
        eprint!("{}", plot(&series, 72, 16));
    }
    Ok(())
}

/// A small character plot of every channel, 0..255 on the y axis.
fn plot(series: &Measurement, width: usize, height: usize) -> String {
    const MARKS: [char; 4] = ['*', '+', 'o', 'x'];
    let mut grid = vec![vec![' '; width]; height];
    let n = series.rows.len().max(1);
    for (i, row) in series.rows.iter().enumerate() {
        let x = i * (width - 1) / n.max(2).saturating_sub(1).max(1);
        for (c, &v) in row.values.iter().enumerate() {
            let y = (height - 1) - usize::from(v) * (height - 1) / 255;
            grid[y][x.min(width - 1)] = MARKS[c % MARKS.len()];
        }
    }
    let mut out = String::new();
    for (r, line) in grid.iter().enumerate() {
        let label = match r {
            0 => "255 |".to_string(),
            r if r == height - 1 => "  0 |".to_string(),
            _ => "    |".to_string(),
        };
        out.push_str(&label);
        out.extend(line.iter());
        out.push('\n');
    }
    let last = series.rows.last().map_or(0.0, |r| r.time_ns as f64 * 1e-9);
    out.push_str(&format!("    +{}\n", "-".repeat(width)));
    out.push_str(&format!(
        "     0 s{:>w$}\n",
        format!("{last:.2} s"),
        w = width - 3
    ));
    let legend: Vec<String> = series
        .channels
        .iter()
        .enumerate()
        .map(|(i, ch)| format!("{} ch{ch}", MARKS[i % MARKS.len()]))
        .collect();
    out.push_str(&format!("     {}\n", legend.join("   ")));
    out
}

fn print_hex(start: u16, data: &[u8]) -> anyhow::Result<()> {
    let mut listing = String::new();
    for (i, chunk) in data.chunks(16).enumerate() {
        let hex: Vec<String> = chunk.iter().map(|b| format!("{b:02x}")).collect();
        listing.push_str(&format!(
            "{:04x}: {}\n",
            usize::from(start) + i * 16,
            hex.join(" ")
        ));
    }
    print_stdout(&listing)
}

/// Writes to stdout; a reader that went away (`| head`) just ends the output.
fn print_stdout(text: &str) -> anyhow::Result<()> {
    let mut out = io::stdout().lock();
    match out.write_all(text.as_bytes()).and_then(|()| out.flush()) {
        Err(e) if e.kind() == io::ErrorKind::BrokenPipe => Ok(()),
        other => Ok(other?),
    }
}

fn number(s: &str, what: &str, max: u32) -> anyhow::Result<u32> {
    match parse_number(s) {
        Some(v) if v <= max => Ok(v),
        _ => bail!("{what} `{s}` is not a number in 0..{max} (decimal, 0x1F or 1Fh)"),
    }
}

fn duration(s: &str) -> Result<Duration, String> {
    parse_duration_ns(s)
        .map(Duration::from_nanos)
        .ok_or_else(|| format!("`{s}` is not a duration like 500ms or 2s"))
}

/// Writes `path` so that a crash leaves either the old or the new contents.
fn write_atomically(path: &Path, data: &[u8]) -> anyhow::Result<()> {
    let dir = path
        .parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let name = path.file_name().context("the output path names no file")?;
    let tmp = dir.join(format!(".{}.tmp", name.to_string_lossy()));
    let result = (|| {
        let mut f = fs::File::create(&tmp)?;
        f.write_all(data)?;
        f.sync_all()?;
        fs::rename(&tmp, path)
    })();
    if result.is_err() {
        let _ = fs::remove_file(&tmp);
    }
    result.with_context(|| format!("writing {}", path.display()))
}

// ----- serving the model --------------------------------------------------------------------

/// What [`spawn_served`] needs.
#[derive(Clone, Debug, Default)]
pub struct ServeOptions {
    pub state: Option<PathBuf>,
    pub link: Option<PathBuf>,
    /// `(channel, source)` pairs.
    pub analog: Vec<(u8, Source)>,
}

/// A cell served on a PTY by a background thread.
pub struct ServedCell {
    path: PathBuf,
    control: Sender<Control<Cell>>,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<io::Result<()>>>,
}

impl ServedCell {
    /// The PTY path clients open.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Runs a control command on the cell (e.g. `ControlCommand::parse("key press 1s")`); the
    /// reply line comes back.
    #[allow(dead_code)] // for `buslab lab`
    pub fn control(&self, cmd: ControlCommand) -> anyhow::Result<String> {
        self.with_cell(move |cell, now| control::apply(cell, now, &cmd))
    }

    /// Runs `work` on the cell in its serve thread at the current virtual time, and returns
    /// its result.
    pub fn with_cell<R: Send + 'static>(
        &self,
        work: impl FnOnce(&mut Cell, u64) -> R + Send + 'static,
    ) -> anyhow::Result<R> {
        let (tx, rx) = mpsc::channel();
        self.control
            .send(Box::new(move |cell: &mut Cell, now| {
                let _ = tx.send(work(cell, now));
            }))
            .ok()
            .context("the cell's serve thread has stopped")?;
        rx.recv_timeout(Duration::from_secs(5))
            .context("the cell's serve thread did not answer")
    }

    fn sender(&self) -> Sender<Control<Cell>> {
        self.control.clone()
    }

    /// Stops serving (saving the state file) and waits for the thread.
    pub fn stop(mut self) -> anyhow::Result<()> {
        self.shutdown()
    }

    fn shutdown(&mut self) -> anyhow::Result<()> {
        self.stop.store(true, Ordering::SeqCst);
        match self.thread.take().map(JoinHandle::join) {
            Some(Ok(result)) => Ok(result?),
            Some(Err(_)) => bail!("the cell's serve thread panicked"),
            None => Ok(()),
        }
    }
}

impl Drop for ServedCell {
    fn drop(&mut self) {
        let _ = self.shutdown();
    }
}

/// Starts a ZELLE cell on a new PTY in a background thread (for `buslab lab` and tests). The
/// state file, if any, is read now, rewritten whenever the battery-backed RAM changed (checked
/// every second), on power-off and when the cell stops.
pub fn spawn_served(options: ServeOptions) -> anyhow::Result<ServedCell> {
    let ram = match &options.state {
        Some(path) => {
            let ram = load_state(path)?;
            // Written once now, so a state file that cannot be written is an error at start,
            // not a warning when the first change is lost.
            save_state(path, &ram)?;
            ram
        }
        None => BatteryRam::default(),
    };
    let mut cell = Cell::new(ram);
    for (ch, source) in &options.analog {
        cell.set_analog(*ch, source.clone())?;
    }
    let mut pty = Pty::open().context("opening a pseudo-terminal")?;
    if let Some(link) = &options.link {
        pty.link_at(link)
            .with_context(|| format!("linking {}", link.display()))?;
    }
    let path = pty.path().to_path_buf();
    let (control_tx, control_rx) = mpsc::channel::<Control<Cell>>();
    let stop = Arc::new(AtomicBool::new(false));

    // Every second, ask the serve loop for the RAM if it changed, and save it.
    if let Some(state) = options.state.clone() {
        let sender = control_tx.clone();
        let stop = stop.clone();
        thread::spawn(move || {
            let mut saved_generation = 0;
            while !stop.load(Ordering::Relaxed) {
                thread::sleep(Duration::from_secs(1));
                let (tx, rx) = mpsc::channel();
                let work: Control<Cell> = Box::new(move |cell: &mut Cell, _now| {
                    let _ = tx.send((cell.ram_generation(), cell.ram().clone()));
                });
                if sender.send(work).is_err() {
                    break;
                }
                if let Ok((generation, ram)) = rx.recv_timeout(Duration::from_secs(5))
                    && generation != saved_generation
                {
                    match save_state(&state, &ram) {
                        Ok(()) => saved_generation = generation,
                        Err(e) => eprintln!("warning: {e:#}"),
                    }
                }
            }
        });
    }

    let thread_stop = stop.clone();
    let state = options.state.clone();
    let thread = thread::Builder::new()
        .name("zelle-serve".into())
        .spawn(move || {
            let result = buslab_link::serve(&mut cell, &pty, LINE, &control_rx, &thread_stop);
            if let Some(path) = &state
                && let Err(e) = save_state(path, cell.ram())
            {
                eprintln!("warning: {e:#}");
            }
            drop(pty);
            result
        })?;
    Ok(ServedCell {
        path,
        control: control_tx,
        stop,
        thread: Some(thread),
    })
}

fn load_state(path: &Path) -> anyhow::Result<BatteryRam> {
    match fs::read_to_string(path) {
        Ok(text) => BatteryRam::from_state_file(&text)
            .with_context(|| format!("reading state file {}", path.display())),
        Err(e) if e.kind() == io::ErrorKind::NotFound => Ok(BatteryRam::default()),
        Err(e) => Err(e).with_context(|| format!("reading state file {}", path.display())),
    }
}

fn save_state(path: &Path, ram: &BatteryRam) -> anyhow::Result<()> {
    write_atomically(path, ram.to_state_file().as_bytes())
}

/// Parses `CH=SOURCE`, reading a CSV replay file if named.
fn analog_arg(arg: &str) -> anyhow::Result<(u8, Source)> {
    let (ch, spec) = arg
        .split_once('=')
        .with_context(|| format!("--analog `{arg}` must look like CH=SOURCE, e.g. 1=sine:1Hz"))?;
    let ch = match parse_number(ch) {
        Some(c @ 1..=4) => c as u8,
        _ => bail!("--analog `{arg}`: channel `{ch}` is out of range 1..4"),
    };
    Ok((ch, load_source(SourceSpec::parse(spec)?)?))
}

fn load_source(spec: SourceSpec) -> anyhow::Result<Source> {
    match spec {
        SourceSpec::Ready(s) => Ok(s),
        SourceSpec::CsvFile(path) => {
            let text = fs::read_to_string(&path)
                .with_context(|| format!("reading replay file {}", path.display()))?;
            Ok(Source::replay_from_csv(&text)?)
        }
    }
}

/// Handles one control line: CSV files are read here, `save` writes the state file, and
/// power-off saves it too. Returns the reply line.
fn handle_line(
    line: &str,
    control: &Sender<Control<Cell>>,
    state: Option<&Path>,
) -> Option<String> {
    let cmd = match ControlCommand::parse(line) {
        Ok(None) => return None,
        Ok(Some(cmd)) => cmd,
        Err(e) => return Some(format!("error: {e}")),
    };
    let cmd = match cmd {
        ControlCommand::Analog { channel, source } => match load_source(source) {
            Ok(s) => ControlCommand::Analog {
                channel,
                source: SourceSpec::Ready(s),
            },
            Err(e) => return Some(format!("error: {e:#}")),
        },
        other => other,
    };
    let save = matches!(cmd, ControlCommand::Save | ControlCommand::PowerOff);
    let (tx, rx) = mpsc::channel();
    let work: Control<Cell> = Box::new(move |cell: &mut Cell, now| {
        let reply = control::apply(cell, now, &cmd);
        let _ = tx.send((reply, save.then(|| cell.ram().clone())));
    });
    if control.send(work).is_err() {
        return Some("error: the cell has stopped".into());
    }
    let (mut reply, ram) = match rx.recv_timeout(Duration::from_secs(5)) {
        Ok(answer) => answer,
        Err(_) => return Some("error: the cell did not answer".into()),
    };
    if let (Some(ram), Some(path)) = (ram, state) {
        match save_state(path, &ram) {
            Ok(()) => reply.push_str(&format!("; saved {}", path.display())),
            Err(e) => reply.push_str(&format!("; error: {e:#}")),
        }
    }
    Some(if reply.starts_with("error") {
        reply
    } else {
        format!("ok {reply}")
    })
}

fn serve(args: ServeArgs) -> anyhow::Result<()> {
    let analog = args
        .analog
        .iter()
        .map(|a| analog_arg(a))
        .collect::<anyhow::Result<Vec<_>>>()?;
    let served = spawn_served(ServeOptions {
        state: args.state.clone(),
        link: args.link.clone(),
        analog,
    })?;
    // The path alone on the first line, for scripts.
    say!("{}", served.path().display());
    eprintln!(
        "ZELLE cell model at 9600 8N2 on {}{}; control lines on stdin ({})",
        served.path().display(),
        args.link
            .as_ref()
            .map(|l| format!(" (linked as {})", l.display()))
            .unwrap_or_default(),
        control::HELP
    );
    let _ = io::stdout().flush();

    let stop = Arc::new(AtomicBool::new(false));
    {
        let stop = stop.clone();
        ctrlc::set_handler(move || stop.store(true, Ordering::SeqCst))
            .context("installing the Ctrl-C handler")?;
    }

    let sender = served.sender();
    let state = args.state.clone();
    thread::spawn(move || {
        for line in io::stdin().lock().lines() {
            let Ok(line) = line else { break };
            if let Some(reply) = handle_line(&line, &sender, state.as_deref()) {
                // A closed stdout (`serve | head -1`) must not end the control thread.
                let _ = print_stdout(&format!("{reply}\n"));
            }
        }
    });

    let _socket = match &args.control {
        Some(path) => Some(ControlSocket::bind(
            path,
            served.sender(),
            args.state.clone(),
        )?),
        None => None,
    };

    while !stop.load(Ordering::SeqCst) {
        thread::sleep(Duration::from_millis(50));
    }
    served.stop()
}

/// A unix socket that takes control lines, one reply line each.
struct ControlSocket {
    path: PathBuf,
    /// Device and inode of our socket file, so that one another server has bound at the same
    /// path since is not removed.
    id: Option<(u64, u64)>,
}

fn file_id(path: &Path) -> Option<(u64, u64)> {
    use std::os::unix::fs::MetadataExt;
    fs::symlink_metadata(path).ok().map(|m| (m.dev(), m.ino()))
}

impl ControlSocket {
    fn bind(
        path: &Path,
        sender: Sender<Control<Cell>>,
        state: Option<PathBuf>,
    ) -> anyhow::Result<ControlSocket> {
        if let Ok(meta) = fs::symlink_metadata(path) {
            use std::os::unix::fs::FileTypeExt;
            if meta.file_type().is_socket() {
                fs::remove_file(path)?;
            }
        }
        let listener = UnixListener::bind(path)
            .with_context(|| format!("binding control socket {}", path.display()))?;
        thread::spawn(move || {
            for stream in listener.incoming().flatten() {
                let sender = sender.clone();
                let state = state.clone();
                thread::spawn(move || serve_control_client(stream, &sender, state.as_deref()));
            }
        });
        Ok(ControlSocket {
            path: path.to_path_buf(),
            id: file_id(path),
        })
    }
}

impl Drop for ControlSocket {
    fn drop(&mut self) {
        if self.id.is_some() && file_id(&self.path) == self.id {
            let _ = fs::remove_file(&self.path);
        }
    }
}

fn serve_control_client(stream: UnixStream, sender: &Sender<Control<Cell>>, state: Option<&Path>) {
    let Ok(mut writer) = stream.try_clone() else {
        return;
    };
    for line in BufReader::new(stream).lines() {
        let Ok(line) = line else { break };
        if let Some(reply) = handle_line(&line, sender, state)
            && writeln!(writer, "{reply}").is_err()
        {
            break;
        }
    }
}
