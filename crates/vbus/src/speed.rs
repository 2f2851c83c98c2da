//! How fast the server runs its bus: paced to the wall clock (N times real time) or as fast as
//! the CPU allows (`max`, for benchmarks).

use std::fmt;
use std::str::FromStr;

/// The slowest and fastest paced speeds: outside them the pacing arithmetic overflows
/// `Duration`.
pub const PACED: std::ops::RangeInclusive<f64> = 0.001..=1_000_000.0;

/// How the server's virtual time relates to the wall clock.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Speed {
    /// Virtual seconds per wall-clock second (1.0 is real time), within [`PACED`].
    Times(f64),
    /// No pacing: the bus runs whenever it has work, as fast as the CPU allows, and the loop
    /// never sleeps while a client has input waiting or a frame is on the wire.
    Max,
}

impl Default for Speed {
    fn default() -> Self {
        Speed::Times(1.0)
    }
}

/// A speed that is neither `max` nor a number in [`PACED`].
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error(
    "speed {0} must be \"max\" or a number 0.001..=1000000 (times real time; \"max\": as fast as the CPU allows)"
)]
pub struct SpeedError(pub String);

impl Speed {
    /// The speed, checked: [`Speed::Times`] within [`PACED`].
    pub fn times(factor: f64) -> Result<Self, SpeedError> {
        let speed = Speed::Times(factor);
        speed.check()?;
        Ok(speed)
    }

    /// Whether the speed can be served.
    pub fn check(self) -> Result<(), SpeedError> {
        match self {
            Speed::Times(f) if !PACED.contains(&f) => Err(SpeedError(f.to_string())),
            _ => Ok(()),
        }
    }

    /// Whether virtual time is real time.
    pub fn is_real_time(self) -> bool {
        self == Speed::Times(1.0)
    }
}

impl FromStr for Speed {
    type Err = SpeedError;

    fn from_str(text: &str) -> Result<Self, SpeedError> {
        let text = text.trim();
        if text.eq_ignore_ascii_case("max") {
            return Ok(Speed::Max);
        }
        let factor: f64 = text.parse().map_err(|_| SpeedError(format!("{text:?}")))?;
        // Named as given (`1e7`, not `10000000`).
        Speed::times(factor).map_err(|_| SpeedError(text.to_string()))
    }
}

impl fmt::Display for Speed {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Speed::Times(factor) => write!(f, "{factor}"),
            Speed::Max => f.write_str("max"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn max_and_numbers_in_range_are_speeds() {
        assert_eq!("max".parse(), Ok(Speed::Max));
        assert_eq!("MAX".parse(), Ok(Speed::Max));
        assert_eq!("1".parse(), Ok(Speed::Times(1.0)));
        assert_eq!("0.001".parse(), Ok(Speed::Times(0.001)));
        assert_eq!("1000000".parse(), Ok(Speed::Times(1_000_000.0)));
        assert!(Speed::default().is_real_time());
    }

    #[test]
    fn bad_speeds_are_named_with_what_is_allowed() {
        for (text, named) in [
            ("fast", "speed \"fast\" must be"),
            ("", "speed \"\" must be"),
            ("0", "speed 0 must be"),
            ("-1", "speed -1 must be"),
            ("1e7", "speed 1e7 must be"),
            ("NaN", "speed NaN must be"),
            ("inf", "speed inf must be"),
        ] {
            let err = text.parse::<Speed>().expect_err(text).to_string();
            assert!(err.contains(named), "{text}: {err}");
            assert!(
                err.contains("\"max\"") && err.contains("0.001..=1000000"),
                "{text}: {err}"
            );
        }
    }
}
