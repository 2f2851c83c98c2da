//! The byte-device seam between buslab's serial device models and their hosts. Std only: no
//! threads, clocks, files or OS calls.
//!
//! - [`ByteDevice`]: a device model that talks over one UART, driven in virtual nanoseconds
//!   (the ZELLE cell, the CPU196 board). Adapters pace it to the wall clock behind a
//!   pseudo-terminal (`buslab-link`), or [`SimPort`] runs it in virtual time.
//! - [`Persistent`]: the part of a device's state that outlives a power cycle, as file bytes,
//!   and its changes as journal records ([`ChangeLog`]).
//! - [`LineSettings`]: how bytes are framed on the line, and how long one takes.
//! - [`Port`]: what a host client needs from its line to the device, time included: a real
//!   serial port (`buslab_link::SerialLine`) or [`SimPort`]. Clients read the port's clock and
//!   pause through it, so the same client code runs against a board or against the model in
//!   virtual time, deterministically.
//! - [`Human`]: a duration as people read it (`2.06 s`), for messages.
//! - [`printable`]: text from a device or a server made safe to print on a terminal.

mod device;
mod human;
mod line;
mod port;
mod printable;
mod sim_port;

pub use buslab_can::Nanos;
pub use device::{ByteDevice, ChangeLog, Changes, Persistent, ReplayError};
pub use human::Human;
pub use line::{LineSettings, Parity};
pub use port::Port;
pub use printable::printable;
pub use sim_port::SimPort;
