//! `buslab dump [IFACE[,FILTER…]]…`: print every frame on one or more buses like candump;
//! `-l FILE` also writes a log in any format `buslab_logs` writes, `-L` prints candump log
//! lines instead; interface arguments and filters are `buslab_backends::BusSpec`, `any` every
//! bus this machine names.
//!
//! With `--dbc FILE` each frame of a message of the database is followed by its decoded signals
//! (`cantools decode`'s layout, or `--single-line`), and `--message NAME` keeps the frames of
//! named messages only.
//!
//! Nothing is printed before it is in the log: frames are taken in batches (what is waiting,
//! and for BLF and SQLite what comes within [`Log::LINGER`]), written, flushed (a BLF
//! container and header, an SQLite commit), and only then printed. A `kill -9` at any moment
//! leaves a log that holds every frame printed.

use std::io::{self, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc;
use std::time::{Duration, Instant, UNIX_EPOCH};

use anyhow::{Context, bail};
use buslab_backends::{BusSpec, BusUrl, DynBus, FilterSet, resolve};
use buslab_canbus::{Record, Timestamp};
use buslab_logs::candump::{self, Terminal, TimestampMode, View};
use buslab_logs::text;
use buslab_logs::{Format, LogWriter, Message, WriteOptions, create_writer_with};

use super::busopt::{open, set_name};
use crate::dbc::{Decoder, Layout, MessageFilter, Selected};

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
    /// Log to FILE as -l FILE does (newer candump's -f); `-f -` prints log lines on stdout,
    /// as -L.
    #[arg(short = 'f', value_name = "FILE", conflicts_with_all = ["log", "write_log"])]
    pub log_file: Option<PathBuf>,
    /// End after this long without a frame, as candump -T MSECS: a duration (500ms, 2s); a
    /// bare number is taken as milliseconds, as candump does, with a warning.
    #[arg(short = 'T', long = "idle-timeout", value_name = "DURATION", value_parser = parse_idle)]
    pub idle_timeout: Option<Idle>,
    /// Report frames lost before they reached this dump, as candump -d (`DROPCOUNT: …`
    /// lines): a buslab bus counts them per node (its chip's receive FIFO overruns, and the
    /// frames the server dropped because this client did not keep up).
    #[arg(short = 'd', long = "drops")]
    pub drops: bool,
    /// Keep going when a bus goes away (its server stops, its adapter is unplugged): warn
    /// and reopen it every second, as candump -D keeps reading an interface that went down.
    #[arg(short = 'D', long = "keep-going")]
    pub keep_going: bool,
    /// As candump -s: 0 prints every frame (the default, also with -l), 1 turns a spinner
    /// instead, 2 prints nothing.
    #[arg(short = 's', long = "silent", value_name = "LEVEL",
          value_parser = clap::value_parser!(u8).range(0..=2))]
    pub silent: Option<u8>,
    #[command(flatten)]
    pub dbc: crate::dbc::Selection,
    /// With --dbc: each decoded message on its frame's line (`LINE :: Name(Sig: 1.5 V, …)`, as
    /// `cantools decode --single-line`) instead of one signal per line below it.
    #[arg(long, requires = "dbc")]
    pub single_line: bool,
    /// candump -H (hardware timestamps): refused, with the reason.
    #[arg(short = 'H', hide = true)]
    pub hardware_timestamps: bool,
    /// candump -u USECS (its old bridge mode's delay): refused, with the reason.
    #[arg(short = 'u', hide = true, value_name = "USECS")]
    pub bridge_delay: Option<String>,
    /// candump -r SIZE (the socket's receive buffer): refused, with the reason.
    #[arg(short = 'r', hide = true, value_name = "SIZE")]
    pub receive_buffer: Option<String>,
}

/// `-T`: how long without a frame, and whether it was written as candump's bare milliseconds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Idle {
    pub after: Duration,
    pub bare: bool,
}

