//! A source and its voltage at any moment.

use std::f64::consts::TAU;
use std::fmt;

use buslab_can::Nanos;

use crate::error::SourceError;
use crate::units::parse_volts;

/// A periodic waveform shape.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Shape {
    Sine,
    Triangle,
    Square,
}

/// A voltage source for one analog input.
#[derive(Clone, Debug, PartialEq)]
pub enum Source {
    Constant(f64),
    /// `offset + amplitude * shape(2π · hz · t)`; every shape starts at `offset` going up
    /// (the square at its high half).
    Wave {
        shape: Shape,
        hz: f64,
        amplitude: f64,
        offset: f64,
    },
    /// Rises linearly from `from` to `to` over `period` (never zero), then starts again.
    Ramp {
        from: f64,
        to: f64,
        period: Nanos,
    },
    /// Recorded samples `(time, volts)`, sorted by time; each value holds until the next, the
    /// first before it starts and the last after it ends.
    Replay(Vec<(Nanos, f64)>),
}

impl Default for Source {
    /// An open input reads 0 V.
    fn default() -> Self {
        Source::Constant(0.0)
    }
}

impl Source {
    /// The voltage at `at` on the device's clock.
    pub fn volts(&self, at: Nanos) -> f64 {
        match self {
            Source::Constant(v) => *v,
            Source::Wave {
                shape,
                hz,
                amplitude,
                offset,
            } => {
                let cycles = seconds(at) * hz;
                let phase = cycles.fract();
                let unit = match shape {
                    Shape::Sine => (TAU * phase).sin(),
                    Shape::Triangle => {
                        if phase < 0.25 {
                            4.0 * phase
                        } else if phase < 0.75 {
                            2.0 - 4.0 * phase
                        } else {
                            4.0 * phase - 4.0
                        }
                    }
                    Shape::Square => {
                        if phase < 0.5 {
                            1.0
                        } else {
                            -1.0
                        }
                    }
                };
                offset + amplitude * unit
            }
            Source::Ramp { from, to, period } => {
                let period = period.get().max(1);
                let phase = (at.get() % period) as f64 / period as f64;
                from + (to - from) * phase
            }
            Source::Replay(points) => {
                let i = points.partition_point(|&(t, _)| t <= at);
                match i {
                    0 => points.first().map_or(0.0, |p| p.1),
                    i => points[i - 1].1,
                }
            }
        }
    }

    /// Parses a replay table: lines of `seconds,volts` (`;` or a tab also separate; a header
    /// line, blank lines and lines starting with `#` are skipped). Times must not go
    /// backwards.
    pub fn replay_from_csv(text: &str) -> Result<Source, SourceError> {
        let mut points: Vec<(Nanos, f64)> = Vec::new();
        for (n, line) in text.lines().enumerate() {
            let line_no = n + 1;
            let line = line.trim();
            if line.is_empty() || line.starts_with('#') {
                continue;
            }
            let bad = |why: String| SourceError::CsvLine {
                line: line_no,
                text: line.to_owned(),
                why,
            };
            let mut fields: Vec<&str> = line.split([',', ';', '\t']).map(str::trim).collect();
            while fields.last() == Some(&"") {
                fields.pop(); // trailing separators, as spreadsheets write them
            }
            // A third column would be dropped without a word (`time,ch1,ch2` is not a replay).
            let [t, v] = fields[..] else {
                return Err(bad("expected two fields `seconds,volts`".into()));
            };
            let (Ok(t), Ok(v)) = (t.parse::<f64>(), parse_volts(v)) else {
                if points.is_empty() && n == 0 {
                    continue; // a header line
                }
                return Err(bad("fields are not numbers `seconds,volts`".into()));
            };
            if !(t.is_finite() && (0.0..1e9).contains(&t)) {
                return Err(bad(format!(
                    "time {t} is not a number of seconds from 0 to 1e9"
                )));
            }
            let at = Nanos::new((t * 1e9).round() as u64);
            if points.last().is_some_and(|&(prev, _)| at < prev) {
                return Err(bad("time goes backwards".into()));
            }
            points.push((at, v));
        }
        if points.is_empty() {
            return Err(SourceError::CsvEmpty);
        }
        Ok(Source::Replay(points))
    }
}

fn seconds(at: Nanos) -> f64 {
    at.get() as f64 * 1e-9
}

