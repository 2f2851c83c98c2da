//! Chip facts from the datasheets: pure data and arithmetic, no chip behaviour.
//!
//! Both the models (`buslab-sja1000`, `buslab-slio`) and the bus vocabulary (`buslab-bus`)
//! need these facts; keeping them here lets a crate that only talks to a bus decode registers
//! and name SLIOs without depending on a model. The model crates re-export them at their old
//! paths.
//!
//! - [`sja1000`]: the register map, the two register layouts ([`sja1000::CanMode`]), the
//!   acceptance filter ([`sja1000::FilterMode`]) and bit timing ([`sja1000::BitTiming`]).
//! - [`slio`]: SLIO identifiers ([`slio::SlioId`]) and the demo board's LED pins and supply.
#![forbid(unsafe_code)]

pub mod sja1000;
pub mod slio;
