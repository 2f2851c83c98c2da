//! `buslab play [FILE|-] [WRITE=LOG…]`: replay a log onto a bus at the pace of its timestamps,
//! like can-utils' canplayer (`-I FILE` or standard input, `-g` gap, `-t` no timing, `-l`
//! loops, `-s` skip long gaps, `-n` count, `WRITE=LOG` interface mapping with its `stdout=LOG`
//! hook, `-v` to see each frame) plus `--speed`. Any log format buslab reads.

use std::io::{self, BufReader, IsTerminal, Write};
use std::path::PathBuf;
use std::str::FromStr;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError};
use std::time::{Duration, Instant};

use anyhow::{Context, bail};
use buslab_backends::{BusUrl, DynBus};
use buslab_canbus::Filter;
use buslab_logs::candump;
use buslab_logs::replay::{ReplaySchedule, ReplayTiming};
use buslab_logs::{Format, LogReader, Message, OpenOptions, ReadError, Record, open_source};

use super::busopt::{BusOpt, confirm_sent, open};
use crate::units::CanUtilsDuration;

#[derive(clap::Args)]
pub struct Args {
    /// `[FILE] [WRITE=LOG]…`: the log to play (any format buslab reads: .log, .asc, .blf,
    /// .trc, .csv, .pcap, .pcapng, .db; `-` standard input), unless -I names it; then
    /// canplayer's interface assignments WRITE=LOG: the frames logged on interface LOG go to
    /// WRITE, a bus URL or a channel name on --bus's server (vcan1=can0), or `stdout` to print
    /// them. With assignments, frames of other interfaces are not sent; without, every frame
    /// goes to --bus.
    #[arg(value_name = "[FILE] [WRITE=LOG]")]
    pub words: Vec<String>,
    /// The log to play, as canplayer -I (`-`: standard input). Without FILE or -I, standard
    /// input, as canplayer, when it is not a terminal.
    #[arg(short = 'I', long = "input", value_name = "FILE")]
    pub input: Option<PathBuf>,
    /// The log's format when its extension does not tell (standard input: candump unless
    /// given).
    #[arg(long, value_name = "FORMAT")]
    pub from: Option<Format>,
    #[command(flatten)]
    pub bus: BusOpt,
    /// At least this gap between two frames, with a unit (`5ms`); a bare number is
    /// milliseconds, as canplayer's -g (with a warning). The file's own gaps are kept when
    /// they are longer.
    #[arg(short = 'g', long, value_name = "DURATION", value_parser = crate::units::milliseconds_if_bare)]
    pub gap: Option<CanUtilsDuration>,
    /// Ignore the file's timestamps (canplayer -t): frames go out --gap apart, or as fast as
    /// the bus takes them.
    #[arg(short = 't', long)]
    pub ignore_timestamps: bool,
    /// Play the file this many times (canplayer -l); `i` plays it until Ctrl-C.
    #[arg(short = 'l', long = "loop", value_name = "N|i", default_value = "1")]
    pub loops: Loops,
    /// Skip the gaps in the file's times longer than this (canplayer -s): the frame after
    /// such a gap goes out at once. A bare number is seconds, as canplayer's -s (with a
    /// warning).
    #[arg(short = 's', long = "skip-gaps", value_name = "DURATION", value_parser = crate::units::seconds_if_bare)]
    pub skip_gaps: Option<CanUtilsDuration>,
    /// Play at most this many frames (canplayer -n).
    #[arg(short = 'n', long = "count", value_name = "COUNT")]
    pub count: Option<u64>,
    /// Pace faster or slower than the file: 2 plays twice as fast, 0.5 at half speed.
    #[arg(long, value_name = "FACTOR", default_value = "1", value_parser = parse_speed)]
    pub speed: f64,
    /// Step over bad lines or records of the log instead of stopping at the first one.
    #[arg(long)]
    pub skip_bad: bool,
    /// How long to wait at the end for the last frames to be sent, beyond the time they need
    /// on the bus, with a unit.
    #[arg(long, value_name = "DURATION", default_value = "10s", value_parser = crate::units::duration)]
    pub timeout: Duration,
    /// canplayer -x (no local loopback): not offered (refused with the reason).
    #[arg(short = 'x', hide = true)]
    pub no_loopback: bool,
    /// canplayer -i (interactive): not offered (refused with the reason).
    #[arg(short = 'i', hide = true)]
    pub interactive: bool,
}

/// Where the log comes from.
#[derive(Clone, Debug, PartialEq, Eq)]
enum Input {
    File(PathBuf),
    Stdin,
}

impl Input {
    fn new(path: PathBuf) -> Self {
        if path.as_os_str() == "-" {
            Input::Stdin
        } else {
            Input::File(path)
        }
    }

