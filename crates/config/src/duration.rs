//! Durations as people write them: a number with a unit, always (`2s`, `500ms`, `1.5s`,
//! `250us`, `1m30s`, `2h`: humantime's syntax, plus decimal fractions with a single unit). The
//! command line (`buslab`'s `units`) and the configuration file read them alike.

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
