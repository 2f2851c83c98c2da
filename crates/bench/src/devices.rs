//! The lab's serial devices: the ZELLE cell and the CPU196 board, each served on a
//! pseudo-terminal by its own thread, their state kept in the lab's folder.

use std::io;
use std::path::{Path, PathBuf};

use buslab_analog::{Shape, Source};
use buslab_cpu196::Board;
use buslab_link::{Served, ServedError};
use buslab_served::ServeError;
use buslab_served::zelle::ServedCell;

const ZELLE: &str = "ZELLE cell";
const CPU196: &str = "CPU196 board";

/// Why the lab's devices did not start or stop cleanly.
#[derive(Debug, thiserror::Error)]
pub enum DevicesError {
    #[error("cannot create the lab folder {}: {source}", path.display())]
    Folder { path: PathBuf, source: io::Error },
    #[error("starting the {device}: {source}")]
    Start {
        device: &'static str,
        source: ServeError,
    },
    #[error("stopping the {device}: {source}")]
    Stop {
        device: &'static str,
        source: ServedError,
    },
}

/// The served devices, running until [`LabDevices::stop`].
pub struct LabDevices {
    pub zelle: ServedCell,
    pub cpu196: Served<Board>,
    /// What tools should open: the stable links in the lab's folder when there is one, else
    /// the pseudo-terminals.
    pub zelle_port: PathBuf,
    pub cpu196_port: PathBuf,
}

impl LabDevices {
    /// Starts both devices; with `dir`, their state files and links (`zelle`, `zelle.toml`,
    /// `cpu196`, `cpu196.toml`) live there. The CPU196 line runs at `cpu196_baud` (8N1).
    pub fn start(dir: Option<&Path>, cpu196_baud: u32) -> Result<Self, DevicesError> {
        if let Some(dir) = dir {
            std::fs::create_dir_all(dir).map_err(|source| DevicesError::Folder {
                path: dir.to_path_buf(),
                source,
            })?;
        }
        let file = |name: &str| dir.map(|d| d.join(name));
        // Two sine waves on the cell's first channels, so a measurement shows something.
        let sine = |amplitude, offset| Source::Wave {
            shape: Shape::Sine,
            hz: 0.5,
            amplitude,
            offset,
        };
        let zelle = ServedCell::spawn(buslab_served::zelle::CellOptions {
            state: file("zelle.toml"),
            link: file("zelle"),
            analog: vec![(1, sine(2.0, 2.5)), (2, sine(1.0, 2.5))],
            trace: None,
        })
        .map_err(|source| DevicesError::Start {
            device: ZELLE,
            source,
        })?;
        let cpu196 = buslab_served::cpu196::spawn_board(buslab_served::cpu196::BoardOptions {
            image: file("cpu196.toml"),
            link: file("cpu196"),
            baud: cpu196_baud,
            inputs: buslab_cpu196::source::Inputs::default(),
            peer: buslab_cpu196::pic::Peer::default(),
        })
        .map_err(|source| DevicesError::Start {
            device: CPU196,
            source,
        })?;
        Ok(Self {
            zelle_port: file("zelle").unwrap_or_else(|| zelle.path().to_path_buf()),
            cpu196_port: file("cpu196").unwrap_or_else(|| cpu196.path().to_path_buf()),
            zelle,
            cpu196,
        })
    }

    /// Stops both, their state saved.
    pub fn stop(self) -> Result<(), DevicesError> {
        let stopping = |device| move |source| DevicesError::Stop { device, source };
        self.zelle.stop().map_err(stopping(ZELLE))?;
        self.cpu196.stop().map_err(stopping(CPU196))?;
        Ok(())
    }
}
