//! `buslab dump [IFACE[,FILTER…]]…`: print every frame on one or more buses like candump;
//! `-l FILE` also writes a log in any format `buslab_logs` writes, `-L` prints candump log
//! lines instead; interface arguments and filters are `buslab_backends::BusSpec`.

use std::io::{self, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc;
use std::time::{Duration, Instant, UNIX_EPOCH};

use anyhow::{Context, bail};
use buslab_backends::{BusSpec, BusUrl, DynBus, FilterSet, resolve};
use buslab_canbus::BusEvent;
use buslab_logs::candump::{Terminal, TimestampMode, View, format_line};
use buslab_logs::{Entry, Format, LogWriter, WriteOptions, create_writer_with};

use super::busopt::{open, set_name};

#[derive(clap::Args)]
pub struct Args {
    /// Buses with candump filters, as candump takes interfaces: `vcan0`,
    /// `can0,123:7FF,~200:700,#FFFFFFFF` (ID:MASK, ~ inverted, #ERRORMASK, j to AND them);
    /// several buses are printed together. A name is vcan0 (buslab's bus on this machine),
    /// an interface (can0), an SLCAN adapter's path or a URL. Default: the configuration's
    /// `bus` (docs/config.md), else vcan0.
    #[arg(value_name = "IFACE[,FILTER…]")]
    pub interfaces: Vec<BusSpec>,
    /// One more bus, without filters (the URL form of IFACE).
    #[arg(long, value_name = "BUS", value_parser = resolve)]
    pub bus: Option<BusUrl>,
    /// Also write every frame to this log file, in the format its extension names: .log
    /// (candump, also without an extension), .asc, .blf, .trc, .csv, .pcap, .pcapng, .db
    /// (python-can's SQLite).
    #[arg(short = 'l', long = "log", value_name = "FILE")]
    pub log: Option<PathBuf>,
    /// Write every frame to the configuration's `log_file` (JerryCAN's "write to the log
    /// file"), as -l FILE does (docs/config.md).
    #[arg(short = 'w', long = "write-log", conflicts_with = "log")]
    pub write_log: bool,
    /// The log's format whatever FILE's extension: candump, asc, blf, trc, trc11, csv, pcap,
    /// pcapng or sqlite.
    #[arg(long, value_name = "FORMAT", requires = "log")]
    pub to: Option<Format>,
    /// Print candump log lines (`(SEC.USEC) IFACE ID#DATA`) instead of the terminal layout,
    /// as candump -L.
    #[arg(short = 'L', long = "log-format")]
    pub log_format: bool,
    /// Prefix each line with a time, as candump -t: `a` absolute (the default when MODE is
    /// left out), `d` since the previous line, `z` since the first line, `A` absolute with
    /// the date (UTC).
    #[arg(short = 't', long = "timestamps", value_name = "MODE", num_args = 0..=1,
          default_missing_value = "a", value_parser = parse_mode)]
    pub timestamps: Option<Stamp>,
    /// Show the data as ASCII too, as candump -a.
    #[arg(short = 'a', long)]
    pub ascii: bool,
    /// Show the direction (RX/TX) after the interface, as candump -x (and R/T in the log).
    #[arg(short = 'x', long)]
    pub extra: bool,
    /// Colour each interface's lines, as candump -c.
    #[arg(short = 'c', long)]
    pub color: bool,
    /// Exit after this many frames (error frames do not count).
    #[arg(short = 'n', long, value_name = "COUNT")]
    pub count: Option<u64>,
    /// Name this client's node on a buslab bus (shown by `buslab status`).
    #[arg(long, value_name = "NAME")]
    pub name: Option<String>,
    /// Also show error frames: this node's bus errors, lost arbitrations and state changes,
    /// in words as candump -e (an interface's `#ERRORMASK` chooses classes).
    #[arg(short = 'e', long)]
    pub errors: bool,
}

/// `-t`'s modes: candump's, and `A` (absolute with the date).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stamp {
    Plain(TimestampMode),
    Date,
}

/// `a`, `d`, `z` or `A`.
fn parse_mode(text: &str) -> Result<Stamp, String> {
    match text {
        "a" => Ok(Stamp::Plain(TimestampMode::Absolute)),
        "d" => Ok(Stamp::Plain(TimestampMode::Delta)),
        "z" => Ok(Stamp::Plain(TimestampMode::Zero)),
        "A" => Ok(Stamp::Date),
        _ => Err(format!(
            "timestamp mode {text:?} must be a (absolute), d (delta) or z (from zero), or A (absolute with the date)"
        )),
    }
}

pub fn run(args: Args) -> anyhow::Result<()> {
    match dump(args) {
        Err(e)
            if e.downcast_ref::<io::Error>()
                .is_some_and(|e| e.kind() == io::ErrorKind::BrokenPipe) =>
        {
            Ok(())
        }
        other => other,
    }
}

