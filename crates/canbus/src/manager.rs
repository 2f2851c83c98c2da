//! The single owner of a driver (the seed's `SjaManager`): one thread owns the
//! [`Sja1000Driver`] and is the only one touching the chip. Other threads hold a
//! [`ManagerHandle`]: they subscribe to received frames, status changes and error-register
//! changes, and post requests — send with confirmation, re-init, abort current, abort all.
//!
//! Sends are queued in the manager and given to the chip's single TX buffer one at a time;
//! each [`Confirmation`] resolves when its frame has left (or could not leave) the chip.

use std::collections::VecDeque;
use std::fmt;
use std::sync::mpsc::{self, Receiver, RecvTimeoutError, Sender};
use std::sync::{Arc, Mutex, OnceLock};
use std::thread::{self, JoinHandle};
use std::time::{Duration, Instant};

use buslab_can::Frame;

use crate::bus::{self, BusError, CanBus, ErrorState, Filter, Message, Timestamp};
use crate::config::Sja1000Config;
use crate::decode::{ErrorRegisters, RegisterDump, Status};
use crate::driver::{ControllerState, DriverError, DriverEvent, Sja1000Driver, TxFailure, TxMode};
use crate::regs::RegisterAccess;

/// Where message times come from.
pub type Clock = Arc<dyn Fn() -> Timestamp + Send + Sync>;

pub use crate::bus::wall_clock;

/// How the manager runs.
#[derive(Clone)]
pub struct ManagerConfig {
    /// How often the chip is polled when no request arrives (the seed's
    /// `managersleepingtime`; zero polls without pause). Default 1 ms.
    pub poll_interval: Duration,
    /// The channel name put in every [`Message`]. Default `"sja1000"`.
    pub channel: String,
    /// Timestamps for received messages. Default: wall clock ([`wall_clock`]).
    pub clock: Clock,
}

impl Default for ManagerConfig {
    fn default() -> Self {
        Self {
            poll_interval: Duration::from_millis(1),
            channel: "sja1000".into(),
            clock: Arc::new(wall_clock),
        }
    }
}

impl fmt::Debug for ManagerConfig {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("ManagerConfig")
            .field("poll_interval", &self.poll_interval)
            .field("channel", &self.channel)
            .finish_non_exhaustive()
    }
}

/// Why a send was not confirmed.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum SendError {
    #[error("the transmission was aborted")]
    Aborted,
    #[error("the single-shot transmission failed")]
    Failed,
    #[error("the controller is bus-off")]
    BusOff,
    #[error("no confirmation within the timeout")]
    Timeout,
    #[error("the manager has shut down")]
    Shutdown,
    #[error("the driver refused the frame: {0}")]
    Rejected(DriverError),
}

/// A request to the manager failed.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ManagerError {
    #[error("the manager has shut down")]
    Shutdown,
    #[error(transparent)]
    Driver(#[from] DriverError),
}

/// The outcome of one [`ManagerHandle::send`]. Once known it is kept: asking again gives the
/// same answer.
#[derive(Debug)]
pub struct Confirmation {
    rx: Receiver<Result<(), SendError>>,
    outcome: OnceLock<Result<(), SendError>>,
}

impl Confirmation {
    fn new(rx: Receiver<Result<(), SendError>>) -> Self {
        Self {
            rx,
            outcome: OnceLock::new(),
        }
    }

    /// Waits for the outcome; `None` waits as long as it takes. `Timeout` leaves the frame
    /// queued (it may still be sent, and a later `wait` can still see it confirmed).
    pub fn wait(&self, timeout: Option<Duration>) -> Result<(), SendError> {
        if let Some(outcome) = self.outcome.get() {
            return outcome.clone();
        }
        let outcome = match timeout {
            None => self.rx.recv().unwrap_or(Err(SendError::Shutdown)),
            Some(t) => match self.rx.recv_timeout(t) {
                Ok(result) => result,
                Err(RecvTimeoutError::Timeout) => return Err(SendError::Timeout),
                Err(RecvTimeoutError::Disconnected) => Err(SendError::Shutdown),
            },
        };
        self.outcome.get_or_init(|| outcome).clone()
    }

