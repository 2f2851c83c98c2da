//! The Philips/NXP SJA1000 stand-alone CAN controller as a register-level model.
//!
//! A host program (buslab's driver, or code written for the chip) reads and writes the
//! registers with [`Sja1000::read`] / [`Sja1000::write`]; the simulated bus steps the chip once
//! per bit-time with [`Sja1000::output`] / [`Sja1000::sample`]. The protocol itself (frames,
//! arbitration, errors, fault confinement) is buslab's [`Controller`](buslab_can::controller);
//! this crate is the register logic around it: modes and access rules, commands, status,
//! interrupts, the RX FIFO and acceptance filter, error captures.

mod chip;
pub mod fifo;
pub mod layout;
mod mac;

/// The register map, acceptance filter and bit timing are datasheet facts shared with the bus
/// vocabulary; they live in `buslab-chips` and keep their paths here.
pub use buslab_chips::sja1000::{filter, regs, timing};

pub use buslab_chips::sja1000::{BitTiming, CanMode, FilterMode, TimingError};
pub use chip::Sja1000;