/// A duration, or a bare number of milliseconds (candump's unit).
fn parse_idle(text: &str) -> Result<Idle, String> {
    if !text.is_empty() && text.bytes().all(|b| b.is_ascii_digit()) {
        let ms: u64 = text
            .parse()
            .map_err(|_| format!("-T {text:?}: too many milliseconds"))?;
        return Ok(Idle {
            after: Duration::from_millis(ms),
            bare: true,
        });
    }
    crate::units::duration(text).map(|after| Idle { after, bare: false })
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
    let args = candump_habits(args)?;
    dump(args)
}

/// candump's options that mean something else here, or nothing: taken as what they mean, or
/// refused saying why.
fn candump_habits(mut args: Args) -> anyhow::Result<Args> {
    if args.hardware_timestamps {
        bail!(
            "-H (candump: read the interface's hardware timestamps) does not apply: the times \
             buslab prints come from the bus side where there is one (a buslab or socketcand \
             server stamps each frame; an SLCAN adapter's millisecond counter refines the \
             host's time), and its SocketCAN backend reads the kernel's receive times only"
        );
    }
    if let Some(usecs) = &args.bridge_delay {
        bail!(
            "-u {usecs} (candump: the delay of its old bridge mode -b/-B) has nothing to delay \
             here: buslab copies frames between buses with `buslab bridge A B`"
        );
    }
    if let Some(size) = &args.receive_buffer {
        bail!(
            "-r {size} (candump: a SocketCAN socket's kernel receive buffer) does not apply: \
             buslab's backends read into their own queue, and dump holds up to {QUEUE} frames \
             between the buses and the printer without dropping any (a slow terminal slows \
             the reading; what the bus side drops meanwhile, -d reports)"
        );
    }
    if let Some(idle) = args.idle_timeout
        && idle.bare
    {
        tracing::warn!(
            "-T {} taken as milliseconds, as candump does: write -T {}ms",
            idle.after.as_millis(),
            idle.after.as_millis()
        );
    }
    if let Some(file) = args.log_file.take() {
        if file.as_os_str() == "-" {
            // candump: `-f -` is -L.
            args.log_format = true;
        } else {
            args.log = Some(file);
        }
    }
    Ok(args)
}

/// Events waiting between the bus readers and the printer.
const QUEUE: usize = 4096;
/// The most entries printed at once (a bound on the batch held while the log is flushed).
const BATCH: usize = 4096;
/// How long the printer waits for an event before it looks at Ctrl-C, -T and the log.
const TICK: Duration = Duration::from_millis(100);
/// How often a lost bus is tried again (-D) and drop counts are asked for (-d).
const RETRY: Duration = Duration::from_secs(1);

/// The name `any` takes, as candump's.
const ANY: &str = "any";

/// One bus being dumped.
struct Source {
    url: BusUrl,
    filters: FilterSet,
    /// The name printed (right-aligned to the longest, as candump does with several).
    name: String,
    /// Found by `any`: left out with a warning if it cannot be opened.
    optional: bool,
}

/// `any`: every bus this machine names — the configuration's bus (vcan0, buslab's bus, unless
/// configured otherwise) and every SocketCAN interface the kernel lists. SLCAN adapters are
/// not probed (opening a serial device that is something else could disturb it): name them.
fn any_buses() -> Vec<BusUrl> {
    let mut urls = vec![crate::config::get().bus.clone()];
    let mut kernel: Vec<String> = std::fs::read_dir("/sys/class/net")
        .map(|dir| {
            dir.filter_map(Result::ok)
                .filter(|e| {
                    // ARPHRD_CAN
                    std::fs::read_to_string(e.path().join("type")).is_ok_and(|t| t.trim() == "280")
                })
                .filter_map(|e| e.file_name().into_string().ok())
                .collect()
        })
        .unwrap_or_default();
    kernel.sort();
    for name in kernel {
        let url = BusUrl::SocketCan { interface: name };
        if !urls.contains(&url) {
            urls.push(url);
        }
    }
    urls
}

fn is_any(url: &BusUrl) -> bool {
    matches!(url, BusUrl::SocketCan { interface } if interface == ANY)
}

