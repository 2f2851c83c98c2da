//! A bus joined to remote buses (`cannelloni://`, `cannelloni+tcp://`, `mqtt://`): the one
//! [`JoinBus`] every join transport gives, its frames coming from the transport's threads and
//! going to them, and its [`JoinReport`] (what was sent, lost, reordered, per peer).
//!
//! Sending never waits for the network: a frame the transport cannot carry now (no
//! connection, a full queue) is dropped and counted as `unsent`, and its sequence number is
//! spent, so the receivers count it as lost. Receiving pushes back: frames wait in a bounded
//! queue for the reader, and a transport whose reader is slow stops reading the network
//! (UDP and MQTT QoS 0 then lose frames there, counted by sequence number).

use std::sync::mpsc::{self, Receiver, RecvTimeoutError, SyncSender, TrySendError};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use buslab_bus::{
    BusError, CanBus, ErrorFrame, ErrorState, FdSupport, Filter, Message, Record, matches_any,
    matches_any_id, wall_clock,
};
use buslab_can::{FdFrame, Frame};
use buslab_join::{CanFrame, JoinReport, Tracker};

/// Frames waiting for the transport, and for the reader, at most.
pub const JOIN_QUEUE: usize = 8192;

/// What the transport's threads hand the bus.
pub(crate) enum Inbound {
    Frame(CanFrame),
    /// The transport is gone for good.
    Failed(BusError),
}

/// The counters a transport keeps, shared with the bus that shows them.
pub(crate) struct Accounting {
    pub(crate) tracker: Tracker,
    pub(crate) report: JoinReport,
}

impl Accounting {
    pub(crate) fn new(origin: u64) -> Self {
        Self {
            tracker: Tracker::new(origin),
            report: JoinReport {
                origin: format!("{origin:016x}"),
                ..JoinReport::default()
            },
        }
    }

    /// The report with the tracker's current counts.
    pub(crate) fn snapshot(&self) -> JoinReport {
        JoinReport {
            echoes: self.tracker.echoes(),
            peers: self.tracker.peers().cloned().collect(),
            ..self.report.clone()
        }
    }
}

pub(crate) type Shared = Arc<Mutex<Accounting>>;

/// Both ends of a bounded channel.
pub(crate) type Queue<T> = (SyncSender<T>, Receiver<T>);

/// A random origin ID for this process's member of a join (std's hasher keys are random).
pub(crate) fn new_origin() -> u64 {
    use std::hash::{BuildHasher, Hasher};
    let mut h = std::collections::hash_map::RandomState::new().build_hasher();
    h.write_u32(std::process::id());
    h.write_u128(wall_clock().as_micros());
    h.finish()
}

/// Microseconds on the wall clock.
pub(crate) fn wall_us() -> u64 {
    wall_clock().as_micros() as u64
}

/// Hands frames to the transport from any thread ([`JoinBus::sender`]).
#[derive(Clone)]
pub struct JoinSender {
    outbox: SyncSender<CanFrame>,
    shared: Shared,
}

impl JoinSender {
    /// Queues a frame; a full queue drops it (counted as unsent).
    pub fn send(&self, frame: CanFrame) -> Result<(), BusError> {
        match self.outbox.try_send(frame) {
            Ok(()) => Ok(()),
            Err(TrySendError::Full(_)) => {
                if let Ok(mut a) = self.shared.lock() {
                    a.report.unsent += 1;
                }
                Ok(())
            }
            Err(TrySendError::Disconnected(_)) => Err(BusError::Closed),
        }
    }

    /// What was sent, lost and reordered so far, per peer.
    pub fn report(&self) -> JoinReport {
        self.shared.lock().map(|a| a.snapshot()).unwrap_or_default()
    }
}

impl std::fmt::Debug for JoinSender {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("JoinSender")
            .field("report", &self.report())
            .finish()
    }
}

/// A bus joined to remote buses through a transport.
pub struct JoinBus {
    url: String,
    sender: JoinSender,
    inbox: Receiver<Inbound>,
    filters: Vec<Filter>,
    error_frames: bool,
    /// Dropped with the bus: stops the transport's threads.
    _transport: Box<dyn Send>,
}

