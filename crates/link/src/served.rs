//! One device model served on a pseudo-terminal by a background thread: the adapter every
//! served device uses (`buslab zelle serve`, `buslab cpu196 serve`, `buslab lab`, tests).
//!
//! It opens the PTY (and an optional symlink to it), paces the device with [`serve`], runs
//! work on the device from other threads, and keeps a [`Persistent`] device's state in a file:
//! written at start (so a file that cannot be written is an error at once, not a lost change
//! later), whenever the state changed (looked at periodically, between two byte events, so it
//! is never seen half-updated), on request, and when serving stops. All writes of one device go
//! through one saver thread in the order the snapshots were taken, each with
//! [`write_atomic`](crate::fs::write_atomic). Dropping the handle stops the device.
//!
//! Between two state files the device's changes go to a [`journal`](crate::journal), synced
//! before any byte the device sends after them reaches the client: whatever the device
//! acknowledged survives a `kill -9`. The caller replays the journals into the state it builds
//! the device from ([`journal::replay`](crate::journal::replay)); the state file written at
//! start holds them, and they are deleted.
//!
//! [`serve`]: crate::serve()

use std::io;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{Receiver, Sender, channel};
use std::thread::JoinHandle;
use std::time::Duration;

use buslab_device::{ByteDevice, Changes, LineSettings, Nanos, Persistent};

use crate::Pty;
use crate::fs::write_atomic;
use crate::journal;
use crate::serve::{Control, serve_with};

/// Why a served device failed.
#[derive(Debug, thiserror::Error)]
pub enum ServedError {
    #[error("cannot open a pseudo-terminal: {0}")]
    Pty(#[source] io::Error),
    #[error("cannot make the link {}: {source}", path.display())]
    Link {
        path: PathBuf,
        #[source]
        source: io::Error,
    },
    #[error("cannot write {what} {}: {source}", path.display())]
    Save {
        what: &'static str,
        path: PathBuf,
        #[source]
        source: io::Error,
    },
    #[error("serving the device failed: {0}")]
    Serve(#[source] io::Error),
    #[error("the device is no longer served")]
    Stopped,
    #[error("the device's serve thread panicked")]
    Panicked,
}

/// A snapshot taken in the serve thread, turned into the file's bytes in the saver thread.
type Snapshot = Box<dyn FnOnce() -> Vec<u8> + Send>;

fn take_snapshot<D: Persistent>(device: &D) -> Snapshot {
    let snapshot = device.snapshot();
    Box::new(move || D::file_bytes(&snapshot))
}

/// Where and how often a device's persistent state is saved.
struct Persistence<D> {
    path: PathBuf,
    what: &'static str,
    every: Duration,
    generation: fn(&D) -> u64,
    snapshot: fn(&D) -> Snapshot,
    take_changes: fn(&mut D) -> Changes,
}

/// What to serve, and how: `Serve::new(device, line).link(..).persist(..).spawn()`.
pub struct Serve<D> {
    device: D,
    line: LineSettings,
    name: String,
    link: Option<PathBuf>,
    persistence: Option<Persistence<D>>,
}

impl<D: ByteDevice + Send + 'static> Serve<D> {
    /// `device` on a line at `line`.
    pub fn new(device: D, line: LineSettings) -> Self {
        Self {
            device,
            line,
            name: "device".into(),
            link: None,
            persistence: None,
        }
    }

    /// The device's name in thread names and log lines (`zelle`, `cpu196`).
    pub fn name(mut self, name: &str) -> Self {
        self.name = name.into();
        self
    }

    /// Also makes this symlink to the PTY (removed when serving stops).
    pub fn link(mut self, link: Option<PathBuf>) -> Self {
        self.link = link;
        self
    }

    /// Opens the PTY and serves the device on it in a background thread.
    pub fn spawn(self) -> Result<Served<D>, ServedError> {
        let Serve {
            device,
            line,
            name,
            link,
            persistence,
        } = self;
        let mut pty = Pty::open().map_err(ServedError::Pty)?;
        if let Some(link) = &link {
            pty.link_at(link).map_err(|source| ServedError::Link {
                path: link.clone(),
                source,
            })?;
        }
        let path = pty.path().to_path_buf();
        let mut device = device;
        // The saver thread and the journal, when the state is kept in a file.
        let keeping = match persistence {
            Some(p) => {
                // The device was built from the state file with its journals replayed: what
                // it holds now is everything, and older changes are not journaled again.
                let _ = (p.take_changes)(&mut device);
                // Written once now: a file that cannot be written is an error at start.
                write_atomic(&p.path, &(p.snapshot)(&device)()).map_err(|e| ServedError::Save {
                    what: p.what,
                    path: e.path,
                    source: e.source,
                })?;
                let journal_error = |source| ServedError::Save {
                    what: "journal",
                    path: journal::journal_path(&p.path, 0),
                    source,
                };
                let old = journal::existing(&p.path).map_err(journal_error)?;
                let next = old.last().map_or(1, |(seq, _)| seq + 1);
                journal::retire(&p.path, old.first().map_or(next, |(seq, _)| *seq), next);
                let writer = journal::Writer::create(&p.path, next).map_err(journal_error)?;
                let saved = (p.generation)(&device);
                Some((Saver::spawn(&name, p, saved, next)?, writer))
            }
            None => None,
        };
        let handle_saver = keeping.as_ref().map(|(saver, _)| saver.clone());
        let (control, control_rx) = channel::<Control<D>>();
        let stop = Arc::new(AtomicBool::new(false));
        let thread = {
            let stop = stop.clone();
            let name = name.clone();
            std::thread::Builder::new()
                .name(format!("{name}-serve"))
                .spawn(move || run(&name, device, pty, line, &control_rx, &stop, keeping))
                .map_err(ServedError::Serve)?
        };
        tracing::info!(device = %name, pty = %path.display(), "serving at {line}");
        Ok(Served {
            path,
            handle: Handle {
                control,
                saver: handle_saver,
            },
            stop,
            thread: Some(thread),
        })
    }
}

impl<D: ByteDevice + Persistent + Send + 'static> Serve<D> {
    /// Keeps the device's state in `path` (nothing if `None`): written at start, whenever it
    /// changed (looked at every `every`), on [`Handle::save`] and when serving stops. `what`
    /// names the file in messages (`state file`, `image`).
    pub fn persist(mut self, path: Option<PathBuf>, what: &'static str, every: Duration) -> Self {
        self.persistence = path.map(|path| Persistence {
            path,
            what,
            every,
            generation: D::state_generation,
            snapshot: take_snapshot::<D>,
            take_changes: D::take_changes,
        });
        self
    }
}

