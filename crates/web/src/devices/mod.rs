//! The bench's devices as dashboard panels (`buslab lab`): the SLIO boards on the bus, the
//! ZELLE cell and the CPU196 board on their serial lines.
//!
//! The SLIO panels are learned from the bus (the pump feeds every frame to
//! [`slio::SlioPanels`]); the serial devices are driven by a worker thread each, which opens
//! the device's port only while it works, so `buslab zelle`/`buslab cpu196` on the same port
//! work between two clicks. Every change bumps [`Devices::version`]; a live viewer gets the
//! panels again when it moved.

pub mod cpu196;
pub mod slio;
pub mod zelle;

use std::path::PathBuf;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Duration;

use buslab_chips::slio::SlioId;
use serde::Serialize;

/// The devices a server shows besides the bus (all optional).
#[derive(Clone, Debug, Default)]
pub struct DeviceConfig {
    /// SLIO demo boards on the bus.
    pub slios: Vec<SlioId>,
    /// The ZELLE cell's serial port (9600 8N2).
    pub zelle: Option<PathBuf>,
    /// The CPU196 board's serial port and its line rate (8N1).
    pub cpu196: Option<(PathBuf, u32)>,
}

impl DeviceConfig {
    pub fn is_empty(&self) -> bool {
        self.slios.is_empty() && self.zelle.is_none() && self.cpu196.is_none()
    }
}

/// A counter every panel bumps when it changed.
#[derive(Clone, Default)]
pub struct Version(Arc<AtomicU64>);

impl Version {
    pub fn bump(&self) {
        self.0.fetch_add(1, Ordering::Relaxed);
    }

    pub fn get(&self) -> u64 {
        self.0.load(Ordering::Relaxed)
    }
}

/// Locks, going on with the state a panicked thread left (each state is whole between calls).
/// How long a panel waits for a port another client holds (a `buslab zelle` in a terminal),
/// and for a device's answer beyond its time on the line. A dashboard shares its machine with
/// everything else; a late answer is better than a failed measurement.
pub(crate) const PANEL_PATIENCE: Duration = Duration::from_secs(5);

pub(crate) fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

/// The panels and their workers.
pub struct Devices {
    slio: Mutex<slio::SlioPanels>,
    pub zelle: Option<zelle::ZelleWorker>,
    pub cpu196: Option<cpu196::Cpu196Worker>,
    version: Version,
}

/// Every panel, as `/api/devices` and the live updates give it.
#[derive(Serialize)]
pub struct DevicesView {
    pub version: u64,
    pub slio: Vec<slio::BoardView>,
    pub zelle: Option<zelle::ZelleView>,
    pub cpu196: Option<cpu196::Cpu196View>,
}

impl Devices {
    pub fn start(config: &DeviceConfig) -> std::io::Result<Self> {
        let version = Version::default();
        let zelle = match &config.zelle {
            Some(port) => Some(zelle::ZelleWorker::spawn(port.clone(), version.clone())?),
            None => None,
        };
        let cpu196 = match &config.cpu196 {
            Some((port, baud)) => Some(cpu196::Cpu196Worker::spawn(
                port.clone(),
                *baud,
                version.clone(),
            )?),
            None => None,
        };
        Ok(Self {
            slio: Mutex::new(slio::SlioPanels::new(&config.slios)),
            zelle,
            cpu196,
            version,
        })
    }

    pub fn is_empty(&self) -> bool {
        lock(&self.slio).is_empty() && self.zelle.is_none() && self.cpu196.is_none()
    }

    pub fn version(&self) -> u64 {
        self.version.get()
    }

    pub fn slio(&self) -> MutexGuard<'_, slio::SlioPanels> {
        lock(&self.slio)
    }

    /// A frame on the bus: only SLIO frames lock the panels.
    pub fn frame(&self, frame: &buslab_can::Frame) {
        if SlioId::from_id(frame.id()).is_some() && self.slio().frame(frame) {
            self.version.bump();
        }
    }

    pub fn changed(&self) {
        self.version.bump();
    }

    pub fn view(&self) -> DevicesView {
        DevicesView {
            version: self.version(),
            slio: self.slio().view(),
            zelle: self.zelle.as_ref().map(|z| z.view()),
            cpu196: self.cpu196.as_ref().map(|c| c.view()),
        }
    }
}
