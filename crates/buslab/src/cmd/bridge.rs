//! `buslab bridge BUS_A BUS_B`: copies frames between two buses (the idea of cangw and
//! cannelloni), so a real adapter joins the virtual bench or a virtual bus is watched with
//! real tools.
//!
//! No frame is copied twice or back: each side's backend does not hand its own frames back
//! (socketcand clients do not get their own frames, a SocketCAN socket does not receive what
//! it sent, an SLCAN adapter does not echo), so a frame from A sent to B is never seen on B's
//! side of the bridge. Bridging a bus to itself is refused.
//!
//! CAN FD frames are copied to a bus that carries FD (a SocketCAN interface with MTU 72, an
//! SLCAN adapter opened with `fd=1`); a classic destination (buslab's bit-level bus,
//! socketcand, an interface with MTU 16) cannot take them: they are counted, the reason is
//! said once per destination, and the count is shown when the bridge stops.

use std::collections::HashSet;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, mpsc};
use std::time::Duration;

use anyhow::bail;
use buslab_backends::{BusUrl, FilterItem, Pump, PumpEvent, TrySendError, filter_set, resolve};
use buslab_canbus::{BusError, CanBus, Filter, Record};

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

/// CAN FD frames a destination could not take: counted, each reason said once.
#[derive(Default)]
struct FdRefusals {
    count: AtomicU64,
    said: Mutex<HashSet<String>>,
}

impl FdRefusals {
    /// One FD frame from `from` that `refusal` (the destination's words) kept out.
    fn refused(&self, from: &BusUrl, refusal: &str) {
        self.count.fetch_add(1, Ordering::Relaxed);
        let first = self
            .said
            .lock()
            .map(|mut said| said.insert(refusal.to_string()))
            .unwrap_or(false);
        if first {
            tracing::warn!(
                "CAN FD frames from {from} are not bridged: {refusal} (counted; the count is shown when the bridge stops)"
            );
        }
    }
}

/// Why `bus` cannot take FD frames, in its words; `None` when it can.
fn fd_refusal(bus: &dyn CanBus, url: &BusUrl) -> Option<String> {
    bus.fd_support().classic_reason().map(|why| {
        BusError::ClassicOnly {
            bus: url.to_string(),
            why: why.clone(),
        }
        .to_string()
    })
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
    // Why each side cannot take FD frames, if it cannot.
    let (a_refuses_fd, b_refuses_fd) = (
        fd_refusal(a.as_ref(), &args.a),
        fd_refusal(b.as_ref(), &args.b),
    );
    let fd_refusals = Arc::new(FdRefusals::default());
    // Frames (classic or FD) go through this thread: each pump hands what it receives over,
    // tagged.
    let (tx, frames) = mpsc::sync_channel::<(Way, Record)>(buslab_backends::pump::QUEUE);
    let pump = |name: &str, bus, way: Way| {
        let tx = tx.clone();
        let stop = stop.clone();
        let fd_refusals = fd_refusals.clone();
        // This pump's bus, and the one whose frames it sends.
        let (url, from) = match way {
            Way::AtoB => (args.a.clone(), args.b.clone()),
            Way::BtoA => (args.b.clone(), args.a.clone()),
        };
        Pump::spawn(name, bus, move |event| match event {
            PumpEvent::Received(m) => match m.record {
                record @ (Record::Frame(_) | Record::Fd(_)) => tx.send((way, record)).is_ok(),
                Record::Error(_) => true,
            },
            // An FD frame the bus found it could not carry after all (an interface whose MTU
            // went down to 16): counted with the others.
            PumpEvent::SendFailed {
                frame: Record::Fd(_),
                error: error @ BusError::ClassicOnly { .. },
            } => {
                fd_refusals.refused(&from, &error.to_string());
                true
            }
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
        "bridge: {} {} {}{}{}",
        args.a,
        if args.one_way { "->" } else { "<->" },
        args.b,
        if filters.ids.is_empty() {
            String::new()
        } else {
            let shown: Vec<String> = filters.ids.iter().map(ToString::to_string).collect();
            format!(" (frames passing {})", shown.join(","))
        },
        match (&a_refuses_fd, &b_refuses_fd) {
            (None, None) => ", CAN FD both ways",
            (Some(_), Some(_)) => ", classic CAN",
            _ => ", CAN FD one way",
        }
    );
    let (mut a_to_b, mut b_to_a, mut filtered, mut dropped) = (0u64, 0u64, 0u64, 0u64);
    while !stop.load(Ordering::SeqCst) && args.count.is_none_or(|n| a_to_b + b_to_a < n) {
        let (way, record) = match frames.recv_timeout(Duration::from_millis(100)) {
            Ok(got) => got,
            Err(mpsc::RecvTimeoutError::Timeout) => continue,
            Err(mpsc::RecvTimeoutError::Disconnected) => break,
        };
        let passes = match &record {
            Record::Frame(frame) => filters.passes(frame),
            Record::Fd(frame) => filters.passes_fd(frame),
            Record::Error(_) => false,
        };
        if !passes {
            filtered += 1;
            continue;
        }
        if way == Way::BtoA && args.one_way {
            continue;
        }
        let (to, from, refusal) = match way {
            Way::AtoB => (&pump_b, &args.a, &b_refuses_fd),
            Way::BtoA => (&pump_a, &args.b, &a_refuses_fd),
        };
        // Never blocks: this thread also drains what both pumps receive.
        let sent = match &record {
            Record::Fd(_) if let Some(refusal) = refusal => {
                fd_refusals.refused(from, refusal);
                continue;
            }
            Record::Fd(frame) => to.try_send_fd(*frame),
            Record::Frame(frame) => to.try_send(*frame),
            Record::Error(_) => continue,
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
            "{record} {}",
            if way == Way::AtoB { "A -> B" } else { "B -> A" }
        );
    }
    // Dropping the pumps sends what is queued.
    drop(pump_a);
    drop(pump_b);
    let fd_refused = fd_refusals.count.load(Ordering::Relaxed);
    tracing::info!(
        "bridge: stopped; {a_to_b} frames A -> B, {b_to_a} B -> A, {filtered} held back by the filter, {dropped} dropped (a bus too slow), {fd_refused} CAN FD frames not bridged (classic destination)"
    );
    if fd_refused > 0 {
        tracing::warn!(
            "bridge: {fd_refused} CAN FD frames were not bridged: their destination is classic CAN"
        );
    }
    Ok(())
}
