//! A bus driven by a thread of its own, so frames can be handed to it while it waits for
//! frames: a [`CanBus`] is used through one `&mut` at a time, and a bridge or an adapter model
//! must send to a bus and receive from it at once.
//!
//! The thread alternates between the jobs handed to it (frames to send, work on the bus) and
//! waiting for the bus; everything it receives goes to a callback. A job ends the wait: the
//! bus's [`RecvWaker`] wakes it, so a frame handed to an idle bus is sent at once. A bus
//! without one is waited for at most [`JOB_LATENCY`] at a time.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering, fence};
use std::sync::mpsc::{self, Receiver, SyncSender, TryRecvError};
use std::thread::JoinHandle;
use std::time::Duration;

use buslab_bus::{BusError, CanBus, Message, Record, RecvWaker};
use buslab_can::{FdFrame, Frame};

use crate::DynBus;

/// How long a job (a frame to send) waits at most while the thread waits for a bus that has
/// no [`RecvWaker`], and how long a frame the bus's full queue refused waits to be tried again.
pub const JOB_LATENCY: Duration = Duration::from_millis(2);

/// Jobs waiting for the thread at most; beyond, [`Pump::send`] blocks (pushing back on whoever
/// feeds the bus faster than it takes frames).
pub const QUEUE: usize = 1024;

/// What the pump reports to its callback.
#[derive(Debug)]
pub enum PumpEvent {
    /// A frame or error frame from the bus.
    Received(Message),
    /// A frame (classic or FD: [`Record::Frame`] or [`Record::Fd`]) the bus refused; it is
    /// dropped.
    SendFailed { frame: Record, error: BusError },
    /// Receiving failed: the pump stops.
    Failed(BusError),
}

/// Work on the bus, run by the pump's thread between waits.
pub type BusJob = Box<dyn FnOnce(&mut dyn CanBus) + Send>;

enum Job {
    Send(Outgoing),
    Run(BusJob),
}

/// A frame to send, classic or FD.
#[derive(Clone, Copy)]
enum Outgoing {
    Classic(Frame),
    Fd(FdFrame),
}

impl Outgoing {
    fn send(&self, bus: &mut dyn CanBus) -> Result<(), BusError> {
        match self {
            Outgoing::Classic(frame) => bus.send(frame),
            Outgoing::Fd(frame) => bus.send_fd(frame),
        }
    }

    fn into_record(self) -> Record {
        match self {
            Outgoing::Classic(frame) => Record::Frame(frame),
            Outgoing::Fd(frame) => Record::Fd(frame),
        }
    }
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

/// Wakes the pump's thread when a job comes while it waits for the bus.
struct Alarm {
    waker: Option<Arc<dyn RecvWaker>>,
    /// The thread waits for the bus (or is about to): a job must wake it. Only then, so a
    /// busy pump is not woken once per frame.
    waiting: AtomicBool,
}

impl Alarm {
    /// After a job was queued.
    fn job_queued(&self) {
        let Some(waker) = &self.waker else { return };
        // Pairs with the fence in [`Alarm::about_to_wait`]: either the thread sees the job
        // before it waits, or this sees it waiting.
        fence(Ordering::SeqCst);
        if self.waiting.swap(false, Ordering::SeqCst) {
            waker.wake();
        }
    }

    /// Before the thread looks at the queue a last time and waits.
    fn about_to_wait(&self) {
        self.waiting.store(true, Ordering::SeqCst);
        fence(Ordering::SeqCst);
    }

    fn done_waiting(&self) {
        self.waiting.store(false, Ordering::SeqCst);
    }

    /// How long the thread waits for the bus: until a frame or a job when a job wakes it,
    /// else [`JOB_LATENCY`].
    fn wait(&self) -> Option<Duration> {
        match self.waker {
            Some(_) => None,
            None => Some(JOB_LATENCY),
        }
    }
}

/// A handle that hands frames to a pump from any thread.
#[derive(Clone)]
pub struct PumpSender {
    jobs: SyncSender<Job>,
    alarm: Arc<Alarm>,
}

impl PumpSender {
    /// Queues a frame for the bus (blocks while [`QUEUE`] jobs wait).
    pub fn send(&self, frame: Frame) -> Result<(), PumpStopped> {
        self.queue(Job::Send(Outgoing::Classic(frame)))
    }

