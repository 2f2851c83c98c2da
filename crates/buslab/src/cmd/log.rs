//! `buslab log convert|info|cat`: CAN log files in every format `buslab_logs` reads (candump,
//! ASC, BLF, TRC, CSV, pcap, pcapng, SQLite). With `--dbc FILE`, `cat` decodes the frames of
//! the database's messages and `convert` to CSV writes their signals as a table
//! ([`signals`]); `--message NAME` keeps the frames of named messages.

mod signals;

use std::io::{self, IsTerminal, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use anyhow::{Context, bail};
use buslab_logs::stats::LogStats;
use buslab_logs::{
    Format, LogBitRate, LogSource, LogWriter, Message, OpenOptions, ReadError, candump,
    create_writer, create_writer_atomic, open_source,
};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

use crate::dbc::{Decoder, Layout, Selection};
use crate::units::Human;

#[derive(clap::Args)]
pub struct Args {
    #[command(subcommand)]
    pub command: LogCommand,
}

#[derive(clap::Subcommand)]
pub enum LogCommand {
    /// Convert a log to another format (formats from the extensions, or --from/--to), e.g.
    /// `buslab log convert trace.log trace.blf`.
    Convert(ConvertArgs),
    /// What a log holds: entries, interfaces, IDs, time span, bus load.
    Info(InfoArgs),
    /// Print a log as candump log lines (`(SECONDS) IFACE FRAME`), decoded with --dbc.
    Cat(CatArgs),
}

/// The log to read and how.
#[derive(clap::Args)]
pub struct Input {
    /// The log file to read (a regular file).
    #[arg(value_name = "IN")]
    pub input: PathBuf,
    /// Its format when the extension does not tell: candump (.log), asc, blf, trc, csv, pcap,
    /// pcapng, sqlite (.db).
    #[arg(long, value_name = "FORMAT")]
    pub from: Option<Format>,
    /// Step over bad lines or records (each is reported; the count at the end) instead of
    /// stopping at the first one.
    #[arg(long)]
    pub skip_bad: bool,
}

#[derive(clap::Args)]
pub struct ConvertArgs {
    #[command(flatten)]
    pub input: Input,
    /// The file to write (replaced only when the conversion is done, unless --follow).
    #[arg(value_name = "OUT")]
    pub output: PathBuf,
    /// The output's format when the extension does not tell: candump, asc, blf, trc (2.1),
    /// trc11, trc21, csv, pcap, pcapng, sqlite.
    #[arg(long, value_name = "FORMAT")]
    pub to: Option<Format>,
    /// Keep reading IN as it grows (like `tail -F`, e.g. a `candump -l` log) until Ctrl-C,
    /// SIGTERM or SIGHUP; OUT is written in place and flushed whenever IN has nothing new and
    /// at least every second (-v logs each flush). When IN is truncated, rewritten or
    /// replaced (rotated), a warning says which and its new content is read from the start.
    #[arg(short, long)]
    pub follow: bool,
    // With --dbc and a CSV OUT: one row per frame of a message of the database (time, ID,
    // message, then a column per signal, `Message.Signal`); with another format, --dbc only
    // names the messages --message keeps.
    #[command(flatten)]
    pub dbc: Selection,
}

#[derive(clap::Args)]
pub struct InfoArgs {
    #[command(flatten)]
    pub input: Input,
    /// The bus's bit rate, for the load: by default the one the log gives (a TRC header's,
    /// or from the frame lengths ASC and BLF loggers record), else 500 kbit/s, said as an
    /// assumption.
    #[arg(long, value_name = "BIT/S", value_parser = clap::value_parser!(u32).range(1_000..=1_000_000))]
    pub bitrate: Option<u32>,
    /// Also draw the bus load over time, per interface, as an SVG figure.
    #[arg(long, value_name = "FILE.svg")]
    pub plot: Option<PathBuf>,
}

#[derive(clap::Args)]
pub struct CatArgs {
    #[command(flatten)]
    pub input: Input,
    /// Add the direction after each frame, ` R` or ` T`, when the log knows it (candump -x).
    #[arg(short = 'x', long)]
    pub direction: bool,
    /// Nine decimals (nanoseconds, as candump -N) instead of six.
    #[arg(short = 'N', long)]
    pub nanos: bool,
    #[command(flatten)]
    pub dbc: Selection,
    /// With --dbc: each decoded message on its frame's line (`LINE :: Name(Sig: 1.5 V, …)`, as
    /// `cantools decode --single-line`) instead of one signal per line below it.
    #[arg(long, requires = "dbc")]
    pub single_line: bool,
}

pub fn run(args: Args, quiet: bool) -> anyhow::Result<()> {
    let result = match args.command {
        LogCommand::Convert(a) => convert(a, quiet),
        LogCommand::Info(a) => info(a),
        LogCommand::Cat(a) => cat(a),
    };
    match result {
        // The reader of our output left (`| head`): not an error.
        Err(e) if is_broken_pipe(&e) => Ok(()),
        other => other,
    }
}

fn is_broken_pipe(e: &anyhow::Error) -> bool {
    e.downcast_ref::<io::Error>()
        .is_some_and(|e| e.kind() == io::ErrorKind::BrokenPipe)
}

/// The input's format: `--from`, else its extension.
pub(crate) fn input_format(input: &Input) -> anyhow::Result<Format> {
    Ok(match input.from {
        Some(f) => f,
        None => Format::from_path(&input.input)?,
    })
}

/// What reading a log came to.
#[derive(Default)]
pub(crate) struct Tally {
    entries: u64,
    bad: u64,
}

/// Reads every entry of `source` into `each` until the end, `stop` or an error. Bad records
/// are skipped with a warning when `skip_bad`; otherwise (and for fatal errors) the error is
/// returned, after `each` has seen everything before it.
pub(crate) fn read_all(
    source: &mut LogSource,
    skip_bad: bool,
    stop: &AtomicBool,
    tally: &mut Tally,
    mut each: impl FnMut(&Message) -> anyhow::Result<()>,
) -> Result<(), ReadFailure> {
    let mut entry = Message::default();
    while !stop.load(Ordering::Relaxed) {
        match source.reader.read_into(&mut entry) {
            Ok(true) => {
                tally.entries += 1;
                each(&entry).map_err(ReadFailure::Other)?;
            }
            Ok(false) => return Ok(()),
            Err(e) if skip_bad && !e.is_fatal() => {
                tally.bad += 1;
                tracing::warn!("skipped: {e}");
            }
            Err(e) => return Err(ReadFailure::Read(e)),
        }
    }
    Ok(())
}

pub(crate) enum ReadFailure {
    Read(ReadError),
    Other(anyhow::Error),
}

impl ReadFailure {
    pub(crate) fn into_error(self, tally: &Tally, kept: &str) -> anyhow::Error {
        match self {
            ReadFailure::Read(e) => {
                let hint = if e.is_fatal() {
                    String::new()
                } else {
                    " (--skip-bad steps over bad lines and records)".to_string()
                };
                let n = tally.entries;
                let entries = if n == 1 { "entry" } else { "entries" };
                anyhow::anyhow!("{e}{hint}; {kept} the {n} {entries} before it")
            }
            ReadFailure::Other(e) => e,
        }
    }
}

fn same_file(a: &Path, b: &Path) -> bool {
    match (a.canonicalize(), b.canonicalize()) {
        (Ok(a), Ok(b)) => a == b,
        _ => false,
    }
}

fn convert(args: ConvertArgs, quiet: bool) -> anyhow::Result<()> {
    let from = input_format(&args.input)?;
    let to = match args.to {
        Some(f) => f,
        None => Format::from_path(&args.output)?,
    };
    let (input, output) = (&args.input.input, &args.output);
    if same_file(input, output) {
        bail!("{} is both input and output", input.display());
    }
    let selected = args.dbc.resolve()?;
    let filter = selected.as_ref().and_then(|s| s.filter.clone());
    let signals = match selected {
        Some(s) if to == Format::Csv => Some(s),
        Some(_) if filter.is_none() => bail!(
            "--dbc writes decoded signals to a CSV file, and {} is {to}: name a .csv OUT (or \
             --to csv), or add --message NAME to keep some messages' frames in {to}",
            output.display()
        ),
        _ => None,
    };
    let stop = super::interrupted()?;
    super::file_size_limit_as_error()?;
    let writer: Box<dyn LogWriter + Send> = match &signals {
        Some(s) => Box::new(signals::SignalCsv::create(
            output,
            s.database.clone(),
            filter.as_ref(),
            args.follow,
        )?),
        None if args.follow => create_writer(output, to)?,
        None => create_writer_atomic(output, to)?,
    };
    // Shared with the follower, which flushes it whenever the input has nothing new.
    let writer: Arc<Mutex<Box<dyn LogWriter + Send>>> = Arc::new(Mutex::new(writer));
    // Entries written, and in the file (-v logs each flush, so a script knows what a kill
    // cannot take back).
    let written = Arc::new(AtomicU64::new(0));
    let flush = {
        let (writer, written, output) = (writer.clone(), written.clone(), output.clone());
        let reported = Arc::new(AtomicU64::new(0));
        move || {
            let n = written.load(Ordering::SeqCst);
            match lock(&writer).flush() {
                Ok(()) if reported.swap(n, Ordering::SeqCst) != n => {
                    tracing::info!("{}: {n} entries flushed", output.display());
                }
                Ok(()) => {}
                Err(e) => tracing::warn!("flushing {}: {e}", output.display()),
            }
        }
    };
    let mut options = OpenOptions::default();
    if args.follow {
        options.follow_until = Some(stop.clone());
        options.on_wait = Some(Arc::new(flush.clone()));
    }
    let mut source = open_source(input, from, &options)?;
    drop(options); // its hook holds the writer too
    let bar = progress(source.len, quiet || args.follow);
    let started = Instant::now();
    let mut tally = Tally::default();
    let bytes = source.bytes_read.clone();
    let mut last_flush = Instant::now();
    let mut other_messages = 0u64;
    let read = read_all(
        &mut source,
        args.input.skip_bad,
        &stop,
        &mut tally,
        |entry| {
            if filter.as_ref().is_some_and(|f| !f.passes(&entry.record)) {
                other_messages += 1;
                return Ok(());
            }
            lock(&writer)
                .write(entry)
                .with_context(|| format!("writing {}", output.display()))?;
            let n = written.fetch_add(1, Ordering::SeqCst) + 1;
            // A followed input that never pauses still reaches the output every second.
            if args.follow && last_flush.elapsed() >= FOLLOW_FLUSH {
                flush();
                last_flush = Instant::now();
            }
            // Every 16384th entry: cheaper than moving the bar each time.
            if n.is_multiple_of(16_384) && !bar.is_hidden() {
                bar.set_position(bytes.get());
                let rate = n as f64 / started.elapsed().as_secs_f64().max(1e-9);
                bar.set_message(format!("{rate:.0} frames/s"));
            }
            Ok(())
        },
    );
    drop(source); // the follower's hook holds the writer
    drop(flush); // and so does this
    bar.finish_and_clear();
    let writer = match Arc::try_unwrap(writer) {
        Ok(m) => m.into_inner().unwrap_or_else(|p| p.into_inner()),
        Err(_) => bail!("internal: the output is still shared"),
    };
    let left_out = writer.left_out();
    // Whatever happened, what was read is written (after a write error, what was flushed
    // stays, and the write error is the one reported).
    let finished = writer
        .finish()
        .with_context(|| format!("finishing {}", output.display()));
    let counted = count_line(&tally, entries_word(tally.entries, from));
    if let Err(failure) = read {
        return Err(failure.into_error(&tally, &format!("{} holds", output.display())));
    }
    finished?;
    if !quiet {
        let mut line = format!(
            "{} ({from}) → {} ({to}): {counted} in {}",
            input.display(),
            output.display(),
            Human(started.elapsed())
        );
        if other_messages > 0 {
            line.push_str(&format!(
                "; {other_messages} frames of other messages left out (--message)"
            ));
        }
        if left_out > 0 && signals.is_some() {
            line.push_str(&format!(
                "; {left_out} left out (error frames, remote frames and frames of messages \
                 the database does not have)"
            ));
        } else if left_out > 0 {
            line.push_str(&format!("; {left_out} left out ({to} cannot hold them)"));
        }
        if stop.load(Ordering::Relaxed) && !args.follow {
            line.push_str("; interrupted");
        }
        eprintln!("{line}");
    }
    Ok(())
}

/// How often a followed conversion flushes its output while the input keeps growing.
const FOLLOW_FLUSH: Duration = Duration::from_secs(1);

fn entries_word(n: u64, _format: Format) -> String {
    format!("{n} {}", if n == 1 { "entry" } else { "entries" })
}

fn count_line(tally: &Tally, entries: String) -> String {
    if tally.bad > 0 {
        format!("{entries}, {} bad skipped", tally.bad)
    } else {
        entries
    }
}

fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|p| p.into_inner())
}

