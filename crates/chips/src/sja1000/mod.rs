//! Facts of the Philips/NXP SJA1000 stand-alone CAN controller.

pub mod filter;
pub mod regs;
pub mod timing;

pub use filter::FilterMode;
pub use timing::{BitTiming, TimingError};

/// The two register layouts of the SJA1000.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum CanMode {
    /// PCA82C200-compatible: 11-bit IDs only, 32 registers.
    Basic,
    /// CAN 2.0B: extended IDs, error counters and captures, 128 registers.
    Peli,
}
