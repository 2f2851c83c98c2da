//! The board's two clocks, below every other module: the CPU's and the SJA1000 card's.

/// The CPU clock: a PPC403GA-25.
pub const CPU_HZ: u32 = 25_000_000;

/// The PowerPC board's SJA1000 crystal (the seed: "Xtal de 16MHz"); the CAN clock is half.
pub const CRYSTAL_HZ: u32 = 16_000_000;
