//! The one vocabulary for durations on the command line: a number with a unit, always.
//!
//! `2s`, `500ms`, `1.5s`, `250us`, `1m30s`, `2h` (humantime's syntax, plus decimal fractions
//! with a single unit). A bare number is refused, because in one option it would mean seconds
//! and in the next milliseconds. Durations are printed the same way (`2.06 s`, `350 ms`).
//!
//! The one exception is an option that copies a can-utils option with a unit of its own
//! (cangen's and canplayer's `-g` in milliseconds, canplayer's `-s` in seconds): there a bare
//! number means what it means to can-utils, and a warning says so ([`CanUtilsDuration`]).

use std::time::Duration;

/// An 11-bit CAN identifier as help texts show it (`0x700`, `0x000`): hex, as the bus
/// commands print identifiers, and read back by the options' parsers.
pub fn hex_id(id: u16) -> String {
    format!("0x{id:03X}")
}

/// The parser lives with the configuration file's (its durations are the command line's).
pub use buslab_config::duration::{MAX_DURATION, duration};

/// A duration given to an option that copies a can-utils option: with a unit, or a bare
/// number in can-utils' unit for it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct CanUtilsDuration {
    pub duration: Duration,
    /// The bare number and the unit it was taken in (`"10"`, `"ms"`), for the warning.
    pub bare: Option<(String, &'static str)>,
}

impl CanUtilsDuration {
    /// Says (once, as a warning) how a bare number was taken: `option` is how it was given
    /// (`-g`), `tool` the can-utils program it copies.
    pub fn warn_if_bare(&self, option: &str, tool: &str) {
        if let Some((number, unit)) = &self.bare {
            let word = unit_word(unit);
            tracing::warn!(
                "{option} {number}: a number without a unit is taken as {word}, as {tool} takes it (write {option} {number}{unit} to say so)"
            );
        }
    }
}

fn unit_word(unit: &str) -> &'static str {
    match unit {
        "ms" => "milliseconds",
        _ => "seconds",
    }
}

/// A duration with a unit, or a bare number in `unit` (`ms` or `s`).
fn can_utils_duration(text: &str, unit: &'static str) -> Result<CanUtilsDuration, String> {
    let t = text.trim();
    if t.is_empty() || !t.bytes().all(|b| b.is_ascii_digit() || b == b'.') {
        return duration(text).map(|duration| CanUtilsDuration {
            duration,
            bare: None,
        });
    }
    let Ok(value) = t.parse::<f64>() else {
        return Err(format!(
            "duration {text:?} is not a number: give {} as can-utils does (e.g. 10) or a number with a unit (10ms, 2s)",
            unit_word(unit)
        ));
    };
    let seconds = value * if unit == "ms" { 1e-3 } else { 1.0 };
    if !seconds.is_finite() || seconds > MAX_DURATION.as_secs_f64() {
        return Err(format!(
            "duration {text:?} ({t}{unit}) is longer than the longest accepted, {}",
            humantime::format_duration(MAX_DURATION)
        ));
    }
    Ok(CanUtilsDuration {
        duration: Duration::from_secs_f64(seconds),
        bare: Some((t.to_string(), unit)),
    })
}

/// cangen's and canplayer's `-g`: a bare number is milliseconds.
pub fn milliseconds_if_bare(text: &str) -> Result<CanUtilsDuration, String> {
    can_utils_duration(text, "ms")
}

/// canplayer's `-s`: a bare number is seconds.
pub fn seconds_if_bare(text: &str) -> Result<CanUtilsDuration, String> {
    can_utils_duration(text, "s")
}

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
    fn can_utils_options_take_a_bare_number_in_their_unit() {
        let gap = milliseconds_if_bare("4").unwrap();
        assert_eq!(gap.duration, Duration::from_millis(4));
        assert_eq!(gap.bare, Some(("4".to_string(), "ms")));
        assert_eq!(
            milliseconds_if_bare("0.5").unwrap().duration,
            Duration::from_micros(500)
        );
        let with_unit = milliseconds_if_bare("2s").unwrap();
        assert_eq!(
            (with_unit.duration, with_unit.bare),
            (Duration::from_secs(2), None)
        );
        assert_eq!(
            seconds_if_bare("3").unwrap().duration,
            Duration::from_secs(3)
        );
        let err = milliseconds_if_bare("1.2.3").unwrap_err();
        assert!(
            err.contains("\"1.2.3\" is not a number") && err.contains("milliseconds"),
            "{err}"
        );
        let err = seconds_if_bare("99999999999").unwrap_err();
        assert!(
            err.contains("\"99999999999\" (99999999999s) is longer than the longest accepted"),
            "{err}"
        );
        let err = milliseconds_if_bare("99999999999999").unwrap_err();
        assert!(err.contains("(99999999999999ms) is longer"), "{err}");
        for bad in ["1e22", "-5", "NaN", "5 parsecs", ""] {
            let err = milliseconds_if_bare(bad).unwrap_err();
            assert!(err.contains(&format!("{bad:?}")), "{bad}: {err}");
        }
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
