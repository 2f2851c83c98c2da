//! The host side of buslab's serial device models: what `buslab zelle serve`,
//! `buslab cpu196 serve` and `buslab lab` run.
//!
//! - [`analog`]: analog sources as the serving tools take them, CSV replays read here.
//! - [`zelle`]: the ZELLE cell on a pseudo-terminal with its battery-backed RAM in a state file,
//!   analog inputs (CSV replays read here), and its control lines.
//! - [`cpu196`]: the CPU196 board on a pseudo-terminal with its image file, and the file
//!   service the monitor offers a board ([`cpu196::FileService`]).
//! - [`ppc`]: the PowerPC node's VT100 terminal on a pseudo-terminal, while the node runs on a
//!   virtual bus server.
//!
//! Both use the one served-device adapter, [`buslab_link::Serve`]; files are read with a size
//! limit and written atomically ([`buslab_link::fs`]); the changes between two saves are
//! journaled and replayed after a crash ([`buslab_link::journal`]), so nothing the device
//! acknowledged is lost.

pub mod analog;
pub mod cpu196;
pub mod ppc;
pub mod zelle;

use std::path::PathBuf;

use std::path::Path;

use buslab_link::fs::ReadError;
use buslab_link::journal::{self, JournalError};
use buslab_link::{Persistent, ServedError};

/// Why a device could not be served.
#[derive(Debug, thiserror::Error)]
pub enum ServeError {
    #[error(transparent)]
    Served(#[from] ServedError),
    #[error(transparent)]
    Read(#[from] ReadError),
    #[error(transparent)]
    Journal(#[from] JournalError),
    #[error("state file {}: {source}", path.display())]
    State {
        path: PathBuf,
        #[source]
        source: buslab_zelle::StateFileError,
    },
    #[error("image {} is not a CPU196 image: {detail}", path.display())]
    Image { path: PathBuf, detail: String },
    #[error(transparent)]
    Source(#[from] buslab_analog::SourceError),
    #[error(transparent)]
    Input(#[from] buslab_zelle::InputError),
}

/// Applies the journals a killed server left beside `path` to the state read from it.
fn replay_journals<D: Persistent>(path: &Path, state: &mut D::Snapshot) -> Result<(), ServeError> {
    let replayed = journal::replay::<D>(path, state)?;
    if replayed.records > 0 {
        tracing::info!(
            "{}: {} changes recovered from {} journal(s) (the last server did not stop cleanly)",
            path.display(),
            replayed.records,
            replayed.journals
        );
    }
    Ok(())
}