    /// The outcome if it is known already.
    pub fn try_result(&self) -> Option<Result<(), SendError>> {
        if let Some(outcome) = self.outcome.get() {
            return Some(outcome.clone());
        }
        let outcome = match self.rx.try_recv() {
            Ok(result) => result,
            Err(mpsc::TryRecvError::Empty) => return None,
            Err(mpsc::TryRecvError::Disconnected) => Err(SendError::Shutdown),
        };
        Some(self.outcome.get_or_init(|| outcome).clone())
    }
}

type Reply<T> = Sender<Result<T, ManagerError>>;

enum Request {
    Send {
        frame: Frame,
        mode: TxMode,
        reply: Sender<Result<(), SendError>>,
    },
    Reinit(Box<Sja1000Config>, Reply<()>),
    Restart(Reply<()>),
    AbortCurrent,
    AbortAll,
    Frames(Sender<Message<Frame>>),
    Status(Sender<Status>),
    Errors(Sender<ErrorRegisters>),
    Events(Sender<DriverEvent>),
    Snapshot(Sender<Snapshot>),
    Dump(Sender<RegisterDump>),
    Shutdown,
}

/// What [`ManagerHandle::snapshot`] returns.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Snapshot {
    pub status: Status,
    pub state: ControllerState,
    /// `None` in BasicCAN mode.
    pub errors: Option<ErrorRegisters>,
    /// The configuration of the last successful init, if any.
    pub config: Option<Sja1000Config>,
    /// Frames queued in the manager, including the one in the TX buffer.
    pub queued: usize,
}

/// Starts managers.
pub struct Manager;

impl Manager {
    /// Moves `driver` into a new thread that owns it until [`ManagerHandle::shutdown`] (or
    /// until every handle is dropped). The driver may be initialised already or later with
    /// [`ManagerHandle::reinit`].
    pub fn start<R: RegisterAccess + Send + 'static>(
        driver: Sja1000Driver<R>,
        config: ManagerConfig,
    ) -> ManagerHandle {
        let (tx, rx) = mpsc::channel();
        let worker = Worker::new(driver, config);
        let join = thread::Builder::new()
            .name("sja1000-manager".into())
            .spawn(move || worker.run(rx))
            .expect("spawning the manager thread");
        ManagerHandle {
            tx,
            join: Arc::new(Mutex::new(Some(join))),
        }
    }
}

/// Talks to a running manager. Cheap to clone; every clone reaches the same thread.
#[derive(Clone)]
pub struct ManagerHandle {
    tx: Sender<Request>,
    join: Arc<Mutex<Option<JoinHandle<()>>>>,
}

impl fmt::Debug for ManagerHandle {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("ManagerHandle").finish_non_exhaustive()
    }
}

impl ManagerHandle {
    fn post(&self, request: Request) -> Result<(), ManagerError> {
        self.tx.send(request).map_err(|_| ManagerError::Shutdown)
    }

    fn ask<T>(&self, make: impl FnOnce(Sender<T>) -> Request) -> Result<T, ManagerError> {
        let (tx, rx) = mpsc::channel();
        self.post(make(tx))?;
        rx.recv().map_err(|_| ManagerError::Shutdown)
    }

    /// Every received frame from now on. Dropping the receiver unsubscribes.
    pub fn subscribe_frames(&self) -> Receiver<Message<Frame>> {
        let (tx, rx) = mpsc::channel();
        let _ = self.post(Request::Frames(tx));
        rx
    }

    /// The status register now, then each time it changes (as seen by the polls).
    pub fn subscribe_status(&self) -> Receiver<Status> {
        let (tx, rx) = mpsc::channel();
        let _ = self.post(Request::Status(tx));
        rx
    }

