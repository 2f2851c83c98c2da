//! Bit-level CAN bus simulator: any number of [`buslab_can::controller::Controller`]s on one
//! wired-AND wire, stepped together in virtual time counted in bit-times.
//!
//! Sans-IO: no threads, no clock, no files. Time advances only in [`Simulation::run_until`];
//! callers pace it to the wall clock if they want (see `buslab lab`).
//!
//! - [`Traffic`]: what each node sends (periodic, bursts, a file, one-shot frames).
//! - [`Fault`]: disconnect, unterminated cut, flipped bits, stuck-dominant, noise.
//! - Observers: the trace of [`Record`]s, per-node [`NodeStats`], a TEC/REC series, bus load,
//!   and [`LevelChange`]s for the [`VcdWriter`].
//!
//! The engine knows no particular model: scenario files, which put SLIO boards and SJA1000
//! nodes on the wire, are read by `buslab-bench`.
#![forbid(unsafe_code)]

mod error;
pub mod fault;
pub mod observe;
mod rng;
mod simulation;
pub mod time;
pub mod traffic;
pub mod vcd;

pub use error::DurationError;
pub use fault::{Fault, FaultKind};
pub use observe::{
    BusStats, CounterSample, Happening, LevelChange, NodeStats, Record, RecordedEvents,
};
pub use simulation::{Node, Simulation};
pub use time::{BitTime, Span};
pub use traffic::Traffic;
pub use vcd::VcdWriter;
