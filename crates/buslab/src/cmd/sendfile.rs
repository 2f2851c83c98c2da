//! `buslab sendfile --id ID FILE`: JerryCAN's "send a file" (seed 002 §5.4.4.5) with the file
//! protocol (SPEC N5): 8 bytes a frame on one identifier, the last frame shorter — empty when
//! the size is a multiple of 8. `buslab recvfile` is the other end.
//!
//! A frame that loses arbitration or meets errors is retransmitted by the controller: the
//! sender waits, says why, and goes on once the bus carries frames again (a wire cut and
//! repaired), unless `--stall` passes first.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use anyhow::Context;
use buslab_can::Id;

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

/// The largest file sent (the receiver keeps a file in memory until it is complete).
pub const MAX_FILE: u64 = 256 * 1024 * 1024;

pub fn run(args: Args) -> anyhow::Result<()> {
    let data = buslab_link::fs::read_limited(&args.file, MAX_FILE)
        .with_context(|| format!("files up to {MAX_FILE} bytes are sent"))?;
    let id = Id::standard(args.id).context("the file's identifier")?;
    let stop = super::interrupted()?;
    let url = &args.bus.bus;
    let mut bus = open(url)?;
    let started = Instant::now();
    let bar = transfer::bar(data.len() as u64, "sending");
    let sent = transfer::send_data(&mut bus, url, id, &data, &bar, args.stall, &stop);
    bar.finish_and_clear();
    sent?;
    let elapsed = started.elapsed();
    eprintln!(
        "sent {} ({} bytes) on ID {:03X} in {} ({:.0} bytes/s)",
        args.file.display(),
        data.len(),
        args.id,
        Human(elapsed),
        data.len() as f64 / elapsed.as_secs_f64().max(1e-9)
    );
    Ok(())
}
