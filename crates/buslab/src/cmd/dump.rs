//! `buslab dump`: print every frame on a bus like candump; `-l FILE` also writes a candump log.
//! The formats are `buslab_logs::candump`'s.

use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use anyhow::Context;
use buslab_canbus::BusEvent;
use buslab_logs::Entry;
use buslab_logs::candump::{Terminal, TimestampMode, View, Writer};

use super::busopt::{BusOpt, open, set_name};

#[derive(clap::Args)]
pub struct Args {
    #[command(flatten)]
    pub bus: BusOpt,
    /// Also write every frame to this candump log file (`(SEC.USEC) IFACE ID#DATA`), which
    /// can-utils and python-can read.
    #[arg(short = 'l', long = "log", value_name = "FILE")]
    pub log: Option<PathBuf>,
    /// Prefix each line with a time, as candump -t: `a` absolute (the default when MODE is
    /// left out), `d` since the previous line, `z` since the first line.
    #[arg(short = 't', long = "timestamps", value_name = "MODE", num_args = 0..=1,
          default_missing_value = "a", value_parser = parse_mode)]
    pub timestamps: Option<TimestampMode>,
    /// Show the data as ASCII too, as candump -a.
    #[arg(short = 'a', long)]
    pub ascii: bool,
    /// Show the direction (RX/TX) after the interface, as candump -x (and R/T in the log).
    #[arg(short = 'x', long)]
    pub extra: bool,
    /// Exit after this many frames (error frames do not count).
    #[arg(short = 'n', long, value_name = "COUNT")]
    pub count: Option<u64>,
    /// Name this client's node on a buslab bus (shown by `buslab status`).
    #[arg(long, value_name = "NAME")]
    pub name: Option<String>,
    /// Also show error frames: this node's bus errors, lost arbitrations and state changes,
    /// in words as candump -e.
    #[arg(short = 'e', long)]
    pub errors: bool,
}

/// `a`, `d` or `z`.
fn parse_mode(text: &str) -> Result<TimestampMode, String> {
    match text {
        "a" => Ok(TimestampMode::Absolute),
        "d" => Ok(TimestampMode::Delta),
        "z" => Ok(TimestampMode::Zero),
        _ => Err(format!(
            "timestamp mode {text:?} must be a (absolute), d (delta) or z (from zero)"
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

fn dump(args: Args) -> anyhow::Result<()> {
    let url = &args.bus.bus;
    let mut bus = open(url)?;
    set_name(&mut bus, url, args.name.as_deref())?;
    if args.errors {
        bus.set_error_frames(true)?;
    }
    let mut log = match &args.log {
        Some(path) => Some(
            Writer::new(BufWriter::new(
                File::create(path).with_context(|| format!("cannot create {}", path.display()))?,
            ))
            .with_direction(args.extra),
        ),
        None => None,
    };
    let stop = Arc::new(AtomicBool::new(false));
    {
        let stop = stop.clone();
        let _ = ctrlc::set_handler(move || stop.store(true, Ordering::SeqCst));
    }
    // Tests and scripts wait for this line (-v) before they send.
    tracing::info!(
        "dump: listening on {url}{}",
        if args.errors {
            " with error frames"
        } else {
            ""
        }
    );
    let mut terminal = Terminal::new(View {
        timestamps: args.timestamps,
        ascii: args.ascii,
        extra: args.extra,
        error_words: true,
    });
    let stdout = io::stdout();
    let mut out = stdout.lock();
    let mut seen = 0u64;
    // The channel as the URL names it (a server may call itself something else).
    let channel = url.channel().to_string();
    while !stop.load(Ordering::SeqCst) && args.count.is_none_or(|n| seen < n) {
        // Short waits, so Ctrl-C is noticed.
        let Some(event) = bus.recv_event(Some(Duration::from_millis(100)))? else {
            continue;
        };
        if let BusEvent::Frame(_) = event {
            seen += 1;
        }
        let mut entry = Entry::from_event(&event);
        entry.interface.clone_from(&channel);
        writeln!(out, "{}", terminal.line(&entry))?;
        out.flush()?;
        if let Some(log) = &mut log {
            log.write(&entry)?;
            log.flush()?;
        }
    }
    Ok(())
}
