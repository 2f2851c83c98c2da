//! A moment in time as buslab's tools carry it: a frame's time on a bus, in a log, on a screen.

use core::fmt;
use core::time::Duration;

/// A moment on a host's clock or a simulation's, as the time since its epoch: the Unix epoch
/// for wall-clock sources and most logs, the start of the bus for a simulation, the start of
/// the recording for logs with relative times. Nanosecond precision (BLF and pcapng carry
/// nanoseconds; candump and socketcand microseconds), the range of a [`Duration`].
///
/// Float seconds (python-can's `Message.timestamp`) come in and go out only at the edges:
/// [`Timestamp::from_secs_f64`], [`Timestamp::as_secs_f64`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Timestamp(Duration);

impl Timestamp {
    /// The epoch itself.
    pub const EPOCH: Self = Self(Duration::ZERO);

    /// `since` after the epoch.
    pub const fn since_epoch(since: Duration) -> Self {
        Self(since)
    }

    pub const fn from_nanos(nanos: u64) -> Self {
        Self(Duration::from_nanos(nanos))
    }

    pub const fn from_micros(micros: u64) -> Self {
        Self(Duration::from_micros(micros))
    }

    pub const fn from_secs(secs: u64) -> Self {
        Self(Duration::from_secs(secs))
    }

    /// Whole seconds and microseconds after them (`micros` beyond 999 999 count as 999 999).
    pub const fn from_secs_micros(secs: u64, micros: u32) -> Self {
        let micros = if micros > 999_999 { 999_999 } else { micros };
        Self(Duration::new(secs, micros * 1000))
    }

    /// Float seconds (python-can's, a simulation's), rounded to the microsecond (the precision
    /// socketcand and candump carry: truncating would turn `.218691` into `.218690`).
    /// Negative or NaN values are the epoch; huge ones the latest microsecond a `u64` counts.
    pub fn from_secs_f64(secs: f64) -> Self {
        // Half up by hand: `f64::round` needs std.
        let micros = secs * 1e6 + 0.5;
        if micros.is_nan() || micros < 1.0 {
            Self::EPOCH
        } else if micros >= u64::MAX as f64 {
            Self::from_micros(u64::MAX)
        } else {
            Self::from_micros(micros as u64)
        }
    }

    /// The time since the epoch.
    pub const fn since_epoch_duration(self) -> Duration {
        self.0
    }

    pub fn as_secs_f64(self) -> f64 {
        self.0.as_secs_f64()
    }

    /// Whole seconds since the epoch.
    pub const fn as_secs(self) -> u64 {
        self.0.as_secs()
    }

    /// Microseconds since the epoch (truncated).
    pub const fn as_micros(self) -> u128 {
        self.0.as_micros()
    }

    /// Nanoseconds since the epoch.
    pub const fn as_nanos(self) -> u128 {
        self.0.as_nanos()
    }

    /// Whole seconds and the microseconds after them (truncated, as candump prints them).
    pub const fn secs_and_micros(self) -> (u64, u32) {
        (self.0.as_secs(), self.0.subsec_micros())
    }

    pub fn checked_add(self, d: Duration) -> Option<Self> {
        self.0.checked_add(d).map(Self)
    }

    pub fn saturating_add(self, d: Duration) -> Self {
        Self(self.0.saturating_add(d))
    }

    /// How long after `earlier` this is; zero if it is not later.
    pub fn saturating_since(self, earlier: Self) -> Duration {
        self.0.saturating_sub(earlier.0)
    }
}

/// Seconds with six decimals, truncated as candump prints them: `1700000000.123456`.
impl fmt::Display for Timestamp {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let (secs, micros) = self.secs_and_micros();
        write!(f, "{secs}.{micros:06}")
    }
}

/// Time on a CAN bus, counted in nominal bit-times: a moment since the bus started or a span
/// between two. The clock of the protocol controller, the bus engine and every bit-level node;
/// [`BitTime::at_bitrate`] and [`Nanos::bit_times_at`] are the only conversions to and from
/// a host's nanoseconds.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct BitTime(u64);

/// Time of a byte device or a host-side core, in nanoseconds: a moment since the core started
/// or a span between two. The clock of the served devices (ZELLE, CPU196, MoniCAN's
/// terminal), the 8051 core's peripherals and the sans-IO protocol sessions.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Nanos(u64);

