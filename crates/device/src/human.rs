//! Durations in messages.

use core::fmt;
use core::time::Duration;

/// A duration for people: three significant digits and a unit (`2.06 s`, `350 ms`, `87.0 µs`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Human(pub Duration);

impl fmt::Display for Human {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let s = self.0.as_secs_f64();
        let (value, unit) = if s >= 1.0 {
            (s, "s")
        } else if s >= 1e-3 {
            (s * 1e3, "ms")
        } else if s >= 1e-6 {
            (s * 1e6, "µs")
        } else {
            (s * 1e9, "ns")
        };
        let decimals = if value >= 100.0 {
            0
        } else if value >= 10.0 {
            1
        } else {
            2
        };
        write!(f, "{value:.decimals$} {unit}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn three_significant_digits_and_a_unit() {
        let human = |d| Human(d).to_string();
        assert_eq!(human(Duration::from_secs_f64(2.06288)), "2.06 s");
        assert_eq!(human(Duration::from_millis(350)), "350 ms");
        assert_eq!(human(Duration::from_micros(87)), "87.0 µs");
        assert_eq!(human(Duration::from_secs(120)), "120 s");
    }
}
