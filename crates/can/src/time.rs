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
}