macro_rules! counted_time {
    ($name:ident) => {
        impl $name {
            pub const ZERO: Self = Self(0);
            pub const MAX: Self = Self(u64::MAX);

            pub const fn new(count: u64) -> Self {
                Self(count)
            }

            /// The count itself, for arithmetic with other counts (bytes, bits per frame).
            pub const fn get(self) -> u64 {
                self.0
            }

            pub const fn saturating_add(self, other: Self) -> Self {
                Self(self.0.saturating_add(other.0))
            }

            /// How far `self` is past `earlier`; zero if it is not later.
            pub const fn saturating_sub(self, earlier: Self) -> Self {
                Self(self.0.saturating_sub(earlier.0))
            }

            /// How far apart `self` and `other` are, whichever is later.
            pub const fn abs_diff(self, other: Self) -> Self {
                Self(self.0.abs_diff(other.0))
            }

            /// `times` of these spans; the longest a `u64` counts if more.
            pub const fn saturating_mul(self, times: u64) -> Self {
                Self(self.0.saturating_mul(times))
            }

            pub const fn checked_add(self, other: Self) -> Option<Self> {
                match self.0.checked_add(other.0) {
                    Some(sum) => Some(Self(sum)),
                    None => None,
                }
            }

            pub const fn checked_sub(self, other: Self) -> Option<Self> {
                match self.0.checked_sub(other.0) {
                    Some(difference) => Some(Self(difference)),
                    None => None,
                }
            }
        }

        impl core::ops::Add for $name {
            type Output = Self;
            fn add(self, other: Self) -> Self {
                Self(self.0 + other.0)
            }
        }

        impl core::ops::AddAssign for $name {
            fn add_assign(&mut self, other: Self) {
                self.0 += other.0;
            }
        }

        impl core::ops::Sub for $name {
            type Output = Self;
            fn sub(self, other: Self) -> Self {
                Self(self.0 - other.0)
            }
        }

        impl core::ops::SubAssign for $name {
            fn sub_assign(&mut self, other: Self) {
                self.0 -= other.0;
            }
        }

        impl core::ops::Mul<u64> for $name {
            type Output = Self;
            fn mul(self, times: u64) -> Self {
                Self(self.0 * times)
            }
        }

        /// A count of spans: `bytes * byte_time` reads as `byte_time * bytes`.
        impl core::ops::Mul<$name> for u64 {
            type Output = $name;
            fn mul(self, time: $name) -> $name {
                $name(self * time.0)
            }
        }

        impl core::ops::Div<u64> for $name {
            type Output = Self;
            fn div(self, parts: u64) -> Self {
                Self(self.0 / parts)
            }
        }

        /// How many times `other` fits in `self` (whole times).
        impl core::ops::Div for $name {
            type Output = u64;
            fn div(self, other: Self) -> u64 {
                self.0 / other.0
            }
        }

        impl core::ops::Rem for $name {
            type Output = Self;
            fn rem(self, other: Self) -> Self {
                Self(self.0 % other.0)
            }
        }

        impl core::iter::Sum for $name {
            fn sum<I: Iterator<Item = Self>>(iter: I) -> Self {
                Self(iter.map(|t| t.0).sum())
            }
        }

        /// The bare count, as traces and VCD files print it.
        impl fmt::Display for $name {
            fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                fmt::Display::fmt(&self.0, f)
            }
        }
    };
}

counted_time!(BitTime);
counted_time!(Nanos);

const NANOS_PER_SECOND: u128 = 1_000_000_000;

impl BitTime {
    /// One bit-time: the bus's tick.
    pub const ONE: Self = Self(1);

    /// These bit-times as float seconds at `bitrate` bit/s (unrounded), for plots and logs
    /// (a zero bitrate counts as 1 bit/s).
    pub fn secs_f64_at(self, bitrate: u32) -> f64 {
        self.0 as f64 / f64::from(bitrate.max(1))
    }

