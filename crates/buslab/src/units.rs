//! The one vocabulary for durations on the command line: a number with a unit, always.
//!
//! `2s`, `500ms`, `1.5s`, `250us`, `1m30s`, `2h` (humantime's syntax, plus decimal fractions
//! with a single unit). A bare number is refused, because in one option it would mean seconds
//! and in the next milliseconds. Durations are printed the same way (`2.06 s`, `350 ms`).

use std::time::Duration;

/// The longest duration any option accepts: long runs are measured in days, and beyond this
/// the clock arithmetic (`Instant + Duration`) could overflow.
pub const MAX_DURATION: Duration = Duration::from_secs(100 * 86_400);

/// Parses a wall-clock duration with its unit (see the module docs), up to [`MAX_DURATION`].
pub fn duration(text: &str) -> Result<Duration, String> {
    let t = text.trim();
    if !t.is_empty() && t.bytes().all(|b| b.is_ascii_digit() || b == b'.') {
        return Err(format!(
            "duration {text:?} has no unit: write e.g. {t}s or {t}ms"
        ));
    }
    let parsed = humantime::parse_duration(t)
        .ok()
        .or_else(|| decimal(t))
        .ok_or_else(|| {
            format!("duration {text:?} must be a number with a unit, e.g. 2s, 500ms, 1.5s, 1m30s")
        })?;
    if parsed > MAX_DURATION {
        return Err(format!(
            "duration {text:?} is longer than the longest accepted, {}",
            humantime::format_duration(MAX_DURATION)
        ));
    }
    Ok(parsed)
}

/// `1.5s`, `0.25ms`: a decimal number and one unit (humantime takes integers only).
fn decimal(text: &str) -> Option<Duration> {
    let split = text.find(|c: char| !(c.is_ascii_digit() || c == '.'))?;
    let (number, unit) = text.split_at(split);
    let scale = match unit.trim() {
        "s" | "sec" | "secs" => 1.0,
        "ms" | "msec" => 1e-3,
        "us" | "µs" | "usec" => 1e-6,
        "ns" | "nsec" => 1e-9,
        "m" | "min" | "mins" => 60.0,
        "h" | "hr" | "hrs" => 3600.0,
        _ => return None,
    };
    if number.is_empty() || number.bytes().filter(|&b| b == b'.').count() > 1 {
        return None;
    }
    let seconds = number.parse::<f64>().ok()? * scale;
    (seconds.is_finite() && seconds <= MAX_DURATION.as_secs_f64())
        .then(|| Duration::from_secs_f64(seconds))
}

/// A duration for people: three significant digits and a unit (`2.06 s`, `350 ms`, `87.0 µs`).
pub use buslab_device::Human;

#[cfg(test)]
mod tests {
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
