//! `buslab cpu196`: serve the CPU196 board model on a pseudo-terminal, or drive a board (the
//! model or a real one) the way the original PC monitor did.

use std::fs;
use std::io::{IsTerminal, Write};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use anyhow::{Context, bail};
use buslab_cpu196::codes::MsgCode;
use buslab_cpu196::flash::is_user_block;
use buslab_cpu196::host::{Client, FileService, Port, Recorder};
use buslab_cpu196::image::{BAUD_RATES, BootConfig};
use buslab_cpu196::message::{Bridge, Message, Pwm, Start, Thread};
use buslab_cpu196::pic::Peer;
use buslab_cpu196::served::Served;
use buslab_cpu196::source::{Inputs, Source};
use buslab_cpu196::wire::{PIC_BLOCK, PIC_EEPROM};
use buslab_cpu196::{Board, Image};
use buslab_link::{LineSettings, open_serial};
use indicatif::{ProgressBar, ProgressStyle};

/// `println!` for an output that may be a pipe closed early (`| head`): the program then ends
/// quietly instead of panicking.
macro_rules! say {
    () => {
        emit(format_args!("\n"))
    };
    ($($arg:tt)*) => {
        emit(format_args!("{}\n", format_args!($($arg)*)))
    };
}

/// `print!` to match [`say!`].
macro_rules! say_inline {
    ($($arg:tt)*) => {
        emit(format_args!($($arg)*))
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

/// The line rate a new board image boots with.
pub const DEFAULT_BAUD: u32 = 115_200;

#[derive(clap::Args)]
pub struct Args {
    /// Serial port of the board: a real port or the PTY `cpu196 serve` printed.
    #[arg(long, short, global = true, value_name = "PATH")]
    pub port: Option<PathBuf>,
    /// Line rate (the board's boot configuration; 8N1).
    #[arg(long, global = true, default_value_t = DEFAULT_BAUD)]
    pub baud: u32,
    /// Do not ask before destructive operations (erase, write, power down, reset).
    #[arg(long, global = true)]
    pub yes: bool,
    #[command(subcommand)]
    pub command: Cmd,
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
        #[arg(long)]
        files: Option<PathBuf>,
        /// Record streamed samples to this CSV file.
        #[arg(long)]
        record: Option<PathBuf>,
        /// Stop after this many seconds (default: until Ctrl-C).
        #[arg(long, value_parser = parse_seconds)]
        duration: Option<f64>,
        /// START this configuration set first (80C196 A/D on) and STOP at the end, so the
        /// monitor sees the program's start-up output and knows the sample layout.
        #[arg(long, value_parser = parse_bank)]
        start: Option<u8>,
        /// Bank of `--start`.
        #[arg(long, default_value_t = 0, value_parser = parse_bank)]
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
        value: u16,
    },
    /// Use the PIC's bridges: spi/sci send a byte (prints what comes back), par-write,
    /// par-mask, par-read.
    Bridge {
        /// spi, sci, par-write, par-mask, par-read.
        op: String,
        #[arg(value_parser = parse_u8)]
        byte: Option<u8>,
    },
    /// Flash banks (8 × 256 blocks × 256 bytes).
    #[command(subcommand)]
    Flash(FlashCmd),
    /// PIC program blocks (1..3, 4096 bytes).
    #[command(subcommand)]
    Pic(PicCmd),
    /// PIC EEPROM (256 bytes).
    #[command(subcommand)]
    Eeprom(EepromCmd),
    /// Print the acquisition configuration of a bank's configuration set (CFGAD).
    Cfgad {
        #[arg(value_parser = parse_bank)]
        bank: u8,
        #[arg(value_parser = parse_bank)]
        config: u8,
    },
    /// START an acquisition, record the samples to CSV, STOP.
    Record {
        #[command(flatten)]
        start: StartArgs,
        #[arg(long)]
        out: PathBuf,
        /// Seconds to record.
        #[arg(long, default_value_t = 2.0, value_parser = parse_seconds)]
        duration: f64,
    },
    /// CPUFORMAT: boot configuration, serial number, PIC kernel, emergency erase.
    #[command(subcommand)]
    Format(FormatCmd),
    /// Power the board down (it cuts its supply).
    Powerdown,
    /// Software reset.
    Reset,
    /// Send a user command (00h..EFh) with parameter bytes, then print what the board sends
    /// within the time-out.
    User {
        #[arg(value_parser = parse_u8)]
        cmd: u8,
        #[arg(value_parser = parse_u8)]
        bytes: Vec<u8>,
    },
}

#[derive(clap::Args)]
pub struct ServeArgs {
    /// Board image (boot configuration, flash, PIC); created if missing, saved on changes.
    #[arg(long)]
    pub image: Option<PathBuf>,
    /// Also make this symlink to the PTY.
    #[arg(long)]
    pub link: Option<PathBuf>,
    /// Analog input CH=SOURCE of the 80C196 (const:V, sine:OFF,AMP,HZ, ramp:A,B,S, square:L,H,HZ).
    #[arg(long, value_name = "CH=SOURCE")]
    pub input: Vec<String>,
    /// Analog input CH=SOURCE of the PIC (channel 0 is the battery).
    #[arg(long, value_name = "CH=SOURCE")]
    pub pic_input: Vec<String>,
    /// The device on the PIC's SCI and SPI/I2C: loopback, silent, or script:SENT=REPLY,...
    /// (hex, e.g. script:41=4F4B).
    #[arg(long, default_value = "loopback")]
    pub peer: String,
}

#[derive(clap::Args, Clone, Copy)]
pub struct StartArgs {
    #[arg(long, default_value_t = 0, value_parser = parse_bank)]
    pub bank: u8,
    #[arg(long, default_value_t = 0, value_parser = parse_bank)]
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
}

#[derive(clap::Subcommand)]
pub enum FlashCmd {
    /// Read a block, or a whole bank (64 KiB), to a file.
    Read {
        #[arg(long, value_parser = parse_bank)]
        bank: u8,
        #[arg(long, value_parser = parse_u8)]
        block: Option<u8>,
        #[arg(long)]
        out: PathBuf,
    },
    /// Write a file (≤ 64 KiB, block 0 at offset 0) into a bank: every block that is not all
    /// FFh is written and read back. Blocks must be blank (erase first).
    Write {
        #[arg(long, value_parser = parse_bank)]
        bank: u8,
        #[arg(long = "in")]
        input: PathBuf,
    },
    /// Erase a bank.
    Erase {
        #[arg(long, value_parser = parse_bank)]
        bank: u8,
    },
}

#[derive(clap::Subcommand)]
pub enum PicCmd {
    /// Read a program block (4096 bytes) to a file.
    Read {
        #[arg(long, value_parser = parse_pic_block)]
        block: u8,
        #[arg(long)]
        out: PathBuf,
    },
    /// Write a 4096-byte file (shorter files are padded with FFh) and read it back.
    Write {
        #[arg(long, value_parser = parse_pic_block)]
        block: u8,
        #[arg(long = "in")]
        input: PathBuf,
    },
}

#[derive(clap::Subcommand)]
pub enum EepromCmd {
    /// Read the EEPROM (256 bytes) to a file.
    Read {
        #[arg(long)]
        out: PathBuf,
    },
    /// Write a 256-byte file (shorter: padded with FFh) and read it back.
    Write {
        #[arg(long = "in")]
        input: PathBuf,
    },
}

#[derive(clap::Subcommand)]
pub enum FormatCmd {
    /// Show the boot configuration (boot flash block 5).
    Boot,
    /// Change the boot configuration (erase + write boot block 5, verified). It applies from
    /// the board's next reset; a served model takes a new rate when served again.
    BootSet {
        #[arg(long)]
        line_baud: Option<u32>,
        /// on or off.
        #[arg(long)]
        watchdog: Option<String>,
        /// Three battery thresholds, e.g. 100,140,220 (255 disables one).
        #[arg(long)]
        thresholds: Option<String>,
        #[arg(long)]
        address: Option<u8>,
        /// START at boot: BANK:CONFIG (80C196 A/D on), or `none`.
        #[arg(long)]
        boot_start: Option<String>,
    },
    /// Give the board a new serial number: ERASES all flash banks and the PIC.
    Serial {
        /// 8 ASCII characters.
        new: String,
    },
    /// Read the PIC kernel.
    PicKernelRead {
        #[arg(long)]
        out: PathBuf,
    },
    /// Write the PIC kernel (4096 bytes, verified).
    PicKernelWrite {
        #[arg(long = "in")]
        input: PathBuf,
    },
    /// Emergency erase right after a reset: y=3 flash, y=C boot, x=F both, x=C PIC,
    /// x=A PIC + standby (e.g. 03, 0C, F0, C0).
    Emergency {
        #[arg(value_parser = parse_u8)]
        code: u8,
    },
}

fn parse_u8(s: &str) -> Result<u8, String> {
    let t = s.trim();
    let r = if let Some(h) = t.strip_prefix("0x").or_else(|| t.strip_prefix("0X")) {
        u8::from_str_radix(h, 16)
    } else if let Some(h) = t.strip_suffix(['h', 'H']) {
        u8::from_str_radix(h, 16)
    } else {
        t.parse()
    };
    r.map_err(|_| format!("`{s}` is not a byte (0..255, 0x1F or 1Fh)"))
}

/// Longest `--duration` (about 31 years); `Duration::from_secs_f64` panics on NaN, negative
/// or huge values.
const MAX_SECONDS: f64 = 1e9;

fn parse_seconds(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(v) if (0.0..=MAX_SECONDS).contains(&v) => Ok(v),
        _ => Err(format!(
            "`{s}` is not a number of seconds in 0..{MAX_SECONDS}"
        )),
    }
}