/// The serve thread: paces the device, journals its changes, takes snapshots when its state
/// changed, saves it at the end.
fn run<D: ByteDevice>(
    name: &str,
    mut device: D,
    pty: Pty,
    line: LineSettings,
    control: &Receiver<Control<D>>,
    stop: &AtomicBool,
    keeping: Option<(Saver<D>, journal::Writer)>,
) -> Result<(), ServedError> {
    let mut keeper = keeping.map(|(saver, writer)| Keeper {
        saver,
        writer: Some(writer),
        next_look: Nanos::ZERO,
        must_save: false,
        failing: false,
    });
    let result = serve_with(
        name,
        &mut device,
        &pty,
        line,
        control,
        stop,
        &mut |device, now, output| {
            if let Some(keeper) = &mut keeper {
                keeper.after_poll(device, now, output);
            }
        },
    );
    // The link goes before the final save: a new server may take the name meanwhile.
    drop(pty);
    let saved = match &mut keeper {
        Some(keeper) => keeper.finish(&mut device),
        None => Ok(()),
    };
    result.map_err(ServedError::Serve)?;
    saved
}

/// Keeps a device's state on disk from the serve thread: its changes in the journal, synced
/// before the device's output leaves, and a snapshot whenever the state moved.
struct Keeper<D> {
    saver: Saver<D>,
    /// `None` once the journal could not be continued.
    writer: Option<journal::Writer>,
    next_look: Nanos,
    /// Changes are not all in the journal: a snapshot must be written before output leaves.
    must_save: bool,
    /// The journal failed (warned once).
    failing: bool,
}

impl<D> Keeper<D> {
    fn after_poll(&mut self, device: &mut D, now: Nanos, output: bool) {
        match (self.saver.take_changes)(device) {
            Changes::Records(records) if records.is_empty() => {}
            Changes::Records(records) => {
                let appended = match &mut self.writer {
                    Some(w) => w.append(&records),
                    None => Err(std::io::Error::other("no journal")),
                };
                if let Err(e) = appended {
                    self.journal_failed(&e);
                }
            }
            Changes::Snapshot => self.must_save = true,
        }
        if output {
            // An acknowledgement follows the change it acknowledges: both reach the disk first.
            if !self.must_save
                && let Some(w) = &mut self.writer
                && let Err(e) = w.sync()
            {
                self.journal_failed(&e);
            }
            if self.must_save {
                self.must_save = false;
                self.next_look = now.saturating_add(self.saver.every_ns);
                let retire = self.rotate();
                if let Err(e) = self.saver.save_and_wait(device, retire) {
                    tracing::warn!("{e}");
                }
                return;
            }
        }
        if now >= self.next_look {
            self.next_look = now.saturating_add(self.saver.every_ns);
            if self.saver.changed(device) {
                let retire = self.rotate();
                self.saver.save(device, retire);
            }
        }
    }

