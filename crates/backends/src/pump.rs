//! A bus driven by a thread of its own, so frames can be handed to it while it waits for
//! frames: a [`CanBus`] is used through one `&mut` at a time, and a bridge or an adapter model
//! must send to a bus and receive from it at once.
//!
//! The thread alternates between the jobs handed to it (frames to send, work on the bus) and
//! waiting for the bus at most [`JOB_LATENCY`]; everything it receives goes to a callback.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{self, Receiver, SyncSender, TryRecvError};
use std::thread::JoinHandle;
use std::time::Duration;

use buslab_bus::{BusError, CanBus, Message};
use buslab_can::Frame;

use crate::DynBus;

/// How long a job (a frame to send) waits at most while the thread waits for the bus.
pub const JOB_LATENCY: Duration = Duration::from_millis(2);

/// Jobs waiting for the thread at most; beyond, [`Pump::send`] blocks (pushing back on whoever
/// feeds the bus faster than it takes frames).
pub const QUEUE: usize = 1024;

/// What the pump reports to its callback.
#[derive(Debug)]
pub enum PumpEvent {
    /// A frame or error frame from the bus.
    Received(Message),
    /// A frame the bus refused (it is dropped).
    SendFailed { frame: Frame, error: BusError },
    /// Receiving failed: the pump stops.
    Failed(BusError),
}

/// Work on the bus, run by the pump's thread between waits.
pub type BusJob = Box<dyn FnOnce(&mut dyn CanBus) + Send>;

enum Job {
    Send(Frame),
    Run(BusJob),
}

/// The pump was stopped or its bus failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[error("the bus is no longer served (its pump stopped)")]
pub struct PumpStopped;

/// Why [`PumpSender::try_send`] did not queue a frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum TrySendError {
    #[error("{QUEUE} frames already wait for the bus")]
    Full,
    #[error(transparent)]
    Stopped(#[from] PumpStopped),
}

/// A handle that hands frames to a pump from any thread.
#[derive(Clone)]
pub struct PumpSender(SyncSender<Job>);

impl PumpSender {
    /// Queues a frame for the bus (blocks while [`QUEUE`] jobs wait).
    pub fn send(&self, frame: Frame) -> Result<(), PumpStopped> {
        self.0.send(Job::Send(frame)).map_err(|_| PumpStopped)
    }

    /// Queues a frame unless [`QUEUE`] jobs wait already. Whoever forwards frames between
    /// pumps must not block (two pumps waiting on each other's full queues would wait
    /// forever): a full queue means the bus does not take frames as fast as they come, and
    /// the frame is dropped, as a gateway drops them when the interface queue is full.
    pub fn try_send(&self, frame: Frame) -> Result<(), TrySendError> {
        self.0.try_send(Job::Send(frame)).map_err(|e| match e {
            mpsc::TrySendError::Full(_) => TrySendError::Full,
            mpsc::TrySendError::Disconnected(_) => TrySendError::Stopped(PumpStopped),
        })
    }

    /// Runs `job` on the bus from the pump's thread.
    pub fn run(&self, job: BusJob) -> Result<(), PumpStopped> {
        self.0.send(Job::Run(job)).map_err(|_| PumpStopped)
    }
}

