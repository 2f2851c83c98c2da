//! The one vocabulary for durations on the command line: a number with a unit, always.
//!
//! `2s`, `500ms`, `1.5s`, `250us`, `1m30s`, `2h` (humantime's syntax, plus decimal fractions
//! with a single unit). A bare number is refused, because in one option it would mean seconds
//! and in the next milliseconds. Durations are printed the same way (`2.06 s`, `350 ms`).

/// The parser lives with the configuration file's (its durations are the command line's).
pub use buslab_config::duration::{MAX_DURATION, duration};

/// A duration for people: three significant digits and a unit (`2.06 s`, `350 ms`, `87.0 µs`).
pub use buslab_device::Human;

#[cfg(test)]
mod tests {
    use std::time::Duration;

    use super::*;

    #[test]
    fn durations_need_a_unit() {
        assert_eq!(duration("2s"), Ok(Duration::from_secs(2)));
        assert_eq!(duration("500ms"), Ok(Duration::from_millis(500)));
        assert_eq!(duration("1.5s"), Ok(Duration::from_millis(1500)));
        assert_eq!(duration(" 250us "), Ok(Duration::from_micros(250)));
        assert_eq!(duration("1m30s"), Ok(Duration::from_secs(90)));
        let bare = duration("2").unwrap_err();
        assert!(bare.contains("no unit") && bare.contains("2s"), "{bare}");
        for bad in [
            "",
            "s",
            "2 parsecs",
            "-1s",
            "1.2.3s",
            "1e400s",
            "nan s",
            "ms10",
        ] {
            let err = duration(bad).unwrap_err();
            assert!(err.contains(&format!("{bad:?}")), "{bad}: {err}");
        }
        assert!(duration("101days").unwrap_err().contains("longest"));
        assert!(duration("100000000000h").is_err());
    }

    #[test]
    fn durations_print_with_a_unit() {
        assert_eq!(
            Human(Duration::from_secs_f64(2.06288)).to_string(),
            "2.06 s"
        );
        assert_eq!(Human(Duration::from_millis(350)).to_string(), "350 ms");
        assert_eq!(Human(Duration::from_micros(87)).to_string(), "87.0 µs");
        assert_eq!(Human(Duration::from_secs(120)).to_string(), "120 s");
        assert_eq!(Human(Duration::ZERO).to_string(), "0.00 ns");
    }
}
