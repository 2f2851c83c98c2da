//! `buslab bridge BUS_A BUS_B`: copies frames between two buses (the idea of cangw and
//! cannelloni), so a real adapter joins the virtual bench or a virtual bus is watched with
//! real tools.
//!
//! No frame is copied twice or back: each side's backend does not hand its own frames back
//! (socketcand clients do not get their own frames, a SocketCAN socket does not receive what
//! it sent, an SLCAN adapter does not echo), so a frame from A sent to B is never seen on B's
//! side of the bridge. Bridging a bus to itself is refused.

use std::sync::atomic::Ordering;
use std::sync::mpsc;
use std::time::Duration;

use anyhow::bail;
use buslab_backends::{BusUrl, FilterItem, Pump, PumpEvent, TrySendError, filter_set, resolve};
use buslab_can::Frame;
use buslab_canbus::{Filter, Record};

use super::busopt::open;

#[derive(clap::Args)]
pub struct Args {
    /// One bus: vcan0 (buslab's bus on this machine), an interface (can0), an SLCAN adapter's
    /// path or a URL.
    #[arg(value_name = "BUS_A", value_parser = resolve)]
    pub a: BusUrl,
    /// The other bus.
    #[arg(value_name = "BUS_B", value_parser = resolve)]
    pub b: BusUrl,
    /// Copy only frames that pass these candump filters: ID:MASK, ID~MASK (or ~ID:MASK)
    /// inverted, j to AND them; comma-separated or repeated.
    #[arg(long, value_name = "FILTER", value_delimiter = ',')]
    pub filter: Vec<FilterItem>,
    /// Copy from BUS_A to BUS_B only.
    #[arg(long)]
    pub one_way: bool,
    /// Stop after this many frames were copied (both ways together).
    #[arg(short = 'n', long, value_name = "COUNT")]
    pub count: Option<u64>,
}

/// Which way a frame goes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Way {
    AtoB,
    BtoA,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    if args.a == args.b {
        bail!(
            "{} is bridged to itself: every frame would come back forever",
            args.a
        );
    }
    if args
        .filter
        .iter()
        .any(|f| matches!(f, FilterItem::ErrorMask(_)))
    {
        bail!("--filter: error frames are not copied (#ERRORMASK does not apply)");
    }
    let filters = filter_set(args.filter.iter().copied());
    let stop = super::interrupted()?;
    let a = open(&args.a)?;
    let mut b = open(&args.b)?;
    if args.one_way {
        // B's traffic is not wanted: nothing kept for it.
        b.set_filters(&[Filter::NONE])?;
    }
    // Frames go through this thread: each pump hands what it receives over, tagged.
    let (tx, frames) = mpsc::sync_channel::<(Way, Frame)>(buslab_backends::pump::QUEUE);
    let pump = |name: &str, bus, way: Way| {
        let tx = tx.clone();
        let stop = stop.clone();
        let url = match way {
            Way::AtoB => args.a.clone(),
            Way::BtoA => args.b.clone(),
        };
        Pump::spawn(name, bus, move |event| match event {
            PumpEvent::Received(m) => match m.record {
                Record::Frame(frame) => tx.send((way, frame)).is_ok(),
                Record::Fd(frame) => {
                    tracing::warn!("{url}: CAN FD frame {frame} not bridged (classic frames only)");
                    true
                }
                Record::Error(_) => true,
            },
            PumpEvent::SendFailed { frame, error } => {
                tracing::warn!("{url} refused {frame}: {error}");
                true
            }
            PumpEvent::Failed(error) => {
                tracing::error!("{url} failed: {error}");
                stop.store(true, Ordering::SeqCst);
                false
            }
        })
    };
    let pump_a = pump("bridge-a", a, Way::AtoB)?;
    let pump_b = pump("bridge-b", b, Way::BtoA)?;
    drop(tx);
    tracing::info!(
        "bridge: {} {} {}{}",
        args.a,
        if args.one_way { "->" } else { "<->" },
        args.b,
        if filters.ids.is_empty() {
            String::new()
        } else {
            let shown: Vec<String> = filters.ids.iter().map(ToString::to_string).collect();
            format!(" (frames passing {})", shown.join(","))
        }
    );
    let (mut a_to_b, mut b_to_a, mut filtered, mut dropped) = (0u64, 0u64, 0u64, 0u64);
    while !stop.load(Ordering::SeqCst) && args.count.is_none_or(|n| a_to_b + b_to_a < n) {
        let (way, frame) = match frames.recv_timeout(Duration::from_millis(100)) {
            Ok(got) => got,
            Err(mpsc::RecvTimeoutError::Timeout) => continue,
            Err(mpsc::RecvTimeoutError::Disconnected) => break,
        };
        if !filters.passes(&frame) {
            filtered += 1;
            continue;
        }
        // Never blocks: this thread also drains what both pumps receive.
        let sent = match way {
            Way::AtoB => pump_b.try_send(frame),
            Way::BtoA if args.one_way => continue,
            Way::BtoA => pump_a.try_send(frame),
        };
        match sent {
            Ok(()) if way == Way::AtoB => a_to_b += 1,
            Ok(()) => b_to_a += 1,
            Err(TrySendError::Full) => {
                dropped += 1;
                if dropped.is_power_of_two() {
                    tracing::warn!(
                        "{} does not take frames as fast as {} gives them: {dropped} dropped so far",
                        if way == Way::AtoB { &args.b } else { &args.a },
                        if way == Way::AtoB { &args.a } else { &args.b },
                    );
                }
                continue;
            }
            Err(TrySendError::Stopped(_)) => break,
        }
        tracing::debug!(
            "{frame} {}",
            if way == Way::AtoB { "A -> B" } else { "B -> A" }
        );
    }
    // Dropping the pumps sends what is queued.
    drop(pump_a);
    drop(pump_b);
    tracing::info!(
        "bridge: stopped; {a_to_b} frames A -> B, {b_to_a} B -> A, {filtered} held back by the filter, {dropped} dropped (a bus too slow)"
    );
    Ok(())
}