    /// Queues a CAN FD frame for the bus (blocks while [`QUEUE`] jobs wait); a bus that
    /// carries no FD refuses it ([`PumpEvent::SendFailed`]).
    pub fn send_fd(&self, frame: FdFrame) -> Result<(), PumpStopped> {
        self.queue(Job::Send(Outgoing::Fd(frame)))
    }

    fn queue(&self, job: Job) -> Result<(), PumpStopped> {
        self.jobs.send(job).map_err(|_| PumpStopped)?;
        self.alarm.job_queued();
        Ok(())
    }

    /// Queues a frame unless [`QUEUE`] jobs wait already. Whoever forwards frames between
    /// pumps must not block (two pumps waiting on each other's full queues would wait
    /// forever): a full queue means the bus does not take frames as fast as they come, and
    /// the frame is dropped, as a gateway drops them when the interface queue is full.
    pub fn try_send(&self, frame: Frame) -> Result<(), TrySendError> {
        self.try_queue(Job::Send(Outgoing::Classic(frame)))
    }

    /// [`Self::try_send`] for a CAN FD frame.
    pub fn try_send_fd(&self, frame: FdFrame) -> Result<(), TrySendError> {
        self.try_queue(Job::Send(Outgoing::Fd(frame)))
    }

    fn try_queue(&self, job: Job) -> Result<(), TrySendError> {
        self.jobs.try_send(job).map_err(|e| match e {
            mpsc::TrySendError::Full(_) => TrySendError::Full,
            mpsc::TrySendError::Disconnected(_) => TrySendError::Stopped(PumpStopped),
        })?;
        self.alarm.job_queued();
        Ok(())
    }

