//! The benches buslab puts on the one bus engine, and the models they are made of.
//!
//! The engine (`buslab-sim`) and the virtual bus server (`buslab-vbus`) take any `BusNode` and
//! know no particular model; which nodes a bench has, and how they are wired, is known here:
//!
//! - [`scenario`]: scenario files (TOML) for `buslab sim` and `buslab bus serve --nodes`.
//! - [`nodes`]: the node factory scenario files use (SJA1000 nodes running the host library's
//!   driver, SLIO demo boards).
//! - [`board`]: the SLIO demo boards of `bus serve --slio` and the lab, their analog inputs.
//! - [`ppc`]: the PowerPC node running MoniCAN.
//! - [`serve`]: the bench `buslab bus serve` puts beside its clients.
//! - [`lab`]: the lab's bench (`buslab lab`): simulated traffic, the SLIO bench, its server;
//!   [`devices`], its serial devices; [`counter`], its counter node; [`status`], the bench at
//!   a glance.
#![forbid(unsafe_code)]

pub mod board;
pub mod counter;
pub mod devices;
mod error;
pub mod lab;
pub mod nodes;
pub mod ppc;
pub mod scenario;
pub mod serve;
pub mod status;

pub use error::ScenarioError;
pub use nodes::Sja1000Spec;
pub use scenario::{NodeKind, NodeSpec, Scenario};