/// A progress bar of bytes read and frames per second, on a terminal only.
fn progress(len: u64, hidden: bool) -> ProgressBar {
    if hidden || !io::stderr().is_terminal() || len == 0 {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::with_draw_target(Some(len), ProgressDrawTarget::stderr());
    bar.set_style(
        ProgressStyle::with_template("{bytes:>9}/{total_bytes} [{bar:20}] {percent:>3}% {msg}")
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    bar
}

fn info(args: InfoArgs) -> anyhow::Result<()> {
    if let Some(path) = &args.plot {
        super::plot::check_target(path)?;
    }
    let mut load = args.plot.as_ref().map(|_| super::plot::LoadWindows::new());
    let format = input_format(&args.input)?;
    let path = &args.input.input;
    let mut source = open_source(path, format, &OpenOptions::default())?;
    let stop = super::interrupted()?;
    let mut stats = LogStats::default();
    let mut tally = Tally::default();
    let read = read_all(&mut source, args.input.skip_bad, &stop, &mut tally, |e| {
        if let (Some(bits), Some(load)) = (stats.add(e), &mut load) {
            load.add(&e.channel, e.at, bits);
        }
        Ok(())
    });
    if let Err(failure) = read {
        return Err(failure.into_error(&tally, "counted"));
    }
    let mut out = io::stdout().lock();
    let size = std::fs::metadata(path).map(|m| m.len()).unwrap_or(0);
    writeln!(
        out,
        "file        {} ({format}, {size} bytes)",
        path.display()
    )?;
    writeln!(
        out,
        "entries     {} frames, {} error frames{}",
        stats.frames(),
        stats.errors(),
        if tally.bad > 0 {
            format!(", {} bad skipped", tally.bad)
        } else {
            String::new()
        }
    )?;
    if let Some((first, last)) = stats.first_last() {
        writeln!(
            out,
            "time        {} .. {} ({})",
            first,
            last,
            Human(last.saturating_since(first))
        )?;
    }
    let mut rates = Vec::new();
    for (name, s) in &stats.interfaces {
        let rate = BitRate::choose(args.bitrate, source.reader.bit_rate(name));
        rates.push(rate.bits_per_s());
        let load = match s.load_percent(rate.bits_per_s()) {
            Some(percent) => rate.load_text(percent),
            None => "n/a (one instant)".to_string(),
        };
        let top: Vec<String> = s
            .busiest(5)
            .into_iter()
            .map(|(ext, id, n)| {
                if ext {
                    format!("{id:08X} ({n})")
                } else {
                    format!("{id:03X} ({n})")
                }
            })
            .collect();
        writeln!(
            out,
            "{name:<11} {} frames ({} extended, {} remote{}), {} error frames, {}{} IDs, load {load}",
            s.frames,
            s.extended,
            s.remote,
            if s.fd > 0 {
                // The load counts classic frames: an FD frame's time needs its data bit rate.
                format!(", {} CAN FD, not in the load", s.fd)
            } else {
                String::new()
            },
            s.errors,
            if s.ids_overflow { "more than " } else { "" },
            s.ids()
        )?;
        if !top.is_empty() {
            writeln!(out, "{:<11} busiest: {}", "", top.join(", "))?;
        }
    }
    if let (Some(load), Some(plot)) = (load, &args.plot) {
        // One rate for the figure: the interfaces' own when they agree.
        rates.dedup();
        let bitrate = match rates[..] {
            [one] => one,
            _ => args.bitrate.unwrap_or(ASSUMED_BITRATE),
        };
        let title = format!("{}: bus load at {}", path.display(), kbit(bitrate));
        super::plot::write(&load.figure(title, bitrate), plot)?;
    }
    Ok(())
}

/// The bit rate `log info` assumes when neither the log nor `--bitrate` gives one.
const ASSUMED_BITRATE: u32 = 500_000;

/// The bit rate an interface's load is computed at, and why that one.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum BitRate {
    /// `--bitrate`, and what the log says if it says something else.
    Given { given: u32, log: Option<LogBitRate> },
    /// The log's own.
    Log(LogBitRate),
    /// Neither: [`ASSUMED_BITRATE`].
    Assumed,
}

impl BitRate {
    fn choose(given: Option<u32>, log: Option<LogBitRate>) -> Self {
        match (given, log) {
            (Some(given), log) => BitRate::Given { given, log },
            (None, Some(log)) => BitRate::Log(log),
            (None, None) => BitRate::Assumed,
        }
    }

    fn bits_per_s(self) -> u32 {
        match self {
            BitRate::Given { given, .. } => given,
            BitRate::Log(log) => log.bits_per_s,
            BitRate::Assumed => ASSUMED_BITRATE,
        }
    }

    /// `17.1 % at 125 kbit/s (the log's header)`, or the assumption said as one.
    fn load_text(self, percent: f64) -> String {
        let at = kbit(self.bits_per_s());
        match self {
            BitRate::Given { log: Some(log), .. } if log.bits_per_s != self.bits_per_s() => {
                format!(
                    "{percent:.1} % at {at} (--bitrate; {} says {})",
                    log.source,
                    kbit(log.bits_per_s)
                )
            }
            BitRate::Given { .. } => format!("{percent:.1} % at {at} (--bitrate)"),
            BitRate::Log(log) => format!("{percent:.1} % at {at} ({})", log.source),
            BitRate::Assumed => format!(
                "{percent:.1} % if the bus ran at {at} (the log does not give its bit rate: \
                 --bitrate N says it)"
            ),
        }
    }
}

/// `125 kbit/s`, `83.333 kbit/s`, `1000 kbit/s`.
fn kbit(bits_per_s: u32) -> String {
    format!("{} kbit/s", f64::from(bits_per_s) / 1000.0)
}

fn cat(args: CatArgs) -> anyhow::Result<()> {
    let selected = args.dbc.resolve()?;
    let format = input_format(&args.input)?;
    let mut source = open_source(&args.input.input, format, &OpenOptions::default())?;
    let stop = super::interrupted()?;
    let stdout = io::stdout();
    let mut out = io::BufWriter::with_capacity(64 * 1024, stdout.lock());
    let mut line = Vec::with_capacity(128);
    let mut tally = Tally::default();
    let layout = if args.single_line {
        Layout::SingleLine
    } else {
        Layout::MultiLine
    };
    let filter = selected.as_ref().and_then(|s| s.filter.clone());
    let mut decoder = selected.map(|s| Decoder::new(s.database, layout));
    let read = read_all(&mut source, args.input.skip_bad, &stop, &mut tally, |e| {
        if filter.as_ref().is_some_and(|f| !f.passes(&e.record)) {
            return Ok(());
        }
        line.clear();
        candump::write_line(&mut line, e, args.direction, args.nanos);
        if let Some(decoder) = &mut decoder {
            decoder.append(&mut line, &e.record);
        }
        line.push(b'\n');
        out.write_all(&line)?;
        Ok(())
    });
    out.flush()?;
    if let Err(failure) = read {
        return Err(failure.into_error(&tally, "printed"));
    }
    Ok(())
}
