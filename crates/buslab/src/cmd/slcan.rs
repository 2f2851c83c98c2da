//! `buslab slcan serve`: an SLCAN (Lawicel) USB adapter model on a pseudo-terminal, plugged
//! into any bus buslab can open. python-can's `interface='slcan'` and Linux's `slcand` use
//! the PTY as if an adapter were plugged in.
//!
//! On a bus that carries CAN FD (a SocketCAN interface with MTU 72, an FD SLCAN adapter) the
//! adapter is a CANable 2.0's kind: FD frames (`d`, `D`, `b`, `B`) and data bit rates (`Yn`)
//! pass both ways. On a classic bus (buslab's bit-level bus, socketcand) it is a CANUSB's
//! kind: the host's FD frames are answered BEL, said once with the bus's reason, and counted.

use std::path::PathBuf;
use std::sync::atomic::Ordering;
use std::sync::mpsc;

use anyhow::Context;
use buslab_backends::{BusUrl, Pump, PumpEvent, PumpSender, TrySendError, resolve};
use buslab_canbus::{BitTiming, BusError, BusOffRecovery, CanBus, Record};
use buslab_link::Pty;
use buslab_slcan::{Adapter, AdapterEvent, BTR_CLOCK_HZ, Identity, Input, Timing};

/// How long the answer to the host's `O` waits for the adapter's node to be initialised.
const OPEN_WAIT: std::time::Duration = std::time::Duration::from_secs(2);

use super::busopt::open;

#[derive(clap::Args)]
pub struct Args {
    #[command(subcommand)]
    pub command: SlcanCommand,
}

#[derive(clap::Subcommand)]
pub enum SlcanCommand {
    /// Serve an SLCAN adapter on a pseudo-terminal, plugged into a bus: python-can
    /// (`interface='slcan'`, channel = the PTY) and slcand use it as a USB adapter.
    Serve(ServeArgs),
}

#[derive(clap::Args)]
pub struct ServeArgs {
    /// The bus the adapter is plugged into: vcan0 (buslab's bus on this machine), an
    /// interface (can0), a device path or a bus URL.
    /// Default: the configuration's `bus` (docs/config.md), else vcan0.
    #[arg(long, value_name = "BUS", default_value = crate::config::get().bus_name.as_str(),
          value_parser = resolve)]
    pub bus: BusUrl,
    /// Also make this path a symlink to the pseudo-terminal (e.g. /tmp/ttyACM0); removed on
    /// exit.
    #[arg(long, value_name = "PATH")]
    pub link: Option<PathBuf>,
    /// The serial number the adapter reports (`N`): 4 letters or digits.
    #[arg(long, default_value = "BL01", value_parser = four_alphanumerics)]
    pub serial: [u8; 4],
}

fn four_alphanumerics(text: &str) -> Result<[u8; 4], String> {
    <[u8; 4]>::try_from(text.as_bytes())
        .ok()
        .filter(|b| b.iter().all(u8::is_ascii_alphanumeric))
        .ok_or_else(|| format!("serial number {text:?} must be 4 letters or digits"))
}

pub fn run(args: Args) -> anyhow::Result<()> {
    match args.command {
        SlcanCommand::Serve(a) => serve(a),
    }
}