/// The spelling [`SourceSpec::parse`](crate::SourceSpec::parse) reads back (a replay as its
/// size: its file is the caller's).
impl fmt::Display for Source {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Source::Constant(v) => write!(f, "const:{v}V"),
            Source::Wave {
                shape,
                hz,
                amplitude,
                offset,
            } => {
                let name = match shape {
                    Shape::Sine => "sine",
                    Shape::Triangle => "triangle",
                    Shape::Square => "square",
                };
                write!(f, "{name}:{hz}Hz:{amplitude}V:{offset}V")
            }
            Source::Ramp { from, to, period } => {
                write!(f, "ramp:{from}V:{to}V:{}s", seconds(*period))
            }
            Source::Replay(points) => write!(f, "replay of {} points", points.len()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::SourceSpec;

    fn ready(spec: &str) -> Source {
        match SourceSpec::parse(spec).unwrap() {
            SourceSpec::Ready(s) => s,
            other => panic!("{spec} gave {other:?}"),
        }
    }

    fn ms(m: u64) -> Nanos {
        Nanos::from_millis(m)
    }

    #[test]
    fn sine_follows_its_parameters() {
        let s = ready("sine:1Hz:2V:2.5V");
        assert!((s.volts(Nanos::ZERO) - 2.5).abs() < 1e-9);
        assert!((s.volts(ms(250)) - 4.5).abs() < 1e-9); // peak a quarter period in
        assert!((s.volts(ms(750)) - 0.5).abs() < 1e-9);
        assert!((s.volts(ms(1250)) - 4.5).abs() < 1e-9); // periodic
    }

    #[test]
    fn triangle_square_and_ramp_shapes() {
        let t = ready("triangle:10Hz:1V:2V");
        assert!((t.volts(ms(25)) - 3.0).abs() < 1e-9);
        assert!((t.volts(ms(75)) - 1.0).abs() < 1e-9);
        let q = ready("square:10Hz:1V:2V");
        assert_eq!(q.volts(ms(10)), 3.0);
        assert_eq!(q.volts(ms(60)), 1.0);
        let r = ready("ramp:0V:5V:10s");
        assert!((r.volts(ms(5000)) - 2.5).abs() < 1e-9);
        assert!((r.volts(ms(12_000)) - 1.0).abs() < 1e-9);
        // A ramp built by hand with a zero period holds its start instead of dividing by 0.
        let flat = Source::Ramp {
            from: 1.0,
            to: 2.0,
            period: Nanos::ZERO,
        };
        assert_eq!(flat.volts(ms(3)), 1.0);
    }

    #[test]
    fn every_source_reads_back_from_its_spelling() {
        for spec in [
            "const:3.3V",
            "sine:2Hz:1V:2.5V",
            "triangle:0.5Hz:2V:2V",
            "square:50Hz:2.5V:2.5V",
            "ramp:0V:5V:2.5s",
        ] {
            let source = ready(spec);
            assert_eq!(source.to_string(), spec);
            assert_eq!(ready(&source.to_string()), source);
        }
    }

    #[test]
    fn replay_holds_values_between_and_after_points() {
        let s =
            Source::replay_from_csv("time,volts\n0,1.0\n0.5,2.0\n# comment\n\n1.0;3V\n").unwrap();
        assert_eq!(s.volts(Nanos::ZERO), 1.0);
        assert_eq!(s.volts(Nanos::new(499_999_999)), 1.0);
        assert_eq!(s.volts(ms(500)), 2.0);
        assert_eq!(s.volts(ms(9000)), 3.0);
    }

    #[test]
    fn replay_garbage_is_refused_with_the_line() {
        let err = Source::replay_from_csv("0,1\nx,y\n").unwrap_err();
        assert!(err.to_string().contains("line 2"), "{err}");
        let err = Source::replay_from_csv("1,1\n0,1\n").unwrap_err();
        assert!(err.to_string().contains("backwards"), "{err}");
        assert_eq!(
            Source::replay_from_csv("\n# nothing\n"),
            Err(SourceError::CsvEmpty)
        );
        assert!(Source::replay_from_csv("-1,2").is_err());
        assert!(Source::replay_from_csv("1e300,2").is_err());
        let err = Source::replay_from_csv("0,1\n0.5,2,3\n").unwrap_err();
        assert_eq!(
            err.to_string(),
            "replay CSV line 2 `0.5,2,3`: expected two fields `seconds,volts`"
        );
        assert_eq!(
            Source::replay_from_csv("0;1;\n").unwrap(),
            Source::Replay(vec![(Nanos::ZERO, 1.0)])
        );
        assert!(Source::replay_from_csv("5").is_err());
    }
}
