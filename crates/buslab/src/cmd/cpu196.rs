//! `buslab cpu196`: serve the CPU196 board model on a pseudo-terminal, or drive a board (the
//! model or a real one) the way the original PC monitor did. Argument definitions and
//! printing; the client, the monitor session and the value checks are in `buslab-cpu196`, the
//! served board and the file service in `buslab-served`.

use std::io::{IsTerminal, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::Ordering;
use std::time::Duration;

use anyhow::{Context, bail};
use buslab_cpu196::adconfig::ConfigReport;
use buslab_cpu196::codes::MsgCode;
use buslab_cpu196::host::{
    Client, ClientError, CsvSamples, DEFAULT_TIMEOUT, FileRequests, Monitor, Port, Recorder,
    Sample, SampleSink, SampleSource,
};
use buslab_cpu196::image::{BAUD_RATES, BootConfig, BootEdit};
use buslab_cpu196::message::{Bridge, Message, Start, printable};
use buslab_cpu196::pic::Peer;
use buslab_cpu196::source::{FULL_SCALE_V, Inputs, Source};
use buslab_cpu196::values::{self, ValueError};
use buslab_cpu196::wire::{PIC_BLOCK, PIC_EEPROM};
use buslab_link::fs::{read_limited, write_atomic};
use buslab_link::{LineSettings, SerialLine};
use buslab_plot::{Figure, Panel, Series};
use buslab_served::cpu196::{BoardOptions, FileService, spawn_board};
use indicatif::{ProgressBar, ProgressStyle};

use crate::units::duration;

/// `println!` for an output that may be a pipe closed early (`| head`): the program then ends
/// quietly instead of panicking.
macro_rules! say {
    ($($arg:tt)*) => {
        emit(format_args!("{}\n", format_args!($($arg)*)))
    };
}

fn emit(args: std::fmt::Arguments) {
    if let Err(e) = std::io::stdout().lock().write_fmt(args) {
        if e.kind() == std::io::ErrorKind::BrokenPipe {
            std::process::exit(0);
        }
        eprintln!("error: writing to stdout: {e}");
        std::process::exit(1);
    }
}

/// Prints text the library produced (it ends its own lines).
fn show(text: &mut String) {
    if !text.is_empty() {
        emit(format_args!("{text}"));
        let _ = std::io::stdout().flush();
        text.clear();
    }
}

#[path = "cpu196_program.rs"]
mod program;

/// The line rate a new board image boots with.
pub const DEFAULT_BAUD: u32 = 115_200;

/// How long a monitor turn waits for the board before pinging again if due.
const TURN: Duration = Duration::from_millis(50);

#[derive(clap::Args)]
pub struct Args {
    /// Serial port of the board, for the client commands (give it before the command): a real
    /// port or the PTY `cpu196 serve` printed.
    #[arg(long, short, value_name = "PATH")]
    pub port: Option<PathBuf>,
    /// Line rate of the client, 8N1; it must match the board's boot configuration
    /// [default: 115200].
    #[arg(long, value_name = "BAUD", value_parser = baud)]
    pub baud: Option<u32>,
    /// How long to wait for each answer beyond its bytes' time on the line, with a unit
    /// (`2s`, `500ms`) [default: 2s].
    #[arg(long, value_parser = duration, value_name = "DURATION")]
    pub timeout: Option<Duration>,
    /// Do not ask before destructive operations (erase, write, power down, reset); also
    /// taken after such a command.
    #[arg(long)]
    pub yes: bool,
    #[command(subcommand)]
    pub command: Cmd,
}

/// `--yes` on a destructive command.
#[derive(clap::Args, Clone, Copy, Debug, Default)]
pub struct Confirm {
    /// Do not ask for confirmation (needed when stdin is not a terminal).
    #[arg(long)]
    pub yes: bool,
}

#[derive(clap::Subcommand)]
pub enum Cmd {
    /// Serve the board model on a new pseudo-terminal until Ctrl-C.
    Serve(ServeArgs),
    /// Print the board identity (CPUINF).
    Info,
    /// Keep the link alive and show what the board sends: THREAD text/numbers, alerts,
    /// messages; serve its file requests; optionally record samples.
    Monitor {
        /// Folder the board's files are read from and written to (never outside it).
        #[arg(long, value_name = "DIR")]
        files: Option<PathBuf>,
        /// Record streamed samples to this CSV file.
        #[arg(long, value_name = "FILE")]
        record: Option<PathBuf>,
        /// Stop after this long, with a unit (`10s`, `1m`); default: until Ctrl-C.
        #[arg(long, value_parser = duration, value_name = "DURATION")]
        duration: Option<Duration>,
        /// START this configuration set (0..7) first and STOP it at the end, so the monitor
        /// sees the program's start-up output and the sample layout. The 80C196 A/D runs
        /// unless the set has no conversion sequence or `--no-ad` is given.
        #[arg(long, value_parser = bank, value_name = "CONFIG")]
        start: Option<u8>,
        /// Bank (0..7) of `--start`.
        #[arg(long, default_value_t = 0, value_parser = bank)]
        bank: u8,
        /// With `--start`: leave the 80C196 A/D off.
        #[arg(long)]
        no_ad: bool,
    },
    /// Enter the lower loop with a configuration set (START).
    Start(StartArgs),
    /// Leave the lower loop (STOP).
    Stop,
    /// Set a PWM: 0..2 = 80C196 8-bit, 3 = PIC 10-bit; `dac` = PIC 5-bit D/A.
    Pwm {
        /// 0, 1, 2, 3 or `dac`.
        output: String,
        /// 0..255 (PWM 0..2), 0..1023 (PWM 3), 0..31 (dac).
        value: u16,
    },
    /// Use the PIC's bridges: spi/sci send a byte (prints what comes back), par-write,
    /// par-mask, par-read.
    Bridge {
        /// spi, sci, par-write, par-mask, par-read.
        op: String,
        /// The byte to send or write (42, 0x2A or 2Ah); not for par-read.
        #[arg(value_parser = byte)]
        byte: Option<u8>,
    },
    /// Flash banks (8 × 256 blocks × 256 bytes).
    #[command(subcommand)]
    Flash(FlashCmd),
    /// User programs: WebAssembly modules in flash that the kernel runs on its hooks
    /// (docs/cpu196.md).
    #[command(subcommand)]
    Program(program::ProgramCmd),
    /// PIC program blocks (1..3, 4096 bytes).
    #[command(subcommand)]
    Pic(PicCmd),
    /// PIC EEPROM (256 bytes).
    #[command(subcommand)]
    Eeprom(EepromCmd),
    /// Print the acquisition configuration of a bank's configuration set (CFGAD).
    Cfgad {
        /// Bank 0..7.
        #[arg(value_parser = bank)]
        bank: u8,
        /// Configuration set 0..7.
        #[arg(value_parser = bank)]
        config: u8,
    },
    /// START an acquisition, record the samples to CSV, STOP.
    Record {
        #[command(flatten)]
        start: StartArgs,
        /// The CSV file to write.
        #[arg(long, value_name = "FILE")]
        out: PathBuf,
        /// How long to record, with a unit (`2s`, `500ms`).
        #[arg(long, default_value = "2s", value_parser = duration, value_name = "DURATION")]
        duration: Duration,
        /// Also draw the recording as an SVG figure: volts over time, one line per channel
        /// (virtual channels in a panel of their own).
        #[arg(long, value_name = "FILE.svg")]
        plot: Option<PathBuf>,
    },
    /// CPUFORMAT: boot configuration, serial number, PIC kernel, emergency erase.
    #[command(subcommand)]
    Format(FormatCmd),
    /// Power the board down (it cuts its supply).
    Powerdown(Confirm),
    /// Software reset.
    Reset(Confirm),
    /// Send a user command (00h..EFh) with parameter bytes, then print what the board sends
    /// within the time-out.
    User {
        /// The command byte, 00h..EFh (F0h..FFh are the kernel's).
        #[arg(value_parser = user_command)]
        cmd: u8,
        /// Parameter bytes (42, 0x2A or 2Ah each).
        #[arg(value_parser = byte)]
        bytes: Vec<u8>,
    },
}

#[derive(clap::Args)]
pub struct ServeArgs {
    /// Line rate of the served board, 8N1 (it overrides the image's boot configuration).
    #[arg(long, default_value_t = DEFAULT_BAUD, value_parser = baud)]
    pub baud: u32,
    /// Board image (boot configuration, flash, PIC); created if missing, saved on changes.
    #[arg(long, value_name = "FILE")]
    pub image: Option<PathBuf>,
    /// Also make this symlink to the PTY.
    #[arg(long, value_name = "PATH")]
    pub link: Option<PathBuf>,
    /// Analog input CH=SOURCE of the 80C196, channel 0..7: VOLTS, sine|triangle|square:FREQ[:AMPLITUDE[:OFFSET]],
    /// ramp:FROM:TO:PERIOD or csv:FILE (e.g. 0=sine:1Hz:2V:2.5V), as `zelle serve --analog`.
    #[arg(long, value_name = "CH=SOURCE", value_parser = input)]
    pub input: Vec<(u8, Source)>,
    /// Analog input CH=SOURCE of the PIC (channel 0 is the battery).
    #[arg(long, value_name = "CH=SOURCE", value_parser = input)]
    pub pic_input: Vec<(u8, Source)>,
    /// The device on the PIC's SCI and SPI/I2C: loopback, silent, or script:SENT=REPLY,...
    /// (hex, e.g. script:41=4F4B).
    #[arg(long, default_value = "loopback", value_parser = peer)]
    pub peer: Peer,
}

#[derive(clap::Args, Clone, Copy)]
pub struct StartArgs {
    /// Bank 0..7 of the configuration set.
    #[arg(long, default_value_t = 0, value_parser = bank)]
    pub bank: u8,
    /// Configuration set 0..7.
    #[arg(long, default_value_t = 0, value_parser = bank)]
    pub config: u8,
    /// Leave the 80C196 A/D off.
    #[arg(long)]
    pub no_ad: bool,
    /// Start the PIC A/D (FB samples of the channels in the set's mask).
    #[arg(long)]
    pub pic_ad: bool,
    /// Start the PIC timer.
    #[arg(long)]
    pub pic_timer: bool,
}

impl StartArgs {
    fn word(self) -> Start {
        Start::new(
            !self.no_ad,
            self.pic_ad,
            self.bank,
            self.config,
            0,
            self.pic_timer,
            false,
            false,
        )
    }

    fn context(self) -> String {
        format!("START bank {} configuration {}", self.bank, self.config)
    }
}

#[derive(clap::Subcommand)]
pub enum FlashCmd {
    /// Read a block, or a whole bank (64 KiB), to a file.
    Read {
        /// Bank 0..7.
        #[arg(long, value_parser = bank)]
        bank: u8,
        /// Block 00h..FFh (42, 0x2A or 2Ah); default: the whole bank.
        #[arg(long, value_parser = byte)]
        block: Option<u8>,
        /// The file to write.
        #[arg(long, value_name = "FILE")]
        out: PathBuf,
    },
    /// Write a file (≤ 64 KiB, block 0 at offset 0) into a bank: every block that is not all
    /// FFh is written and read back. Blocks must be blank (erase first).
    Write {
        /// Bank 0..7.
        #[arg(long, value_parser = bank)]
        bank: u8,
        /// The file to read.
        #[arg(long = "in", value_name = "FILE")]
        input: PathBuf,
        #[command(flatten)]
        confirm: Confirm,
    },
    /// Erase a bank.
    Erase {
        /// Bank 0..7.
        #[arg(long, value_parser = bank)]
        bank: u8,
        #[command(flatten)]
        confirm: Confirm,
    },
}

#[derive(clap::Subcommand)]
pub enum PicCmd {
    /// Read a program block (4096 bytes) to a file.
    Read {
        /// Block 1..3.
        #[arg(long, value_parser = pic_block)]
        block: u8,
        /// The file to write.
        #[arg(long, value_name = "FILE")]
        out: PathBuf,
    },
    /// Write a 4096-byte file (shorter files are padded with FFh) and read it back.
    Write {
        /// Block 1..3.
        #[arg(long, value_parser = pic_block)]
        block: u8,
        /// The file to read.
        #[arg(long = "in", value_name = "FILE")]
        input: PathBuf,
        #[command(flatten)]
        confirm: Confirm,
    },
}

#[derive(clap::Subcommand)]
pub enum EepromCmd {
    /// Read the EEPROM (256 bytes) to a file.
    Read {
        /// The file to write.
        #[arg(long, value_name = "FILE")]
        out: PathBuf,
    },
    /// Write a 256-byte file (shorter: padded with FFh) and read it back.
    Write {
        /// The file to read.
        #[arg(long = "in", value_name = "FILE")]
        input: PathBuf,
        #[command(flatten)]
        confirm: Confirm,
    },
}

#[derive(clap::Subcommand)]
pub enum FormatCmd {
    /// Show the boot configuration (boot flash block 5).
    Boot,
    /// Change the boot configuration (erase + write boot block 5, verified). It applies from
    /// the board's next reset; a served model takes a new rate when served again.
    BootSet {
        /// The board's line rate, one of 1200, 2400, 9600, 19200, 38400, 57600, 115200,
        /// 250000.
        #[arg(long)]
        line_baud: Option<u32>,
        /// The watchdog: on or off.
        #[arg(long, value_parser = on_off)]
        watchdog: Option<bool>,
        /// Three battery thresholds, e.g. 100,140,220 (255 disables one).
        #[arg(long, value_parser = thresholds, value_name = "A,B,C")]
        thresholds: Option<[u8; 3]>,
        /// The board's address 0..63.
        #[arg(long)]
        address: Option<u8>,
        /// START at boot: BANK:CONFIG (80C196 A/D on), or `none`.
        #[arg(long, value_parser = boot_start, value_name = "BANK:CONFIG|none")]
        boot_start: Option<u16>,
        #[command(flatten)]
        confirm: Confirm,
    },
    /// Give the board a new serial number: ERASES all flash banks and the PIC.
    Serial {
        /// 8 ASCII characters.
        #[arg(value_parser = serial_number)]
        new: [u8; 8],
        #[command(flatten)]
        confirm: Confirm,
    },
    /// Read the PIC kernel.
    PicKernelRead {
        /// The file to write.
        #[arg(long, value_name = "FILE")]
        out: PathBuf,
    },
    /// Write the PIC kernel (4096 bytes, verified).
    PicKernelWrite {
        /// The file to read.
        #[arg(long = "in", value_name = "FILE")]
        input: PathBuf,
        #[command(flatten)]
        confirm: Confirm,
    },
    /// Emergency erase right after a reset: y=3 flash, y=C boot, x=F both, x=C PIC,
    /// x=A PIC + standby (e.g. 03, 0C, F0, C0).
    Emergency {
        /// The code xy (03h, 0Ch, F0h, C0h, ...).
        #[arg(value_parser = byte)]
        code: u8,
        #[command(flatten)]
        confirm: Confirm,
    },
}

// Value parsers: the checks live in `buslab_cpu196::values`.
fn byte(s: &str) -> Result<u8, ValueError> {
    values::parse_byte(s)
}
fn bank(s: &str) -> Result<u8, ValueError> {
    values::parse_bank(s)
}
fn pic_block(s: &str) -> Result<u8, ValueError> {
    values::parse_pic_block(s)
}
fn user_command(s: &str) -> Result<u8, ValueError> {
    values::parse_user_command(s)
}
fn serial_number(s: &str) -> Result<[u8; 8], ValueError> {
    values::parse_serial_number(s)
}
fn thresholds(s: &str) -> Result<[u8; 3], ValueError> {
    values::parse_thresholds(s)
}
fn boot_start(s: &str) -> Result<u16, ValueError> {
    values::parse_boot_start(s)
}
fn on_off(s: &str) -> Result<bool, ValueError> {
    values::parse_on_off(s)
}
fn input(s: &str) -> Result<(u8, Source), buslab_served::ServeError> {
    buslab_served::analog::channel_input(s, buslab_cpu196::source::CHANNELS)
}
fn peer(s: &str) -> Result<Peer, String> {
    s.parse()
}
fn baud(s: &str) -> Result<u32, String> {
    match s.trim().parse::<u32>() {
        Ok(b) if BAUD_RATES.contains(&b) || b == 31250 => Ok(b),
        _ => Err(format!(
            "baud rate {s} is not one the board offers: {BAUD_RATES:?} (31250 for MIDI)"
        )),
    }
}

/// `quiet` (the global `-q`): no `Ctrl-C to stop`.
pub fn run(args: Args, quiet: bool) -> anyhow::Result<()> {
    if let Cmd::Serve(s) = &args.command {
        if args.port.is_some() || args.baud.is_some() || args.timeout.is_some() || args.yes {
            bail!(
                "--port, --baud, --timeout and --yes are for the client commands; `cpu196 serve` \
                 makes its own port and takes its own --baud"
            );
        }
        return serve(s, quiet);
    }
    if let Cmd::Program(program::ProgramCmd::Check { module }) = &args.command {
        return program::check(module);
    }
    let baud = args.baud.unwrap_or(DEFAULT_BAUD);
    let path = args
        .port
        .clone()
        .context("this command needs --port PATH (the board's serial port or PTY)")?;
    let timeout = args.timeout.unwrap_or(DEFAULT_TIMEOUT);
    let port = SerialLine::open_when_free(&path, LineSettings::n81(baud), timeout)?;
    let mut c = Client::new(port, baud);
    c.timeout = timeout;
    // Whatever the board said before we came (e.g. its boot report) is not an answer. (Bounded:
    // a running acquisition never falls silent.)
    let drain_until = c.now() + Duration::from_millis(100);
    while c.now() < drain_until && c.next(Duration::from_millis(30))?.is_some() {}
    let _ = c.take_backlog();
    let yes = args.yes;
    match args.command {
        Cmd::Serve(_) => unreachable!("served above"),
        Cmd::Info => {
            say!("{}", c.info()?);
            Ok(())
        }
        Cmd::Monitor {
            files,
            record,
            duration,
            start,
            bank,
            no_ad,
        } => {
            let start = start.map(|config| StartArgs {
                bank,
                config,
                no_ad,
                pic_ad: false,
                pic_timer: false,
            });
            monitor(
                &mut c,
                files.as_deref(),
                record.as_deref(),
                duration,
                start,
                quiet,
            )
        }
        Cmd::Start(s) => {
            start(&mut c, s)?;
            say!("started bank {} configuration {}", s.bank, s.config);
            Ok(())
        }
        Cmd::Stop => Ok(c.stop()?),
        Cmd::Pwm { output, value } => {
            c.command(&Message::Pwm(values::pwm(&output, value)?))?;
            say!("PWM {output} = {value}");
            Ok(())
        }
        Cmd::Bridge { op, byte } => {
            match c.bridge(values::bridge(&op, byte)?)? {
                Some(Bridge::SpiReceived(d)) => say!("SPI received {d:02X}h"),
                Some(Bridge::SciReceived(d)) => say!("SCI received {d:02X}h"),
                Some(Bridge::ParallelRead(d)) => say!("parallel bus reads {d:02X}h"),
                _ => say!("done"),
            }
            Ok(())
        }
        Cmd::Flash(f) => flash(&mut c, f, yes),
        Cmd::Program(p) => program::run(&mut c, p, yes),
        Cmd::Pic(p) => pic(&mut c, p, yes),
        Cmd::Eeprom(e) => eeprom(&mut c, e, yes),
        Cmd::Cfgad { bank, config } => {
            let (c196, pic) = c
                .cfgad(bank, config)
                .with_context(|| format!("CFGAD bank {bank} configuration {config}"))?;
            say!(
                "{}",
                ConfigReport {
                    bank,
                    config,
                    c196,
                    pic
                }
            );
            Ok(())
        }
        Cmd::Record {
            start,
            out,
            duration,
            plot,
        } => record(&mut c, start, &out, duration, plot.as_deref()),
        Cmd::Format(f) => format(&mut c, f, yes),
        Cmd::Powerdown(Confirm { yes: also }) => {
            confirm(yes || also, "power the board down (it cuts its own supply)")?;
            c.power_down()?;
            say!("the board powered down");
            Ok(())
        }
        Cmd::Reset(Confirm { yes: also }) => {
            confirm(yes || also, "reset the board")?;
            c.reset()?;
            say!("the board reset");
            Ok(())
        }
        Cmd::User { cmd, bytes } => {
            c.send(&Message::User { cmd, params: bytes })?;
            let until = c.now() + c.timeout;
            while let Some(m) = c.next(until.saturating_sub(c.now()))? {
                say!("{}", buslab_cpu196::message::describe(&m));
            }
            Ok(())
        }
    }
}

/// START, naming the set in errors; a refused acquisition says why, and how to do without.
fn start<P: Port>(c: &mut Client<P>, s: StartArgs) -> anyhow::Result<()> {
    match c.start(s.word()) {
        Ok(()) => Ok(()),
        Err(e @ ClientError::AdConfig { why: Some(_), .. }) => Err(anyhow::anyhow!(
            "{}: {e}; --no-ad starts the set with the 80C196 A/D off",
            s.context()
        )),
        Err(e) => Err(anyhow::Error::from(e).context(s.context())),
    }
}

fn confirm(yes: bool, what: &str) -> anyhow::Result<()> {
    if yes {
        return Ok(());
    }
    if !std::io::stdin().is_terminal() {
        bail!("refusing to {what} without confirmation: pass --yes");
    }
    eprint!("{what}? [y/N] ");
    std::io::stderr().flush().ok();
    let mut line = String::new();
    std::io::stdin().read_line(&mut line)?;
    if matches!(line.trim(), "y" | "Y" | "yes") {
        Ok(())
    } else {
        bail!("cancelled")
    }
}

fn bar(len: u64, what: &str) -> ProgressBar {
    let pb = ProgressBar::new(len);
    pb.set_style(
        ProgressStyle::with_template("{msg} [{bar:30}] {bytes}/{total_bytes} {bytes_per_sec}")
            .expect("template")
            .progress_chars("=> "),
    );
    pb.set_message(what.to_string());
    pb
}

fn serve(s: &ServeArgs, quiet: bool) -> anyhow::Result<()> {
    // Before the PTY and its link exist (see `zelle serve`).
    let stopped = super::stop_requests()?;
    let mut inputs = Inputs::default();
    for (ch, source) in &s.input {
        inputs.c196[usize::from(*ch)] = source.clone();
    }
    for (ch, source) in &s.pic_input {
        inputs.pic[usize::from(*ch)] = source.clone();
    }
    let served = spawn_board(BoardOptions {
        image: s.image.clone(),
        link: s.link.clone(),
        baud: s.baud,
        inputs,
        peer: s.peer.clone(),
    })?;
    say!("{}", served.path().display());
    if let Some(l) = &s.link {
        say!("{}", l.display());
    }
    eprintln!(
        "CPU196 board model serving at {} baud 8N1{}",
        s.baud,
        if quiet { "" } else { "; Ctrl-C to stop" }
    );
    std::io::stdout().flush().ok();
    // The kernel's log (what it refused and why), as it comes. A serve thread that ended (an
    // error on the PTY) ends the wait too; `stop` then reports why.
    while stopped.recv_timeout(Duration::from_millis(100)).is_err() {
        let Ok(log) = served.with(|b, _| b.take_log()) else {
            break;
        };
        for line in log {
            eprintln!("board: {line}");
        }
    }
    Ok(served.stop()?)
}

fn monitor<P: Port>(
    c: &mut Client<P>,
    files: Option<&Path>,
    record: Option<&Path>,
    duration: Option<Duration>,
    start: Option<StartArgs>,
    quiet: bool,
) -> anyhow::Result<()> {
    let files = match files {
        Some(d) => Some(Box::new(
            FileService::new(d).with_context(|| format!("files folder {}", d.display()))?,
        ) as Box<dyn FileRequests>),
        None => None,
    };
    let recorder = match record {
        Some(p) => {
            let mut r = new_recorder(c, p)?;
            // log8 samples expand through the board's own table (readable in the upper loop
            // only).
            match c.log_table() {
                Ok(t) => r.set_log_table(t),
                Err(e) => {
                    tracing::warn!("log table not read ({e}); log8 samples use the default")
                }
            }
            Some(r)
        }
        None => None,
    };
    let mut session = Monitor::new(files, recorder, c.now());
    let mut out = String::new();
    say!("monitoring{}", if quiet { "" } else { "; Ctrl-C to stop" });
    if let Some(s) = start {
        let started = session.start(c, s.word()).with_context(|| s.context())?;
        let without_ad = if started.ad196() == s.word().ad196() {
            ""
        } else {
            " with the 80C196 A/D off (the set has no conversion sequence)"
        };
        say!(
            "started bank {} configuration {}{without_ad}",
            s.bank,
            s.config
        );
    }
    let stop = super::interrupted()?;
    let end = duration.map(|d| c.now() + d);
    while !stop.load(Ordering::Relaxed) && end.is_none_or(|e| c.now() < e) {
        session.turn(c, TURN, &mut out)?;
        show(&mut out);
    }
    if start.is_some() {
        session.stop(c, &mut out)?;
        show(&mut out);
        say!("stopped");
    }
    if let Some((_, frames, samples)) = session.finish()? {
        say!("recorded {samples} samples from {frames} frames");
    }
    report_frame_errors(c);
    Ok(())
}

/// Tells how many damaged frames the client skipped (a noisy line, a wrong baud rate).
fn report_frame_errors<P: Port>(c: &Client<P>) {
    if let Some(first) = c.frame_errors.first() {
        tracing::warn!(
            "{} damaged frames skipped (first: {first})",
            c.frame_errors.count()
        );
    }
}

/// A CSV recorder on a new file.
fn new_recorder<P: Port>(c: &Client<P>, path: &Path) -> anyhow::Result<Recorder<CsvFile>> {
    Ok(Recorder::new(csv_file(path)?, c.now()))
}

type CsvFile = CsvSamples<std::io::BufWriter<std::fs::File>>;

/// Samples as CSV in a new file (written as they come, so a run cut short keeps what was
/// recorded).
fn csv_file(path: &Path) -> anyhow::Result<CsvFile> {
    let file =
        std::fs::File::create(path).with_context(|| format!("creating {}", path.display()))?;
    Ok(CsvSamples::new(std::io::BufWriter::new(file))?)
}

fn record<P: Port>(
    c: &mut Client<P>,
    s: StartArgs,
    out_path: &Path,
    duration: Duration,
    plot: Option<&Path>,
) -> anyhow::Result<()> {
    if let Some(path) = plot {
        super::plot::check_target(path)?;
    }
    // The figure's series as the samples come (an empty one without --plot).
    let mut recorder = Recorder::new((csv_file(out_path)?, FigureSamples::default()), c.now());
    // log8 samples expand through the board's own table.
    recorder.set_log_table(c.log_table()?);
    let mut session = Monitor::new(None, Some(recorder), c.now());
    let mut out = String::new();
    start(c, s)?;
    let end = c.now() + duration;
    while c.now() < end {
        session.turn(c, Duration::from_millis(20), &mut out)?;
        show(&mut out);
    }
    session.stop(c, &mut out)?;
    show(&mut out);
    report_frame_errors(c);
    let ((_, figure), frames, samples) = session.finish()?.expect("a recorder was given");
    say!(
        "recorded {samples} samples from {frames} frames into {}",
        out_path.display()
    );
    if let Some(path) = plot {
        super::plot::write(&figure.figure(out_path)?, path)?;
    }
    Ok(())
}

/// The `--plot` figure of a recording, built from its samples as they come: a line per source
/// and channel, in volts; virtual channels (no volts) in their own panel.
#[derive(Default)]
struct FigureSamples {
    volts: std::collections::BTreeMap<(SampleSource, u8), Series>,
    virtual_values: std::collections::BTreeMap<u8, Series>,
}

impl SampleSink for FigureSamples {
    fn sample(&mut self, s: &Sample) -> std::io::Result<()> {
        let name = || format!("{} ch{}", s.source, s.channel);
        match s.volts {
            Some(volts) => self
                .volts
                .entry((s.source, s.channel))
                .or_insert_with(|| Series::new(name()))
                .push(s.t_s, volts),
            None => self
                .virtual_values
                .entry(s.channel)
                .or_insert_with(|| Series::new(name()))
                .push(s.t_s, s.value),
        }
        Ok(())
    }
}

impl FigureSamples {
    /// The figure of the recording written to `csv`.
    fn figure(self, csv: &Path) -> anyhow::Result<Figure> {
        let mut analog = Panel::new("A/D channels", "voltage", Some("V"));
        analog.covers = Some((0.0, FULL_SCALE_V));
        analog.series = self.volts.into_values().collect();
        let mut virtuals = Panel::new("virtual channels", "value", None);
        virtuals.series = self.virtual_values.into_values().collect();
        let mut figure = Figure::new(format!("CPU196 recording {}", csv.display()));
        // A panel without a series says nothing; a figure with none is refused when drawn.
        figure.panels = [analog, virtuals]
            .into_iter()
            .filter(|p| !p.series.is_empty())
            .collect();
        if figure.panels.is_empty() {
            bail!("no samples were recorded: nothing to plot");
        }
        Ok(figure)
    }
}

/// A file's bytes, at most `max`, padded with FFh to `max`.
fn read_padded(path: &Path, max: usize) -> anyhow::Result<Vec<u8>> {
    let mut d = read_limited(path, max as u64)?;
    d.resize(max, 0xFF);
    Ok(d)
}

fn flash<P: Port>(c: &mut Client<P>, f: FlashCmd, yes: bool) -> anyhow::Result<()> {
    match f {
        FlashCmd::Read {
            bank,
            block: Some(block),
            out,
        } => {
            write_atomic(&out, &c.flash_read(bank, block)?[..])?;
            say!("read bank {bank} block {block:02X}h into {}", out.display());
        }
        FlashCmd::Read {
            bank,
            block: None,
            out,
        } => {
            let pb = bar(65536, &format!("reading bank {bank}"));
            let all = c.flash_read_bank(bank, &mut |n| pb.set_position(n as u64))?;
            pb.finish();
            write_atomic(&out, &all)?;
            say!("read bank {bank} (256 blocks) into {}", out.display());
        }
        FlashCmd::Write {
            bank,
            input,
            confirm: Confirm { yes: also },
        } => {
            let yes = yes || also;
            let data = read_padded(&input, 65536)?;
            let blocks = values::flash_blocks_to_write(&data)
                .map_err(|e| anyhow::anyhow!("{} has {e}", input.display()))?;
            confirm(
                yes,
                &format!("write {} blocks into flash bank {bank}", blocks.len()),
            )?;
            let pb = bar(blocks.len() as u64 * 256, &format!("writing bank {bank}"));
            for &b in &blocks {
                let block: [u8; 256] = data[b as usize * 256..][..256].try_into().expect("256");
                c.flash_write(bank, b, &block).map_err(|e| match e {
                    ClientError::Board(MsgCode::NOT_BLANK_ERROR) => anyhow::anyhow!(
                        "bank {bank} block {b:02X}h is not blank (msg_not_blank_error); erase the bank first: `flash erase --bank {bank}`"
                    ),
                    other => anyhow::Error::from(other).context(format!("bank {bank} block {b:02X}h")),
                })?;
                pb.inc(256);
            }
            pb.finish();
            say!("wrote and verified {} blocks of bank {bank}", blocks.len());
        }
        FlashCmd::Erase {
            bank,
            confirm: Confirm { yes: also },
        } => {
            let yes = yes || also;
            confirm(yes, &format!("erase flash bank {bank}"))?;
            c.flash_erase(bank)?;
            say!("erased bank {bank}");
        }
    }
    Ok(())
}

fn pic<P: Port>(c: &mut Client<P>, p: PicCmd, yes: bool) -> anyhow::Result<()> {
    match p {
        PicCmd::Read { block, out } => {
            write_atomic(&out, &c.pic_read(block)?[..])?;
            say!("read PIC block {block} into {}", out.display());
        }
        PicCmd::Write {
            block,
            input,
            confirm: Confirm { yes: also },
        } => {
            let yes = yes || also;
            let data: [u8; PIC_BLOCK] = read_padded(&input, PIC_BLOCK)?.try_into().expect("4096");
            confirm(yes, &format!("write PIC program block {block}"))?;
            let pb = bar(PIC_BLOCK as u64, &format!("writing PIC block {block}"));
            c.pic_write(block, &data, &mut |n| pb.set_position(n as u64))?;
            pb.finish();
            say!("wrote and verified PIC block {block}");
        }
    }
    Ok(())
}

fn eeprom<P: Port>(c: &mut Client<P>, e: EepromCmd, yes: bool) -> anyhow::Result<()> {
    match e {
        EepromCmd::Read { out } => {
            write_atomic(&out, &c.eeprom_read()?[..])?;
            say!("read the EEPROM into {}", out.display());
        }
        EepromCmd::Write {
            input,
            confirm: Confirm { yes: also },
        } => {
            let yes = yes || also;
            let data: [u8; PIC_EEPROM] = read_padded(&input, PIC_EEPROM)?.try_into().expect("256");
            confirm(yes, "write the PIC EEPROM")?;
            c.eeprom_write(&data)?;
            say!("wrote and verified the EEPROM");
        }
    }
    Ok(())
}

fn format<P: Port>(c: &mut Client<P>, f: FormatCmd, yes: bool) -> anyhow::Result<()> {
    match f {
        FormatCmd::Boot => match c.boot_config()? {
            Some((boot, _)) => say!("{boot}"),
            None => {
                say!("boot block 5 is erased or not valid: the kernel runs on its defaults")
            }
        },
        FormatCmd::BootSet {
            line_baud,
            watchdog,
            thresholds,
            address,
            boot_start,
            confirm: Confirm { yes: also },
        } => {
            let yes = yes || also;
            let (mut boot, user) = c
                .boot_config()?
                .unwrap_or_else(|| (BootConfig::default(), Vec::new()));
            boot.apply(&BootEdit {
                baud: line_baud,
                watchdog,
                thresholds,
                address,
                boot_start,
            })?;
            confirm(
                yes,
                "erase the boot flash and write the new boot configuration",
            )?;
            c.set_boot_config(&boot, &user)?;
            say!("{boot}");
            say!("written and verified; it applies from the next reset");
        }
        FormatCmd::Serial {
            new,
            confirm: Confirm { yes: also },
        } => {
            let yes = yes || also;
            let current = c.info()?.serial;
            confirm(
                yes,
                &format!(
                    "change the serial number {} to {} and ERASE all flash banks and the PIC",
                    printable(&current),
                    printable(&new)
                ),
            )?;
            c.set_serial(&current, &new)?;
            say!(
                "serial number is now {}; flash and PIC erased",
                printable(&new)
            );
        }
        FormatCmd::PicKernelRead { out } => {
            let serial = c.info()?.serial;
            write_atomic(&out, &c.pic_kernel_read(&serial)?[..])?;
            say!("read the PIC kernel into {}", out.display());
        }
        FormatCmd::PicKernelWrite {
            input,
            confirm: Confirm { yes: also },
        } => {
            let yes = yes || also;
            let data: [u8; PIC_BLOCK] = read_padded(&input, PIC_BLOCK)?.try_into().expect("4096");
            let serial = c.info()?.serial;
            confirm(yes, "overwrite the PIC kernel")?;
            c.pic_kernel_write(&serial, &data)?;
            say!("wrote and verified the PIC kernel");
        }
        FormatCmd::Emergency {
            code,
            confirm: Confirm { yes: also },
        } => {
            let yes = yes || also;
            confirm(
                yes,
                &format!("reset the board and emergency-erase with code {code:02X}h"),
            )?;
            c.emergency_erase(code)?;
            say!("emergency erase {code:02X}h done");
        }
    }
    Ok(())
}