fn serve(args: ServeArgs) -> anyhow::Result<()> {
    let url = args.bus.clone();
    let mut bus = open(&url)?;
    // The adapter speaks FD exactly when its bus carries FD.
    let no_fd = bus.fd_support().classic_reason().map(|why| {
        BusError::ClassicOnly {
            bus: url.to_string(),
            why: why.clone(),
        }
        .to_string()
    });
    // The adapter's controller tells its host its state (`F`, BEL when bus-off).
    if let Err(e) = bus.set_error_frames(true) {
        tracing::debug!("no error frames from {url}: {e}");
    }
    let mut pty = Pty::open().context("opening a pseudo-terminal")?;
    if let Some(link) = &args.link {
        pty.link_at(link)
            .with_context(|| format!("linking {}", link.display()))?;
    }
    let stop = super::interrupted()?;
    let (feed, inputs) = mpsc::sync_channel(buslab_slcan::INPUT_QUEUE);
    let pump = {
        let feed = feed.clone();
        let stop = stop.clone();
        Pump::spawn("slcan-bus", bus, move |event| match event {
            PumpEvent::Received(m) => match m.record {
                Record::Frame(frame) => feed.send(Input::Frame(frame)).is_ok(),
                Record::Fd(frame) => feed.send(Input::Fd(frame)).is_ok(),
                Record::Error(error) => feed.send(Input::Error(error)).is_ok(),
            },
            PumpEvent::SendFailed { frame, error } => {
                tracing::warn!("the bus refused {frame}: {error}");
                true
            }
            PumpEvent::Failed(error) => {
                tracing::error!("the bus failed: {error}");
                stop.store(true, Ordering::SeqCst);
                false
            }
        })?
    };
    let shown = args.link.as_deref().unwrap_or(pty.path());
    // The first line on stdout: what clients open (scripts and tests read it).
    println!("{}", shown.display());
    tracing::info!(
        "slcan serve: an SLCAN adapter on {} (PTY {}), plugged into {url}{}",
        shown.display(),
        pty.path().display(),
        if no_fd.is_none() { ", CAN FD" } else { "" }
    );
    let mut adapter = Adapter::new(Identity {
        serial: args.serial,
        ..Identity::default()
    })
    .with_fd(no_fd.is_none());
    let to_bus = pump.sender();
    let mut tally = Tally {
        no_fd,
        ..Tally::default()
    };
    let result = buslab_slcan::serve(
        std::os::fd::AsFd::as_fd(&pty),
        &mut adapter,
        feed,
        inputs,
        |event| on_adapter_event(event, &to_bus, &mut tally),
        &stop,
    );
    drop(pump);
    tracing::info!(
        "slcan serve: stopped ({} bad lines answered with BEL, {} CAN FD frames refused, {} frames the host did not read in time)",
        tally.garbage,
        tally.refused_fd,
        adapter.dropped()
    );
    Ok(result?)
}

/// What the serve loop counts of the host's doings, and why the bus refuses FD (if it does).
#[derive(Default)]
struct Tally {
    garbage: u64,
    refused_fd: u64,
    no_fd: Option<String>,
}

/// A frame, classic or FD, handed to the bus without blocking (the pump may be waiting for
/// this loop to take what it received).
fn to_bus(frame: impl std::fmt::Display, sent: Result<(), TrySendError>) {
    match sent {
        Ok(()) => {}
        Err(TrySendError::Full) => {
            tracing::warn!("{frame} dropped: the host sends faster than the bus takes frames")
        }
        Err(TrySendError::Stopped(_)) => tracing::warn!("{frame} not sent: the bus is gone"),
    }
}

/// What the host asked of the adapter, carried out on the bus.
fn on_adapter_event(event: AdapterEvent, bus: &PumpSender, tally: &mut Tally) {
    match event {
        AdapterEvent::Transmit(frame) => to_bus(frame, bus.try_send(frame)),
        AdapterEvent::TransmitFd(frame) => to_bus(frame, bus.try_send_fd(frame)),
        AdapterEvent::RefusedFd(frame) => {
            tally.refused_fd += 1;
            if tally.refused_fd == 1 {
                tracing::warn!(
                    "the host sends CAN FD frames (first {frame}): answered BEL, as a classic adapter does: {} (counted; the count is shown at the end)",
                    tally.no_fd.as_deref().unwrap_or("the bus is classic CAN")
                );
            }
        }
        AdapterEvent::Opened {
            listen_only,
            timing,
            data_bitrate,
        } => {
            tracing::info!(
                "the host opened the adapter{}{}{}",
                if listen_only { " listen-only" } else { "" },
                timing.map_or(String::new(), |t| format!(" ({})", describe(t))),
                data_bitrate.map_or(String::new(), |r| format!(
                    ", CAN FD data phase at {r} bit/s (as the bus runs it)"
                ))
            );
            let host = timing.map(describe);
            // On buslab's bus the adapter's node takes the host's timing: a bit rate that
            // does not match the bus cannot communicate, as with a real adapter. Opening
            // initialises the chip (ending a bus-off), which then stays bus-off until the
            // next opening, as a Lawicel CANUSB's.
            let regs = timing.and_then(registers);
            let (done, opened) = mpsc::sync_channel(1);
            let queued = bus.run(Box::new(move |bus: &mut dyn CanBus| {
                if let Some(admin) = bus.admin() {
                    open_node(admin, regs, host.as_deref());
                }
                let _ = done.send(());
            }));
            // The host's `O` is answered when this returns: by then the node is initialised,
            // so a frame put on the bus after the answer reaches the host (initialising a chip
            // drops what is on the wire meanwhile). Bounded: the pump may itself be waiting
            // for this loop to take frames.
            if queued.is_ok() && opened.recv_timeout(OPEN_WAIT).is_err() {
                tracing::debug!("the adapter's node was not initialised within {OPEN_WAIT:?}");
            }
        }
        AdapterEvent::RefusedBusOff(frame) => tracing::warn!(
            "{frame} refused (BEL): the adapter is bus-off; the host must close and open the channel (C, O)"
        ),
        AdapterEvent::Closed => tracing::info!("the host closed the adapter"),
        AdapterEvent::FilterNotModelled { code, mask } => tracing::warn!(
            "acceptance filter M{code:08X} m{mask:08X} is not modelled: the adapter delivers every frame"
        ),
        AdapterEvent::Garbage(e) => {
            tally.garbage += 1;
            if tally.garbage == 1 {
                tracing::warn!("answered BEL to a bad line from the host: {e} (more at -v)");
            } else {
                tracing::debug!("answered BEL: {e}");
            }
        }
        AdapterEvent::Overrun => {
            tracing::warn!("the host does not read: frames are dropped (F reports a data overrun)")
        }
    }
}

