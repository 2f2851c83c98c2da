//! The PowerPC node's CAN loader (seed 002 §4.4, `loadcan.s`): a supervisor sends a program as
//! Motorola S-records over CAN and the node writes it into its memory.
//!
//! - [`srec`]: S-records of every kind, read with every record checked (each bad line named
//!   with its number), and written.
//! - [`memory`]: the node's memory map (where programs may go) and its memory image.
//! - [`loader`]: the loader's protocol as a sans-IO state machine (frames in; the answer
//!   frame and the outcome out).
//! - [`report`]: what the loader shows on the node's terminal.
//!
//! The host side (`buslab load`) checks a file with the same [`loader::check`] before it sends
//! it. A model crate: no I/O, no clock.
#![forbid(unsafe_code)]

pub mod loader;
pub mod memory;
pub mod report;
pub mod srec;

pub use loader::{Loader, Outcome, check};
pub use memory::{MemoryImage, MemoryMap};
pub use srec::{Program, SrecError, SrecErrors};
