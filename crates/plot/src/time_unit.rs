//! The time axis' unit.

/// The unit a time axis is labelled in.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TimeUnit {
    Seconds,
    Milliseconds,
    Microseconds,
}

impl TimeUnit {
    /// The unit that shows a span of `seconds` with tick values of about 1 to 1000: seconds
    /// from 2 s on, milliseconds from 2 ms on, microseconds below.
    pub fn for_span(seconds: f64) -> TimeUnit {
        if seconds >= 2.0 {
            TimeUnit::Seconds
        } else if seconds >= 2e-3 {
            TimeUnit::Milliseconds
        } else {
            TimeUnit::Microseconds
        }
    }

    /// How many of this unit make a second.
    pub fn per_second(self) -> f64 {
        match self {
            TimeUnit::Seconds => 1.0,
            TimeUnit::Milliseconds => 1e3,
            TimeUnit::Microseconds => 1e6,
        }
    }

    pub fn symbol(self) -> &'static str {
        match self {
            TimeUnit::Seconds => "s",
            TimeUnit::Milliseconds => "ms",
            TimeUnit::Microseconds => "µs",
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_unit_follows_the_span() {
        assert_eq!(TimeUnit::for_span(3600.0), TimeUnit::Seconds);
        assert_eq!(TimeUnit::for_span(2.0), TimeUnit::Seconds);
        assert_eq!(TimeUnit::for_span(1.0), TimeUnit::Milliseconds);
        assert_eq!(TimeUnit::for_span(0.002), TimeUnit::Milliseconds);
        assert_eq!(TimeUnit::for_span(0.0005), TimeUnit::Microseconds);
        assert_eq!(TimeUnit::for_span(0.0), TimeUnit::Microseconds);
    }
}