fn sources(args: &Args) -> Vec<Source> {
    let mut specs: Vec<(BusSpec, bool)> = Vec::new();
    for spec in &args.interfaces {
        if is_any(&spec.url) {
            for url in any_buses() {
                specs.push((
                    BusSpec {
                        url,
                        filters: spec.filters.clone(),
                    },
                    true,
                ));
            }
        } else {
            specs.push((spec.clone(), false));
        }
    }
    if let Some(url) = &args.bus {
        specs.push((
            BusSpec {
                url: url.clone(),
                filters: FilterSet::default(),
            },
            false,
        ));
    }
    if specs.is_empty() {
        specs.push((
            BusSpec {
                url: crate::config::get().bus.clone(),
                filters: FilterSet::default(),
            },
            false,
        ));
    }
    let width = specs.iter().map(|(s, _)| s.url.channel().len()).max();
    let several = specs.len() > 1;
    specs
        .into_iter()
        .map(|(s, optional)| {
            let channel = s.url.channel();
            let name = match width {
                Some(w) if several => format!("{channel:>w$}"),
                _ => channel.to_string(),
            };
            Source {
                url: s.url,
                filters: s.filters,
                name,
                optional,
            }
        })
        .collect()
}

/// Opens a source's bus as dump uses it: named, with error frames if asked for.
fn open_source(source: &Source, args: &Args) -> anyhow::Result<DynBus> {
    let mut bus = open(&source.url)?;
    set_name(&mut bus, &source.url, args.name.as_deref())?;
    if args.errors || source.filters.error_mask.is_some() {
        bus.set_error_frames(true)?;
    }
    if args.drops && bus.admin().is_none() {
        bail!(
            "{}: -d needs a bus that counts the frames it lost for this client, and this one \
             keeps no count (a buslab bus does; a plain socketcand, a SocketCAN interface as \
             buslab's backend reads it, and an SLCAN adapter report none)",
            source.url
        );
    }
    Ok(bus)
}