fn parse_bank(s: &str) -> Result<u8, String> {
    match s.parse::<u8>() {
        Ok(v) if v < 8 => Ok(v),
        _ => Err(format!("`{s}` is out of range 0..7")),
    }
}

fn parse_pic_block(s: &str) -> Result<u8, String> {
    match s.parse::<u8>() {
        Ok(v @ 1..=3) => Ok(v),
        _ => Err(format!("PIC block `{s}` is out of range 1..3")),
    }
}

fn parse_inputs(spec: &[String], into: &mut [Source; 8], what: &str) -> anyhow::Result<()> {
    for s in spec {
        let (ch, src) = s
            .split_once('=')
            .with_context(|| format!("{what} `{s}` is not CH=SOURCE"))?;
        let ch: usize = ch
            .parse()
            .ok()
            .filter(|c| *c < 8)
            .with_context(|| format!("{what} channel `{ch}` is out of range 0..7"))?;
        into[ch] = src.parse::<Source>()?;
    }
    Ok(())
}

/// A served board for `buslab lab` and tests: a PTY in a background thread; stop it by
/// dropping the handle. `image`: load it if it exists (else start from the default image), and
/// save it there on changes.
pub fn spawn_served(
    image: Option<&Path>,
    link: Option<&Path>,
    baud: u32,
    inputs: Inputs,
) -> anyhow::Result<Served> {
    spawn_served_with_peer(image, link, baud, inputs, Peer::Loopback)
}