    fn name(&self) -> String {
        match self {
            Input::File(p) => p.display().to_string(),
            Input::Stdin => "standard input".to_string(),
        }
    }
}

/// `WRITE=LOG`.
#[derive(Clone, Debug)]
pub struct Mapping {
    pub write: String,
    pub log: String,
}

impl FromStr for Mapping {
    type Err = String;

    fn from_str(text: &str) -> Result<Self, String> {
        match text.rsplit_once('=') {
            Some((write, log)) if !write.is_empty() && !log.is_empty() => Ok(Self {
                write: write.to_string(),
                log: log.to_string(),
            }),
            _ => Err(format!(
                "interface assignment {text:?} must be WRITE=LOG, e.g. vcan1=can0 (frames logged on can0 go to vcan1)"
            )),
        }
    }
}

/// How many times to play.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Loops {
    Times(u64),
    Forever,
}

impl FromStr for Loops {
    type Err = String;

    fn from_str(text: &str) -> Result<Self, String> {
        match text {
            "i" | "inf" | "forever" => Ok(Loops::Forever),
            n => match n.parse::<u64>() {
                Ok(n) if n > 0 => Ok(Loops::Times(n)),
                _ => Err(format!(
                    "loops {text:?} must be a count 1 or more, or i (until Ctrl-C)"
                )),
            },
        }
    }
}

fn parse_speed(text: &str) -> Result<f64, String> {
    match text.parse::<f64>() {
        Ok(s) if (1e-6..=1e6).contains(&s) => Ok(s),
        _ => Err(format!(
            "speed {text:?} must be a factor between 0.000001 and 1000000, e.g. 2 or 0.5"
        )),
    }
}

/// Where the frames of one interface go: a bus, or canplayer's `stdout` hook.
enum Target {
    Bus { url: BusUrl, bus: DynBus, sent: u64 },
    Stdout,
}

impl Target {
    fn name(&self) -> String {
        match self {
            Target::Bus { url, .. } => url.to_string(),
            Target::Stdout => "stdout".to_string(),
        }
    }
}

/// The bus URL `write` names: a URL as it is, or a channel name on `base`'s server.
fn target_url(write: &str, base: &BusUrl) -> anyhow::Result<BusUrl> {
    if write.contains(':') {
        return Ok(write.parse()?);
    }
    Ok(match base {
        BusUrl::Socketcand { host, port, .. } => BusUrl::Socketcand {
            host: host.clone(),
            port: *port,
            channel: write.to_string(),
        },
        BusUrl::SocketCan { .. } => BusUrl::SocketCan {
            interface: write.to_string(),
        },
        other => bail!(
            "{write:?} is a channel name, but --bus {other} has no channels: give WRITE as a bus URL"
        ),
    })
}

fn connect(url: BusUrl) -> anyhow::Result<Target> {
    let mut bus = open(&url)?;
    // Only our own frames matter; what the bus carries is not kept.
    bus.set_filters(&[Filter::NONE])?;
    Ok(Target::Bus { url, bus, sent: 0 })
}

/// Sleeps until `deadline` in short steps; `false` if stopped meanwhile.
fn sleep_until(deadline: Instant, stop: &AtomicBool) -> bool {
    loop {
        if stop.load(Ordering::Relaxed) {
            return false;
        }
        let now = Instant::now();
        if now >= deadline {
            return true;
        }
        std::thread::sleep((deadline - now).min(Duration::from_millis(50)));
    }
}

/// The input and the assignments from `[FILE] [WRITE=LOG]…` and `-I`: with -I every word is an
/// assignment, else a first word without `=` is the input.
fn input_and_mappings(args: &Args) -> anyhow::Result<(Input, Vec<Mapping>)> {
    let mut words = args.words.iter().peekable();
    let input = match &args.input {
        Some(path) => Input::new(path.clone()),
        None => match words.next_if(|w| !w.contains('=')) {
            Some(word) => Input::new(PathBuf::from(word)),
            None if io::stdin().is_terminal() => bail!(
                "no log to play: give FILE, -I FILE, or - for standard input (e.g. `buslab play -I trace.log`, `candump -L can0 | buslab play -`)"
            ),
            None => Input::Stdin,
        },
    };
    let mappings = words
        .map(|w| w.parse::<Mapping>().map_err(anyhow::Error::msg))
        .collect::<anyhow::Result<Vec<_>>>()?;
    Ok((input, mappings))
}

/// Entries read from standard input by a thread, so that Ctrl-C is heard while the writer on
/// the other side of the pipe is silent; the queue between them is bounded.
const STDIN_QUEUE: usize = 1024;

