//! Serving the model on a pseudo-terminal in a background thread (the adapter around
//! [`Board`]): paced by `buslab_link::serve`, the image saved atomically whenever it changes.

use std::io;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Sender, channel};
use std::thread::JoinHandle;
use std::time::Duration;

use buslab_link::{Control, Pty};

use crate::Board;

/// A board served on a PTY. Dropping it stops the board (and saves its image).
pub struct Served {
    path: PathBuf,
    stop: Arc<AtomicBool>,
    control: Sender<Control<Board>>,
    thread: Option<JoinHandle<io::Result<()>>>,
}

impl Served {
    /// Opens a PTY (and a symlink `link` to it), then serves `board` on it until dropped.
    /// With `image_path`, the image is saved there after every change and at the end.
    pub fn spawn(
        board: Board,
        link: Option<&Path>,
        image_path: Option<PathBuf>,
    ) -> io::Result<Self> {
        let (ready_tx, ready_rx) = channel();
        let (control, control_rx) = channel::<Control<Board>>();
        let stop = Arc::new(AtomicBool::new(false));
        let link = link.map(Path::to_path_buf);
        let image_path_saver = image_path.clone();
        let stop_in = stop.clone();
        let thread = std::thread::Builder::new()
            .name("cpu196-board".into())
            .spawn(move || -> io::Result<()> {
                let mut board = board;
                let pty = match Pty::open().and_then(|mut p| {
                    if let Some(l) = &link {
                        p.link_at(l)?;
                    }
                    Ok(p)
                }) {
                    Ok(p) => p,
                    Err(e) => {
                        let _ = ready_tx.send(Err(io::Error::new(e.kind(), e.to_string())));
                        return Err(e);
                    }
                };
                let _ = ready_tx.send(Ok(pty.path().to_path_buf()));
                let line = board.line();
                let result = buslab_link::serve(&mut board, &pty, line, &control_rx, &stop_in);
                if let Some(path) = &image_path {
                    board.image().save(path).map_err(io::Error::other)?;
                }
                drop(pty);
                result
            })?;
        let path = ready_rx
            .recv()
            .map_err(|_| io::Error::other("the board thread died"))??;
        if let Some(image_path) = image_path_saver {
            spawn_saver(control.clone(), stop.clone(), image_path)?;
        }
        Ok(Self {
            path,
            stop,
            control,
            thread: Some(thread),
        })
    }

    /// The PTY path clients open.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Runs `work` on the board inside its thread (change inputs, press buttons, inspect).
    pub fn control(&self, work: Control<Board>) -> bool {
        self.control.send(work).is_ok()
    }

    /// Runs `f` on the board and waits for its result.
    pub fn with<T: Send + 'static>(
        &self,
        f: impl FnOnce(&mut Board, u64) -> T + Send + 'static,
    ) -> Option<T> {
        let (tx, rx) = channel();
        self.control(Box::new(move |b, now| {
            let _ = tx.send(f(b, now));
        }));
        rx.recv_timeout(Duration::from_secs(5)).ok()
    }

    /// Stops the board and waits for its thread.
    pub fn stop(mut self) -> io::Result<()> {
        self.halt()
    }

    fn halt(&mut self) -> io::Result<()> {
        self.stop.store(true, Ordering::Relaxed);
        match self.thread.take() {
            Some(t) => t
                .join()
                .map_err(|_| io::Error::other("the board thread panicked"))?,
            None => Ok(()),
        }
    }
}

/// Every 200 ms, saves the image if the board changed it. Saving runs in the board thread
/// (between two byte events), so the image is never seen half-updated.
fn spawn_saver(
    control: Sender<Control<Board>>,
    stop: Arc<AtomicBool>,
    path: PathBuf,
) -> io::Result<()> {
    std::thread::Builder::new()
        .name("cpu196-image".into())
        .spawn(move || {
            while !stop.load(Ordering::Relaxed) {
                std::thread::sleep(Duration::from_millis(200));
                let path = path.clone();
                let work: Control<Board> = Box::new(move |b, _| {
                    if b.take_dirty()
                        && let Err(e) = b.image().save(&path)
                    {
                        eprintln!("warning: {e}");
                    }
                });
                if control.send(work).is_err() {
                    break;
                }
            }
        })?;
    Ok(())
}

impl Drop for Served {
    fn drop(&mut self) {
        let _ = self.halt();
    }
}
