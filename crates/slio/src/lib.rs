//! The Philips P82C150 "CAN Serial Linked I/O" (SLIO), the seed's demo board around it, and
//! what a host needs to talk to SLIOs (SPEC N4; seed 002 §2.1, §3.2, §4.2).
//!
//! - [`ids`]: the 16 SLIO numbers, their identifiers both ways, the calibration frame.
//! - [`registers`]: the nine registers (one table, [`registers::MAP`]), the 3-byte frames.
//! - [`slio`]: the chip as a bit-level node of the one bus engine (calibration, register
//!   logic, edge reports, ADC, DPM, the network watchdog).
//! - [`board`]: the demo board (ID/input switches, potentiometer, LEDs, DPM outputs).
//! - [`master`]: the host side, sans-IO: calibration, inventory, confirmed register access.
#![forbid(unsafe_code)]

pub mod board;
/// SLIO identifiers are chip facts shared with the bus vocabulary (`buslab-chips`).
pub use buslab_chips::slio::ids;
pub mod master;
pub use buslab_chips::slio::registers;
pub mod slio;

pub use board::DemoBoard;
pub use ids::{CALIBRATION_ID, Direction, SlioId, calibration_frame};
pub use master::{Master, MasterEvent, RequestId, Transmit};
pub use registers::{NotReadable, Register, Reply, Request, Status};
pub use slio::{Calibration, ModeChangeCause, Slio, SlioError, SlioNotice};
