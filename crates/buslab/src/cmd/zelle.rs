//! `buslab zelle`: serve the ZELLE cell model on a pseudo-terminal, or talk to a cell (the
//! model or a real one) as its host. Argument definitions and printing; the client, the
//! served cell and the control lines are in `buslab-zelle` and `buslab-served`.

use std::io::{self, BufRead, Write};
use std::path::{Path, PathBuf};
use std::sync::mpsc::RecvTimeoutError;
use std::time::Duration;

use anyhow::Context;
use buslab_link::fs::{read_limited, write_atomic};
use buslab_link::{ControlSocket, SerialLine};
use buslab_plot::{Figure, Panel, Series};
use buslab_served::zelle::{CellOptions, ServedCell, analog_input};
use buslab_zelle::analog::{FULL_SCALE_VOLTS, to_volts};
use buslab_zelle::client::{
    Client, DEFAULT_TIMEOUT, Measurement, Port, Progress, SeriesParams, Transfer,
};
use buslab_zelle::control::{self, parse_number_in};
use buslab_zelle::timing::LINE;
use buslab_zelle::{DATA_AREA, EXT_RAM_SIZE, PARAMS_LEN, SetupRule, TraceEvent, hex_listing};

use crate::units::duration;

/// `println!` through [`print_stdout`]: a reader that went away (`| head`) ends the output
/// quietly instead of a panic.
macro_rules! say {
    ($($arg:tt)*) => {
        print_stdout(&format!("{}\n", format_args!($($arg)*)))?
    };
}

/// The largest file `load` and `upload` read (an Intel HEX file of the whole RAM is ~90 KB).
const MAX_INPUT_FILE: u64 = 1 << 20;

#[derive(clap::Args)]
pub struct Args {
    /// Serial port of the cell, for the client commands (give it before the command): a real
    /// port (/dev/ttyUSB0) or the PTY `zelle serve` printed.
    #[arg(long, short, value_name = "PATH")]
    pub port: Option<PathBuf>,
    /// How long to wait for each answer beyond its bytes' time on the line, with a unit
    /// (`500ms`, `2s`) [default: 500ms].
    #[arg(long, value_parser = duration, value_name = "DURATION")]
    pub timeout: Option<Duration>,
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
        #[arg(long, short, value_name = "FILE")]
        output: Option<PathBuf>,
        /// Wait for each byte before asking for the next (slow; for comparison).
        #[arg(long)]
        stop_and_wait: bool,
    },
    /// Write a file's bytes into the data area from 0800h (command 3).
    Upload {
        /// The bytes to write (raw binary, at most 30720).
        file: PathBuf,
        /// Wait for each timing byte before sending the next pair (slow; for comparison).
        #[arg(long)]
        stop_and_wait: bool,
    },
    /// Read a RAM byte (command 18).
    Peek {
        /// Address 0..FFFFh: 2048, 0x800 or 0800h.
        addr: String,
    },
    /// Write a RAM byte (command 19).
    Poke {
        /// Address 0..FFFFh: 2048, 0x800 or 0800h.
        addr: String,
        /// Byte 0..255: 171, 0xAB or ABh.
        value: String,
    },
    /// Read port 1 (command 12), or write it (command 11).
    Port1 {
        /// The latch to write (0..255; keep bits 0..3 and inputs high); none: read the pins.
        value: Option<String>,
    },
    /// Read P2.6 (command 15), or write it (command 14).
    P26 {
        /// The level to write, 0 or 1; none: read it.
        value: Option<String>,
    },
    /// Read the START key (command 13).
    Key,
    /// Read an internal RAM register (command 16), or write it (command 17).
    Reg {
        /// Register address: 0..127 internal RAM, 128..255 (80h..FFh) special function
        /// registers (read only).
        addr: String,
        /// Byte to write (0..255); none: read it.
        value: Option<String>,
    },
    /// Show the internal RAM as a program left it (the four register banks, the bit area, the
    /// rest) and the special function registers as the OS has them (command 16 for each).
    Regs,
    /// Read a parallel-bus address, or write it (command 8).
    Bus {
        /// Bus address 0..127.
        addr: String,
        /// Byte to write (0..255); none: read it.
        value: Option<String>,
    },
    /// Load a program (raw binary, or Intel HEX with addresses in 0400h..07FFh) (command 5).
    Load {
        /// The program file.
        file: PathBuf,
        /// Wait for each timing byte before sending the next pair (slow; for comparison).
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
    /// Lose a byte whose start bit falls within the 1 ms set-up after commands 1, 2, 3 and 5,
    /// as the cell does. Without it such a byte is kept and counted (`status`: kept in
    /// set-up): a pseudo-terminal does not carry the line's timing, so a client must then pause
    /// far beyond 1 ms after its drain, and a loaded host may still lose its byte.
    #[arg(long)]
    pub strict_setup: bool,
    /// Show the instructions programs run on stderr: at most N a second of the cell's time
    /// (1..1000000; the rest counted as not traced) [default N: 1000].
    #[arg(long, value_name = "N", num_args = 0..=1, default_missing_value = "1000",
          value_parser = clap::value_parser!(u32).range(1..=1_000_000))]
    pub trace: Option<u32>,
}