enum FromStdin {
    Message(Message),
    Bad(ReadError),
    /// The end, with the lines skipped because they were no log lines (candump).
    End {
        skipped: u64,
    },
    Failed(String),
}

/// Reads standard input as `format` as it comes.
fn read_stdin(format: Format) -> anyhow::Result<Receiver<FromStdin>> {
    if format == Format::Sqlite {
        bail!("an SQLite log is read from a file, not from standard input: give its path");
    }
    let (tx, rx) = mpsc::sync_channel(STDIN_QUEUE);
    std::thread::Builder::new()
        .name("play-stdin".into())
        .spawn(move || {
            let input = BufReader::with_capacity(64 * 1024, io::stdin());
            if format == Format::Candump {
                let mut reader = candump::Reader::new(input);
                if forward(&mut reader, &tx) {
                    let skipped = reader.skipped();
                    let _ = tx.send(FromStdin::End { skipped });
                }
                return;
            }
            match buslab_logs::reader(input, format) {
                Ok(mut reader) => {
                    if forward(&mut reader, &tx) {
                        let _ = tx.send(FromStdin::End { skipped: 0 });
                    }
                }
                Err(e) => {
                    let _ = tx.send(FromStdin::Failed(e.to_string()));
                }
            }
        })
        .context("cannot start the thread that reads standard input")?;
    Ok(rx)
}

/// Hands `reader`'s entries and errors over; whether it reached the end.
fn forward(reader: &mut impl LogReader, tx: &mpsc::SyncSender<FromStdin>) -> bool {
    loop {
        let mut entry = Message::default();
        let message = match reader.read_into(&mut entry) {
            Ok(true) => FromStdin::Message(entry),
            Ok(false) => return true,
            Err(e) => {
                let fatal = e.is_fatal();
                if tx.send(FromStdin::Bad(e)).is_err() || fatal {
                    return false;
                }
                continue;
            }
        };
        if tx.send(message).is_err() {
            return false;
        }
    }
}

/// One pass over the input.
enum Pass {
    File(Box<dyn LogReader + Send>),
    Stdin(Receiver<FromStdin>),
}

impl Pass {
    /// The next entry; `Ok(false)` at the end (or when stopped while waiting for input).
    fn next(
        &mut self,
        entry: &mut Message,
        stop: &AtomicBool,
        skipped: &mut u64,
    ) -> Result<bool, ReadError> {
        match self {
            Pass::File(reader) => reader.read_into(entry),
            Pass::Stdin(rx) => loop {
                match rx.recv_timeout(Duration::from_millis(100)) {
                    Ok(FromStdin::Message(e)) => {
                        *entry = e;
                        return Ok(true);
                    }
                    Ok(FromStdin::Bad(e)) => return Err(e),
                    Ok(FromStdin::End { skipped: n }) => {
                        *skipped = n;
                        return Ok(false);
                    }
                    Ok(FromStdin::Failed(text)) => {
                        return Err(ReadError::io(io::Error::other(text)));
                    }
                    Err(RecvTimeoutError::Timeout) if stop.load(Ordering::Relaxed) => {
                        return Ok(false);
                    }
                    Err(RecvTimeoutError::Timeout) => {}
                    Err(RecvTimeoutError::Disconnected) => return Ok(false),
                }
            },
        }
    }
}

