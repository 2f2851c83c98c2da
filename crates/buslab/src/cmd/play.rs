//! `buslab play FILE --bus URL`: replay a log onto a bus at the pace of its timestamps, like
//! can-utils' canplayer (`-g` gap, `-t` no timing, `-l` loops, `WRITE=LOG` interface mapping)
//! plus `--speed`. Any log format buslab reads.

use std::path::PathBuf;
use std::str::FromStr;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use anyhow::{Context, bail};
use buslab_backends::{BusUrl, DynBus};
use buslab_canbus::Filter;
use buslab_logs::{Entry, Format, OpenOptions, Record, open_source};

use super::busopt::{BusOpt, confirm_sent, open};

#[derive(clap::Args)]
pub struct Args {
    /// The log to play (any format buslab reads: .log, .asc, .blf, .trc, .csv, .pcap,
    /// .pcapng, .db).
    #[arg(value_name = "FILE")]
    pub input: PathBuf,
    /// The log's format when its extension does not tell.
    #[arg(long, value_name = "FORMAT")]
    pub from: Option<Format>,
    #[command(flatten)]
    pub bus: BusOpt,
    /// canplayer's interface assignment WRITE=LOG: the frames logged on interface LOG go to
    /// WRITE, a bus URL or a channel name on --bus's server (vcan1=can0). With assignments,
    /// frames of other interfaces are not sent; without, every frame goes to --bus.
    #[arg(value_name = "WRITE=LOG")]
    pub map: Vec<Mapping>,
    /// At least this gap between two frames, with a unit (canplayer -g 5 is `-g 5ms`); the
    /// file's own gaps are kept when they are longer.
    #[arg(short = 'g', long, value_name = "DURATION", value_parser = crate::units::duration)]
    pub gap: Option<Duration>,
    /// Ignore the file's timestamps (canplayer -t): frames go out --gap apart, or as fast as
    /// the bus takes them.
    #[arg(short = 't', long)]
    pub ignore_timestamps: bool,
    /// Play the file this many times (canplayer -l); `i` plays it until Ctrl-C.
    #[arg(short = 'l', long = "loop", value_name = "N|i", default_value = "1")]
    pub loops: Loops,
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

/// A bus frames are played to.
struct Target {
    url: BusUrl,
    bus: DynBus,
    sent: u64,
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
    Ok(Target { url, bus, sent: 0 })
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

pub fn run(args: Args, quiet: bool) -> anyhow::Result<()> {
    let format = match args.from {
        Some(f) => f,
        None => Format::from_path(&args.input)?,
    };
    let stop = super::interrupted()?;
    // Targets: one per distinct WRITE (or --bus alone), and which log interface goes where.
    let mut targets: Vec<Target> = Vec::new();
    let mut routes: Vec<(String, usize)> = Vec::new();
    if args.map.is_empty() {
        targets.push(connect(args.bus.bus.clone())?);
    }
    for m in &args.map {
        let url = target_url(&m.write, &args.bus.bus)?;
        let index = match targets.iter().position(|t| t.url == url) {
            Some(i) => i,
            None => {
                targets.push(connect(url)?);
                targets.len() - 1
            }
        };
        routes.push((m.log.clone(), index));
    }
    let (mut errors, mut unmapped, mut bad) = (0u64, 0u64, 0u64);
    let mut played = 0u64;
    let mut last_sent: Option<Instant> = None;
    let mut round = 0u64;
    'rounds: while match args.loops {
        Loops::Times(n) => round < n,
        Loops::Forever => true,
    } {
        round += 1;
        let mut source = open_source(&args.input, format, &OpenOptions::default())?;
        let mut entry = Entry::default();
        let mut zero: Option<(Duration, Instant)> = None;
        loop {
            if stop.load(Ordering::Relaxed) {
                break 'rounds;
            }
            match source.reader.read_into(&mut entry) {
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
                    return Err(anyhow::anyhow!("{e}{hint}; {played} frames were played"));
                }
            }
            let Record::Frame(frame) = &entry.record else {
                errors += 1;
                continue;
            };
            let index = if routes.is_empty() {
                0
            } else {
                match routes.iter().find(|(log, _)| *log == entry.interface) {
                    Some((_, i)) => *i,
                    None => {
                        unmapped += 1;
                        continue;
                    }
                }
            };
            let now = Instant::now();
            let mut due = now;
            if !args.ignore_timestamps {
                let (t0, start) = *zero.get_or_insert((entry.timestamp, now));
                let offset = entry.timestamp.saturating_sub(t0).as_secs_f64() / args.speed;
                due = start
                    + Duration::from_secs_f64(offset.min(crate::units::MAX_DURATION.as_secs_f64()));
            }
            if let (Some(gap), Some(last)) = (args.gap, last_sent) {
                due = due.max(last + gap);
            }
            if !sleep_until(due, &stop) {
                break 'rounds;
            }
            let target = &mut targets[index];
            target
                .bus
                .send(frame)
                .with_context(|| format!("sending {frame} to {}", target.url))?;
            target.sent += 1;
            played += 1;
            last_sent = Some(Instant::now());
        }
    }
    for t in &mut targets {
        if t.sent > 0 {
            confirm_sent(&mut t.bus, &t.url, t.sent, args.timeout)?;
        }
    }
    if !quiet {
        let mut line = format!(
            "played {played} frames from {} ({round} time{})",
            args.input.display(),
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
