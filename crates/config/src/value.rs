//! One value as it arrives (a TOML value from the file, or text from the environment or the
//! command line) and the readers every key's value goes through.

use std::time::Duration;

/// A value before it is checked.
#[derive(Clone, Debug, PartialEq)]
pub enum Raw {
    /// A TOML string.
    Str(String),
    /// A TOML integer (any radix).
    Int(i128),
    Float(f64),
    Bool(bool),
    /// Another TOML type (its name: `array`, `table`, `datetime`).
    Other(&'static str),
    /// Text from an environment variable, `--set` or a prompt: read as the key's type.
    Text(String),
}

impl Raw {
    /// From the TOML parser's value.
    pub(super) fn from_toml(value: &toml::de::DeValue<'_>) -> Self {
        use toml::de::DeValue;
        match value {
            DeValue::String(s) => Raw::Str(s.to_string()),
            DeValue::Integer(i) => {
                i128::from_str_radix(i.as_str(), i.radix()).map_or(Raw::Other("integer"), Raw::Int)
            }
            DeValue::Float(f) => f.as_str().parse().map_or(Raw::Other("float"), Raw::Float),
            DeValue::Boolean(b) => Raw::Bool(*b),
            other => Raw::Other(other.type_str()),
        }
    }

    /// What it is, for "must be …, not a string".
    fn kind(&self) -> &'static str {
        match self {
            Raw::Str(_) => "a string",
            Raw::Int(_) => "an integer",
            Raw::Float(_) => "a number with a fraction",
            Raw::Bool(_) => "a boolean",
            Raw::Other("table") => "a table",
            Raw::Other("array") => "an array",
            Raw::Other(_) => "another kind of value",
            Raw::Text(_) => "text",
        }
    }
}

/// Text: a TOML string, or the text as it is.
pub fn text(raw: &Raw) -> Result<&str, String> {
    match raw {
        Raw::Str(s) | Raw::Text(s) => Ok(s),
        other => Err(format!("must be a string in quotes, not {}", other.kind())),
    }
}

/// An integer in `min..=max`: a TOML integer (`0x700`, `1792`), or text in decimal or with
/// `0x`. `allowed` says what is accepted.
pub fn integer(raw: &Raw, min: u64, max: u64, allowed: &str) -> Result<u64, String> {
    let n = match raw {
        Raw::Int(n) => Some(*n),
        Raw::Text(t) => integer_text(t),
        Raw::Str(s) if integer_text(s).is_some() => {
            return Err(format!("{allowed}, written without quotes"));
        }
        _ => None,
    };
    match n {
        Some(n) if (i128::from(min)..=i128::from(max)).contains(&n) => Ok(n as u64),
        _ => Err(allowed.to_string()),
    }
}

/// `1792`, `0x700`, `0X700`, `0b101`, with `_` between digits as TOML allows.
pub fn integer_text(text: &str) -> Option<i128> {
    let t = text.trim().replace('_', "");
    let (digits, radix) = match t.get(..2) {
        Some("0x" | "0X") => (&t[2..], 16),
        Some("0b" | "0B") => (&t[2..], 2),
        Some("0o" | "0O") => (&t[2..], 8),
        _ => (&t[..], 10),
    };
    if digits.is_empty() || !digits.bytes().all(|b| b.is_ascii_alphanumeric()) {
        return None;
    }
    i128::from_str_radix(digits, radix).ok()
}

/// `true`/`false` (and, as text, `1`/`0`, `yes`/`no`, `on`/`off`).
pub fn boolean(raw: &Raw) -> Result<bool, String> {
    const ALLOWED: &str = "must be true or false";
    match raw {
        Raw::Bool(b) => Ok(*b),
        Raw::Text(t) => match t.trim().to_ascii_lowercase().as_str() {
            "true" | "1" | "yes" | "on" => Ok(true),
            "false" | "0" | "no" | "off" => Ok(false),
            _ => Err(ALLOWED.into()),
        },
        Raw::Str(_) => Err(format!("{ALLOWED}, written without quotes")),
        _ => Err(ALLOWED.into()),
    }
}

/// A duration with its unit (`"60s"`, `"1ms"`, `"1m30s"`) in `min..=max`.
pub fn duration(
    raw: &Raw,
    min: Duration,
    max: Duration,
    allowed: &str,
) -> Result<Duration, String> {
    match raw {
        Raw::Str(t) | Raw::Text(t) => {
            let d = crate::duration::duration(t).map_err(|e| format!("{allowed} ({e})"))?;
            if (min..=max).contains(&d) {
                Ok(d)
            } else {
                Err(allowed.to_string())
            }
        }
        Raw::Int(n) => Err(format!(
            "{allowed}: write the unit, e.g. \"{n}s\" or \"{n}ms\""
        )),
        _ => Err(allowed.to_string()),
    }
}

/// A bit rate in bit/s, 1..=1000000: an integer (`125000`), or text as people write it:
/// `125k`, `125 kbit/s`, `125kbps`, `1M`, `1 Mbit/s`, `83.3k` (rounded to the bit/s).
pub fn bitrate(raw: &Raw, allowed: &str) -> Result<u32, String> {
    let n = match raw {
        Raw::Int(n) => Some(*n as f64),
        Raw::Str(t) | Raw::Text(t) => bitrate_text(t),
        _ => None,
    };
    match n {
        Some(n) if n.is_finite() && (1.0..=1_000_000.0).contains(&n.round()) => {
            Ok(n.round() as u32)
        }
        _ => Err(allowed.to_string()),
    }
}

