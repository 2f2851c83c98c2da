//! The core's one unit of time: oscillator periods ("clocks"), and the crystal that turns them
//! into nanoseconds.

use core::fmt;
use core::ops::{Add, AddAssign, Div, Mul, Rem, Sub};

use buslab_can::Nanos;

/// Oscillator periods in one machine cycle.
pub const CLOCKS_PER_CYCLE: u64 = 12;

/// A point in the core's time or a span of it, in oscillator periods since the core was made.
/// A machine cycle is 12 of them; every instruction takes 1, 2 or 4 machine cycles.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Clocks(pub u64);

impl Clocks {
    /// The start.
    pub const ZERO: Clocks = Clocks(0);
    /// Later than anything the core will reach.
    pub const NEVER: Clocks = Clocks(u64::MAX);
    /// One machine cycle.
    pub const CYCLE: Clocks = Clocks(CLOCKS_PER_CYCLE);

    /// `n` machine cycles.
    pub const fn from_cycles(n: u64) -> Clocks {
        Clocks(n.saturating_mul(CLOCKS_PER_CYCLE))
    }

    /// Whole machine cycles in this span (rounded down).
    pub const fn cycles(self) -> u64 {
        self.0 / CLOCKS_PER_CYCLE
    }

    /// `n` machine cycles later, with `u64`'s own `+` rather than saturating: for the
    /// instruction loop, where the saturating add measurably costs (3 % more host
    /// instructions on bench/mcs51_speed.sh) and the clock cannot get near `u64::MAX` (5 800
    /// years at 100 MHz).
    #[inline(always)]
    pub(crate) const fn plus_cycles(self, n: u8) -> Clocks {
        Clocks(self.0 + n as u64 * CLOCKS_PER_CYCLE)
    }

    /// The start of the machine cycle this instant falls in.
    pub const fn cycle_start(self) -> Clocks {
        Clocks(self.0 - self.0 % CLOCKS_PER_CYCLE)
    }

    /// How far into its machine cycle this instant is (0..12).
    pub const fn into_cycle(self) -> Clocks {
        Clocks(self.0 % CLOCKS_PER_CYCLE)
    }

    /// The first machine cycle boundary at or after this instant (the last boundary below
    /// `u64::MAX` if there is none).
    pub const fn round_up_to_cycle(self) -> Clocks {
        let last = u64::MAX - u64::MAX % CLOCKS_PER_CYCLE;
        let up = self
            .0
            .div_ceil(CLOCKS_PER_CYCLE)
            .saturating_mul(CLOCKS_PER_CYCLE);
        Clocks(if up > last { last } else { up })
    }
}

impl Add for Clocks {
    type Output = Clocks;
    fn add(self, rhs: Clocks) -> Clocks {
        Clocks(self.0.saturating_add(rhs.0))
    }
}

impl Sub for Clocks {
    type Output = Clocks;
    fn sub(self, rhs: Clocks) -> Clocks {
        Clocks(self.0.saturating_sub(rhs.0))
    }
}

impl AddAssign for Clocks {
    fn add_assign(&mut self, rhs: Clocks) {
        *self = *self + rhs;
    }
}

/// `n` times a span (saturating).
impl Mul<u64> for Clocks {
    type Output = Clocks;
    fn mul(self, n: u64) -> Clocks {
        Clocks(self.0.saturating_mul(n))
    }
}

/// How many whole `rhs` spans fit in `self`: a count, not a time.
impl Div for Clocks {
    type Output = u64;
    fn div(self, rhs: Clocks) -> u64 {
        self.0 / rhs.0
    }
}

/// A span split in `n` equal parts (rounded down).
impl Div<u64> for Clocks {
    type Output = Clocks;
    fn div(self, n: u64) -> Clocks {
        Clocks(self.0 / n)
    }
}

/// What is left of `self` after the whole `rhs` spans.
impl Rem for Clocks {
    type Output = Clocks;
    fn rem(self, rhs: Clocks) -> Clocks {
        Clocks(self.0 % rhs.0)
    }
}

impl fmt::Display for Clocks {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} clocks", self.0)
    }
}

/// The crystal: how many clocks make a second.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Crystal {
    hz: u32,
}

/// A crystal frequency the core cannot run at.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[error("crystal frequency {0} Hz is out of range 1..=100000000")]
pub struct CrystalError(pub u32);

