//! `buslab send 123#1122`: send frames in cansend syntax, and wait until they were sent.

use std::time::Duration;

use buslab_can::Frame;
use buslab_canbus::CanBus;

use super::bus::{BusOpt, open, wait_sent};

#[derive(clap::Args)]
pub struct Args {
    #[command(flatten)]
    pub bus: BusOpt,
    /// Frames in can-utils syntax: 123#DEADBEEF, 1F334455#, 123#R, 00000123#R3.
    #[arg(required = true, value_name = "FRAME")]
    pub frames: Vec<Frame>,
    /// Program this client's SJA1000 with BTR0:BTR1 (hex) first, e.g. 07:4D; a bit rate that
    /// does not match the bus cannot communicate (an induced error).
    #[arg(long, value_name = "BTR0:BTR1", value_parser = parse_btr)]
    pub btr: Option<(u8, u8)>,
    /// Name this client's node on a buslab bus.
    #[arg(long)]
    pub name: Option<String>,
    /// How long to wait for the frames to be sent (`2s`, `500ms`).
    #[arg(long, default_value = "10s", value_parser = crate::units::duration)]
    pub timeout: Duration,
}

/// `07:4D` → (0x07, 0x4D).
pub fn parse_btr(text: &str) -> Result<(u8, u8), String> {
    let bad = || format!("bit timing {text:?} must be BTR0:BTR1 in hex, e.g. 07:4D");
    let (a, b) = text.split_once(':').ok_or_else(bad)?;
    let byte = |t: &str| {
        (1..=2)
            .contains(&t.len())
            .then(|| u8::from_str_radix(t, 16).ok())
            .flatten()
    };
    Ok((byte(a).ok_or_else(bad)?, byte(b).ok_or_else(bad)?))
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let mut open = open(&args.bus.bus)?;
    if open.extensions {
        if let Some(name) = &args.name {
            open.bus.set_name(name)?;
        }
        if let Some((btr0, btr1)) = args.btr {
            open.bus.set_btr(btr0, btr1)?;
        }
    } else if args.btr.is_some() {
        anyhow::bail!("--btr needs a buslab server (this one does not know buslab_btr)");
    }
    for f in &args.frames {
        open.bus.send(f)?;
    }
    wait_sent(&mut open, args.frames.len() as u64, args.timeout)
}