/// One bus being dumped.
struct Source {
    url: BusUrl,
    filters: FilterSet,
    /// The name printed (right-aligned to the longest, as candump does with several).
    name: String,
}

fn sources(args: &Args) -> Vec<Source> {
    let mut specs = args.interfaces.clone();
    if let Some(url) = &args.bus {
        specs.push(BusSpec {
            url: url.clone(),
            filters: FilterSet::default(),
        });
    }
    if specs.is_empty() {
        specs.push(BusSpec {
            url: crate::config::get().bus.clone(),
            filters: FilterSet::default(),
        });
    }
    let width = specs.iter().map(|s| s.url.channel().len()).max();
    let several = specs.len() > 1;
    specs
        .into_iter()
        .map(|s| {
            let channel = s.url.channel();
            let name = match width {
                Some(w) if several => format!("{channel:>w$}"),
                _ => channel.to_string(),
            };
            Source {
                url: s.url,
                filters: s.filters,
                name,
            }
        })
        .collect()
}

fn dump(args: Args) -> anyhow::Result<()> {
    if args.log_format
        && matches!(
            args.timestamps,
            Some(Stamp::Plain(TimestampMode::Delta) | Stamp::Date)
        )
    {
        bail!(
            "-L writes absolute times or, with -t z, times from zero: -t d and -t A do not apply"
        );
    }
    let log_path = match (&args.log, args.write_log) {
        (Some(path), _) => Some(path.clone()),
        (None, true) => Some(crate::config::get().log_file.clone().context(
            "-w writes to the configuration's log_file, and none is set (docs/config.md)",
        )?),
        (None, false) => None,
    };
    let mut log = match &log_path {
        Some(path) => Some(Log::create(path, args.to, args.extra)?),
        None => None,
    };
    let sources = sources(&args);
    let mut buses = Vec::with_capacity(sources.len());
    for source in &sources {
        let mut bus = open(&source.url)?;
        set_name(&mut bus, &source.url, args.name.as_deref())?;
        if args.errors || source.filters.error_mask.is_some() {
            bus.set_error_frames(true)?;
        }
        buses.push(bus);
    }
    let stop = super::interrupted()?;
    let (tx, events) = mpsc::sync_channel(4096);
    let readers: Vec<_> = buses
        .into_iter()
        .enumerate()
        .map(|(index, bus)| {
            let tx = tx.clone();
            let stop = stop.clone();
            std::thread::spawn(move || read(bus, index, &tx, &stop))
        })
        .collect();
    drop(tx);
    for source in &sources {
        // Tests and scripts wait for this line (-v) before they send.
        tracing::info!(
            "dump: listening on {}{}",
            source.url,
            if args.errors || source.filters.error_mask.is_some() {
                " with error frames"
            } else {
                ""
            }
        );
    }
    let (timestamps, dated) = match args.timestamps {
        Some(Stamp::Plain(mode)) => (Some(mode), false),
        Some(Stamp::Date) => (None, true),
        None => (None, false),
    };
    let mut terminal = Terminal::new(View {
        timestamps,
        ascii: args.ascii,
        extra: args.extra,
        error_words: true,
    });
    let stdout = io::stdout();
    let mut out = stdout.lock();
    let mut seen = 0u64;
    let mut zero = None;
    let result = loop {
        if stop.load(Ordering::SeqCst) || args.count.is_some_and(|n| seen >= n) {
            break Ok(());
        }
        let (index, event) = match events.recv_timeout(Duration::from_millis(100)) {
            Ok((index, Ok(event))) => (index, event),
            Ok((_, Err(e))) => break Err(e),
            Err(mpsc::RecvTimeoutError::Timeout) => {
                if let Some(log) = &mut log {
                    log.idle()?;
                }
                continue;
            }
            Err(mpsc::RecvTimeoutError::Disconnected) => break Ok(()),
        };
        let source = &sources[index];
        let passes = match &event {
            BusEvent::Frame(m) => source.filters.passes(&m.frame),
            BusEvent::Error(e) => source
                .filters
                .passes_error(&e.error, if args.errors { u32::MAX } else { 0 }),
        };
        if !passes {
            continue;
        }
        if let BusEvent::Frame(_) = event {
            seen += 1;
        }
        let mut entry = Entry::from_event(&event);
        entry.interface.clone_from(&source.name);
        let line = if args.log_format {
            let mut shown = entry.clone();
            if timestamps == Some(TimestampMode::Zero) {
                let first = *zero.get_or_insert(entry.timestamp);
                shown.timestamp = entry.timestamp.saturating_sub(first);
            }
            format_line(&shown, args.extra)
        } else if dated {
            let line = terminal.line(&entry);
            format!(" ({}) {}", date(entry.timestamp), &line[1..])
        } else {
            terminal.line(&entry)
        };
        if args.color {
            writeln!(out, "\x1b[{}m{line}\x1b[0m", 31 + index % 6)?;
        } else {
            writeln!(out, "{line}")?;
        }
        out.flush()?;
        if let Some(log) = &mut log {
            log.write(&entry)?;
        }
    };
    stop.store(true, Ordering::SeqCst);
    drop(events);
    for r in readers {
        let _ = r.join();
    }
    // Finished on every way out (Ctrl-C, SIGTERM, SIGHUP, -n, an error): BLF's last container,
    // ASC's end line and SQLite's last rows are in the file.
    let finished = match log {
        Some(log) => log.finish(),
        None => Ok(()),
    };
    result.and(finished)
}

