//! A gateway between a local bus and a join transport (`bus serve --join URL`): it is one
//! node of the local bus (so the remote frames it sends arbitrate there like any other), it
//! hands every frame the other local nodes send to the transport, and it never sends a frame
//! back where it came from (a node does not receive its own frames; the transport drops its
//! own envelopes' echoes).
//!
//! Remote frames wait for the local bus (the local pump's queue pushes back on the
//! transport's reader); local frames never wait for the network ([`crate::JoinSender`]).

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;
use std::time::Duration;

use buslab_bus::{CanBus, Record};

use buslab_join::{CanFrame, JoinReport};

use crate::DynBus;
use crate::join::{JoinBus, JoinSender};
use crate::pump::{Pump, PumpEvent};

/// How often the remote side's reader looks whether the gateway is stopping.
const POLL: Duration = Duration::from_millis(100);

/// A running gateway; [`Gateway::stop`] ends it and gives its last report.
pub struct Gateway {
    remote: JoinSender,
    stop: Arc<AtomicBool>,
    inbound: Option<JoinHandle<()>>,
}

impl Gateway {
    /// Starts the gateway between `local` (a bus this gateway is a node of) and `remote`.
    pub fn spawn(name: &str, local: DynBus, mut remote: JoinBus) -> std::io::Result<Self> {
        let to_remote = remote.sender();
        let outbound = to_remote.clone();
        let stop = Arc::new(AtomicBool::new(false));
        let pump_stop = stop.clone();
        let label = name.to_string();
        let local = Pump::spawn(
            &format!("gateway-{name}"),
            local,
            move |event| match event {
                PumpEvent::Received(m) => match m.record {
                    Record::Frame(f) => outbound.send(CanFrame::Classic(f)).is_ok(),
                    Record::Fd(f) => outbound.send(CanFrame::Fd(f)).is_ok(),
                    Record::Error(_) => true,
                },
                PumpEvent::SendFailed { frame, error } => {
                    tracing::warn!("gateway {label}: the local bus refused {frame}: {error}");
                    true
                }
                PumpEvent::Failed(error) => {
                    tracing::error!("gateway {label}: the local bus failed: {error}");
                    pump_stop.store(true, Ordering::SeqCst);
                    false
                }
            },
        )?;
        let in_stop = stop.clone();
        let label = name.to_string();
        let inbound = std::thread::Builder::new()
            .name(format!("gateway-in-{name}"))
            .spawn(move || {
                while !in_stop.load(Ordering::SeqCst) {
                    let record = match remote.recv_event(Some(POLL)) {
                        Ok(Some(m)) => m.record,
                        Ok(None) => continue,
                        Err(e) => {
                            tracing::error!("gateway {label}: {e}");
                            in_stop.store(true, Ordering::SeqCst);
                            break;
                        }
                    };
                    let sent = match record {
                        Record::Frame(f) => local.send(f),
                        // The local bus is classic CAN (buslab's bit-level bus).
                        Record::Fd(_) | Record::Error(_) => continue,
                    };
                    if sent.is_err() {
                        break;
                    }
                }
                // Dropping the pump sends what is queued.
                drop(local);
                drop(remote);
            })?;
        Ok(Self {
            remote: to_remote,
            stop,
            inbound: Some(inbound),
        })
    }

    /// What the transport sent, lost and reordered so far.
    pub fn report(&self) -> JoinReport {
        self.remote.report()
    }

    /// Whether the gateway stopped by itself (a side failed).
    pub fn has_stopped(&self) -> bool {
        self.stop.load(Ordering::SeqCst)
    }

    /// Stops the gateway: frames already queued for the local bus are sent first.
    pub fn stop(mut self) -> JoinReport {
        self.stop.store(true, Ordering::SeqCst);
        if let Some(t) = self.inbound.take() {
            let _ = t.join();
        }
        self.remote.report()
    }
}
