//! `buslab recvfile --id ID OUT`: receives one file sent with the file protocol (SPEC N5) on
//! `ID` (`buslab sendfile`, JerryCAN, a scenario's `file` traffic) and writes it atomically:
//! OUT appears whole once the frame shorter than 8 bytes arrived, or not at all. OUT is
//! checked (its temporary file made beside it) before the bus is joined, and the bytes go to
//! that file as they come, not to memory.

use std::path::PathBuf;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use anyhow::{Context, bail};
use buslab_can::Id;
use buslab_canbus::{FileError, FileReceiver, Filter};
use buslab_link::fs::AtomicFile;
use indicatif::{ProgressBar, ProgressStyle};

use super::busopt::{BusOpt, open};
use crate::units::Human;

#[derive(clap::Args)]
pub struct Args {
    /// The 11-bit identifier the file arrives on (hex with 0x, or decimal).
    #[arg(long, value_name = "ID", value_parser = super::monican::parse_id)]
    pub id: u16,
    /// Where to write the file (replaced atomically once the whole file is in; checked
    /// before the first frame).
    pub out: PathBuf,
    #[command(flatten)]
    pub bus: BusOpt,
    /// Refuse a file longer than this many bytes.
    #[arg(long, value_name = "BYTES", default_value_t = super::sendfile::MAX_FILE as usize)]
    pub max_size: usize,
    /// Give up when the file has not begun after this long (`30s`); default: wait until
    /// Ctrl-C.
    #[arg(long, value_name = "DURATION", value_parser = crate::units::duration)]
    pub timeout: Option<Duration>,
}

/// How often the receiver looks at Ctrl-C and its progress.
const LOOK: Duration = Duration::from_millis(200);

pub fn run(args: Args) -> anyhow::Result<()> {
    let id = Id::standard(args.id).context("the file's identifier")?;
    // Before anything arrives: a target that cannot be written is refused now, not after
    // the whole transfer.
    let mut out = AtomicFile::create(&args.out)?;
    let stop = super::interrupted()?;
    let url = &args.bus.bus;
    let mut bus = open(url)?;
    bus.set_filters(&[Filter::standard(args.id)])?;
    eprintln!("waiting for a file on ID {:03X} of {url}", args.id);
    let mut file = FileReceiver::with_limit(id, args.max_size);
    let bar = ProgressBar::new_spinner();
    bar.set_style(
        ProgressStyle::with_template("{spinner} receiving {bytes} {bytes_per_sec}")
            .expect("a valid template"),
    );
    let waiting_since = Instant::now();
    let mut first_frame: Option<Instant> = None;
    // Dropping `out` on the way out of an error removes its temporary file.
    loop {
        if stop.load(Ordering::SeqCst) {
            bar.finish_and_clear();
            bail!(
                "interrupted after {} bytes; {} was not written",
                file.len(),
                args.out.display()
            );
        }
        if first_frame.is_none()
            && let Some(limit) = args.timeout
            && waiting_since.elapsed() >= limit
        {
            bar.finish_and_clear();
            bail!(
                "no file began on ID {:03X} within {}",
                args.id,
                Human(limit)
            );
        }
        let Some(message) = bus.recv(Some(LOOK))? else {
            continue;
        };
        if message.record.id() != id {
            continue;
        }
        first_frame.get_or_insert_with(Instant::now);
        match file.push(&message.record) {
            Ok(received) => {
                out.write_all(received.bytes)?;
                if received.complete {
                    break;
                }
                bar.set_position(file.len() as u64);
            }
            Err(FileError::RemoteFrame { frame }) => {
                tracing::warn!("ignored remote frame {frame} (the file protocol uses data frames)")
            }
            Err(e) => {
                bar.finish_and_clear();
                bail!("{e}; {} was not written", args.out.display());
            }
        }
    }
    bar.finish_and_clear();
    let elapsed = first_frame.map_or(Duration::ZERO, |t| t.elapsed());
    out.commit()?;
    let len = file.len();
    eprintln!(
        "received {} bytes on ID {:03X} in {} ({:.0} bytes/s), written to {}",
        len,
        args.id,
        Human(elapsed),
        len as f64 / elapsed.as_secs_f64().max(1e-9),
        args.out.display()
    );
    Ok(())
}