pub fn run(args: Args, quiet: bool) -> anyhow::Result<()> {
    if args.no_loopback {
        bail!(
            "-x (canplayer's \"disable local loopback\") is not offered: on a buslab bus every other node sees the frames played, as on a real bus, and this client does not receive its own"
        );
    }
    if args.interactive {
        bail!("-i (canplayer's interactive mode) is not offered: use -n COUNT or -g to pace");
    }
    let (input, mappings) = input_and_mappings(&args)?;
    let format = match (&args.from, &input) {
        (Some(f), _) => *f,
        (None, Input::File(path)) => Format::from_path(path)?,
        (None, Input::Stdin) => Format::Candump,
    };
    if input == Input::Stdin && args.loops != Loops::Times(1) {
        bail!("-l: standard input can be read only once; play a file to loop it");
    }
    if let Some(gap) = &args.gap {
        gap.warn_if_bare("-g", "canplayer");
    }
    if let Some(skip) = &args.skip_gaps {
        skip.warn_if_bare("-s", "canplayer");
    }
    let mut schedule = ReplaySchedule::new(ReplayTiming {
        speed: args.speed,
        skip_gaps: args.skip_gaps.as_ref().map(|s| s.duration),
        min_gap: args.gap.as_ref().map(|g| g.duration),
        ignore_timestamps: args.ignore_timestamps,
    });
    // The schedule's clock.
    let epoch = Instant::now();
    let stop = super::interrupted()?;
    // Targets: one per distinct WRITE (or --bus alone), and which log interface goes where.
    let mut targets: Vec<Target> = Vec::new();
    let mut routes: Vec<(String, usize)> = Vec::new();
    if mappings.is_empty() {
        targets.push(connect(args.bus.bus.clone())?);
    }
    for m in &mappings {
        let index = if m.write == "stdout" {
            match targets.iter().position(|t| matches!(t, Target::Stdout)) {
                Some(i) => i,
                None => {
                    targets.push(Target::Stdout);
                    targets.len() - 1
                }
            }
        } else {
            let url = target_url(&m.write, &args.bus.bus)?;
            match targets
                .iter()
                .position(|t| matches!(t, Target::Bus { url: u, .. } if *u == url))
            {
                Some(i) => i,
                None => {
                    targets.push(connect(url)?);
                    targets.len() - 1
                }
            }
        };
        routes.push((m.log.clone(), index));
    }
    let stdout = io::stdout();
    let (mut errors, mut unmapped, mut bad, mut skipped) = (0u64, 0u64, 0u64, 0u64);
    let mut played = 0u64;
    let mut round = 0u64;
    'rounds: while match args.loops {
        Loops::Times(n) => round < n,
        Loops::Forever => true,
    } {
        round += 1;
        let mut pass = match &input {
            Input::File(path) => {
                Pass::File(open_source(path, format, &OpenOptions::default())?.reader)
            }
            Input::Stdin => Pass::Stdin(read_stdin(format)?),
        };
        let mut entry = Message::default();
        schedule.restart();
        loop {
            if stop.load(Ordering::Relaxed) || args.count.is_some_and(|n| played >= n) {
                break 'rounds;
            }
            match pass.next(&mut entry, &stop, &mut skipped) {
                Ok(true) => {}
                Ok(false) => break,
                Err(e) if args.skip_bad && !e.is_fatal() => {
                    bad += 1;
                    tracing::warn!("skipped: {e}");
                    continue;
                }
                Err(e) => {
                    let hint = if e.is_fatal() {
                        ""
                    } else {
                        " (--skip-bad steps over bad lines and records)"
                    };
                    let from = match &input {
                        Input::Stdin => "standard input: ",
                        Input::File(_) => "",
                    };
                    return Err(anyhow::anyhow!(
                        "{from}{e}{hint}; {played} frames were played"
                    ));
                }
            }
            let index = if routes.is_empty() {
                0
            } else {
                match routes.iter().find(|(log, _)| *log == entry.channel) {
                    Some((_, i)) => *i,
                    None => {
                        unmapped += 1;
                        continue;
                    }
                }
            };
            if matches!(targets[index], Target::Stdout) {
                // canplayer's hook: the log line, as it is, on stdout.
                let mut out = stdout.lock();
                writeln!(out, "{}", candump::format_line(&entry, false))
                    .and_then(|()| out.flush())
                    .context("writing to stdout")?;
                continue;
            }
            let Record::Frame(frame) = &entry.record else {
                errors += 1;
                continue;
            };
            let due = schedule
                .due(entry.at, epoch.elapsed())
                .min(epoch.elapsed() + crate::units::MAX_DURATION);
            if !sleep_until(epoch + due, &stop) {
                break 'rounds;
            }
            let target = &mut targets[index];
            let name = target.name();
            let Target::Bus { bus, sent, .. } = target else {
                unreachable!("stdout was handled above");
            };
            bus.send(frame)
                .with_context(|| format!("sending {frame} to {name}"))?;
            *sent += 1;
            played += 1;
            // canplayer -v: each frame as it goes (buslab's -v shows the log's info lines).
            tracing::info!("{name} ({}) {frame}", entry.channel);
            schedule.sent(epoch.elapsed());
        }
    }
    for t in &mut targets {
        if let Target::Bus { url, bus, sent } = t
            && *sent > 0
        {
            confirm_sent(bus, url, *sent, args.timeout)?;
        }
    }
    if skipped > 0 {
        tracing::warn!(
            "{}: {skipped} line(s) were no candump log lines (they do not start with '(') and were skipped, as canplayer does",
            input.name()
        );
    }
    if !quiet {
        let mut line = format!(
            "played {played} frames from {} ({round} time{})",
            input.name(),
            if round == 1 { "" } else { "s" }
        );
        if errors > 0 {
            line.push_str(&format!("; {errors} error frames not sent"));
        }
        if unmapped > 0 {
            line.push_str(&format!(
                "; {unmapped} frames of interfaces without an assignment not sent"
            ));
        }
        if bad > 0 {
            line.push_str(&format!("; {bad} bad records skipped"));
        }
        eprintln!("{line}");
    }
    Ok(())
}