    /// The error registers now, then each time they change (PeliCAN only: nothing arrives
    /// in BasicCAN mode).
    pub fn subscribe_errors(&self) -> Receiver<ErrorRegisters> {
        let (tx, rx) = mpsc::channel();
        let _ = self.post(Request::Errors(tx));
        rx
    }

    /// Every driver event (received and sent frames, errors, state changes) from now on.
    pub fn subscribe_events(&self) -> Receiver<DriverEvent> {
        let (tx, rx) = mpsc::channel();
        let _ = self.post(Request::Events(tx));
        rx
    }

    /// Queues `frame`; the confirmation resolves when it has been sent.
    pub fn send(&self, frame: Frame) -> Confirmation {
        self.send_with(frame, TxMode::Normal)
    }

    /// Queues `frame` with a transmission mode (single-shot, self-reception).
    pub fn send_with(&self, frame: Frame, mode: TxMode) -> Confirmation {
        let (reply, rx) = mpsc::channel();
        let _ = self.post(Request::Send { frame, mode, reply });
        Confirmation::new(rx)
    }

    /// Re-initialises the chip; queued and pending sends fail with [`SendError::Aborted`].
    pub fn reinit(&self, config: Sja1000Config) -> Result<(), ManagerError> {
        self.ask(|tx| Request::Reinit(Box::new(config), tx))?
    }

    /// Back on the bus after bus-off ([`Sja1000Driver::restart`]).
    pub fn restart(&self) -> Result<(), ManagerError> {
        self.ask(Request::Restart)?
    }

    /// Aborts the frame in the TX buffer (one already on the bus still completes).
    pub fn abort_current(&self) {
        let _ = self.post(Request::AbortCurrent);
    }

    /// Aborts the current frame and fails every queued one with [`SendError::Aborted`].
    pub fn abort_all(&self) {
        let _ = self.post(Request::AbortAll);
    }

    /// Status, state, error registers, configuration and queue length.
    pub fn snapshot(&self) -> Result<Snapshot, ManagerError> {
        self.ask(Request::Snapshot)
    }

    pub fn status(&self) -> Result<Status, ManagerError> {
        Ok(self.snapshot()?.status)
    }

    pub fn state(&self) -> Result<ControllerState, ManagerError> {
        Ok(self.snapshot()?.state)
    }

    pub fn error_registers(&self) -> Result<Option<ErrorRegisters>, ManagerError> {
        Ok(self.snapshot()?.errors)
    }

    pub fn register_dump(&self) -> Result<RegisterDump, ManagerError> {
        self.ask(Request::Dump)
    }

    /// Whether the manager thread still runs.
    pub fn is_running(&self) -> bool {
        let join = self.join.lock().unwrap_or_else(|p| p.into_inner());
        join.as_ref().is_some_and(|j| !j.is_finished())
    }

    /// Stops the thread (pending confirmations fail with [`SendError::Shutdown`],
    /// subscriptions end) and waits for it. Safe to call more than once.
    pub fn shutdown(&self) {
        let _ = self.post(Request::Shutdown);
        let join = self.join.lock().unwrap_or_else(|p| p.into_inner()).take();
        if let Some(join) = join {
            let _ = join.join();
        }
    }

    /// A [`CanBus`] view of this manager.
    pub fn bus(&self, channel: impl Into<String>) -> ManagerBus {
        ManagerBus {
            frames: self.subscribe_frames(),
            handle: self.clone(),
            filters: Vec::new(),
            channel: channel.into(),
            confirm_timeout: None,
        }
    }
}

/// A managed SJA1000 as a python-can-like bus. Filters are applied in software.
#[derive(Debug)]
pub struct ManagerBus {
    handle: ManagerHandle,
    frames: Receiver<Message<Frame>>,
    filters: Vec<Filter>,
    channel: String,
    /// `Some(t)`: `send` waits up to `t` for the confirmation and reports failures;
    /// `None` (default): `send` returns once the frame is queued.
    pub confirm_timeout: Option<Duration>,
}

