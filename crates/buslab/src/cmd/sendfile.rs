//! `buslab sendfile --id ID FILE`: JerryCAN's "send a file" (seed 002 §5.4.4.5) with the file
//! protocol (SPEC N5): 8 bytes a frame on one identifier, the last frame shorter — empty when
//! the size is a multiple of 8. `buslab recvfile` is the other end.
//!
//! A frame that loses arbitration or meets errors is retransmitted by the controller: the
//! sender waits, says why, and goes on once the bus carries frames again (a wire cut and
//! repaired), unless `--stall` passes first.
//!
//! The file is read as it is sent (a batch of frames at a time), so its size costs no memory.

use std::io::BufReader;
use std::path::PathBuf;
use std::time::{Duration, Instant};

use anyhow::{Context, bail};
use buslab_can::Id;
use buslab_canbus::FileFrames;

use super::busopt::{BusOpt, open};
use super::transfer;
use crate::units::Human;

#[derive(clap::Args)]
pub struct Args {
    /// The 11-bit identifier the file goes on (hex with 0x, or decimal).
    #[arg(long, value_name = "ID", value_parser = super::monican::parse_id)]
    pub id: u16,
    /// The file to send.
    pub file: PathBuf,
    #[command(flatten)]
    pub bus: BusOpt,
    /// Give up when no frame got through for this long (`30s`, `5min`); default: keep
    /// waiting until Ctrl-C, as the controller keeps retransmitting.
    #[arg(long, value_name = "DURATION", value_parser = crate::units::duration)]
    pub stall: Option<Duration>,
}

/// The largest file sent (also `recvfile`'s default limit; 256 MiB take well over an hour
/// at 1 Mbit/s).
pub const MAX_FILE: u64 = 256 * 1024 * 1024;

pub fn run(args: Args) -> anyhow::Result<()> {
    let path = &args.file;
    let file = buslab_link::fs::open_regular(path, false)
        .with_context(|| format!("cannot read {}", path.display()))?;
    let len = file
        .metadata()
        .with_context(|| format!("cannot read {}", path.display()))?
        .len();
    if len > MAX_FILE {
        bail!(
            "{} is larger than {MAX_FILE} bytes, the most sent",
            path.display()
        );
    }
    let id = Id::standard(args.id).context("the file's identifier")?;
    let stop = super::interrupted()?;
    let url = &args.bus.bus;
    let mut bus = open(url)?;
    let started = Instant::now();
    let bar = transfer::bar(len, "sending");
    // The length read now is what is sent: bytes written to the file meanwhile are not, and a
    // file cut short meanwhile is an error (never a shorter file at the other end).
    let frames = FileFrames::new(id, BufReader::new(file), len);
    let sent = transfer::send_frames(&mut bus, url, frames, &bar, args.stall, &stop);
    bar.finish_and_clear();
    sent.with_context(|| format!("sending {}", path.display()))?;
    let elapsed = started.elapsed();
    eprintln!(
        "sent {} ({} bytes) on ID {:03X} in {} ({:.0} bytes/s)",
        path.display(),
        len,
        args.id,
        Human(elapsed),
        len as f64 / elapsed.as_secs_f64().max(1e-9)
    );
    Ok(())
}
