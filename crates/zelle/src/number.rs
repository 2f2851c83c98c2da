//! Numbers and durations as people type them in control lines and on the command line.

use buslab_device::Nanos;

/// `12`, `0x1F`, `1Fh`.
pub fn parse_number(s: &str) -> Option<u32> {
    let s = s.trim();
    // Digits only: `from_str_radix` and `parse` would take a sign (`+f`, `+5`).
    if !s.bytes().all(|b| b.is_ascii_alphanumeric()) {
        return None;
    }
    if let Some(hex) = s.strip_prefix("0x").or_else(|| s.strip_prefix("0X")) {
        u32::from_str_radix(hex, 16).ok()
    } else if let Some(hex) = s.strip_suffix(['h', 'H']) {
        u32::from_str_radix(hex, 16).ok()
    } else {
        s.parse().ok()
    }
}

/// A number argument outside what is allowed.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
#[error("{what} `{text}` is not a number in 0..{max} (decimal, 0x1F or 1Fh)")]
pub struct NumberError {
    pub what: &'static str,
    pub text: String,
    pub max: u32,
}

/// [`parse_number`] limited to `0..=max`; `what` names the value in the error.
pub fn parse_number_in(text: &str, what: &'static str, max: u32) -> Result<u32, NumberError> {
    parse_number(text)
        .filter(|&v| v <= max)
        .ok_or_else(|| NumberError {
            what,
            text: text.to_owned(),
            max,
        })
}

/// `1.2s`, `500ms`, `2` (seconds).
pub fn parse_duration_ns(s: &str) -> Option<Nanos> {
    let s = s.trim();
    let (num, scale) = if let Some(n) = s.strip_suffix("ms") {
        (n, 1e6)
    } else if let Some(n) = s.strip_suffix("us") {
        (n, 1e3)
    } else if let Some(n) = s.strip_suffix('s') {
        (n, 1e9)
    } else {
        (s, 1e9)
    };
    let v: f64 = num.parse().ok()?;
    let ns = v * scale;
    (ns.is_finite() && (0.0..1e18).contains(&ns)).then_some(Nanos::new(ns.round() as u64))
}