impl ManagerBus {
    pub fn handle(&self) -> &ManagerHandle {
        &self.handle
    }
}

impl CanBus for ManagerBus {
    fn send(&mut self, frame: &Frame) -> Result<(), BusError> {
        let confirmation = self.handle.send(*frame);
        let outcome = match self.confirm_timeout {
            Some(t) => confirmation.wait(Some(t)),
            None => match confirmation.try_result() {
                Some(Err(SendError::Shutdown)) => Err(SendError::Shutdown),
                _ => Ok(()),
            },
        };
        match outcome {
            Ok(()) => Ok(()),
            Err(SendError::Shutdown) => Err(BusError::Closed),
            Err(e) => Err(BusError::Rejected(Box::new(e))),
        }
    }

    fn recv(&mut self, timeout: Option<Duration>) -> Result<Option<Message<Frame>>, BusError> {
        let deadline = timeout.map(|t| Instant::now() + t);
        loop {
            let message = match deadline {
                None => self.frames.recv().map_err(|_| BusError::Closed)?,
                Some(deadline) => {
                    let left = deadline.saturating_duration_since(Instant::now());
                    match self.frames.recv_timeout(left) {
                        Ok(message) => message,
                        Err(RecvTimeoutError::Timeout) => return Ok(None),
                        Err(RecvTimeoutError::Disconnected) => return Err(BusError::Closed),
                    }
                }
            };
            if bus::matches_any(&self.filters, &message.record) {
                return Ok(Some(message));
            }
        }
    }

    fn set_filters(&mut self, filters: &[Filter]) -> Result<(), BusError> {
        self.filters = filters.to_vec();
        Ok(())
    }

    fn state(&mut self) -> Result<ErrorState, BusError> {
        self.handle
            .state()
            .map(ControllerState::error_state)
            .map_err(|_| BusError::Closed)
    }

    fn channel_info(&self) -> String {
        format!("SJA1000 manager on {}", self.channel)
    }
}

/// A queued send.
struct Pending {
    frame: Frame,
    mode: TxMode,
    reply: Sender<Result<(), SendError>>,
}

/// The manager's state and decisions, without the thread: [`handle`](Self::handle) one
/// request, [`tick`](Self::tick) once per poll. [`run`](Self::run) is the thread's loop; tests
/// call the steps by hand to interleave requests, bus bit-times and polls exactly.
struct Worker<R: RegisterAccess> {
    driver: Sja1000Driver<R>,
    config: ManagerConfig,
    queue: VecDeque<Pending>,
    current: Option<Pending>,
    frames: Vec<Sender<Message<Frame>>>,
    statuses: Vec<Sender<Status>>,
    errors: Vec<Sender<ErrorRegisters>>,
    events: Vec<Sender<DriverEvent>>,
    last_status: Option<Status>,
    last_errors: Option<ErrorRegisters>,
}

/// Sends `value` to every subscriber, forgetting those that hung up.
fn publish<T: Clone>(subscribers: &mut Vec<Sender<T>>, value: &T) {
    subscribers.retain(|s| s.send(value.clone()).is_ok());
}

impl<R: RegisterAccess> Worker<R> {
    fn new(driver: Sja1000Driver<R>, config: ManagerConfig) -> Self {
        Self {
            driver,
            config,
            queue: VecDeque::new(),
            current: None,
            frames: Vec::new(),
            statuses: Vec::new(),
            errors: Vec::new(),
            events: Vec::new(),
            last_status: None,
            last_errors: None,
        }
    }

