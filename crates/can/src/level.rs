//! Bus levels.

/// The level of the bus (or of what one node drives) during one bit-time. The bus is a
/// wired-AND: if any node drives dominant, everybody reads dominant.
#[derive(Clone, Copy, PartialEq, Eq, Hash, Debug)]
pub enum Level {
    /// Logic 0; wins over recessive.
    Dominant,
    /// Logic 1; the idle level.
    Recessive,
}

impl Level {
    /// The level carrying logic bit `bit` (`false` = 0 = dominant).
    pub const fn from_bit(bit: bool) -> Self {
        if bit {
            Level::Recessive
        } else {
            Level::Dominant
        }
    }
    /// Logic value: dominant = `false` (0), recessive = `true` (1).
    pub const fn bit(self) -> bool {
        matches!(self, Level::Recessive)
    }
    /// Wired-AND of two drivers.
    pub const fn and(self, other: Level) -> Level {
        if matches!(self, Level::Dominant) || matches!(other, Level::Dominant) {
            Level::Dominant
        } else {
            Level::Recessive
        }
    }
}
