//! The shared state: the bus view, fed by the bus's pump thread and a status poller, read by
//! every request.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError};
use std::sync::{Arc, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use buslab_backends::{DynBus, Pump, PumpEvent, PumpSender};
use buslab_bus::{CanBus, NodeRef, NodeStatus};
use buslab_view::{BusView, ViewConfig};

use crate::request::MAX_WINDOW;

use crate::WebConfig;
use crate::devices::Devices;

/// What the request handlers share.
pub struct Hub {
    view: Mutex<BusView>,
    started: Instant,
    /// The bus's description (`channel_info`).
    pub channel: String,
    /// Why the bus stopped, once it did.
    failure: Mutex<Option<String>>,
    /// Frames the bus refused (sent from the dashboard).
    pub send_failures: AtomicU64,
    /// Connections refused for the connection limit.
    pub refused: AtomicU64,
    /// Whether the bus has an administration side (nodes, faults).
    pub has_admin: bool,
    /// The bench's device panels (none outside `buslab lab`).
    pub devices: Devices,
}

impl Hub {
    /// Time since the server started: the view's clock.
    pub fn now(&self) -> Duration {
        self.started.elapsed()
    }

    pub fn view(&self) -> MutexGuard<'_, BusView> {
        // A panic elsewhere must not take the pages down with it: the view stays consistent
        // between calls.
        self.view.lock().unwrap_or_else(|e| e.into_inner())
    }

    pub fn failure(&self) -> Option<String> {
        self.failure
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .clone()
    }

    fn fail(&self, why: String) {
        *self.failure.lock().unwrap_or_else(|e| e.into_inner()) = Some(why);
    }
}

/// The bus's thread and the status poller; dropping it stops both.
pub struct BusSide {
    pub hub: Arc<Hub>,
    pub sender: PumpSender,
    stop: Option<mpsc::Sender<()>>,
    poller: Option<JoinHandle<()>>,
    pump: Option<Pump>,
}

impl BusSide {
    pub fn start(mut bus: DynBus, config: &WebConfig) -> std::io::Result<Self> {
        let status_every = config.status_every;
        let channel = bus.channel_info();
        // This server's own node is not one the user watches.
        let own = bus.admin().and_then(|admin| {
            if let Err(e) = admin.set_name("buslab-web") {
                tracing::debug!("cannot name the web server's node: {e}");
            }
            admin.node_status(None).ok().map(|s| s.number)
        });
        let has_admin = bus.admin().is_some();
        // Error frames go to the log too (a bus that has none just gives frames).
        if let Err(e) = bus.set_error_frames(true) {
            tracing::debug!("no error frames from {channel}: {e}");
        }
        let hub = Arc::new(Hub {
            view: Mutex::new(BusView::new(ViewConfig {
                bitrate: config.bitrate,
                retention: MAX_WINDOW,
                dbc: config.dbc.clone(),
                ..ViewConfig::default()
            })),
            started: Instant::now(),
            channel,
            failure: Mutex::new(None),
            send_failures: AtomicU64::new(0),
            refused: AtomicU64::new(0),
            has_admin,
            devices: Devices::start(&config.devices)?,
        });
        let pump = Pump::spawn("web-bus", bus, {
            let hub = hub.clone();
            move |event| match event {
                PumpEvent::Received(message) => {
                    let now = hub.now();
                    hub.view().message(now, &message);
                    if let Some(frame) = message.frame() {
                        hub.devices.frame(frame);
                    }
                    true
                }
                PumpEvent::SendFailed { frame, error } => {
                    tracing::warn!("the bus refused {frame}: {error}");
                    hub.send_failures.fetch_add(1, Ordering::Relaxed);
                    true
                }
                PumpEvent::Failed(error) => {
                    tracing::warn!("the bus failed: {error}");
                    hub.fail(error.to_string());
                    false
                }
            }
        })?;
        let sender = pump.sender();
        let (stop, stopped) = mpsc::channel();
        let poller = std::thread::Builder::new()
            .name("web-status".into())
            .spawn({
                let hub = hub.clone();
                let sender = sender.clone();
                move || poll(&hub, &sender, own, status_every, &stopped)
            })?;
        Ok(Self {
            hub,
            sender,
            stop: Some(stop),
            poller: Some(poller),
            pump: Some(pump),
        })
    }
}

impl Drop for BusSide {
    fn drop(&mut self) {
        drop(self.stop.take());
        if let Some(p) = self.poller.take() {
            let _ = p.join();
        }
        drop(self.pump.take());
    }
}

/// Asks for every node's status every `every` (through the pump, which owns the bus) and
/// closes the view's load windows meanwhile.
fn poll(hub: &Hub, sender: &PumpSender, own: Option<u32>, every: Duration, stopped: &Receiver<()>) {
    // The first reads wait one period: a bench's own SLIO host (MoniCAN) initialises its boards
    // at start, and a read of the same board sent at the same instant is a frame of the same ID
    // with other data — the two senders collide in the data field, again at every retry, until
    // one is error passive or bus-off (seen on a loaded CI machine: MoniCAN's node bus-off).
    // What MoniCAN's initialisation reads fills the panels meanwhile.
    let mut slio_asked: Option<Instant> = Some(Instant::now());
    loop {
        let (tx, rx) = mpsc::sync_channel(1);
        let job = Box::new(move |bus: &mut dyn CanBus| {
            let _ = tx.send(statuses(bus, own));
        });
        if sender.run(job).is_err() {
            return;
        }
        // The job is dropped unrun only when the pump stops.
        let Ok(result) = rx.recv() else { return };
        let now = hub.now();
        match result {
            Some(list) => hub.view().nodes(now, list),
            None => hub.view().tick(now),
        }
        ask_slios(hub, sender, &mut slio_asked);
        match stopped.recv_timeout(every) {
            Err(RecvTimeoutError::Timeout) => {}
            Ok(()) | Err(RecvTimeoutError::Disconnected) => return,
        }
    }
}

/// How often the server asks the SLIO boards for the registers it has not heard yet.
const SLIO_ASK_EVERY: Duration = Duration::from_secs(2);

/// Fills the SLIO panels without anyone clicking: reads (which change nothing on a board) of
/// the registers not heard yet, every 2 s until every one was.
fn ask_slios(hub: &Hub, sender: &PumpSender, asked: &mut Option<Instant>) {
    if asked.is_some_and(|t| t.elapsed() < SLIO_ASK_EVERY) {
        return;
    }
    let frames = hub.devices.slio().read_requests(false);
    if frames.is_empty() {
        return;
    }
    *asked = Some(Instant::now());
    for frame in frames {
        // A full queue (a saturated bus): asked again next time.
        if sender.try_send(frame).is_err() {
            break;
        }
    }
}

/// Every node's status but this server's own; `None` if the bus has no nodes to tell of.
fn statuses(bus: &mut dyn CanBus, own: Option<u32>) -> Option<Vec<NodeStatus>> {
    let admin = bus.admin()?;
    let nodes = match admin.nodes() {
        Ok(n) => n,
        Err(e) => {
            tracing::debug!("cannot list the nodes: {e}");
            return None;
        }
    };
    let mut list = Vec::with_capacity(nodes.len());
    for node in nodes.into_iter().filter(|n| Some(n.number) != own) {
        // A node that left between the list and its status is simply not shown.
        match admin.node_status(Some(&NodeRef::Number(node.number))) {
            Ok(s) => list.push(s),
            Err(e) => tracing::debug!("node {}: {e}", node.number),
        }
    }
    Some(list)
}