impl Crystal {
    /// 11.0592 MHz: divides into the standard baud rates exactly (9600 baud is 1152 clocks a
    /// bit, timer 1 reloaded with FDh). The ZELLE cell's crystal (docs/decisions.md).
    pub const MHZ_11_0592: Crystal = Crystal { hz: 11_059_200 };
    /// 12 MHz: one machine cycle per microsecond.
    pub const MHZ_12: Crystal = Crystal { hz: 12_000_000 };

    /// A crystal of `hz` (1 Hz ..= 100 MHz).
    pub const fn new(hz: u32) -> Result<Crystal, CrystalError> {
        if hz == 0 || hz > 100_000_000 {
            Err(CrystalError(hz))
        } else {
            Ok(Crystal { hz })
        }
    }

    /// The frequency in Hz.
    pub const fn hz(self) -> u32 {
        self.hz
    }

    /// Nanoseconds from time 0 to `t` (rounded down). With [`clocks_at_ns`](Self::clocks_at_ns),
    /// the one conversion between the core's clock and a host's.
    pub const fn ns(self, t: Clocks) -> Nanos {
        let ns = t.0 as u128 * 1_000_000_000 / self.hz as u128;
        Nanos::new(if ns > u64::MAX as u128 {
            u64::MAX
        } else {
            ns as u64
        })
    }

    /// The first clock at or after `ns`.
    pub const fn clocks_at_ns(self, ns: Nanos) -> Clocks {
        let c = (ns.get() as u128 * self.hz as u128).div_ceil(1_000_000_000);
        if c > u64::MAX as u128 {
            Clocks::NEVER
        } else {
            Clocks(c as u64)
        }
    }

    /// The TH1 reload value that makes timer 1 (mode 2) clock the UART (modes 1 and 3) at
    /// exactly `baud`, with or without SMOD; `None` if no reload gives the rate exactly.
    pub const fn timer1_reload(self, baud: u32, smod: bool) -> Option<u8> {
        // baud = 2^SMOD / 32 × hz / (12 × (256 − TH1))
        let per_bit = if smod { 192 } else { 384 };
        let denominator = per_bit as u64 * baud as u64;
        if baud == 0 || !(self.hz as u64).is_multiple_of(denominator) {
            return None;
        }
        let steps = self.hz as u64 / denominator;
        if steps == 0 || steps > 256 {
            None
        } else {
            Some((256 - steps) as u8)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_cell_crystal_gives_9600_baud_exactly() {
        let xtal = Crystal::MHZ_11_0592;
        assert_eq!(xtal.timer1_reload(9600, false), Some(0xFD));
        assert_eq!(xtal.timer1_reload(19200, true), Some(0xFD));
        assert_eq!(xtal.timer1_reload(9600, true), Some(0xFA));
        assert_eq!(Crystal::MHZ_12.timer1_reload(9600, false), None);
        // One machine cycle is 1085.07 ns; a 9600-baud bit (1152 clocks) is 104166 ns.
        assert_eq!(xtal.ns(Clocks::from_cycles(1)), Nanos::new(1085));
        assert_eq!(xtal.ns(Clocks(1152)), Nanos::new(104_166));
        assert_eq!(xtal.clocks_at_ns(Nanos::new(104_167)), Clocks(1153));
        assert_eq!(
            xtal.clocks_at_ns(xtal.ns(Clocks(1152 * 9600))),
            Clocks(1152 * 9600)
        );
        assert_eq!(Crystal::new(0), Err(CrystalError(0)));
    }

    #[test]
    fn clock_arithmetic_saturates_and_splits_into_cycles() {
        let mut t = Clocks(30);
        t += Clocks::CYCLE;
        assert_eq!(t, Clocks(42));
        assert_eq!(t - Clocks(50), Clocks::ZERO);
        assert_eq!(Clocks::NEVER + Clocks(1), Clocks::NEVER);
        assert_eq!(Clocks::CYCLE * 3, Clocks(36));
        assert_eq!(Clocks::NEVER * 2, Clocks::NEVER);
        assert_eq!(t / Clocks(4), 10);
        assert_eq!(t / 4, Clocks(10));
        assert_eq!(t % Clocks(4), Clocks(2));
        assert_eq!(t.cycle_start(), Clocks(36));
        assert_eq!(t.into_cycle(), Clocks(6));
        assert_eq!(t.round_up_to_cycle(), Clocks(48));
        assert_eq!(Clocks(48).round_up_to_cycle(), Clocks(48));
        assert_eq!(
            Clocks::NEVER.round_up_to_cycle(),
            Clocks(u64::MAX - u64::MAX % CLOCKS_PER_CYCLE)
        );
        assert_eq!(Clocks::from_cycles(2), Clocks::CYCLE * 2);
    }
}
