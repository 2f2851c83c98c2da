//! `buslab send [IFACE] 123#1122`: send frames in cansend syntax (the interface first, as
//! cansend takes it, or `--bus`), and wait until they were sent. With `--dbc FILE`, messages
//! of the database by name and their signals by value: `buslab send --dbc car.dbc Engine
//! Speed=88.5 Mode=On` ([`encode`]).

mod encode;

use std::time::Duration;

use anyhow::{Context, bail};
use buslab_backends::{BusUrl, resolve};
use buslab_can::{FD_LENGTHS, FdFrame, Frame};
use buslab_logs::Record;

use super::busopt::{admin, confirm_sent, open, set_name};

#[derive(clap::Args)]
pub struct Args {
    /// The bus (default: the configuration's `bus`, else vcan0, buslab's bus on this
    /// machine): a name or URL as IFACE takes.
    #[arg(long, value_name = "BUS", value_parser = resolve)]
    pub bus: Option<BusUrl>,
    /// `[IFACE] FRAME…`: the interface as cansend takes it (vcan0, can0, /dev/ttyACM0 or a
    /// URL), then frames in can-utils syntax: 123#DEADBEEF, 1F334455#, 123#R, 00000123#R3,
    /// CAN FD 123##1112233 (flags digit: BRS 1, ESI 2; on a bus that carries FD).
    /// With --dbc also messages by name, each followed by its SIGNAL=VALUE (a number in the
    /// signal's unit, or a label of its value table); signals left out are sent as 0.
    #[arg(required_unless_present = "jerrycan", value_name = "[IFACE] FRAME")]
    pub words: Vec<String>,
    #[command(flatten)]
    pub dbc: crate::dbc::DbcArg,
    /// A frame whose ID is spelled the JerryCAN way (3 hex digits: the ID shifted left by
    /// one, e.g. 246#1122 is 123#1122); repeatable, sent after the others.
    #[arg(long, value_name = "FRAME", value_parser = Frame::from_jerrycan)]
    pub jerrycan: Vec<Frame>,
    /// Program this client's SJA1000 with BTR0:BTR1 (hex) first, e.g. 07:4D; a bit rate that
    /// does not match the bus cannot communicate (an induced error). Needs a buslab bus.
    #[arg(long, value_name = "BTR0:BTR1", value_parser = parse_btr)]
    pub btr: Option<(u8, u8)>,
    /// Name this client's node on a buslab bus (shown by `buslab status`).
    #[arg(long, value_name = "NAME")]
    pub name: Option<String>,
    /// How long to wait for the frames to be sent, beyond the time they need on the bus, with
    /// a unit (`2s`, `500ms`). A plain socketcand cannot confirm: then there is no wait.
    #[arg(long, value_name = "DURATION", default_value = "10s", value_parser = crate::units::duration)]
    pub timeout: Duration,
}

/// `07:4D` → (0x07, 0x4D).
pub fn parse_btr(text: &str) -> Result<(u8, u8), String> {
    let bad = || format!("bit timing {text:?} must be BTR0:BTR1 in hex, e.g. 07:4D");
    let (a, b) = text.split_once(':').ok_or_else(bad)?;
    let byte = |t: &str| {
        ((1..=2).contains(&t.len()) && t.bytes().all(|b| b.is_ascii_hexdigit()))
            .then(|| u8::from_str_radix(t, 16).ok())
            .flatten()
    };
    Ok((byte(a).ok_or_else(bad)?, byte(b).ok_or_else(bad)?))
}

/// The bus and frames from `[IFACE] FRAME…` and `--bus`: a first word without `#` is the
/// interface (with `--dbc`: unless it names a message, or `--bus` gives the bus).
fn bus_and_frames(args: &Args) -> anyhow::Result<(BusUrl, Vec<Record>)> {
    // A database is read first: a bad one is refused before anything else.
    let database = match &args.dbc.dbc {
        Some(path) => Some((path.as_path(), crate::dbc::load(path)?)),
        None => None,
    };
    let is_message = |word: &str| {
        database
            .as_ref()
            .is_some_and(|(_, db)| db.message_by_name(word).is_some())
    };
    let (iface, frames) = match args.words.split_first() {
        Some((first, rest))
            if !first.contains('#')
                && !(database.is_some()
                    && (args.bus.is_some()
                        || is_message(first)
                        || encode::assignment(first).is_some())) =>
        {
            (Some(first), rest)
        }
        _ => (None, &args.words[..]),
    };
    // Messages are encoded before the interface is looked at: a word meant as a message is
    // named as one.
    let encoded = match &database {
        Some((path, db)) => Some(encode::frames(db, path, frames, iface.map(String::as_str))?),
        None => None,
    };
    let url = match (iface, &args.bus) {
        (Some(_), Some(_)) => bail!(
            "the bus is given twice: as IFACE ({}) and --bus",
            iface.unwrap()
        ),
        (Some(name), None) => resolve(name)?,
        (None, Some(url)) => url.clone(),
        (None, None) => crate::config::get().bus.clone(),
    };
    if frames.is_empty() && args.jerrycan.is_empty() {
        bail!("no frame to send: expected [IFACE] FRAME…, e.g. `buslab send vcan0 123#1122`");
    }
    let mut frames = match encoded {
        Some(frames) => frames,
        None => frames
            .iter()
            .map(|f| parse_frame(f))
            .collect::<anyhow::Result<Vec<_>>>()?,
    };
    frames.extend(args.jerrycan.iter().copied().map(Record::Frame));
    Ok((url, frames))
}

/// A frame in can-utils syntax, classic or FD (`##`), the error naming the word.
fn parse_frame(word: &str) -> anyhow::Result<Record> {
    let record = if word.contains("##") {
        word.parse::<FdFrame>().map(Record::Fd)
    } else {
        word.parse::<Frame>().map(Record::Frame)
    };
    record.with_context(|| format!("invalid value '{word}' for '[IFACE] FRAME'"))
}

/// An FD frame carrying `payload`, padded with zeros to the next CAN FD length (a database may
/// declare a length such as 10 that no FD frame has).
fn fd_frame(id: buslab_can::Id, payload: &[u8]) -> anyhow::Result<FdFrame> {
    let len = FD_LENGTHS
        .iter()
        .copied()
        .find(|&l| l >= payload.len())
        .with_context(|| format!("{} bytes: a CAN FD frame carries 64 at most", payload.len()))?;
    let mut padded = payload.to_vec();
    padded.resize(len, 0);
    Ok(FdFrame::new(id, &padded)?)
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let (url, frames) = bus_and_frames(&args)?;
    let url = &url;
    let mut bus = open(url)?;
    set_name(&mut bus, url, args.name.as_deref())?;
    if let Some((btr0, btr1)) = args.btr {
        admin(&mut bus, url, "bit timing setting (--btr)")?.set_btr(btr0, btr1)?;
    }
    // Only this client's own frames matter now; what the bus carries is not kept.
    bus.set_filters(&[buslab_canbus::Filter::NONE])?;
    for record in &frames {
        match record {
            Record::Frame(f) => bus.send(f)?,
            Record::Fd(f) => bus.send_fd(f)?,
            Record::Error(e) => bail!("{e}: an error frame is not sent"),
        }
    }
    confirm_sent(&mut bus, url, frames.len() as u64, args.timeout)
}