/// What a bus reader hands the printer.
enum Item {
    Event(usize, Message),
    /// Frames the bus lost for this client since the last report (-d), and the total.
    Dropped {
        index: usize,
        frames: u64,
        total: u64,
    },
    /// The bus failed (without -D: the end).
    Failed(usize, anyhow::Error),
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
    // The database first: a bad one or an unknown --message ends the dump before any file or
    // bus is touched.
    let selected = args.dbc.resolve()?;
    let mut log = match &log_path {
        Some(path) => Some(Log::create(path, args.to, args.extra)?),
        None => None,
    };
    let mut sources = sources(&args);
    let mut buses = Vec::with_capacity(sources.len());
    let mut skipped = Vec::new();
    sources.retain(|source| match open_source(source, &args) {
        Ok(bus) => {
            buses.push(Ok(bus));
            true
        }
        Err(e) if source.optional => {
            tracing::warn!("{ANY}: leaving out {}: {e:#}", source.url);
            skipped.push(format!("{}: {e:#}", source.url));
            false
        }
        Err(e) => {
            buses.push(Err(e));
            true
        }
    });
    let buses = buses.into_iter().collect::<anyhow::Result<Vec<_>>>()?;
    if buses.is_empty() {
        bail!(
            "{ANY}: no bus to dump on this machine (the configuration's bus and the kernel's \
             CAN interfaces were tried: {})",
            skipped.join("; ")
        );
    }
    let stop = super::interrupted()?;
    let (tx, events) = mpsc::sync_channel(QUEUE);
    let readers: Vec<_> = buses
        .into_iter()
        .enumerate()
        .map(|(index, bus)| {
            let reader = Reader {
                index,
                url: sources[index].url.clone(),
                name: args.name.clone(),
                error_frames: args.errors || sources[index].filters.error_mask.is_some(),
                drops: args.drops,
                keep_going: args.keep_going,
                tx: tx.clone(),
                stop: stop.clone(),
            };
            std::thread::spawn(move || reader.run(bus))
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
    let mut printer = Printer::new(&args, &sources, selected);
    let linger = log.as_ref().map_or(Duration::ZERO, |l| l.linger);
    let idle = args.idle_timeout.map(|i| i.after);
    let mut last_heard = Instant::now();
    let stdout = io::stdout();
    let mut out = io::BufWriter::with_capacity(64 * 1024, stdout.lock());
    let result: anyhow::Result<()> = loop {
        if stop.load(Ordering::SeqCst) || printer.done() {
            break Ok(());
        }
        // The first event of a batch.
        let wait = idle.map_or(TICK, |i| {
            i.saturating_sub(last_heard.elapsed())
                .min(TICK)
                .max(Duration::from_millis(1))
        });
        let first = match events.recv_timeout(wait) {
            Ok(item) => item,
            Err(mpsc::RecvTimeoutError::Timeout) => {
                if idle.is_some_and(|i| last_heard.elapsed() >= i) {
                    // candump -T: the end, not an error.
                    break Ok(());
                }
                continue;
            }
            Err(mpsc::RecvTimeoutError::Disconnected) => break Ok(()),
        };
        // Then what is waiting, and (BLF, SQLite) what comes within the linger.
        let until = Instant::now() + linger;
        let mut item = Some(first);
        // A bus or log that failed: what came before it is still logged and printed.
        let mut failed = None;
        while let Some(next) = item.take() {
            match printer.take(next, log.as_mut()) {
                Ok(heard) => {
                    if heard {
                        last_heard = Instant::now();
                    }
                }
                Err(e) => {
                    failed = Some(e);
                    break;
                }
            }
            if printer.pending() >= BATCH || printer.done() || stop.load(Ordering::SeqCst) {
                break;
            }
            item = if linger.is_zero() {
                events.try_recv().ok()
            } else {
                events
                    .recv_timeout(until.saturating_duration_since(Instant::now()))
                    .ok()
            };
        }
        // The log first: nothing is printed that is not in the file.
        let flushed = log.as_mut().map_or(Ok(()), Log::flush);
        let printed = match flushed {
            Ok(()) => printer.print(&mut out),
            Err(e) => break Err(failed.unwrap_or(e)),
        };
        if let Some(e) = failed {
            break Err(e);
        }
        match printed {
            Ok(()) => {}
            // The reader of our output left (`| head`): the end, not an error.
            Err(e) if e.kind() == io::ErrorKind::BrokenPipe => break Ok(()),
            Err(e) => break Err(anyhow::Error::new(e).context("cannot print")),
        }
    };
    stop.store(true, Ordering::SeqCst);
    drop(events);
    for r in readers {
        let _ = r.join();
    }
    // Finished on every way out (Ctrl-C, SIGTERM, SIGHUP, -n, -T, a closed stdout, an error):
    // BLF's last container and header, ASC's end line and SQLite's last rows are in the file.
    // After a write error the log is left as its last flush made it.
    let finished = match log {
        Some(log) => log.finish(),
        None => Ok(()),
    };
    result.and(finished)
}

/// Turns events into output lines, held until the log has them: their text is gathered in
/// one buffer (nothing allocated per line once it has grown) and written at once.
struct Printer<'a> {
    args: &'a Args,
    sources: &'a [Source],
    terminal: Terminal,
    timestamps: Option<TimestampMode>,
    dated: bool,
    zero: Option<Timestamp>,
    seen: u64,
    /// The text to print once the log is flushed, and how many lines (or spinner turns).
    held: Vec<u8>,
    lines: usize,
    /// A terminal line before the date goes in front of it (`-t A`).
    scratch: Vec<u8>,
    spin: usize,
    /// `--message`: the frames kept.
    messages: Option<MessageFilter>,
    /// `--dbc`: the decoded message after each frame's line.
    decoder: Option<Decoder>,
}

impl<'a> Printer<'a> {
    fn new(args: &'a Args, sources: &'a [Source], selected: Option<Selected>) -> Self {
        let (timestamps, dated) = match args.timestamps {
            Some(Stamp::Plain(mode)) => (Some(mode), false),
            Some(Stamp::Date) => (None, true),
            None => (None, false),
        };
        Self {
            args,
            sources,
            terminal: Terminal::new(View {
                timestamps,
                ascii: args.ascii,
                extra: args.extra,
                error_words: true,
            }),
            timestamps,
            dated,
            zero: None,
            seen: 0,
            held: Vec::with_capacity(64 * 1024),
            lines: 0,
            scratch: Vec::new(),
            spin: 0,
            messages: selected.as_ref().and_then(|s| s.filter.clone()),
            decoder: selected.map(|s| {
                let layout = if args.single_line {
                    Layout::SingleLine
                } else {
                    Layout::MultiLine
                };
                Decoder::new(s.database, layout)
            }),
        }
    }