impl JoinBus {
    pub(crate) fn new(
        url: String,
        outbox: SyncSender<CanFrame>,
        inbox: Receiver<Inbound>,
        shared: Shared,
        transport: Box<dyn Send>,
    ) -> Self {
        Self {
            url,
            sender: JoinSender { outbox, shared },
            inbox,
            filters: Vec::new(),
            error_frames: false,
            _transport: transport,
        }
    }

    /// A handle that sends from another thread (a gateway receives here and sends there).
    pub fn sender(&self) -> JoinSender {
        self.sender.clone()
    }

    /// What was sent, lost and reordered so far, per peer.
    pub fn report(&self) -> JoinReport {
        self.sender.report()
    }

    /// The channel queue for a transport: its outbox's receiving end and the bus's inbox.
    pub(crate) fn queues() -> (Queue<CanFrame>, Queue<Inbound>) {
        (
            mpsc::sync_channel(JOIN_QUEUE),
            mpsc::sync_channel(JOIN_QUEUE),
        )
    }

    fn message(&self, frame: CanFrame) -> Option<Message> {
        let at = wall_clock();
        let channel = self.url.as_str();
        match frame {
            CanFrame::Classic(f) if matches_any(&self.filters, &f) => {
                Some(Message::rx(at, channel, f).into_record())
            }
            CanFrame::Fd(f) if matches_any_id(&self.filters, f.id()) => {
                Some(Message::fd(at, channel, f))
            }
            CanFrame::Error { class, data } if self.error_frames => {
                ErrorFrame::decode(class, &data)
                    .ok()
                    .map(|e| Message::error(at, channel, e))
            }
            _ => None,
        }
    }
}

impl CanBus for JoinBus {
    fn send(&mut self, frame: &Frame) -> Result<(), BusError> {
        self.sender.send(CanFrame::Classic(*frame))
    }

    fn fd_support(&self) -> FdSupport {
        FdSupport::Carried
    }

    fn send_fd(&mut self, frame: &FdFrame) -> Result<(), BusError> {
        self.sender.send(CanFrame::Fd(*frame))
    }

    fn recv(&mut self, timeout: Option<Duration>) -> Result<Option<Message<Frame>>, BusError> {
        let deadline = timeout.map(|t| Instant::now() + t);
        loop {
            let left = deadline.map(|d| d.saturating_duration_since(Instant::now()));
            match self.recv_event(left)? {
                Some(m) => {
                    if let Record::Frame(f) = m.record {
                        return Ok(Some(Message {
                            at: m.at,
                            channel: m.channel,
                            direction: m.direction,
                            record: f,
                        }));
                    }
                }
                None => return Ok(None),
            }
        }
    }

    fn recv_event(&mut self, timeout: Option<Duration>) -> Result<Option<Message>, BusError> {
        let deadline = timeout.map(|t| Instant::now() + t);
        loop {
            let got = match deadline {
                None => self
                    .inbox
                    .recv()
                    .map_err(|_| RecvTimeoutError::Disconnected),
                Some(d) => self
                    .inbox
                    .recv_timeout(d.saturating_duration_since(Instant::now())),
            };
            match got {
                Ok(Inbound::Frame(frame)) => {
                    if let Some(m) = self.message(frame) {
                        return Ok(Some(m));
                    }
                }
                Ok(Inbound::Failed(e)) => return Err(e),
                Err(RecvTimeoutError::Timeout) => return Ok(None),
                Err(RecvTimeoutError::Disconnected) => return Err(BusError::Closed),
            }
        }
    }

    fn set_error_frames(&mut self, on: bool) -> Result<(), BusError> {
        self.error_frames = on;
        Ok(())
    }

    fn set_filters(&mut self, filters: &[Filter]) -> Result<(), BusError> {
        self.filters = filters.to_vec();
        Ok(())
    }

    fn state(&mut self) -> Result<ErrorState, BusError> {
        // No controller of its own: the remote buses' states are theirs.
        Ok(ErrorState::Active)
    }

    fn channel_info(&self) -> String {
        self.url.clone()
    }
}

impl Drop for JoinBus {
    fn drop(&mut self) {
        tracing::info!("{}: {}", self.url, self.report());
    }
}