    fn run(mut self, requests: Receiver<Request>) {
        loop {
            let first = match requests.recv_timeout(self.config.poll_interval) {
                Ok(request) => Some(request),
                Err(RecvTimeoutError::Timeout) => None,
                Err(RecvTimeoutError::Disconnected) => break,
            };
            let mut stop = false;
            for request in first.into_iter().chain(requests.try_iter()) {
                stop |= !self.handle(request);
            }
            if stop {
                break;
            }
            self.tick();
        }
        self.fail_all(SendError::Shutdown);
    }

    /// Handles one request; `false` means shut down.
    fn handle(&mut self, request: Request) -> bool {
        match request {
            // A bus-off controller refuses it in `feed`.
            Request::Send { frame, mode, reply } => {
                self.queue.push_back(Pending { frame, mode, reply })
            }
            Request::Reinit(config, reply) => {
                self.fail_all(SendError::Aborted);
                let result = self.driver.init(&config).map_err(ManagerError::from);
                let _ = reply.send(result);
            }
            Request::Restart(reply) => {
                self.fail_current(SendError::Aborted);
                let _ = reply.send(self.driver.restart().map_err(ManagerError::from));
            }
            Request::AbortCurrent => self.driver.abort(),
            Request::AbortAll => {
                for pending in self.queue.drain(..) {
                    let _ = pending.reply.send(Err(SendError::Aborted));
                }
                self.driver.abort();
            }
            Request::Frames(tx) => self.frames.push(tx),
            Request::Status(tx) => {
                let status = self.driver.status();
                if tx.send(status).is_ok() {
                    self.statuses.push(tx);
                }
            }
            Request::Errors(tx) => {
                let errors = self.driver.error_registers();
                if errors.is_none_or(|e| tx.send(e).is_ok()) {
                    self.errors.push(tx);
                }
            }
            Request::Events(tx) => self.events.push(tx),
            Request::Snapshot(tx) => {
                let snapshot = Snapshot {
                    status: self.driver.status(),
                    state: self.driver.state(),
                    errors: self.driver.error_registers(),
                    config: self.driver.config().cloned(),
                    queued: self.queue.len() + self.current.is_some() as usize,
                };
                let _ = tx.send(snapshot);
            }
            Request::Dump(tx) => {
                let _ = tx.send(self.driver.register_dump());
            }
            Request::Shutdown => return false,
        }
        true
    }

    /// One poll of the chip: dispatch events, feed the TX buffer, report changes.
    fn tick(&mut self) {
        for event in self.driver.poll() {
            // Event listeners hear of a sent frame before its sender is confirmed.
            publish(&mut self.events, &event);
            match &event {
                DriverEvent::Received(frame) => {
                    let message = Message::rx((self.config.clock)(), &self.config.channel, *frame);
                    publish(&mut self.frames, &message);
                }
                DriverEvent::TxDone(_) => self.finish_current(Ok(())),
                DriverEvent::TxFailed { reason, .. } => self.finish_current(Err(match reason {
                    TxFailure::Aborted => SendError::Aborted,
                    TxFailure::SingleShot => SendError::Failed,
                    TxFailure::BusOff => SendError::BusOff,
                })),
                DriverEvent::StateChanged {
                    to: ControllerState::BusOff,
                    ..
                } => self.fail_all(SendError::BusOff),
                _ => {}
            }
        }
        self.feed();
        let status = self.driver.status();
        if self.last_status != Some(status) {
            self.last_status = Some(status);
            publish(&mut self.statuses, &status);
        }
        let errors = self.driver.error_registers();
        if errors != self.last_errors {
            self.last_errors = errors;
            if let Some(errors) = errors {
                publish(&mut self.errors, &errors);
            }
        }
    }

    /// Gives the next queued frame to the chip when its TX buffer is free.
    fn feed(&mut self) {
        while self.current.is_none() && !self.driver.tx_pending() {
            let Some(next) = self.queue.pop_front() else {
                return;
            };
            match self.driver.send_with(&next.frame, next.mode) {
                Ok(()) => self.current = Some(next),
                Err(DriverError::TxBusy) => {
                    // Released by the chip on a later poll.
                    self.queue.push_front(next);
                    return;
                }
                Err(DriverError::BusOff) => {
                    let _ = next.reply.send(Err(SendError::BusOff));
                }
                Err(e) => {
                    let _ = next.reply.send(Err(SendError::Rejected(e)));
                }
            }
        }
    }