    /// `-n` frames were taken.
    fn done(&self) -> bool {
        self.args.count.is_some_and(|n| self.seen >= n)
    }

    fn pending(&self) -> usize {
        self.lines
    }

    /// Takes one item: an entry goes to the log and its line is held. `Ok(true)` when
    /// something was received (for -T).
    fn take(&mut self, item: Item, log: Option<&mut Log>) -> anyhow::Result<bool> {
        let (index, event) = match item {
            Item::Event(index, event) => (index, event),
            Item::Dropped {
                index,
                frames,
                total,
            } => {
                // candump -d's line (not in the log: no format has a record for it).
                if self.args.silent != Some(2) {
                    let name = self.sources[index].name.trim_start();
                    let s = if frames > 1 { "s" } else { "" };
                    writeln!(
                        self.held,
                        "DROPCOUNT: dropped {frames} CAN frame{s} on '{name}' (total drops {total})"
                    )?;
                    self.lines += 1;
                }
                return Ok(false);
            }
            Item::Failed(index, e) => {
                return Err(e.context(format!("{}", self.sources[index].url)));
            }
        };
        let source = &self.sources[index];
        let passes = match &event.record {
            Record::Frame(frame) => source.filters.passes(frame),
            Record::Fd(frame) => source.filters.passes_fd(frame),
            Record::Error(error) => source
                .filters
                .passes_error(error, if self.args.errors { u32::MAX } else { 0 }),
        };
        if !passes
            || self
                .messages
                .as_ref()
                .is_some_and(|m| !m.passes(&event.record))
        {
            return Ok(false);
        }
        if let Record::Frame(_) | Record::Fd(_) = event.record {
            self.seen += 1;
        }
        let mut entry = event;
        entry.channel.clone_from(&source.name);
        if let Some(log) = log {
            log.write(&entry)?;
        }
        match self.args.silent {
            Some(2) => {}
            Some(1) => {
                const SPINNER: [u8; 4] = [b'|', b'/', b'-', b'\\'];
                self.held.push(SPINNER[self.spin % SPINNER.len()]);
                self.held.push(0x08);
                self.spin += 1;
                self.lines += 1;
            }
            _ => {
                if self.args.color {
                    self.held.extend_from_slice(b"\x1b[");
                    text::push_u64(&mut self.held, (31 + index % 6) as u64);
                    self.held.push(b'm');
                }
                self.line(&mut entry);
                if let Some(decoder) = &mut self.decoder {
                    decoder.append(&mut self.held, &entry.record);
                }
                if self.args.color {
                    self.held.extend_from_slice(b"\x1b[0m");
                }
                self.held.push(b'\n');
                self.lines += 1;
            }
        }
        Ok(true)
    }

    /// Appends `entry`'s line (the log has it already: `-t z` shifts its time for `-L`).
    fn line(&mut self, entry: &mut Message) {
        if self.args.log_format {
            if self.timestamps == Some(TimestampMode::Zero) {
                let first = *self.zero.get_or_insert(entry.at);
                entry.at = Timestamp::since_epoch(entry.at.saturating_since(first));
            }
            candump::write_line(&mut self.held, entry, self.args.extra, false);
        } else if self.dated {
            self.scratch.clear();
            self.terminal.write_line(&mut self.scratch, entry);
            self.held.extend_from_slice(b" (");
            self.held.extend_from_slice(date(entry.at).as_bytes());
            self.held.extend_from_slice(b") ");
            self.held.extend_from_slice(&self.scratch[1..]);
        } else {
            self.terminal.write_line(&mut self.held, entry);
        }
    }

