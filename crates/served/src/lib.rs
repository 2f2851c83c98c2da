//! The host side of buslab's serial device models: what `buslab zelle serve`,
//! `buslab cpu196 serve` and `buslab lab` run.
//!
//! - [`zelle`]: the ZELLE cell on a pseudo-terminal with its battery-backed RAM in a state file,
//!   analog inputs (CSV replays read here), and its control lines.
//! - [`cpu196`]: the CPU196 board on a pseudo-terminal with its image file, and the file
//!   service the monitor offers a board ([`cpu196::FileService`]).
//! - [`ppc`]: the PowerPC node's VT100 terminal on a pseudo-terminal, while the node runs on a
//!   virtual bus server.
//!
//! Both use the one served-device adapter, [`buslab_link::Serve`]; files are read with a size
//! limit and written atomically ([`buslab_link::fs`]).

pub mod cpu196;
pub mod ppc;
pub mod zelle;

use std::path::PathBuf;

use buslab_link::ServedError;
use buslab_link::fs::ReadError;

/// Why a device could not be served.
#[derive(Debug, thiserror::Error)]
pub enum ServeError {
    #[error(transparent)]
    Served(#[from] ServedError),
    #[error(transparent)]
    Read(#[from] ReadError),
    #[error("state file {}: {source}", path.display())]
    State {
        path: PathBuf,
        #[source]
        source: buslab_zelle::StateFileError,
    },
    #[error("image {} is not a CPU196 image: {detail}", path.display())]
    Image { path: PathBuf, detail: String },
    #[error(transparent)]
    Source(#[from] buslab_zelle::analog::SourceError),
    #[error(transparent)]
    Input(#[from] buslab_zelle::InputError),
}