    /// [`Self::at_bitrate`] as whole seconds and microseconds (rounded down), as logs print
    /// a time; without its 128-bit division, as a trace prints one per line.
    pub fn secs_and_micros_at(self, bitrate: u32) -> (u64, u32) {
        // Below about 584 years at any bit rate `at_bitrate` does not saturate, and
        // ⌊⌊t·10⁹/b⌋ / 10⁹⌋ = ⌊t/b⌋, ⌊(⌊t·10⁹/b⌋ mod 10⁹) / 10³⌋ = ⌊(t mod b)·10⁶/b⌋.
        const UNSATURATED_SECS: u64 = u64::MAX / 1_000_000_000 - 1;
        let b = u64::from(bitrate.max(1));
        let secs = self.0 / b;
        if secs >= UNSATURATED_SECS {
            let nanos = self.at_bitrate(bitrate).0;
            return (
                nanos / 1_000_000_000,
                (nanos % 1_000_000_000 / 1_000) as u32,
            );
        }
        (secs, ((self.0 % b) * 1_000_000 / b) as u32)
    }

    /// These bit-times as nanoseconds at `bitrate` bit/s (rounded down; a zero bitrate counts
    /// as 1 bit/s). The one conversion from a bus's clock to a host's.
    pub const fn at_bitrate(self, bitrate: u32) -> Nanos {
        let bitrate = if bitrate == 0 { 1 } else { bitrate as u128 };
        let nanos = self.0 as u128 * NANOS_PER_SECOND / bitrate;
        Nanos(if nanos > u64::MAX as u128 {
            u64::MAX
        } else {
            nanos as u64
        })
    }
}

/// `bits` wire bits last as many bit-times (a frame's length, a bit's index in it).
impl From<u32> for BitTime {
    fn from(bits: u32) -> Self {
        Self(bits as u64)
    }
}

impl Nanos {
    pub const fn from_micros(micros: u64) -> Self {
        Self(micros.saturating_mul(1_000))
    }

    pub const fn from_millis(millis: u64) -> Self {
        Self(millis.saturating_mul(1_000_000))
    }

    pub const fn from_secs(secs: u64) -> Self {
        Self(secs.saturating_mul(1_000_000_000))
    }

    /// The whole bit-times these nanoseconds hold at `bitrate` bit/s (rounded down). The one
    /// conversion from a host's clock to a bus's.
    pub const fn bit_times_at(self, bitrate: u32) -> BitTime {
        BitTime((self.0 as u128 * bitrate as u128 / NANOS_PER_SECOND) as u64)
    }

    /// The first bit-time at `bitrate` bit/s that is not before these nanoseconds (rounded
    /// up; the latest bit-time a `u64` counts if beyond): when a bus-clocked node must wake
    /// for a host-clocked deadline.
    pub const fn first_bit_time_at(self, bitrate: u32) -> BitTime {
        let bits = (self.0 as u128 * bitrate as u128).div_ceil(NANOS_PER_SECOND);
        BitTime(if bits > u64::MAX as u128 {
            u64::MAX
        } else {
            bits as u64
        })
    }

    /// A [`Duration`] of `self` nanoseconds.
    pub const fn as_duration(self) -> Duration {
        Duration::from_nanos(self.0)
    }

    /// `duration` in nanoseconds; the longest a `u64` counts (584 years) for longer ones.
    pub const fn from_duration(duration: Duration) -> Self {
        let nanos = duration.as_nanos();
        Self(if nanos > u64::MAX as u128 {
            u64::MAX
        } else {
            nanos as u64
        })
    }
}

impl From<Duration> for Nanos {
    fn from(duration: Duration) -> Self {
        Self::from_duration(duration)
    }
}

impl From<Nanos> for Duration {
    fn from(nanos: Nanos) -> Self {
        nanos.as_duration()
    }
}