    /// Prints the held lines.
    fn print(&mut self, out: &mut impl Write) -> io::Result<()> {
        let written = out.write_all(&self.held);
        self.held.clear();
        self.lines = 0;
        written?;
        out.flush()
    }
}

/// The `-l` log: written entry by entry, flushed once per batch before the batch is printed.
struct Log {
    writer: Option<Box<dyn LogWriter + Send>>,
    path: PathBuf,
    /// How long a batch may wait for more entries: a BLF flush closes a compressed container
    /// and rewrites the header, an SQLite flush commits (with its syncs), so these gather a
    /// tenth of a second; the other formats flush whatever is waiting at once.
    linger: Duration,
    /// Entries written, and entries in the file (flushed, so printed or about to be).
    written: u64,
    flushed: u64,
}

impl Log {
    /// How long a BLF or SQLite log gathers a batch (the most its lines are late).
    const LINGER: Duration = Duration::from_millis(100);

    fn create(path: &Path, to: Option<Format>, direction: bool) -> anyhow::Result<Self> {
        let format = match to {
            Some(format) => format,
            // candump's habit: `-l` names a candump log.
            None if path.extension().is_none() => Format::Candump,
            None => Format::from_path(path)?,
        };
        // A file-size limit (ulimit -f) makes writes fail with EFBIG, reported as any full
        // disk, instead of killing the process with SIGXFSZ and its log unfinished.
        super::file_size_limit_as_error()?;
        let writer = create_writer_with(path, format, WriteOptions { direction })?;
        Ok(Self {
            writer: Some(writer),
            path: path.to_owned(),
            linger: if matches!(format, Format::Blf | Format::Sqlite) {
                Self::LINGER
            } else {
                Duration::ZERO
            },
            written: 0,
            flushed: 0,
        })
    }

    fn writer(&mut self) -> anyhow::Result<&mut (dyn LogWriter + Send)> {
        match &mut self.writer {
            Some(w) => Ok(w.as_mut()),
            None => bail!("the log {} failed earlier", self.path.display()),
        }
    }

    fn write(&mut self, entry: &Message) -> anyhow::Result<()> {
        let result = self.writer()?.write(entry);
        self.check(result)?;
        self.written += 1;
        Ok(())
    }

    fn flush(&mut self) -> anyhow::Result<()> {
        if self.flushed == self.written {
            return Ok(());
        }
        let result = self.writer()?.flush();
        self.check(result)?;
        self.flushed = self.written;
        Ok(())
    }

    /// A write error (a full disk, a file-size limit): the log stays as its last flush left
    /// it, which the message says.
    fn check(&mut self, result: io::Result<()>) -> anyhow::Result<()> {
        result.with_context(|| {
            let n = self.flushed;
            format!(
                "cannot write the log {}; it keeps the {n} {} written before (every one printed)",
                self.path.display(),
                if n == 1 { "entry" } else { "entries" },
            )
        })
    }

    fn finish(mut self) -> anyhow::Result<()> {
        let Some(writer) = self.writer.take() else {
            return Ok(());
        };
        let failed = format!("cannot finish the log {}", self.path.display());
        let left_out = writer.left_out();
        writer.finish().context(failed)?;
        if left_out > 0 {
            tracing::warn!(
                "{}: {left_out} entries the format cannot hold were left out",
                self.path.display()
            );
        }
        Ok(())
    }
}

/// Reads one bus until `stop`, handing every event to the printer; with -d also the drops the
/// bus counts for this client, with -D it reopens a bus that went away.
struct Reader {
    index: usize,
    url: BusUrl,
    name: Option<String>,
    error_frames: bool,
    drops: bool,
    keep_going: bool,
    tx: mpsc::SyncSender<Item>,
    stop: std::sync::Arc<AtomicBool>,
}

impl Reader {
    fn run(self, mut bus: DynBus) {
        let mut drops = Drops::default();
        loop {
            let err = match self.read(&mut bus, &mut drops) {
                Ok(()) => return,
                Err(e) => e,
            };
            if !self.keep_going {
                let _ = self.tx.send(Item::Failed(self.index, err));
                return;
            }
            tracing::warn!(
                "{}: {err:#}; -D: trying it again every {}",
                self.url,
                crate::units::Human(RETRY)
            );
            match self.reopen() {
                Some(b) => {
                    tracing::warn!("{}: back", self.url);
                    bus = b;
                    // A new node: its counters start again.
                    drops = Drops::default();
                }
                None => return,
            }
        }
    }