    /// Runs `job` on the bus from the pump's thread.
    pub fn run(&self, job: BusJob) -> Result<(), PumpStopped> {
        self.queue(Job::Run(job))
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
        mut bus: DynBus,
        on_event: impl FnMut(PumpEvent) -> bool + Send + 'static,
    ) -> std::io::Result<Self> {
        let (tx, rx) = mpsc::sync_channel(QUEUE);
        let stop = Arc::new(AtomicBool::new(false));
        let waker = bus.recv_waker();
        match waker {
            Some(_) => tracing::debug!("{name}: a job wakes the wait for {}", bus.channel_info()),
            None => tracing::debug!(
                "{name}: {} cannot be woken, a job waits up to {JOB_LATENCY:?}",
                bus.channel_info()
            ),
        }
        let alarm = Arc::new(Alarm {
            waker,
            waiting: AtomicBool::new(false),
        });
        let thread = std::thread::Builder::new().name(name.to_string()).spawn({
            let stop = stop.clone();
            let alarm = alarm.clone();
            move || run(bus, &rx, &alarm, &stop, on_event)
        })?;
        Ok(Self {
            sender: PumpSender { jobs: tx, alarm },
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

    /// Queues a CAN FD frame unless the queue is full (see [`PumpSender::try_send`]).
    pub fn try_send_fd(&self, frame: FdFrame) -> Result<(), TrySendError> {
        self.sender.try_send_fd(frame)
    }

    /// Whether the thread has ended (its bus failed or the callback said stop).
    pub fn is_finished(&self) -> bool {
        self.thread.as_ref().is_none_or(JoinHandle::is_finished)
    }
}

impl Drop for Pump {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        // A thread waiting for the bus sees the stop now.
        if let Some(waker) = &self.sender.alarm.waker {
            waker.wake();
        }
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

fn run(
    mut bus: DynBus,
    jobs: &Receiver<Job>,
    alarm: &Alarm,
    stop: &AtomicBool,
    mut on_event: impl FnMut(PumpEvent) -> bool,
) {
    // A frame the bus's queue had no room for: tried again before any later job.
    let mut held: Option<Outgoing> = None;
    // A job found while getting ready to wait: done before any later one.
    let mut next: Option<Job> = None;
    loop {
        let stopping = stop.load(Ordering::SeqCst);
        loop {
            let job = match (held.take(), next.take()) {
                (Some(frame), _) => Job::Send(frame),
                (None, Some(job)) => job,
                (None, None) => match jobs.try_recv() {
                    Ok(job) => job,
                    Err(TryRecvError::Empty | TryRecvError::Disconnected) => break,
                },
            };
            let frame = match job {
                Job::Send(frame) => frame,
                Job::Run(job) => {
                    job(bus.as_mut());
                    continue;
                }
            };
            match frame.send(bus.as_mut()) {
                Ok(()) => {}
                Err(BusError::QueueFull(_)) if !stopping => {
                    held = Some(frame);
                    break;
                }
                Err(error) => {
                    let frame = frame.into_record();
                    if !on_event(PumpEvent::SendFailed { frame, error }) {
                        return;
                    }
                }
            }
        }
        if stopping {
            return;
        }
        // A frame the bus refused is tried again after a while, not when the next job comes.
        let wait = if held.is_some() {
            Some(JOB_LATENCY)
        } else {
            alarm.about_to_wait();
            // A job queued before the alarm was set did not wake the bus: do it first.
            match jobs.try_recv() {
                Ok(job) => {
                    alarm.done_waiting();
                    next = Some(job);
                    continue;
                }
                Err(TryRecvError::Empty | TryRecvError::Disconnected) => {}
            }
            if stop.load(Ordering::SeqCst) {
                continue;
            }
            alarm.wait()
        };
        let received = bus.recv_event(wait);
        alarm.done_waiting();
        match received {
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

    /// A bus that keeps what it was given; it carries FD when `fd`.
    struct Keeping {
        fd: bool,
        sent: Sender<Record>,
    }

    impl CanBus for Keeping {
        fn fd_support(&self) -> buslab_bus::FdSupport {
            if self.fd {
                buslab_bus::FdSupport::Carried
            } else {
                buslab_bus::FdSupport::Classic(buslab_bus::NoFd::BitLevelBus)
            }
        }
        fn send(&mut self, frame: &Frame) -> Result<(), BusError> {
            let _ = self.sent.send(Record::Frame(*frame));
            Ok(())
        }
        fn send_fd(&mut self, frame: &FdFrame) -> Result<(), BusError> {
            if !self.fd {
                return Err(BusError::ClassicOnly {
                    bus: "keeping".into(),
                    why: buslab_bus::NoFd::BitLevelBus,
                });
            }
            let _ = self.sent.send(Record::Fd(*frame));
            Ok(())
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
            "keeping".into()
        }
    }

    /// A bus on which nothing ever happens: its wait for frames ends only when it is woken
    /// (whatever the timeout), so a pump that waited it out would never send.
    struct Silent {
        woken: Arc<Wake>,
        sent: Sender<Frame>,
    }

    #[derive(Default)]
    struct Wake {
        pending: std::sync::Mutex<bool>,
        changed: std::sync::Condvar,
    }

    impl RecvWaker for Wake {
        fn wake(&self) {
            *self.pending.lock().unwrap() = true;
            self.changed.notify_all();
        }
    }

    impl CanBus for Silent {
        fn send(&mut self, frame: &Frame) -> Result<(), BusError> {
            let _ = self.sent.send(*frame);
            Ok(())
        }
        fn recv(&mut self, _: Option<Duration>) -> Result<Option<Message<Frame>>, BusError> {
            let mut pending = self.woken.pending.lock().unwrap();
            while !*pending {
                pending = self.woken.changed.wait(pending).unwrap();
            }
            *pending = false;
            Ok(None)
        }
        fn set_filters(&mut self, _: &[Filter]) -> Result<(), BusError> {
            Ok(())
        }
        fn state(&mut self) -> Result<ErrorState, BusError> {
            Ok(ErrorState::Active)
        }
        fn channel_info(&self) -> String {
            "silent".into()
        }
        fn recv_waker(&mut self) -> Option<Arc<dyn RecvWaker>> {
            Some(self.woken.clone())
        }
    }

    #[test]
    fn a_frame_for_an_idle_bus_is_sent_without_waiting_for_the_bus() {
        let (tx, sent) = mpsc::channel();
        let bus = Silent {
            woken: Arc::default(),
            sent: tx,
        };
        let pump = Pump::spawn("silent", Box::new(bus), |_| true).unwrap();
        // Each frame is handed over while the pump waits for the bus (or is about to).
        for text in ["123#01", "124#02", "125#03"] {
            let f: Frame = text.parse().unwrap();
            pump.try_send(f).unwrap();
            assert_eq!(sent.recv_timeout(Duration::from_secs(60)), Ok(f));
        }
        let f: Frame = "126#04".parse().unwrap();
        pump.sender().send(f).unwrap();
        assert_eq!(sent.recv_timeout(Duration::from_secs(60)), Ok(f));
        // Dropping it ends the wait too.
        drop(pump);
    }

    #[test]
    fn frames_handed_over_from_several_threads_at_once_all_reach_an_idle_bus() {
        let (tx, sent) = mpsc::channel();
        let bus = Silent {
            woken: Arc::default(),
            sent: tx,
        };
        let pump = Pump::spawn("silent", Box::new(bus), |_| true).unwrap();
        let (threads, each) = (4u32, 2000u32);
        let senders: Vec<_> = (0..threads)
            .map(|t| {
                let to = pump.sender();
                std::thread::spawn(move || {
                    for k in 0..each {
                        let [k0, k1, k2, k3] = k.to_le_bytes();
                        let id = buslab_can::Id::standard(0x100).unwrap();
                        let f = Frame::data(id, &[t as u8, k0, k1, k2, k3]).unwrap();
                        to.send(f).unwrap();
                    }
                })
            })
            .collect();
        // A wake lost on the way would leave the rest waiting for a bus where nothing happens.
        let mut next = vec![0u32; threads as usize];
        for _ in 0..threads * each {
            let f = sent.recv_timeout(Duration::from_secs(60)).unwrap();
            let t = usize::from(f.payload()[0]);
            assert_eq!(
                f.payload()[1..],
                next[t].to_le_bytes(),
                "in order per sender"
            );
            next[t] += 1;
        }
        senders.into_iter().for_each(|s| s.join().unwrap());
        drop(pump);
    }

    #[test]
    fn fd_frames_reach_a_bus_that_carries_fd_in_order_with_classic_ones() {
        let (tx, sent) = mpsc::channel();
        let pump = Pump::spawn("fd", Box::new(Keeping { fd: true, sent: tx }), |_| true).unwrap();
        let classic: Frame = "123#01".parse().unwrap();
        let fd: FdFrame = "456##1112233445566778899AABBCC".parse().unwrap();
        pump.try_send(classic).unwrap();
        pump.try_send_fd(fd).unwrap();
        pump.sender().send_fd(fd).unwrap();
        drop(pump);
        let got: Vec<Record> = sent.iter().collect();
        assert_eq!(
            got,
            [Record::Frame(classic), Record::Fd(fd), Record::Fd(fd)]
        );
    }

    #[test]
    fn an_fd_frame_a_classic_bus_refuses_is_reported_with_the_frame_and_why() {
        let (tx, sent) = mpsc::channel();
        let (report, reports) = mpsc::channel();
        let bus = Box::new(Keeping {
            fd: false,
            sent: tx,
        });
        let pump = Pump::spawn("classic", bus, move |event| {
            if let PumpEvent::SendFailed { frame, error } = event {
                let _ = report.send((frame, error));
            }
            true
        })
        .unwrap();
        let fd: FdFrame = "456##0AA".parse().unwrap();
        pump.try_send_fd(fd).unwrap();
        let (frame, error) = reports.recv_timeout(Duration::from_secs(60)).unwrap();
        assert_eq!(frame, Record::Fd(fd));
        assert!(matches!(error, BusError::ClassicOnly { .. }), "{error:?}");
        drop(pump);
        assert_eq!(sent.iter().count(), 0);
    }
}
