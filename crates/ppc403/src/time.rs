//! The core's time: CPU clock cycles since it was made.

/// A count of CPU clock cycles (the 403's processor clock).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Cycles(pub u64);

impl Cycles {
    pub const ZERO: Cycles = Cycles(0);
    pub const MAX: Cycles = Cycles(u64::MAX);

    /// The cycles a clock of `hz` runs in `ns` nanoseconds (rounded down).
    pub const fn from_nanos(ns: u64, hz: u32) -> Cycles {
        Cycles(((ns as u128 * hz as u128) / 1_000_000_000) as u64)
    }

    /// The nanoseconds `self` cycles of a clock of `hz` take (rounded down).
    pub const fn as_nanos(self, hz: u32) -> u64 {
        ((self.0 as u128 * 1_000_000_000) / hz as u128) as u64
    }
}

impl core::ops::Add for Cycles {
    type Output = Cycles;
    fn add(self, rhs: Cycles) -> Cycles {
        Cycles(self.0.saturating_add(rhs.0))
    }
}

impl core::ops::Sub for Cycles {
    type Output = Cycles;
    fn sub(self, rhs: Cycles) -> Cycles {
        Cycles(self.0.saturating_sub(rhs.0))
    }
}