    /// Until `stop` (`Ok`) or the bus fails.
    fn read(&self, bus: &mut DynBus, drops: &mut Drops) -> anyhow::Result<()> {
        while !self.stop.load(Ordering::SeqCst) {
            if self.drops && drops.due() {
                let status = match bus.admin() {
                    Some(admin) => admin.node_status(None)?,
                    None => bail!("{}: no drop counts", self.url),
                };
                let total = status.counters.overruns + status.counters.rx_lost;
                if let Some(frames) = drops.update(total)
                    && self
                        .tx
                        .send(Item::Dropped {
                            index: self.index,
                            frames,
                            total,
                        })
                        .is_err()
                {
                    return Ok(());
                }
            }
            // Short waits, so Ctrl-C is noticed.
            if let Some(event) = bus.recv_event(Some(TICK))?
                && self.tx.send(Item::Event(self.index, event)).is_err()
            {
                return Ok(());
            }
        }
        Ok(())
    }

    /// Opens the bus again, every [`RETRY`], until it opens or `stop`.
    fn reopen(&self) -> Option<DynBus> {
        while !self.stop.load(Ordering::SeqCst) {
            let deadline = Instant::now() + RETRY;
            while Instant::now() < deadline {
                if self.stop.load(Ordering::SeqCst) {
                    return None;
                }
                std::thread::sleep(TICK);
            }
            let opened = open(&self.url).and_then(|mut bus| {
                set_name(&mut bus, &self.url, self.name.as_deref())?;
                if self.error_frames {
                    bus.set_error_frames(true)?;
                }
                Ok(bus)
            });
            match opened {
                Ok(bus) => return Some(bus),
                Err(e) => tracing::debug!("{}: still away: {e:#}", self.url),
            }
        }
        None
    }
}

/// The frames a bus lost for this client (-d), asked for every [`RETRY`].
#[derive(Default)]
struct Drops {
    last_total: Option<u64>,
    asked: Option<Instant>,
}

impl Drops {
    fn due(&self) -> bool {
        self.asked.is_none_or(|t| t.elapsed() >= RETRY)
    }

    /// The new total: the frames lost since the last report, if any.
    fn update(&mut self, total: u64) -> Option<u64> {
        self.asked = Some(Instant::now());
        let last = self.last_total.replace(total).unwrap_or(0);
        (total > last).then(|| total - last)
    }
}

/// `2026-11-23 23:05:33.123456` (UTC) for `-t A`.
fn date(t: Timestamp) -> String {
    let when = UNIX_EPOCH + t.since_epoch_duration();
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
            date(Timestamp::from_micros(1_700_000_000_123_456)),
            "2023-11-14 22:13:20.123456"
        );
    }

    #[test]
    fn t_takes_a_duration_or_candumps_bare_milliseconds() {
        let bare = parse_idle("300").unwrap();
        assert_eq!((bare.after, bare.bare), (Duration::from_millis(300), true));
        let unit = parse_idle("2s").unwrap();
        assert_eq!((unit.after, unit.bare), (Duration::from_secs(2), false));
        assert!(parse_idle("soon").unwrap_err().contains("\"soon\""));
    }

    #[test]
    fn drops_are_reported_once_each_as_candump_d() {
        let mut d = Drops::default();
        assert!(d.due());
        assert_eq!(d.update(0), None);
        assert!(!d.due(), "asked again only after RETRY");
        assert_eq!(d.update(5), Some(5));
        assert_eq!(d.update(5), None);
        assert_eq!(d.update(12), Some(7));
    }

    #[test]
    fn the_log_format_knows_the_record() {
        let e = Message {
            at: Timestamp::from_secs(1),
            channel: "vcan0".into(),
            record: Record::Frame("123#11".parse().unwrap()),
            direction: None,
        };
        assert_eq!(
            candump::format_line(&e, false),
            "(0000000001.000000) vcan0 123#11"
        );
    }
}
