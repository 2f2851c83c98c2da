//! Analog input sources driving the model's converters (volts as a function of virtual time).

use core::fmt;
use core::str::FromStr;

use buslab_device::Nanos;

/// Full scale of both converters: 0..5 V.
pub const FULL_SCALE_V: f64 = 5.0;

/// A signal on one analog input.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(tag = "kind", rename_all = "lowercase")]
pub enum Source {
    Constant {
        volts: f64,
    },
    Sine {
        offset: f64,
        amplitude: f64,
        hz: f64,
    },
    /// Saw-tooth from `from` to `to` over `period_s`, then again.
    Ramp {
        from: f64,
        to: f64,
        period_s: f64,
    },
    Square {
        low: f64,
        high: f64,
        hz: f64,
    },
}

impl Default for Source {
    fn default() -> Self {
        Self::Constant { volts: 0.0 }
    }
}

impl Source {
    /// Volts at `t_ns`.
    pub fn volts(&self, t_ns: Nanos) -> f64 {
        let t = t_ns.get() as f64 * 1e-9;
        match *self {
            Self::Constant { volts } => volts,
            Self::Sine {
                offset,
                amplitude,
                hz,
            } => offset + amplitude * (2.0 * core::f64::consts::PI * hz * t).sin(),
            Self::Ramp { from, to, period_s } => {
                if period_s <= 0.0 {
                    from
                } else {
                    from + (to - from) * (t / period_s).fract()
                }
            }
            Self::Square { low, high, hz } => {
                if (t * hz).fract() < 0.5 {
                    high
                } else {
                    low
                }
            }
        }
    }

    /// The 10-bit conversion at `t_ns`: round(V × 1023 / 5), clamped to 0..=1023.
    pub fn code10(&self, t_ns: Nanos) -> u16 {
        volts_to_code10(self.volts(t_ns))
    }
}

/// round(V × 1023 / 5) clamped to 0..=1023.
pub fn volts_to_code10(v: f64) -> u16 {
    (v * 1023.0 / FULL_SCALE_V).round().clamp(0.0, 1023.0) as u16
}

/// Volts of a 10-bit code.
pub fn code10_to_volts(code: f64) -> f64 {
    code * FULL_SCALE_V / 1023.0
}

/// Why a source spelling was not understood.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error(
    "analog source `{0}` is not understood; use const:V, sine:OFFSET,AMPLITUDE,HZ, \
     ramp:FROM,TO,PERIOD_S or square:LOW,HIGH,HZ (volts 0..5)"
)]
pub struct SourceParseError(pub String);

impl FromStr for Source {
    type Err = SourceParseError;

    /// `const:2.5`, `sine:2.5,1,10`, `ramp:0,5,2`, `square:0,5,50`.
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let err = || SourceParseError(s.to_string());
        let (kind, args) = s.split_once(':').ok_or_else(err)?;
        let nums: Vec<f64> = args
            .split(',')
            .map(|a| a.trim().parse::<f64>())
            .collect::<Result<_, _>>()
            .map_err(|_| err())?;
        if nums.iter().any(|n| !n.is_finite()) {
            return Err(err());
        }
        Ok(match (kind, nums.as_slice()) {
            ("const", &[volts]) => Self::Constant { volts },
            ("sine", &[offset, amplitude, hz]) => Self::Sine {
                offset,
                amplitude,
                hz,
            },
            ("ramp", &[from, to, period_s]) if period_s > 0.0 => Self::Ramp { from, to, period_s },
            ("square", &[low, high, hz]) => Self::Square { low, high, hz },
            _ => return Err(err()),
        })
    }
}

impl fmt::Display for Source {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Constant { volts } => write!(f, "const:{volts}"),
            Self::Sine {
                offset,
                amplitude,
                hz,
            } => write!(f, "sine:{offset},{amplitude},{hz}"),
            Self::Ramp { from, to, period_s } => write!(f, "ramp:{from},{to},{period_s}"),
            Self::Square { low, high, hz } => write!(f, "square:{low},{high},{hz}"),
        }
    }
}

/// The analog inputs of the board: 8 on the 80C196, 8 on the PIC (PIC channel 0 = battery).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Inputs {
    pub c196: [Source; 8],
    pub pic: [Source; 8],
}

impl Default for Inputs {
    fn default() -> Self {
        let mut c196 = [Source::default(); 8];
        c196[0] = Source::Sine {
            offset: 2.5,
            amplitude: 2.0,
            hz: 1.0,
        };
        c196[1] = Source::Ramp {
            from: 0.0,
            to: 5.0,
            period_s: 4.0,
        };
        c196[2] = Source::Constant { volts: 1.25 };
        c196[3] = Source::Square {
            low: 1.0,
            high: 4.0,
            hz: 2.0,
        };
        let mut pic = [Source::default(); 8];
        // A healthy battery: above the default "ok" threshold.
        pic[0] = Source::Constant { volts: 3.5 };
        Self { c196, pic }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_and_prints_sources() {
        for s in ["const:2.5", "sine:2.5,1,10", "ramp:0,5,2", "square:0,5,50"] {
            assert_eq!(s.parse::<Source>().unwrap().to_string(), s);
        }
        for bad in [
            "",
            "sine:1,2",
            "const:x",
            "ramp:0,5,0",
            "noise:1",
            "const:NaN",
        ] {
            assert!(bad.parse::<Source>().is_err(), "{bad}");
        }
        assert_eq!(volts_to_code10(5.0), 1023);
        assert_eq!(volts_to_code10(9.0), 1023);
        assert_eq!(volts_to_code10(-1.0), 0);
        assert_eq!(
            Source::Ramp {
                from: 0.0,
                to: 5.0,
                period_s: 1.0
            }
            .code10(Nanos::new(500_000_000)),
            512
        );
    }
}