/// The adapter's node on buslab's bus as the host opened it: stays bus-off until the next
/// opening, the host's timing (else its own again, which ends a bus-off), and a warning naming
/// both rates when they differ.
fn open_node(admin: &mut dyn buslab_canbus::BusAdmin, regs: Option<(u8, u8)>, host: Option<&str>) {
    match admin.set_bus_off_recovery(BusOffRecovery::Manual) {
        Ok(()) | Err(BusError::Unsupported { .. }) => {}
        Err(e) => tracing::debug!("the adapter's node recovers from bus-off as the bus says: {e}"),
    }
    // Initialising the chip drops what it was trying to send, as a real adapter's C and O.
    if let Err(e) = admin.abort() {
        tracing::debug!("nothing aborted on the adapter's node: {e}");
    }
    let regs = regs.or_else(|| {
        let status = admin.node_status(None).ok()?;
        status.timing.map(|t| (t.btr0, t.btr1))
    });
    if let Some((btr0, btr1)) = regs
        && let Err(e) = admin.set_btr(btr0, btr1)
    {
        tracing::warn!("cannot give the adapter's node the host's timing: {e}");
        return;
    }
    match admin.node_status(None) {
        Ok(status) => {
            if let Some(t) = status.timing.filter(|t| !t.matches_bus) {
                tracing::warn!(
                    "the host opened the adapter at {} but the bus runs at {} bit/s: it cannot communicate: its node goes error-passive, bus-off when the host sends, and stays off until the host reopens it at {} bit/s (C, then S or s, then O)",
                    host.map_or_else(|| format!("{} bit/s", t.bitrate), str::to_string),
                    status.bus.bitrate,
                    status.bus.bitrate
                );
            }
        }
        Err(e) => tracing::debug!("no status of the adapter's node: {e}"),
    }
}

fn describe(timing: Timing) -> String {
    match timing {
        Timing::Bitrate(rate) => format!("{rate} bit/s"),
        Timing::Btr { btr0, btr1 } => format!(
            "BTR0={btr0:02X} BTR1={btr1:02X}, {} bit/s",
            BitTiming::from_registers(btr0, btr1).bitrate(BTR_CLOCK_HZ)
        ),
        Timing::Cnf([a, b, c]) => format!("MCP2515 CNF {a:02X} {b:02X} {c:02X}"),
    }
}

/// The SJA1000 registers for the host's timing (at the adapter's 8 MHz CAN clock).
fn registers(timing: Timing) -> Option<(u8, u8)> {
    match timing {
        Timing::Bitrate(rate) => BitTiming::for_bitrate(BTR_CLOCK_HZ, rate, None)
            .ok()
            .map(|t| t.registers()),
        Timing::Btr { btr0, btr1 } => Some((btr0, btr1)),
        Timing::Cnf(_) => None,
    }
}
