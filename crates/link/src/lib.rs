//! Transports and adapters for buslab's serial device models and host tools.
//!
//! - [`Pty`]: a pseudo-terminal a model serves on, so any serial program can open it.
//! - [`serve()`]: paces a sans-IO [`ByteDevice`] to the wall clock behind a [`Pty`], as if the
//!   bytes crossed a real UART at the configured line settings.
//! - [`Serve`] / [`Served`]: the one served-device adapter: a device on a PTY in a background
//!   thread, with an optional symlink, persistence of its state and work from other threads;
//!   [`ControlSocket`] takes control lines for it.
//! - [`SerialLine`]: the host side, a real serial port or a PTY as the [`Port`] clients use;
//!   [`open_serial`] opens one as a plain `serialport` port ([`open_tty`]: as the Unix port).
//! - [`fs`]: every file buslab writes is written atomically; files it reads are read with a
//!   size limit.
//! - [`journal`]: a served device's changes between two state files, synced before the
//!   device's next byte leaves, replayed after a crash.
//! - [`wake`]: a bus's wait for frames ended from another thread ([`WakeLine`]), polled beside
//!   the bus's own descriptor ([`wait_readable`]).

mod control;
pub mod journal;
mod pty;
mod serial;
mod serve;
mod served;
pub mod wake;

pub use buslab_device::{ByteDevice, LineSettings, Parity, Persistent, Port};
/// Files written atomically and read with a limit: `buslab-fs`, under the path it had here.
pub use buslab_fs as fs;
pub use control::{ControlLimits, ControlSocket, LineHandler};
pub use pty::Pty;
pub use serial::{SerialError, SerialLine, open_serial, open_tty, tty_fd};
pub use serve::{Control, serve};
pub use served::{Handle, Serve, Served, ServedError};
pub use wake::{WakeLine, wait_readable};