/// The `-l` log and when it reaches the file.
struct Log {
    writer: Box<dyn LogWriter + Send>,
    path: PathBuf,
    /// Flushed after every entry (a text line or a pcap record costs one write), or only when
    /// the bus is idle and at least once a second (a BLF flush closes a compressed container,
    /// an SQLite flush is a commit).
    every_entry: bool,
    unflushed: bool,
    last_flush: Instant,
}

impl Log {
    /// The most a BLF or SQLite log keeps in memory while the bus is busy.
    const FLUSH_INTERVAL: Duration = Duration::from_secs(1);

    fn create(path: &Path, to: Option<Format>, direction: bool) -> anyhow::Result<Self> {
        let format = match to {
            Some(format) => format,
            // candump's habit: `-l` names a candump log.
            None if path.extension().is_none() => Format::Candump,
            None => Format::from_path(path)?,
        };
        let writer = create_writer_with(path, format, WriteOptions { direction })?;
        Ok(Self {
            writer,
            path: path.to_owned(),
            every_entry: !matches!(format, Format::Blf | Format::Sqlite),
            unflushed: false,
            last_flush: Instant::now(),
        })
    }

    fn write(&mut self, entry: &Entry) -> anyhow::Result<()> {
        self.writer.write(entry).with_context(|| self.failed())?;
        self.unflushed = true;
        if self.every_entry || self.last_flush.elapsed() >= Self::FLUSH_INTERVAL {
            self.flush()?;
        }
        Ok(())
    }

    /// The bus has been quiet for a moment: what was logged goes to the file.
    fn idle(&mut self) -> anyhow::Result<()> {
        if self.unflushed {
            self.flush()?;
        }
        Ok(())
    }

    fn flush(&mut self) -> anyhow::Result<()> {
        self.writer.flush().with_context(|| self.failed())?;
        self.unflushed = false;
        self.last_flush = Instant::now();
        Ok(())
    }

    fn finish(self) -> anyhow::Result<()> {
        let failed = self.failed();
        let left_out = self.writer.left_out();
        self.writer.finish().context(failed)?;
        if left_out > 0 {
            tracing::warn!(
                "{}: {left_out} entries the format cannot hold were left out",
                self.path.display()
            );
        }
        Ok(())
    }

    fn failed(&self) -> String {
        format!("cannot write the log {}", self.path.display())
    }
}

/// Reads one bus until `stop`, handing every event to the printer.
fn read(
    mut bus: DynBus,
    index: usize,
    tx: &mpsc::SyncSender<(usize, anyhow::Result<BusEvent>)>,
    stop: &AtomicBool,
) {
    while !stop.load(Ordering::SeqCst) {
        // Short waits, so Ctrl-C is noticed.
        match bus.recv_event(Some(Duration::from_millis(100))) {
            Ok(Some(event)) => {
                if tx.send((index, Ok(event))).is_err() {
                    return;
                }
            }
            Ok(None) => {}
            Err(e) => {
                let _ = tx.send((index, Err(e.into())));
                return;
            }
        }
    }
}

/// `2026-11-23 23:05:33.123456` (UTC) for `-t A`.
fn date(t: Duration) -> String {
    let when = UNIX_EPOCH + t;
    let text = humantime::format_rfc3339_micros(when).to_string();
    // `2026-11-23T23:05:33.123456Z`
    text.trim_end_matches('Z').replacen('T', " ", 1)
}

#[cfg(test)]
mod tests {
    use super::*;
    use buslab_logs::Record;

    #[test]
    fn dates_look_like_candump_t_a() {
        assert_eq!(
            date(Duration::from_micros(1_700_000_000_123_456)),
            "2023-11-14 22:13:20.123456"
        );
    }

    #[test]
    fn the_log_format_knows_the_record() {
        let e = Entry {
            timestamp: Duration::from_secs(1),
            interface: "vcan0".into(),
            record: Record::Frame("123#11".parse().unwrap()),
            direction: None,
        };
        assert_eq!(format_line(&e, false), "(0000000001.000000) vcan0 123#11");
    }
}
