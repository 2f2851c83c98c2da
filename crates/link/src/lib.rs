//! Transports for buslab's device models and host tools.
//!
//! - [`Pty`]: a pseudo-terminal a model serves on, so any serial program can open it.
//! - [`serve`]: paces a sans-IO [`ByteDevice`] to the wall clock behind a [`Pty`], as if the
//!   bytes crossed a real UART at the configured line settings.
//! - [`open_serial`]: the host side, a real serial port or a PTY, set to given line settings.

mod line;
mod pty;
mod serial;
mod serve;

pub use line::{LineSettings, Parity};
pub use pty::Pty;
pub use serial::{SerialError, open_serial};
pub use serve::{ByteDevice, Control, serve};
