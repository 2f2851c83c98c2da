//! Numbers with their units, as specs write them: volts, frequencies, periods.

use buslab_can::Nanos;

pub(crate) fn finite(s: &str) -> Result<f64, ()> {
    match s.trim().parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        _ => Err(()),
    }
}

pub(crate) fn parse_volts(s: &str) -> Result<f64, ()> {
    let s = s.trim();
    if let Some(mv) = s.strip_suffix("mV").or_else(|| s.strip_suffix("mv")) {
        return finite(mv).map(|v| v / 1000.0);
    }
    finite(s.strip_suffix(['V', 'v']).unwrap_or(s))
}

pub(crate) fn parse_hz(s: &str) -> Result<f64, ()> {
    let s = s.trim();
    let (num, scale) = if let Some(n) = s.strip_suffix("kHz") {
        (n, 1e3)
    } else if let Some(n) = s.strip_suffix("mHz") {
        (n, 1e-3)
    } else if let Some(n) = s.strip_suffix("Hz").or_else(|| s.strip_suffix("hz")) {
        (n, 1.0)
    } else {
        (s, 1.0)
    };
    let hz = finite(num)? * scale;
    if hz < 0.0 { Err(()) } else { Ok(hz) }
}

/// `10s`, `250ms` or bare seconds, up to 1e9 s.
pub(crate) fn parse_period(s: &str) -> Result<Nanos, ()> {
    let s = s.trim();
    let (num, scale) = if let Some(n) = s.strip_suffix("ms") {
        (n, 1e6)
    } else if let Some(n) = s.strip_suffix('s') {
        (n, 1e9)
    } else {
        (s, 1e9)
    };
    let ns = finite(num)? * scale;
    if !(0.0..1e18).contains(&ns) {
        return Err(());
    }
    Ok(Nanos::new(ns.round() as u64))
}