/// A bus with its thread. Dropping it sends what is still queued, then stops the thread.
pub struct Pump {
    sender: PumpSender,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl Pump {
    /// Starts a thread named `name` that owns `bus` and gives `on_event` everything it
    /// receives; `on_event` returns `false` to stop the pump.
    pub fn spawn(
        name: &str,
        bus: DynBus,
        on_event: impl FnMut(PumpEvent) -> bool + Send + 'static,
    ) -> std::io::Result<Self> {
        let (tx, rx) = mpsc::sync_channel(QUEUE);
        let stop = Arc::new(AtomicBool::new(false));
        let thread = std::thread::Builder::new().name(name.to_string()).spawn({
            let stop = stop.clone();
            move || run(bus, &rx, &stop, on_event)
        })?;
        Ok(Self {
            sender: PumpSender(tx),
            stop,
            thread: Some(thread),
        })
    }

    pub fn sender(&self) -> PumpSender {
        self.sender.clone()
    }

    /// Queues a frame for the bus (blocks while [`QUEUE`] jobs wait).
    pub fn send(&self, frame: Frame) -> Result<(), PumpStopped> {
        self.sender.send(frame)
    }

    /// Queues a frame unless the queue is full (see [`PumpSender::try_send`]).
    pub fn try_send(&self, frame: Frame) -> Result<(), TrySendError> {
        self.sender.try_send(frame)
    }

    /// Whether the thread has ended (its bus failed or the callback said stop).
    pub fn is_finished(&self) -> bool {
        self.thread.as_ref().is_none_or(JoinHandle::is_finished)
    }
}

impl Drop for Pump {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

fn run(
    mut bus: DynBus,
    jobs: &Receiver<Job>,
    stop: &AtomicBool,
    mut on_event: impl FnMut(PumpEvent) -> bool,
) {
    // A frame the bus's queue had no room for: tried again before any later job.
    let mut held: Option<Frame> = None;
    loop {
        let stopping = stop.load(Ordering::SeqCst);
        loop {
            let job = match held.take() {
                Some(frame) => Job::Send(frame),
                None => match jobs.try_recv() {
                    Ok(job) => job,
                    Err(TryRecvError::Empty | TryRecvError::Disconnected) => break,
                },
            };
            match job {
                Job::Send(frame) => match bus.send(&frame) {
                    Ok(()) => {}
                    Err(BusError::QueueFull(_)) if !stopping => {
                        held = Some(frame);
                        break;
                    }
                    Err(error) => {
                        if !on_event(PumpEvent::SendFailed { frame, error }) {
                            return;
                        }
                    }
                },
                Job::Run(job) => job(bus.as_mut()),
            }
        }
        if stopping {
            return;
        }
        match bus.recv_event(Some(JOB_LATENCY)) {
            Ok(Some(event)) => {
                if !on_event(PumpEvent::Received(event)) {
                    return;
                }
            }
            Ok(None) => {}
            Err(error) => {
                on_event(PumpEvent::Failed(error));
                return;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use buslab_bus::{ErrorState, Filter};
    use std::sync::mpsc::Sender;

    /// A bus whose transmit queue stays full; it reports each attempt.
    struct Jammed(Sender<()>);

    impl CanBus for Jammed {
        fn send(&mut self, _: &Frame) -> Result<(), BusError> {
            let _ = self.0.send(());
            Err(BusError::QueueFull("jammed".into()))
        }
        fn recv(&mut self, timeout: Option<Duration>) -> Result<Option<Message<Frame>>, BusError> {
            std::thread::sleep(timeout.unwrap_or(JOB_LATENCY));
            Ok(None)
        }
        fn set_filters(&mut self, _: &[Filter]) -> Result<(), BusError> {
            Ok(())
        }
        fn state(&mut self) -> Result<ErrorState, BusError> {
            Ok(ErrorState::Active)
        }
        fn channel_info(&self) -> String {
            "jammed".into()
        }
    }

    #[test]
    fn a_full_queue_refuses_instead_of_blocking() {
        let (tx, attempts) = mpsc::channel();
        let pump = Pump::spawn("jammed", Box::new(Jammed(tx)), |_| true).unwrap();
        let f: Frame = "123#".parse().unwrap();
        pump.try_send(f).unwrap();
        // The pump holds that frame for the bus and takes no further job meanwhile.
        attempts.recv_timeout(Duration::from_secs(60)).unwrap();
        for _ in 0..QUEUE {
            pump.try_send(f).unwrap();
        }
        assert_eq!(pump.try_send(f), Err(TrySendError::Full));
        drop(pump);
    }
}