#[derive(clap::Args)]
pub struct MeasureArgs {
    /// Channels, in slot order (up to four of 1..4).
    #[arg(long, short, value_delimiter = ',', default_value = "1")]
    pub channels: Vec<u8>,
    /// Time between scan cycles, with a unit (`10ms`, `1s`): whole milliseconds, at least
    /// 1 ms per channel.
    #[arg(long, short, default_value = "10ms", value_parser = duration, value_name = "DURATION")]
    pub interval: Duration,
    /// Scan cycles per block (the seed's "block length").
    #[arg(long, default_value_t = 100)]
    pub cycles: u16,
    /// Blocks to run, each started by the host (command 9).
    #[arg(long, default_value_t = 1)]
    pub blocks: u32,
    /// Waited beyond each block's length before the next START or the stop (the cell sends
    /// no "block done"): how late the host and the line may be without cutting a block short.
    #[arg(long, default_value = "250ms", value_parser = duration, value_name = "DURATION")]
    pub block_margin: Duration,
    /// Write the CSV here instead of stdout.
    #[arg(long, short, value_name = "FILE")]
    pub output: Option<PathBuf>,
    /// Write volts instead of raw readings 0..255.
    #[arg(long)]
    pub volts: bool,
    /// Draw the series: alone, as characters in the terminal (on stderr); with a file name,
    /// as an SVG figure (volts over time, one line per channel).
    #[arg(long, value_name = "FILE.svg", num_args = 0..=1)]
    pub plot: Option<Option<PathBuf>>,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let port_path = match args.command {
        ZelleCommand::Serve(serve_args) => {
            if args.port.is_some() || args.timeout.is_some() {
                anyhow::bail!(
                    "--port and --timeout are for the client commands; `zelle serve` makes its \
                     own port"
                );
            }
            return serve(serve_args);
        }
        _ => args.port.clone().context(
            "--port PATH is required: the cell's serial port, or the PTY `buslab zelle serve` printed",
        )?,
    };
    let timeout = args.timeout.unwrap_or(DEFAULT_TIMEOUT);
    let serial = SerialLine::open_when_free(&port_path, LINE, timeout)
        .with_context(|| format!("opening the cell at {}", port_path.display()))?;
    let mut cell = Client::with_timeout(serial, timeout);
    // Bytes waiting on the line are no answer to this command: what a program sent with
    // nobody reading (its `Sende` output), or what an earlier client left.
    cell.port()
        .discard_input()
        .with_context(|| format!("clearing the input of {}", port_path.display()))?;
    let mode = |saw: bool| {
        if saw {
            Transfer::StopAndWait
        } else {
            Transfer::Pipelined
        }
    };
    match args.command {
        ZelleCommand::Serve(_) => unreachable!("served above"),
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
                Some(path) => write_atomic(&path, &data)?,
                None => print_stdout(&hex_listing(DATA_AREA, &data))?,
            }
        }
        ZelleCommand::Upload {
            file,
            stop_and_wait,
        } => {
            let data = read_limited(&file, EXT_RAM_SIZE as u64)?;
            cell.write_data(&data, mode(stop_and_wait))?;
            say!("wrote {} bytes from 0800h", data.len());
        }
        ZelleCommand::Peek { addr } => {
            let addr = parse_number_in(&addr, "address", 0xFFFF)? as u16;
            say!("{:#04x}", cell.peek(addr)?);
        }
        ZelleCommand::Poke { addr, value } => {
            let addr = parse_number_in(&addr, "address", 0xFFFF)? as u16;
            cell.poke(addr, parse_number_in(&value, "value", 0xFF)? as u8)?;
        }
        ZelleCommand::Port1 { value: None } => say!("{:#010b}", cell.read_port1()?),
        ZelleCommand::Port1 { value: Some(v) } => {
            cell.write_port1(parse_number_in(&v, "port value", 0xFF)? as u8)?
        }
        ZelleCommand::P26 { value: None } => say!("{}", u8::from(cell.read_p26()?)),
        ZelleCommand::P26 { value: Some(v) } => {
            cell.write_p26(parse_number_in(&v, "P2.6 level", 1)? == 1)?
        }
        ZelleCommand::Regs => {
            let iram = (0..=127u8)
                .map(|addr| cell.read_register(addr))
                .collect::<Result<Vec<u8>, _>>()?;
            let mut sfrs = Vec::new();
            for (name, addr) in SFRS {
                sfrs.push(format!("{name}={:02X}", cell.read_register(addr)?));
            }
            print_stdout(&registers_view(&iram, &sfrs.join(" ")))?;
        }
        ZelleCommand::Key => say!(
            "{}",
            if cell.key_pressed()? {
                "pressed"
            } else {
                "released"
            }
        ),
        ZelleCommand::Reg { addr, value } => match value {
            None => {
                let addr = parse_number_in(&addr, "register address", 0xFF)? as u8;
                say!("{:#04x}", cell.read_register(addr)?)
            }
            Some(v) => {
                // Command 17 writes internal RAM only.
                let addr = parse_number_in(&addr, "register address to write", 127)? as u8;
                cell.write_register(addr, parse_number_in(&v, "value", 0xFF)? as u8)?
            }
        },
        ZelleCommand::Bus { addr, value } => {
            let addr = parse_number_in(&addr, "bus address", 127)? as u8;
            match value {
                None => say!("{:#04x}", cell.bus_read(addr)?),
                Some(v) => cell.bus_write(addr, parse_number_in(&v, "value", 0xFF)? as u8)?,
            }
        }
        ZelleCommand::Load {
            file,
            stop_and_wait,
        } => {
            let contents = read_limited(&file, MAX_INPUT_FILE)?;
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

fn measure<P: Port>(cell: &mut Client<P>, m: MeasureArgs) -> anyhow::Result<()> {
    let params = SeriesParams::with_interval(&m.channels, m.cycles, m.interval)?;
    if let Some(Some(path)) = &m.plot {
        super::plot::check_target(path)?;
    }
    let bar = indicatif::ProgressBar::new(1000);
    bar.set_style(
        indicatif::ProgressStyle::with_template("{msg:>10} [{bar:40}] {percent:>3}%")
            .expect("a valid template"),
    );
    cell.set_block_margin(m.block_margin);
    let result = cell.measure(&params, m.blocks, |p| match p {
        Progress::Measuring {
            block,
            blocks,
            done_ns,
            total_ns,
        } => {
            bar.set_message(format!("block {}/{blocks}", block + 1));
            bar.set_position(done_ns * 900 / total_ns.max(buslab_can::Nanos::new(1)));
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
            write_atomic(path, csv.as_bytes())?;
            eprintln!(
                "{} cycles of {} channel(s) written to {}",
                series.rows.len(),
                series.channels.len(),
                path.display()
            );
        }
        None => print_stdout(&csv)?,
    }
    match &m.plot {
        Some(None) => eprint!("{}", series.plot(72, 16)),
        Some(Some(path)) => super::plot::write(&measurement_figure(&series), path)?,
        None => {}
    }
    let missing = series.missing_values();
    if missing > 0 {
        anyhow::bail!(
            "the cell measured {} of {} readings: a block was cut short (the stop or the next \
             START reached the cell before the block ended: the host or the line was late by \
             more than --block-margin {}), or the data area filled up; what was measured is \
             above",
            series.expected_values - missing,
            series.expected_values,
            buslab_device::Human(m.block_margin)
        );
    }
    Ok(())
}

/// The `--plot FILE.svg` figure: every channel in volts over time (channel k of a cycle was
/// converted k ms after the cycle's start), named as in the CSV header.
fn measurement_figure(series: &Measurement) -> Figure {
    let mut panel = Panel::new("analog inputs", "voltage", Some("V"));
    panel.covers = Some((0.0, FULL_SCALE_VOLTS));
    panel.series = csv_column_names(&series.channels)
        .into_iter()
        .enumerate()
        .map(|(k, name)| {
            let points = series.rows.iter().filter_map(|row| {
                let t = row.time_ns.get() as f64 * 1e-9 + k as f64 * 1e-3;
                Some((t, to_volts(*row.values.get(k)?)))
            });
            Series::from_points(name, points)
        })
        .collect();
    let channels: Vec<String> = series.channels.iter().map(u8::to_string).collect();
    Figure {
        panels: vec![panel],
        ..Figure::new(format!(
            "ZELLE: {} cycles of channel(s) {} every {} ms",
            series.rows.len(),
            channels.join(", "),
            series.params.interval_ms
        ))
    }
}

/// `ch1`, `ch2`, …; a channel measured twice per cycle: `ch1`, `ch1_2` (as the CSV's header).
fn csv_column_names(channels: &[u8]) -> Vec<String> {
    channels
        .iter()
        .enumerate()
        .map(
            |(i, ch)| match channels[..i].iter().filter(|&c| c == ch).count() {
                0 => format!("ch{ch}"),
                d => format!("ch{ch}_{}", d + 1),
            },
        )
        .collect()
}

/// Writes to stdout; a reader that went away (`| head`) just ends the output.
fn print_stdout(text: &str) -> anyhow::Result<()> {
    let mut out = io::stdout().lock();
    match out.write_all(text.as_bytes()).and_then(|()| out.flush()) {
        Err(e) if e.kind() == io::ErrorKind::BrokenPipe => Ok(()),
        other => Ok(other?),
    }
}

/// The special function registers `regs` shows, by name.
const SFRS: [(&str, u8); 20] = [
    ("SP", 0x81),
    ("DPL", 0x82),
    ("DPH", 0x83),
    ("PSW", 0xD0),
    ("ACC", 0xE0),
    ("B", 0xF0),
    ("IE", 0xA8),
    ("IP", 0xB8),
    ("TCON", 0x88),
    ("TMOD", 0x89),
    ("TH0", 0x8C),
    ("TL0", 0x8A),
    ("TH1", 0x8D),
    ("TL1", 0x8B),
    ("SCON", 0x98),
    ("PCON", 0x87),
    ("P0", 0x80),
    ("P1", 0x90),
    ("P2", 0xA0),
    ("P3", 0xB0),
];

/// The internal RAM in rows: the four banks as R0..R7, then 16 bytes a row; the SFRs last.
fn registers_view(iram: &[u8], sfrs: &str) -> String {
    let hex = |bytes: &[u8]| {
        bytes
            .iter()
            .map(|b| format!("{b:02X}"))
            .collect::<Vec<_>>()
            .join(" ")
    };
    let mut out = String::new();
    for (bank, regs) in iram[..32].chunks(8).enumerate() {
        out.push_str(&format!(
            "bank {bank} {:02X}h  R0-R7  {}\n",
            bank * 8,
            hex(regs)
        ));
    }
    for (row, bytes) in iram[32..].chunks(16).enumerate() {
        let addr = 32 + row * 16;
        let what = if addr < 0x30 { "bits " } else { "     " };
        out.push_str(&format!("{addr:02X}h    {what}  {}\n", hex(bytes)));
    }
    out.push_str(&format!("SFR (the OS's, as it answers): {sfrs}\n"));
    out
}

// ----- serving the model --------------------------------------------------------------------

fn serve(args: ServeArgs) -> anyhow::Result<()> {
    // Before the PTY and its link exist: a signal that finds them must find the handler too
    // (an early SIGTERM killed the process and left the link behind).
    let stopped = super::stop_requests()?;
    let analog = args
        .analog
        .iter()
        .map(|a| analog_input(a).with_context(|| format!("--analog {a}")))
        .collect::<anyhow::Result<Vec<_>>>()?;
    let rule = if args.strict_setup {
        SetupRule::Lose
    } else {
        buslab_served::zelle::SERVED_SETUP_RULE
    };
    let served = ServedCell::spawn_with_setup_rule(
        CellOptions {
            state: args.state.clone(),
            link: args.link.clone(),
            analog,
            trace: args.trace,
        },
        rule,
    )?;
    let control = served.control();
    // Bound before the path is printed: a script that reads the path may use the socket at once.
    let _socket = args
        .control
        .as_deref()
        .map(|path| control_socket(path, &control))
        .transpose()?;
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
    {
        let control = control.clone();
        std::thread::spawn(move || {
            for line in io::stdin().lock().lines() {
                let Ok(line) = line else { break };
                if let Some(reply) = control.line(&line) {
                    // A closed stdout (`serve | head -1`) must not end the control thread.
                    let _ = print_stdout(&format!("{reply}\n"));
                }
            }
        });
    }
    match args.trace {
        Some(_) => {
            // The cell queues the trace; it is printed as it comes until a stop is asked for.
            while let Err(RecvTimeoutError::Timeout) = stopped.recv_timeout(TRACE_EVERY) {
                print_trace(&served.take_trace()?);
            }
            print_trace(&served.take_trace()?);
        }
        None => {
            let _ = stopped.recv();
        }
    }
    Ok(served.stop()?)
}

/// How often `serve --trace` prints what the cell traced.
const TRACE_EVERY: Duration = Duration::from_millis(100);

fn print_trace(events: &[TraceEvent]) {
    if events.is_empty() {
        return;
    }
    let mut text = String::new();
    for event in events {
        text.push_str(&format!("{event}\n"));
    }
    // stderr: stdout carries the PTY's path and the control replies.
    let _ = io::stderr().lock().write_all(text.as_bytes());
}

fn control_socket(
    path: &Path,
    control: &buslab_served::zelle::CellControl,
) -> anyhow::Result<ControlSocket> {
    ControlSocket::bind(path, control.handler())
        .with_context(|| format!("binding control socket {}", path.display()))
}