/// A core's moment as a host timestamp: `nanos` after the epoch of the core's clock.
impl From<Nanos> for Timestamp {
    fn from(nanos: Nanos) -> Self {
        Self::from_nanos(nanos.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use alloc::string::ToString;

    #[test]
    fn float_seconds_round_to_the_microsecond_and_clamp() {
        assert_eq!(
            Timestamp::from_secs_f64(1.218691),
            Timestamp::from_micros(1_218_691)
        );
        assert_eq!(Timestamp::from_secs_f64(-3.0), Timestamp::EPOCH);
        assert_eq!(Timestamp::from_secs_f64(f64::NAN), Timestamp::EPOCH);
        assert_eq!(
            Timestamp::from_secs_f64(1e300),
            Timestamp::from_micros(u64::MAX)
        );
    }

    #[test]
    fn shown_as_candump_does() {
        let t = Timestamp::from_nanos(1_700_000_000_123_456_789);
        assert_eq!(t.to_string(), "1700000000.123456");
        assert_eq!(Timestamp::from_micros(5).to_string(), "0.000005");
        assert_eq!(t.secs_and_micros(), (1_700_000_000, 123_456));
    }

    #[test]
    fn arithmetic_saturates_or_says_so() {
        let t = Timestamp::from_secs(10);
        assert_eq!(
            t.saturating_since(Timestamp::from_secs(4)),
            Duration::from_secs(6)
        );
        assert_eq!(Timestamp::from_secs(4).saturating_since(t), Duration::ZERO);
        assert_eq!(
            t.checked_add(Duration::from_millis(5)),
            Some(Timestamp::from_nanos(10_005_000_000))
        );
        assert_eq!(
            Timestamp::since_epoch(Duration::MAX).checked_add(Duration::from_secs(1)),
            None
        );
    }
    #[test]
    fn bit_times_and_nanoseconds_convert_in_one_place() {
        // 500 kbit/s: a bit-time is 2 µs.
        assert_eq!(BitTime::new(3).at_bitrate(500_000), Nanos::new(6_000));
        assert_eq!(Nanos::new(6_999).bit_times_at(500_000), BitTime::new(3));
        // 20 kbit/s: 8192 bit-times (the SLIO watchdog) are 409.6 ms.
        assert_eq!(
            BitTime::new(8192).at_bitrate(20_000),
            Nanos::from_micros(409_600)
        );
        // Far beyond a u64 of nanoseconds, and a zero bitrate, saturate instead of panicking.
        assert_eq!(BitTime::MAX.at_bitrate(1), Nanos::MAX);
        assert_eq!(BitTime::new(2).at_bitrate(0), Nanos::from_secs(2));
        assert_eq!(BitTime::new(1).secs_f64_at(3), 1.0 / 3.0);
        assert_eq!(Nanos::MAX.bit_times_at(1), BitTime::new(18_446_744_073));
        // Rounded up: the bit-time a node must wake at for a deadline between two bits.
        assert_eq!(
            Nanos::new(6_001).first_bit_time_at(500_000),
            BitTime::new(4)
        );
        assert_eq!(
            Nanos::new(6_000).first_bit_time_at(500_000),
            BitTime::new(3)
        );
        assert_eq!(Nanos::MAX.first_bit_time_at(u32::MAX), BitTime::MAX);
    }

    #[test]
    fn counted_time_keeps_its_unit_through_arithmetic() {
        let start = BitTime::new(100);
        let frame = BitTime::new(47);
        assert_eq!(start + frame * 2, BitTime::new(194));
        assert_eq!((start + frame) - start, frame);
        assert_eq!(start.saturating_sub(start + frame), BitTime::ZERO);
        assert_eq!(BitTime::MAX.checked_add(frame), None);
        assert_eq!(BitTime::new(94) / frame, 2);
        assert_eq!(3 * frame, frame * 3);
        assert_eq!(BitTime::MAX.saturating_mul(2), BitTime::MAX);
        assert_eq!(Nanos::new(7).saturating_mul(3), Nanos::new(21));
        assert_eq!(Nanos::new(5).abs_diff(Nanos::new(8)), Nanos::new(3));
        assert_eq!(Nanos::new(8).abs_diff(Nanos::new(5)), Nanos::new(3));
        assert_eq!(BitTime::new(95) % frame, BitTime::new(1));
        assert_eq!(
            Nanos::from_millis(3).as_duration(),
            Duration::from_millis(3)
        );
        assert_eq!(Nanos::from(Duration::MAX), Nanos::MAX);
        assert_eq!(
            Timestamp::from(Nanos::new(1_500)),
            Timestamp::from_nanos(1_500)
        );
        assert_eq!(BitTime::new(42).to_string(), "42");
        assert_eq!(BitTime::from(111u32), BitTime::new(111));
    }

    proptest::proptest! {
        /// The shortcut gives what the nanoseconds give, saturated or not, any bit rate.
        #[test]
        fn seconds_and_microseconds_are_those_of_the_nanoseconds(
            t in proptest::prop_oneof![
                0u64..1 << 40,
                proptest::num::u64::ANY,
            ],
            bitrate in proptest::prop_oneof![0u32..2_000_000, proptest::num::u32::ANY],
        ) {
            let via_nanos = Timestamp::from(BitTime::new(t).at_bitrate(bitrate)).secs_and_micros();
            proptest::prop_assert_eq!(BitTime::new(t).secs_and_micros_at(bitrate), via_nanos);
        }
    }
}