/// `125k`, `500 kbit/s`, `1M`, `125000`, `125000 bit/s`: the bit rate in bit/s.
fn bitrate_text(text: &str) -> Option<f64> {
    let t = text.trim().to_ascii_lowercase().replace('_', "");
    let split = t
        .find(|c: char| !(c.is_ascii_digit() || c == '.'))
        .unwrap_or(t.len());
    let (number, unit) = t.split_at(split);
    let number: f64 = number.parse().ok()?;
    let unit = unit.trim();
    let unit = ["bit/s", "bps", "b/s", "bit", ""]
        .iter()
        .find_map(|suffix| unit.strip_suffix(suffix))?
        .trim();
    let scale = match unit {
        "" => 1.0,
        "k" => 1e3,
        "m" => 1e6,
        _ => return None,
    };
    Some(number * scale)
}

/// A number (`87.5`, `80`, and as text or a string also `87.5%`) in `min..=max`.
pub fn number(raw: &Raw, min: f64, max: f64, allowed: &str) -> Result<f64, String> {
    let n = match raw {
        Raw::Float(f) => Some(*f),
        Raw::Int(i) => Some(*i as f64),
        Raw::Str(t) | Raw::Text(t) => t.trim().trim_end_matches('%').trim().parse().ok(),
        _ => None,
    };
    match n {
        Some(n) if n.is_finite() && (min..=max).contains(&n) => Ok(n),
        _ => Err(allowed.to_string()),
    }
}

/// One of `choices` (case does not matter); returns its index.
pub fn choice(raw: &Raw, choices: &[&str], allowed: &str) -> Result<usize, String> {
    let t = text(raw).map_err(|_| allowed.to_string())?;
    choices
        .iter()
        .position(|c| c.eq_ignore_ascii_case(t.trim()))
        .ok_or_else(|| allowed.to_string())
}

/// A TOML string literal.
pub fn quoted(text: &str) -> String {
    toml::Value::String(text.to_string()).to_string()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn integers_from_the_file_and_from_text() {
        let allowed = "must be 0..=0x7FF";
        assert_eq!(integer(&Raw::Int(0x700), 0, 0x7FF, allowed), Ok(0x700));
        assert_eq!(
            integer(&Raw::Text("0x700".into()), 0, 0x7FF, allowed),
            Ok(0x700)
        );
        assert_eq!(
            integer(&Raw::Text(" 1792 ".into()), 0, 0x7FF, allowed),
            Ok(1792)
        );
        assert_eq!(
            integer(&Raw::Text("0x800".into()), 0, 0x7FF, allowed),
            Err(allowed.into())
        );
        assert_eq!(
            integer(&Raw::Text("0x".into()), 0, 0x7FF, allowed),
            Err(allowed.into())
        );
        assert_eq!(
            integer(&Raw::Text("-1".into()), 0, 0x7FF, allowed),
            Err(allowed.into())
        );
        let quoted = integer(&Raw::Str("0x700".into()), 0, 0x7FF, allowed).unwrap_err();
        assert!(quoted.contains("without quotes"), "{quoted}");
    }

    #[test]
    fn durations_need_their_unit() {
        let (min, max) = (Duration::ZERO, Duration::from_secs(10));
        let ok = duration(&Raw::Str("1ms".into()), min, max, "x");
        assert_eq!(ok, Ok(Duration::from_millis(1)));
        let bare = duration(&Raw::Int(60), min, max, "must be 0s..=10s").unwrap_err();
        assert!(bare.contains("\"60s\""), "{bare}");
        assert!(duration(&Raw::Str("11s".into()), min, max, "x").is_err());
        assert!(duration(&Raw::Text("soon".into()), min, max, "x").is_err());
    }

    #[test]
    fn bit_rates_as_people_write_them() {
        let allowed = "must be a bit rate";
        for (text, rate) in [
            ("125000", 125_000),
            ("125k", 125_000),
            ("125K", 125_000),
            ("125 k", 125_000),
            ("500 kbit/s", 500_000),
            ("500kbps", 500_000),
            ("1M", 1_000_000),
            ("1 Mbit/s", 1_000_000),
            ("83.333k", 83_333),
            ("125000 bit/s", 125_000),
            ("10_000", 10_000),
        ] {
            assert_eq!(
                bitrate(&Raw::Text(text.into()), allowed),
                Ok(rate),
                "{text}"
            );
        }
        assert_eq!(bitrate(&Raw::Int(125_000), allowed), Ok(125_000));
        assert_eq!(bitrate(&Raw::Str("125k".into()), allowed), Ok(125_000));
        for bad in [
            "", "k", "fast", "2M", "125 kHz", "-1", "0", "1.5.0k", "125kk", "nan",
        ] {
            assert_eq!(
                bitrate(&Raw::Text(bad.into()), allowed),
                Err(allowed.into()),
                "{bad}"
            );
        }
        assert!(bitrate(&Raw::Bool(true), allowed).is_err());
    }

    #[test]
    fn booleans_numbers_and_choices() {
        assert_eq!(boolean(&Raw::Text("off".into())), Ok(false));
        assert!(boolean(&Raw::Str("true".into())).is_err());
        assert_eq!(number(&Raw::Str("87.5%".into()), 50.0, 95.0, "x"), Ok(87.5));
        assert!(number(&Raw::Float(f64::NAN), 50.0, 95.0, "x").is_err());
        let modes = ["pelican", "basiccan"];
        assert_eq!(choice(&Raw::Str("BasicCAN".into()), &modes, "x"), Ok(1));
        assert!(choice(&Raw::Int(1), &modes, "x").is_err());
    }
}
