//! Virtual time: the simulator counts bit-times; people write seconds.

use core::fmt;

use crate::error::DurationError;

pub use buslab_can::BitTime;

/// A duration as written by a user: either bit-times or a time with a unit. Converted to
/// bit-times once the bit rate is known.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Span {
    Bits(BitTime),
    Seconds(f64),
}

impl Span {
    /// Parses `2s`, `1.5s`, `500ms`, `250us`, `100ns`, `1000bits` / `1000 bits`, or `0`. A
    /// bare number other than 0 is refused: it could mean bit-times or seconds.
    pub fn parse(text: &str) -> Result<Self, DurationError> {
        let bad = || DurationError {
            text: text.to_owned(),
        };
        let s = text.trim();
        let split = s
            .find(|c: char| !(c.is_ascii_digit() || c == '.'))
            .unwrap_or(s.len());
        let (number, unit) = s.split_at(split);
        if number.is_empty() {
            return Err(bad());
        }
        let unit = unit.trim();
        if unit.is_empty() {
            return match number.parse::<u64>() {
                Ok(0) => Ok(Span::Bits(BitTime::ZERO)),
                _ => Err(bad()),
            };
        }
        if unit == "bits" || unit == "bit" || unit == "b" {
            return number
                .parse::<u64>()
                .map(|bits| Span::Bits(BitTime::new(bits)))
                .map_err(|_| bad());
        }
        let scale = match unit {
            "s" => 1.0,
            "ms" => 1e-3,
            "us" | "µs" => 1e-6,
            "ns" => 1e-9,
            _ => return Err(bad()),
        };
        let value: f64 = number.parse().map_err(|_| bad())?;
        if !value.is_finite() {
            return Err(bad());
        }
        Ok(Span::Seconds(value * scale))
    }

    /// The span in bit-times at `bitrate` bit/s, rounded to the nearest bit.
    pub fn to_bits(self, bitrate: u32) -> BitTime {
        match self {
            Span::Bits(bits) => bits,
            Span::Seconds(s) => {
                let bits = (s * bitrate as f64).round();
                if bits >= u64::MAX as f64 {
                    BitTime::MAX
                } else {
                    BitTime::new(bits as u64)
                }
            }
        }
    }
}

impl fmt::Display for Span {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Span::Bits(b) => write!(f, "{b} bits"),
            Span::Seconds(s) => write!(f, "{s}s"),
        }
    }
}

impl core::str::FromStr for Span {
    type Err = DurationError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Span::parse(s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_units() {
        assert_eq!(
            Span::parse("2s").unwrap().to_bits(500_000),
            BitTime::new(1_000_000)
        );
        assert_eq!(
            Span::parse("1.5ms").unwrap().to_bits(1_000_000),
            BitTime::new(1_500)
        );
        assert_eq!(
            Span::parse("250us").unwrap().to_bits(125_000),
            BitTime::new(31)
        );
        assert_eq!(
            Span::parse("1000bits").unwrap().to_bits(1),
            BitTime::new(1000)
        );
        assert_eq!(Span::parse("0").unwrap(), Span::Bits(BitTime::ZERO));
        assert_eq!(
            Span::parse("1000 bits").unwrap(),
            Span::Bits(BitTime::new(1000))
        );
        assert_eq!(Span::parse(" 7bit ").unwrap(), Span::Bits(BitTime::new(7)));
    }

    #[test]
    fn garbage_names_the_value() {
        for bad in [
            "",
            "1000",
            "s",
            "10 parsecs",
            "1.5",
            "1.2.3s",
            "-1s",
            "ms10",
            "10 ms x",
        ] {
            let err = Span::parse(bad).unwrap_err();
            assert!(err.to_string().contains(&format!("{bad:?}")), "{err}");
        }
    }

    #[test]
    fn timestamps() {
        let secs_micros = |t: u64, bitrate| {
            buslab_can::Timestamp::from(BitTime::new(t).at_bitrate(bitrate)).secs_and_micros()
        };
        assert_eq!(secs_micros(1_500_000, 1_000_000), (1, 500_000));
        assert_eq!(secs_micros(3, 125_000), (0, 24));
        assert_eq!(BitTime::new(3).at_bitrate(125_000).get(), 24_000);
    }
}