/// [`spawn_served`] with a chosen device on the PIC's SCI and SPI/I2C bridges.
pub fn spawn_served_with_peer(
    image: Option<&Path>,
    link: Option<&Path>,
    baud: u32,
    inputs: Inputs,
    peer: Peer,
) -> anyhow::Result<Served> {
    let img = match image {
        Some(p) if p.exists() => Image::load(p)?,
        _ => Image::default(),
    };
    let mut board = Board::new(img, inputs, 0);
    board.set_peer(peer);
    if board.line().baud != baud {
        board.set_baud(baud);
    }
    // Saved once now, so an image that cannot be written is an error at start, not a warning
    // when the first change is lost.
    if let Some(path) = image {
        board.image().save(path)?;
    }
    Ok(Served::spawn(board, link, image.map(Path::to_path_buf))?)
}

pub fn run(args: Args) -> anyhow::Result<()> {
    if !BAUD_RATES.contains(&args.baud) && args.baud != 31250 {
        bail!(
            "baud rate {} is not one the board offers: {BAUD_RATES:?} (31250 for MIDI)",
            args.baud
        );
    }
    if let Cmd::Serve(s) = &args.command {
        return serve(s, args.baud);
    }
    let path = args
        .port
        .clone()
        .context("this command needs --port PATH (the board's serial port or PTY)")?;
    let port = open_serial(
        &path,
        LineSettings::n81(args.baud),
        Duration::from_millis(20),
    )?;
    let mut c = Client::new(port, args.baud);
    // Whatever the board said before we came (e.g. its boot report) is not an answer. (Bounded:
    // a running acquisition never falls silent.)
    let drain_until = Instant::now() + Duration::from_millis(100);
    while Instant::now() < drain_until && c.next(Duration::from_millis(30))?.is_some() {}
    let _ = c.take_backlog();
    let yes = args.yes;
    match args.command {
        Cmd::Serve(_) => unreachable!(),
        Cmd::Info => info(&mut c),
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
            monitor(&mut c, files.as_deref(), record.as_deref(), duration, start)
        }
        Cmd::Start(s) => {
            c.start(s.word())
                .with_context(|| format!("START bank {} configuration {}", s.bank, s.config))?;
            say!("started bank {} configuration {}", s.bank, s.config);
            Ok(())
        }
        Cmd::Stop => Ok(c.stop()?),
        Cmd::Pwm { output, value } => pwm(&mut c, &output, value),
        Cmd::Bridge { op, byte } => bridge(&mut c, &op, byte),
        Cmd::Flash(f) => flash(&mut c, f, yes),
        Cmd::Pic(p) => pic(&mut c, p, yes),
        Cmd::Eeprom(e) => eeprom(&mut c, e, yes),
        Cmd::Cfgad { bank, config } => cfgad(&mut c, bank, config),
        Cmd::Record {
            start,
            out,
            duration,
        } => record(&mut c, start, &out, duration),
        Cmd::Format(f) => format(&mut c, f, yes),
        Cmd::Powerdown => {
            confirm(yes, "power the board down (it cuts its own supply)")?;
            c.power_down()?;
            say!("the board powered down");
            Ok(())
        }
        Cmd::Reset => {
            confirm(yes, "reset the board")?;
            c.reset()?;
            say!("the board reset");
            Ok(())
        }
        Cmd::User { cmd, bytes } => {
            if cmd > 0xEF {
                bail!(
                    "user command {cmd:02X}h is out of range 00h..EFh (F0h..FFh are the kernel's)"
                );
            }
            c.send(&Message::User { cmd, params: bytes })?;
            let until = Instant::now() + c.timeout;
            while let Some(m) = c.next(until.saturating_duration_since(Instant::now()))? {
                say!("{}", buslab_cpu196::message::describe(&m));
            }
            Ok(())
        }
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

fn serve(s: &ServeArgs, baud: u32) -> anyhow::Result<()> {
    let mut inputs = Inputs::default();
    parse_inputs(&s.input, &mut inputs.c196, "--input")?;
    parse_inputs(&s.pic_input, &mut inputs.pic, "--pic-input")?;
    let peer: Peer = s.peer.parse().map_err(anyhow::Error::msg)?;
    let served = spawn_served_with_peer(s.image.as_deref(), s.link.as_deref(), baud, inputs, peer)?;
    say!("{}", served.path().display());
    if let Some(l) = &s.link {
        say!("{}", l.display());
    }
    eprintln!("CPU196 board model serving at {baud} baud 8N1; Ctrl-C to stop");
    std::io::stdout().flush().ok();
    let stop = Arc::new(AtomicBool::new(false));
    let s2 = stop.clone();
    ctrlc::set_handler(move || s2.store(true, Ordering::Relaxed))
        .context("installing the Ctrl-C handler")?;
    while !stop.load(Ordering::Relaxed) {
        std::thread::sleep(Duration::from_millis(100));
        if let Some(log) = served.with(|b, _| b.take_log()) {
            for line in log {
                eprintln!("board: {line}");
            }
        }
    }
    served.stop()?;
    Ok(())
}

fn info<P: Port>(c: &mut Client<P>) -> anyhow::Result<()> {
    let i = c.info()?;
    say!("CPU196 board");
    say!("  serial number   {}", String::from_utf8_lossy(&i.serial));
    say!("  quartz          {} MHz", i.quartz);
    say!("  kernel 80C196   {}", i.version_196);
    say!(
        "  PIC             version {} revision {}",
        i.version_pic,
        i.pic_revision
    );
    say!("  address         {}", i.address);
    say!("  supply          {:.1} V", i.supply as f64 / 10.0);
    say!("  compression     {}", hex(&i.compression));
    Ok(())
}

fn hex(b: &[u8]) -> String {
    b.iter()
        .map(|x| format!("{x:02X}"))
        .collect::<Vec<_>>()
        .join(" ")
}

/// Whether a THREAD display without newline left the line open.
static MID_LINE: AtomicBool = AtomicBool::new(false);

/// Shows one board message the way the monitor does; returns the replies to send.
fn show(m: &Message, files: &mut Option<FileService>) -> Vec<Message> {
    let open = MID_LINE.load(Ordering::Relaxed);
    if let Message::Thread(Thread::Display {
        format,
        newline,
        data,
    }) = m
    {
        // Displays without the newline bit continue the same line, as on the seed's monitor.
        let prefix = if open { "" } else { "THREAD: " };
        say_inline!("{prefix}{}", format.render(data));
        if *newline {
            say!();
        }
        MID_LINE.store(!*newline, Ordering::Relaxed);
        return Vec::new();
    }
    if open
        && !matches!(
            m,
            Message::Watchdog | Message::AdCont(_) | Message::AdSample(_)
        )
    {
        say!();
        MID_LINE.store(false, Ordering::Relaxed);
    }
    match m {
        Message::Thread(t) => match files {
            Some(fs) => {
                let (replies, log) = fs.handle(t);
                if let Some(l) = log {
                    say!("FILE: {l}");
                }
                replies
            }
            None => {
                say!("FILE: request refused (no --files DIR): {t:?}");
                vec![Message::Msg(MsgCode::FILE_ERROR)]
            }
        },
        Message::Alert(a) => {
            say!("ALERT: {a}");
            Vec::new()
        }
        Message::Msg(code) => {
            say!("MSG: {code}");
            Vec::new()
        }
        Message::Power(p) => {
            say!("POWER: {p:?}");
            Vec::new()
        }
        Message::Bridge(b) => {
            say!("BRIDGE: {b:?}");
            Vec::new()
        }
        _ => Vec::new(),
    }
}

fn monitor<P: Port>(
    c: &mut Client<P>,
    files: Option<&Path>,
    record: Option<&Path>,
    duration: Option<f64>,
    start: Option<StartArgs>,
) -> anyhow::Result<()> {
    let mut files = match files {
        Some(d) => {
            Some(FileService::new(d).with_context(|| format!("files folder {}", d.display()))?)
        }
        None => None,
    };
    let mut rec = match record {
        Some(p) => Some(Recorder::new(std::io::BufWriter::new(
            fs::File::create(p).with_context(|| format!("creating {}", p.display()))?,
        ))?),
        None => None,
    };
    let stop = Arc::new(AtomicBool::new(false));
    let s2 = stop.clone();
    let _ = ctrlc::set_handler(move || s2.store(true, Ordering::Relaxed));
    let end = duration.map(|d| Instant::now() + Duration::from_secs_f64(d));
    let mut last_ping = Instant::now() - Duration::from_secs(1);
    let mut last_heard = Instant::now();
    let mut lost = false;
    if let Some(r) = rec.as_mut() {
        // log8 samples expand through the board's own table (readable in the upper loop only).
        match c.log_table() {
            Ok(t) => r.set_log_table(t),
            Err(e) => eprintln!("warning: log table not read ({e}); log8 samples use the default"),
        }
    }
    say!("monitoring; Ctrl-C to stop");
    if let Some(s) = start {
        c.start(s.word())
            .with_context(|| format!("START bank {} configuration {}", s.bank, s.config))?;
        say!("started bank {} configuration {}", s.bank, s.config);
        // What the program said while we waited for START's answer.
        for m in c.take_backlog() {
            if let Some(r) = rec.as_mut() {
                r.record(&m)?;
            }
            for reply in show(&m, &mut files) {
                c.send(&reply)?;
            }
        }
    }
    while !stop.load(Ordering::Relaxed) && end.is_none_or(|e| Instant::now() < e) {
        if last_ping.elapsed() >= Duration::from_millis(500) {
            c.send(&Message::Watchdog)?;
            last_ping = Instant::now();
        }
        if let Some(m) = c.next(Duration::from_millis(50))? {
            last_heard = Instant::now();
            if lost {
                say!("board is back");
                lost = false;
            }
            if let Some(r) = rec.as_mut() {
                r.record(&m)?;
            }
            for reply in show(&m, &mut files) {
                c.send(&reply)?;
            }
        } else if !lost && last_heard.elapsed() > Duration::from_secs(3) {
            say!("board lost: nothing heard for 3 s");
            lost = true;
        }
        std::io::stdout().flush().ok();
    }
    if start.is_some() {
        c.stop()?;
        // The program's last words (fin_prog: closing files).
        for m in c.take_backlog() {
            for reply in show(&m, &mut files) {
                c.send(&reply)?;
            }
        }
        say!("stopped");
    }
    if let Some(r) = rec {
        let (frames, samples) = (r.frames, r.samples);
        r.finish()?;
        say!("recorded {samples} samples from {frames} frames");
    }
    Ok(())
}

fn pwm<P: Port>(c: &mut Client<P>, output: &str, value: u16) -> anyhow::Result<()> {
    let m = match output {
        "dac" => {
            if value > 31 {
                bail!("D/A value {value} is out of range 0..31");
            }
            Pwm::Dac(value as u8)
        }
        "0" | "1" | "2" => {
            if value > 255 {
                bail!("PWM {output} value {value} is out of range 0..255 (8-bit)");
            }
            Pwm::Set {
                n: output.parse()?,
                low: 0,
                value: value as u8,
            }
        }
        "3" => {
            if value > 1023 {
                bail!("PWM 3 value {value} is out of range 0..1023 (10-bit)");
            }
            Pwm::Set {
                n: 3,
                low: (value & 3) as u8,
                value: (value >> 2) as u8,
            }
        }
        other => bail!("PWM output `{other}` is not 0, 1, 2, 3 or dac"),
    };
    c.command(&Message::Pwm(m))?;
    say!("PWM {output} = {value}");
    Ok(())
}

fn bridge<P: Port>(c: &mut Client<P>, op: &str, byte: Option<u8>) -> anyhow::Result<()> {
    let need = || byte.with_context(|| format!("bridge {op} needs a byte"));
    let b = match op {
        "spi" => Bridge::SpiSend(need()?),
        "sci" => Bridge::SciSend(need()?),
        "par-write" => Bridge::ParallelWrite(need()?),
        "par-mask" => Bridge::ParallelAddress(need()?),
        "par-read" => Bridge::ParallelReadRequest,
        other => {
            bail!("bridge operation `{other}` is not spi, sci, par-write, par-mask or par-read")
        }
    };
    match c.bridge(b)? {
        Some(Bridge::SpiReceived(d)) => say!("SPI received {d:02X}h"),
        Some(Bridge::SciReceived(d)) => say!("SCI received {d:02X}h"),
        Some(Bridge::ParallelRead(d)) => say!("parallel bus reads {d:02X}h"),
        _ => say!("done"),
    }
    Ok(())
}

fn read_padded(path: &Path, max: usize) -> anyhow::Result<Vec<u8>> {
    let mut d = fs::read(path).with_context(|| format!("reading {}", path.display()))?;
    if d.len() > max {
        bail!(
            "{} has {} bytes; at most {max} fit",
            path.display(),
            d.len()
        );
    }
    d.resize(max, 0xFF);
    Ok(d)
}

fn write_file(path: &Path, data: &[u8]) -> anyhow::Result<()> {
    fs::write(path, data).with_context(|| format!("writing {}", path.display()))
}

fn flash<P: Port>(c: &mut Client<P>, f: FlashCmd, yes: bool) -> anyhow::Result<()> {
    match f {
        FlashCmd::Read {
            bank,
            block: Some(block),
            out,
        } => {
            write_file(&out, &c.flash_read(bank, block)?[..])?;
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
            write_file(&out, &all)?;
            say!("read bank {bank} (256 blocks) into {}", out.display());
        }
        FlashCmd::Write { bank, input } => {
            let data = read_padded(&input, 65536)?;
            let blocks: Vec<u8> = (0..=255u8)
                .filter(|&b| data[b as usize * 256..][..256].iter().any(|&x| x != 0xFF))
                .collect();
            if let Some(&bad) = blocks.iter().find(|&&b| !is_user_block(b)) {
                bail!(
                    "{} has data in block {bad:02X}h, outside the user flash (blocks 28h..3Fh, 60h..FFh); nothing written",
                    input.display()
                );
            }
            confirm(
                yes,
                &format!("write {} blocks into flash bank {bank}", blocks.len()),
            )?;
            let pb = bar(blocks.len() as u64 * 256, &format!("writing bank {bank}"));
            for &b in &blocks {
                let block: [u8; 256] = data[b as usize * 256..][..256].try_into().expect("256");
                c.flash_write(bank, b, &block).map_err(|e| match e {
                    buslab_cpu196::host::ClientError::Board(MsgCode::NOT_BLANK_ERROR) => anyhow::anyhow!(
                        "bank {bank} block {b:02X}h is not blank (msg_not_blank_error); erase the bank first: `flash erase --bank {bank}`"
                    ),
                    other => anyhow::Error::from(other).context(format!("bank {bank} block {b:02X}h")),
                })?;
                pb.inc(256);
            }
            pb.finish();
            say!("wrote and verified {} blocks of bank {bank}", blocks.len());
        }
        FlashCmd::Erase { bank } => {
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
            write_file(&out, &c.pic_read(block)?[..])?;
            say!("read PIC block {block} into {}", out.display());
        }
        PicCmd::Write { block, input } => {
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
            write_file(&out, &c.eeprom_read()?[..])?;
            say!("read the EEPROM into {}", out.display());
        }
        EepromCmd::Write { input } => {
            let data: [u8; PIC_EEPROM] = read_padded(&input, PIC_EEPROM)?.try_into().expect("256");
            confirm(yes, "write the PIC EEPROM")?;
            c.eeprom_write(&data)?;
            say!("wrote and verified the EEPROM");
        }
    }
    Ok(())
}

fn cfgad<P: Port>(c: &mut Client<P>, bank: u8, config: u8) -> anyhow::Result<()> {
    let (c196, pic) = c
        .cfgad(bank, config)
        .with_context(|| format!("CFGAD bank {bank} configuration {config}"))?;
    say!("bank {bank} configuration {config}");
    say!("  raw        {}", hex(&c196));
    match buslab_cpu196::adconfig::AdConfig::parse(&c196) {
        Ok(cfg) => {
            say!("  sequence   {:?}", cfg.sequence);
            say!(
                "  period     {:.1} µs (T = {}), {} scans per interrupt",
                cfg.period_ns() as f64 / 1000.0,
                cfg.time_base,
                cfg.scans_per_frame()
            );
            for (ch, s) in cfg.transmitted() {
                say!(
                    "  channel {ch}  {}-bit format, filter {:?}",
                    s.format.name(),
                    s.filter
                );
            }
        }
        Err(e) => say!("  80C196 A/D not usable: {e}"),
    }
    say!(
        "  PIC        A/D mask {:02X}h rate {:02X}h, forwarded {:02X}h",
        pic[0],
        pic[1],
        pic[2]
    );
    Ok(())
}

fn record<P: Port>(
    c: &mut Client<P>,
    start: StartArgs,
    out: &Path,
    duration: f64,
) -> anyhow::Result<()> {
    let mut rec = Recorder::new(std::io::BufWriter::new(
        fs::File::create(out).with_context(|| format!("creating {}", out.display()))?,
    ))?;
    // log8 samples expand through the board's own table.
    rec.set_log_table(c.log_table()?);
    c.start(start.word())
        .with_context(|| format!("START bank {} configuration {}", start.bank, start.config))?;
    let end = Instant::now() + Duration::from_secs_f64(duration);
    let mut last_ping = Instant::now();
    let mut files = None;
    while Instant::now() < end {
        if last_ping.elapsed() >= Duration::from_millis(500) {
            c.send(&Message::Watchdog)?;
            last_ping = Instant::now();
        }
        if let Some(m) = c.next(Duration::from_millis(20))? {
            rec.record(&m)?;
            for reply in show(&m, &mut files) {
                c.send(&reply)?;
            }
        }
    }
    c.stop()?;
    for m in c.take_backlog() {
        rec.record(&m)?;
    }
    let (frames, samples) = (rec.frames, rec.samples);
    rec.finish()?;
    if !c.frame_errors.is_empty() {
        eprintln!(
            "warning: {} damaged frames skipped (first: {})",
            c.frame_errors.len(),
            c.frame_errors[0]
        );
    }
    say!(
        "recorded {samples} samples from {frames} frames into {}",
        out.display()
    );
    Ok(())
}

fn show_boot(boot: &BootConfig) {
    let start = if boot.boot_start & 0x8000 != 0 {
        "none".to_string()
    } else {
        let s = Start::from_word(boot.boot_start & !0x6000);
        format!(
            "bank {} configuration {} (A/D {})",
            s.bank(),
            s.config(),
            if s.ad196() { "on" } else { "off" }
        )
    };
    say!("boot configuration");
    say!(
        "  protocol        {:?} (PIC port {:?})",
        boot.protocol,
        boot.protocol_pic
    );
    say!(
        "  line            {} baud 8N1, {}",
        boot.baud,
        if boot.rs232 { "RS232" } else { "TTL" }
    );
    say!(
        "  watchdog        {}",
        if boot.watchdog { "on" } else { "off" }
    );
    say!("  address         {}", boot.address);
    say!("  boot START      {start}");
    say!("  PWM             {:?} (PIC {})", boot.pwm196, boot.pic_pwm);
    say!("  battery         thresholds {:?}", boot.battery_thresholds);
}

fn format<P: Port>(c: &mut Client<P>, f: FormatCmd, yes: bool) -> anyhow::Result<()> {
    match f {
        FormatCmd::Boot => match c.boot_config()? {
            Some((boot, _)) => show_boot(&boot),
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
        } => {
            let (mut boot, user) = c
                .boot_config()?
                .unwrap_or_else(|| (BootConfig::default(), Vec::new()));
            if let Some(b) = line_baud {
                if !BAUD_RATES.contains(&b) {
                    bail!("baud rate {b} is not one of {BAUD_RATES:?}");
                }
                boot.baud = b;
            }
            if let Some(w) = watchdog {
                boot.watchdog = match w.as_str() {
                    "on" => true,
                    "off" => false,
                    other => bail!("--watchdog `{other}` is not on or off"),
                };
            }
            if let Some(t) = thresholds {
                let v: Vec<u8> = t
                    .split(',')
                    .map(|x| x.trim().parse::<u8>())
                    .collect::<Result<_, _>>()
                    .map_err(|_| {
                        anyhow::anyhow!("--thresholds `{t}` is not three numbers 0..255")
                    })?;
                let [a, b2, c2] = v[..] else {
                    bail!("--thresholds `{t}` needs exactly three numbers")
                };
                boot.battery_thresholds = [a, b2, c2];
            }
            if let Some(a) = address {
                if a > 63 {
                    bail!("--address {a} is out of range 0..63");
                }
                boot.address = a;
            }
            if let Some(bs) = boot_start {
                boot.boot_start = if bs == "none" {
                    0x8000
                } else {
                    let (b, cfg) = bs.split_once(':').with_context(|| {
                        format!("--boot-start `{bs}` is not BANK:CONFIG or none")
                    })?;
                    let (b, cfg) = (
                        parse_bank(b).map_err(anyhow::Error::msg)?,
                        parse_bank(cfg).map_err(anyhow::Error::msg)?,
                    );
                    Start::run(b, cfg, true).word()
                };
            }
            confirm(
                yes,
                "erase the boot flash and write the new boot configuration",
            )?;
            c.set_boot_config(&boot, &user)?;
            show_boot(&boot);
            say!("written and verified; it applies from the next reset");
        }
        FormatCmd::Serial { new } => {
            let new: [u8; 8] = new
                .as_bytes()
                .try_into()
                .ok()
                .filter(|_| new.is_ascii())
                .with_context(|| {
                    format!("serial number `{new}` must be exactly 8 ASCII characters")
                })?;
            let current = c.info()?.serial;
            confirm(
                yes,
                &format!(
                    "change the serial number {} to {} and ERASE all flash banks and the PIC",
                    String::from_utf8_lossy(&current),
                    String::from_utf8_lossy(&new)
                ),
            )?;
            c.set_serial(&current, &new)?;
            say!(
                "serial number is now {}; flash and PIC erased",
                String::from_utf8_lossy(&new)
            );
        }
        FormatCmd::PicKernelRead { out } => {
            let serial = c.info()?.serial;
            write_file(&out, &c.pic_kernel_read(&serial)?[..])?;
            say!("read the PIC kernel into {}", out.display());
        }
        FormatCmd::PicKernelWrite { input } => {
            let data: [u8; PIC_BLOCK] = read_padded(&input, PIC_BLOCK)?.try_into().expect("4096");
            let serial = c.info()?.serial;
            confirm(yes, "overwrite the PIC kernel")?;
            c.pic_kernel_write(&serial, &data)?;
            say!("wrote and verified the PIC kernel");
        }
        FormatCmd::Emergency { code } => {
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