    /// Starts the next journal for the changes after a snapshot about to be taken; the number
    /// below which journals go once that snapshot is written.
    fn rotate(&mut self) -> Option<u64> {
        let writer = self.writer.as_mut()?;
        match writer.rotate() {
            Ok(()) => Some(writer.seq()),
            Err(e) => {
                self.journal_failed(&e);
                None
            }
        }
    }

    fn journal_failed(&mut self, e: &std::io::Error) {
        if !self.failing {
            tracing::warn!(
                "the journal of {} failed ({e}); the whole state is saved before the device \
                 answers instead",
                self.saver.path.display()
            );
        }
        self.failing = true;
        self.must_save = true;
    }

    /// At the end: the last changes journaled, the state saved, the journals deleted.
    fn finish(&mut self, device: &mut D) -> Result<(), ServedError> {
        if let Changes::Records(records) = (self.saver.take_changes)(device)
            && let Some(w) = &mut self.writer
            && w.append(&records).and_then(|()| w.sync()).is_err()
        {
            self.writer = None;
        }
        let retire = self.writer.as_ref().map(|w| w.seq() + 1);
        self.saver.save_and_wait(device, retire)
    }
}

/// A device served on a PTY. Dropping it stops the device (and saves its state).
pub struct Served<D> {
    path: PathBuf,
    handle: Handle<D>,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<Result<(), ServedError>>>,
}

impl<D: 'static> Served<D> {
    /// The PTY path clients open.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// A handle for other threads (control lines from a socket, say).
    pub fn handle(&self) -> Handle<D> {
        self.handle.clone()
    }

    /// See [`Handle::with`].
    pub fn with<T: Send + 'static>(
        &self,
        work: impl FnOnce(&mut D, Nanos) -> T + Send + 'static,
    ) -> Result<T, ServedError> {
        self.handle.with(work)
    }

    /// See [`Handle::save`].
    pub fn save(&self) -> Result<Option<PathBuf>, ServedError> {
        self.handle.save()
    }

    /// Stops serving, saves the state, and waits for the serve thread.
    pub fn stop(mut self) -> Result<(), ServedError> {
        self.halt()
    }

    fn halt(&mut self) -> Result<(), ServedError> {
        self.stop.store(true, Ordering::SeqCst);
        match self.thread.take().map(JoinHandle::join) {
            Some(Ok(result)) => result,
            Some(Err(_)) => Err(ServedError::Panicked),
            None => Ok(()),
        }
    }
}

impl<D> Drop for Served<D> {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        if let Some(thread) = self.thread.take() {
            match thread.join() {
                Ok(Err(e)) => tracing::warn!("{e}"),
                Err(_) => tracing::warn!("{}", ServedError::Panicked),
                Ok(Ok(())) => {}
            }
        }
    }
}

/// Reaches a served device from any thread.
pub struct Handle<D> {
    control: Sender<Control<D>>,
    saver: Option<Saver<D>>,
}

impl<D> Clone for Handle<D> {
    fn clone(&self) -> Self {
        Self {
            control: self.control.clone(),
            saver: self.saver.clone(),
        }
    }
}

impl<D: 'static> Handle<D> {
    /// Runs `work` on the device inside its serve thread, between two byte events, at the
    /// current virtual time, and waits for its result.
    pub fn with<T: Send + 'static>(
        &self,
        work: impl FnOnce(&mut D, Nanos) -> T + Send + 'static,
    ) -> Result<T, ServedError> {
        let (tx, rx) = channel();
        self.control(Box::new(move |device, now| {
            let _ = tx.send(work(device, now));
        }))?;
        // Answered, or dropped unrun when serving ends: no time-out needed.
        rx.recv().map_err(|_| ServedError::Stopped)
    }

    /// Queues `work` for the serve thread without waiting.
    pub fn control(&self, work: Control<D>) -> Result<(), ServedError> {
        self.control.send(work).map_err(|_| ServedError::Stopped)
    }

    /// Saves the state now; the file's path, or `None` if the device keeps no file.
    pub fn save(&self) -> Result<Option<PathBuf>, ServedError> {
        let Some(saver) = self.saver.clone() else {
            return Ok(None);
        };
        let path = saver.path.clone();
        self.with(move |device, _| saver.save_and_wait_later(device, None))?
            .recv()
            .map_err(|_| ServedError::Stopped)??;
        Ok(Some(path))
    }
}

/// A snapshot on its way to the file; `done` hears how writing it went. Once it is written,
/// the journals numbered below `retire` are redundant.
struct SaveJob {
    snapshot: Snapshot,
    retire: Option<u64>,
    done: Option<Sender<Result<(), ServedError>>>,
}