    fn finish_current(&mut self, result: Result<(), SendError>) {
        if let Some(current) = self.current.take() {
            let _ = current.reply.send(result);
        }
    }

    fn fail_current(&mut self, error: SendError) {
        self.finish_current(Err(error));
    }

    fn fail_all(&mut self, error: SendError) {
        self.fail_current(error.clone());
        for pending in self.queue.drain(..) {
            let _ = pending.reply.send(Err(error.clone()));
        }
    }
}

#[cfg(test)]
mod tests {
    //! The worker driven by hand, without its thread: requests, bus bit-times and polls
    //! interleave exactly as a test says, so races become plain sequences.

    use buslab_sja1000::Sja1000;

    use super::*;

    /// Bit-times a confirmation may take here: a few frames with their error frames.
    const BITS: u32 = 2_000;

    fn worker() -> Worker<Sja1000> {
        let mut driver = Sja1000Driver::new(Sja1000::new());
        driver.init(&Sja1000Config::default()).unwrap();
        Worker::new(driver, ManagerConfig::default())
    }

    fn send(worker: &mut Worker<Sja1000>, frame: &str) -> Confirmation {
        let (reply, rx) = mpsc::channel();
        let frame = frame.parse().unwrap();
        assert!(worker.handle(Request::Send {
            frame,
            mode: TxMode::Normal,
            reply
        }));
        Confirmation::new(rx)
    }

    /// One bit-time of a bus where this chip is alone (nobody acknowledges), then one poll.
    fn step(worker: &mut Worker<Sja1000>) {
        let chip = worker.driver.registers();
        let level = chip.output();
        chip.sample(level);
        worker.tick();
    }

    /// Steps until `done` holds; panics after [`BITS`] bit-times.
    fn step_until(
        worker: &mut Worker<Sja1000>,
        what: &str,
        done: impl Fn(&mut Worker<Sja1000>) -> bool,
    ) {
        for _ in 0..BITS {
            if done(worker) {
                return;
            }
            step(worker);
        }
        panic!("{what} did not happen within {BITS} bit-times");
    }

    /// Regression: `abort_current_fails_only_the_frame_in_the_buffer` rarely saw `Timeout`
    /// instead of `Aborted`. The first abort drops the frame at its error; the same poll that
    /// confirms it hands the next frame to the chip while the chip still sends its error frame.
    /// An abort at that instant used to be taken for "a frame on the bus, let it finish": the
    /// chip withdrew the frame yet never released its TX buffer, so no outcome ever came.
    #[test]
    fn abort_of_the_next_frame_during_the_error_frame_of_the_aborted_one_fails_it() {
        let mut worker = worker();
        let first = send(&mut worker, "100#");
        let second = send(&mut worker, "101#");
        step_until(&mut worker, "the first attempt", |w| {
            w.driver.status().transmitting()
        });
        assert!(worker.handle(Request::AbortCurrent));
        step_until(&mut worker, "the first frame's outcome", |_| {
            first.try_result().is_some()
        });
        assert_eq!(first.try_result(), Some(Err(SendError::Aborted)));
        let status = worker.driver.status();
        assert!(status.transmitting(), "still in the error frame: {status}");
        assert!(
            !status.transmit_buffer_released(),
            "the second frame is requested"
        );

        assert!(worker.handle(Request::AbortCurrent));
        step_until(&mut worker, "the second frame's outcome", |_| {
            second.try_result().is_some()
        });
        assert_eq!(second.try_result(), Some(Err(SendError::Aborted)));
        assert!(worker.queue.is_empty() && worker.current.is_none());
    }
}
