//! buslab's CAN core: identifiers and frames, the bit-level wire codec (stuffing, CRC-15) and a
//! sans-IO protocol controller (arbitration, error handling, fault confinement).
//!
//! No I/O and no clock: time is counted in bit-times by whoever drives the controller.
#![no_std]
#![forbid(unsafe_code)]

extern crate alloc;
#[cfg(test)]
extern crate std;

pub mod controller;
mod error;
mod fd;
pub mod file;
mod frame;
mod id;
mod level;
pub mod node;
pub mod time;
pub mod wire;

pub use error::ParseError;
pub use fd::{FD_LENGTHS, FD_MAX_LEN, FdFrame, dlc_of_len, fd_len_of_dlc};
pub use frame::Frame;
pub use id::{EFF_MAX, ExtendedId, Id, SFF_MAX, SFF_MAX_CAN20A, StandardId};
pub use level::Level;
pub use time::{BitTime, Nanos, Timestamp};