/// The serve thread's side of the saver thread: snapshots are taken here (a copy), turned into
/// bytes and written there, so the device's pacing never waits for serialisation or the disk.
struct Saver<D> {
    jobs: Sender<SaveJob>,
    path: PathBuf,
    every_ns: Nanos,
    generation: fn(&D) -> u64,
    snapshot: fn(&D) -> Snapshot,
    take_changes: fn(&mut D) -> Changes,
    /// The generation last handed to the saver thread (`u64::MAX` after a failed write, so
    /// the next look saves again).
    enqueued: Arc<AtomicU64>,
}

impl<D> Clone for Saver<D> {
    fn clone(&self) -> Self {
        Self {
            jobs: self.jobs.clone(),
            path: self.path.clone(),
            every_ns: self.every_ns,
            generation: self.generation,
            snapshot: self.snapshot,
            take_changes: self.take_changes,
            enqueued: self.enqueued.clone(),
        }
    }
}

impl<D> Saver<D> {
    fn spawn(
        name: &str,
        p: Persistence<D>,
        saved: u64,
        first_journal: u64,
    ) -> Result<Self, ServedError> {
        let (jobs, rx) = channel();
        let enqueued = Arc::new(AtomicU64::new(saved));
        {
            let path = p.path.clone();
            let what = p.what;
            let enqueued = enqueued.clone();
            std::thread::Builder::new()
                .name(format!("{name}-save"))
                .spawn(move || save_jobs(&rx, &path, what, &enqueued, first_journal))
                .map_err(ServedError::Serve)?;
        }
        Ok(Self {
            jobs,
            path: p.path,
            every_ns: Nanos::from(p.every),
            generation: p.generation,
            snapshot: p.snapshot,
            take_changes: p.take_changes,
            enqueued,
        })
    }

    /// Whether the state moved since the last snapshot handed over.
    fn changed(&self, device: &D) -> bool {
        self.enqueued.load(Ordering::SeqCst) != (self.generation)(device)
    }

    /// In the serve thread: hands a snapshot to the saver thread.
    fn save(&self, device: &D, retire: Option<u64>) {
        self.enqueued
            .store((self.generation)(device), Ordering::SeqCst);
        let _ = self.jobs.send(SaveJob {
            snapshot: (self.snapshot)(device),
            retire,
            done: None,
        });
    }

    /// In the serve thread: hands a snapshot over; the receiver hears when it is written.
    fn save_and_wait_later(
        &self,
        device: &D,
        retire: Option<u64>,
    ) -> Receiver<Result<(), ServedError>> {
        let (tx, rx) = channel();
        self.enqueued
            .store((self.generation)(device), Ordering::SeqCst);
        let job = SaveJob {
            snapshot: (self.snapshot)(device),
            retire,
            done: Some(tx),
        };
        if let Err(unsent) = self.jobs.send(job)
            && let Some(done) = unsent.0.done
        {
            let _ = done.send(Err(ServedError::Stopped));
        }
        rx
    }

    fn save_and_wait(&self, device: &D, retire: Option<u64>) -> Result<(), ServedError> {
        self.save_and_wait_later(device, retire)
            .recv()
            .map_err(|_| ServedError::Stopped)?
    }
}

/// The saver thread: writes the newest snapshot waiting, deletes the journals it makes
/// redundant, tells whoever waits for it; one warning when periodic saving starts failing, one
/// line when it works again.
fn save_jobs(
    jobs: &Receiver<SaveJob>,
    path: &Path,
    what: &'static str,
    enqueued: &AtomicU64,
    first_journal: u64,
) {
    let mut failing = false;
    let mut oldest_journal = first_journal;
    while let Ok(first) = jobs.recv() {
        // Snapshots queue in the order they were taken: only the newest needs writing.
        let mut latest = first.snapshot;
        let mut retire = first.retire;
        let mut waiting: Vec<_> = first.done.into_iter().collect();
        while let Ok(next) = jobs.try_recv() {
            latest = next.snapshot;
            retire = retire.max(next.retire);
            waiting.extend(next.done);
        }
        let result = write_atomic(path, &latest());
        if let (Ok(()), Some(below)) = (&result, retire)
            && below > oldest_journal
        {
            journal::retire(path, oldest_journal, below);
            oldest_journal = below;
        }
        match &result {
            Err(e) => {
                enqueued.store(u64::MAX, Ordering::SeqCst);
                if !failing {
                    tracing::warn!("{what}: {e}; trying again at the next change");
                }
                failing = true;
            }
            Ok(()) => {
                if failing {
                    tracing::info!("{what} {} written again", path.display());
                }
                failing = false;
            }
        }
        for done in waiting {
            let _ = done.send(result.as_ref().map(|_| ()).map_err(|e| ServedError::Save {
                what,
                path: e.path.clone(),
                source: io::Error::new(e.source.kind(), e.source.to_string()),
            }));
        }
    }
}
