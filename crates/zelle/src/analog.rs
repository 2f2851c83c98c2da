//! What feeds the cell's four A/D inputs: voltages as functions of virtual time.
//!
//! The converter is 8-bit over 0..5 V: a reading is `round(volts / 5 * 255)`, clamped to
//! 0..255. Sources are written as short specs, e.g. `2.5V`, `sine:1Hz:2V:2.5V`,
//! `ramp:0V:5V:10s`, `csv:input.csv` (see [`SourceSpec::parse`]).

use std::f64::consts::TAU;
use std::fmt;
use std::path::PathBuf;

use buslab_device::Nanos;

/// Full scale of the A/D converter.
pub const FULL_SCALE_VOLTS: f64 = 5.0;

/// The 8-bit reading the converter gives for `volts`.
pub fn to_code(volts: f64) -> u8 {
    if volts.is_nan() {
        return 0;
    }
    (volts / FULL_SCALE_VOLTS * 255.0).round().clamp(0.0, 255.0) as u8
}

/// The voltage an 8-bit reading stands for.
pub fn to_volts(code: u8) -> f64 {
    f64::from(code) * FULL_SCALE_VOLTS / 255.0
}

/// A periodic waveform shape.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Shape {
    Sine,
    Triangle,
    Square,
}

/// A voltage source for one A/D input.
#[derive(Clone, Debug, PartialEq)]
pub enum Source {
    Constant(f64),
    /// `offset + amplitude * shape(2π · hz · t)`.
    Wave {
        shape: Shape,
        hz: f64,
        amplitude: f64,
        offset: f64,
    },
    /// Rises linearly from `from` to `to` over `period_ns`, then starts again.
    Ramp {
        from: f64,
        to: f64,
        period_ns: Nanos,
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
    /// The voltage at virtual time `t_ns`.
    pub fn volts(&self, t_ns: Nanos) -> f64 {
        match self {
            Source::Constant(v) => *v,
            Source::Wave {
                shape,
                hz,
                amplitude,
                offset,
            } => {
                let cycles = t_ns.get() as f64 * 1e-9 * hz;
                let phase = cycles.fract();
                let unit = match shape {
                    Shape::Sine => (TAU * phase).sin(),
                    // Starts at 0 going up, like the sine.
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
            Source::Ramp {
                from,
                to,
                period_ns,
            } => {
                let phase = (t_ns % *period_ns).get() as f64 / period_ns.get() as f64;
                from + (to - from) * phase
            }
            Source::Replay(points) => {
                let i = points.partition_point(|&(at, _)| at <= t_ns);
                match i {
                    0 => points.first().map_or(0.0, |p| p.1),
                    i => points[i - 1].1,
                }
            }
        }
    }

    /// The converter's reading at `t_ns`.
    pub fn code(&self, t_ns: Nanos) -> u8 {
        to_code(self.volts(t_ns))
    }

    /// Parses a replay table: lines of `seconds,volts` (a header line, blank lines and lines
    /// starting with `#` are skipped). Times must not go backwards.
    pub fn replay_from_csv(text: &str) -> Result<Source, SourceError> {
        let mut points: Vec<(Nanos, f64)> = Vec::new();
        for (n, line) in text.lines().enumerate() {
            let line_no = n + 1;
            let line = line.trim();
            if line.is_empty() || line.starts_with('#') {
                continue;
            }
            let mut fields: Vec<&str> = line.split([',', ';', '\t']).map(str::trim).collect();
            while fields.last() == Some(&"") {
                fields.pop(); // trailing separators, as spreadsheets write them
            }
            // A third column would be dropped without a word (`time,ch1,ch2` is not a replay).
            let [t, v] = fields[..] else {
                return Err(SourceError::CsvLine {
                    line: line_no,
                    text: line.to_owned(),
                    why: "expected two fields `seconds,volts`".into(),
                });
            };
            let (Ok(t), Ok(v)) = (t.parse::<f64>(), parse_volts(v)) else {
                if points.is_empty() && n == 0 {
                    continue; // a header line
                }
                return Err(SourceError::CsvLine {
                    line: line_no,
                    text: line.to_owned(),
                    why: "fields are not numbers `seconds,volts`".into(),
                });
            };
            if !(t.is_finite() && t >= 0.0) {
                return Err(SourceError::CsvLine {
                    line: line_no,
                    text: line.to_owned(),
                    why: format!("time {t} is not a non-negative number of seconds"),
                });
            }
            let at = Nanos::new((t * 1e9).round() as u64);
            if points.last().is_some_and(|&(prev, _)| at < prev) {
                return Err(SourceError::CsvLine {
                    line: line_no,
                    text: line.to_owned(),
                    why: "time goes backwards".into(),
                });
            }
            points.push((at, v));
        }
        if points.is_empty() {
            return Err(SourceError::CsvEmpty);
        }
        Ok(Source::Replay(points))
    }
}

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
            Source::Ramp {
                from,
                to,
                period_ns,
            } => write!(f, "ramp:{from}V:{to}V:{}s", period_ns.get() as f64 * 1e-9),
            Source::Replay(points) => write!(f, "replay of {} points", points.len()),
        }
    }
}

/// A parsed source spec. A CSV replay names a file, which the caller reads (the model does no
/// I/O) and hands to [`Source::replay_from_csv`].
#[derive(Clone, Debug, PartialEq)]
pub enum SourceSpec {
    Ready(Source),
    CsvFile(PathBuf),
}

/// The spec grammar, for error messages.
pub const SPEC_HELP: &str = "VOLTS | const:VOLTS | sine|triangle|square:FREQ[:AMPLITUDE[:OFFSET]] \
     | ramp:FROM:TO:PERIOD | csv:FILE  (e.g. 2.5V, sine:1Hz:2V:2.5V, ramp:0V:5V:10s)";

/// `CH=SOURCE` (`1=sine:1Hz:2V:2.5V`), as `serve --analog` takes it: the channel (1..4) and
/// the source spec.
pub fn parse_channel_source(arg: &str) -> Result<(u8, SourceSpec), SourceError> {
    let (ch, spec) = arg.split_once('=').ok_or_else(|| SourceError::Spec {
        spec: arg.to_owned(),
        why: "must look like CH=SOURCE, e.g. 1=sine:1Hz".into(),
    })?;
    let channel = match crate::number::parse_number(ch) {
        Some(c @ 1..=4) => c as u8,
        _ => {
            return Err(SourceError::Channel {
                arg: arg.to_owned(),
                channel: ch.to_owned(),
            });
        }
    };
    Ok((channel, SourceSpec::parse(spec)?))
}

impl SourceSpec {
    /// Parses `VOLTS`, `const:VOLTS`, `sine:FREQ[:AMPLITUDE[:OFFSET]]` (also `triangle`,
    /// `square`; amplitude and offset default to 2.5 V, i.e. full scale), `ramp:FROM:TO:PERIOD`
    /// or `csv:FILE`. Volts may carry `V` or `mV`, frequencies `Hz`, `kHz` or `mHz`, periods
    /// `s` or `ms`.
    pub fn parse(spec: &str) -> Result<SourceSpec, SourceError> {
        let bad = |why: String| SourceError::Spec {
            spec: spec.to_owned(),
            why,
        };
        let spec_t = spec.trim();
        let (kind, rest) = spec_t.split_once(':').unwrap_or((spec_t, ""));
        let args: Vec<&str> = if rest.is_empty() {
            Vec::new()
        } else {
            rest.split(':').map(str::trim).collect()
        };
        let volts = |s: &str| parse_volts(s).map_err(|_| bad(format!("`{s}` is not a voltage")));
        let ready = |s| Ok(SourceSpec::Ready(s));
        match kind.to_ascii_lowercase().as_str() {
            "csv" if !rest.is_empty() => Ok(SourceSpec::CsvFile(PathBuf::from(rest))),
            "csv" => Err(bad("csv needs a file: csv:FILE".into())),
            "const" | "dc" => match args[..] {
                [v] => ready(Source::Constant(volts(v)?)),
                _ => Err(bad("const takes one voltage: const:2.5V".into())),
            },
            "sine" | "triangle" | "square" => {
                let shape = match kind.to_ascii_lowercase().as_str() {
                    "sine" => Shape::Sine,
                    "triangle" => Shape::Triangle,
                    _ => Shape::Square,
                };
                if args.is_empty() || args.len() > 3 {
                    return Err(bad(format!(
                        "{kind} takes FREQ[:AMPLITUDE[:OFFSET]], e.g. {kind}:1Hz:2V:2.5V"
                    )));
                }
                let hz = parse_hz(args[0])
                    .map_err(|_| bad(format!("`{}` is not a frequency", args[0])))?;
                let amplitude = args.get(1).map_or(Ok(2.5), |s| volts(s))?;
                let offset = args.get(2).map_or(Ok(2.5), |s| volts(s))?;
                ready(Source::Wave {
                    shape,
                    hz,
                    amplitude,
                    offset,
                })
            }
            "ramp" => match args[..] {
                [from, to, period] => {
                    let period_ns = parse_seconds(period)
                        .map_err(|_| bad(format!("`{period}` is not a period like 10s")))?;
                    if period_ns == Nanos::ZERO {
                        return Err(bad("the ramp period must be longer than 0".into()));
                    }
                    ready(Source::Ramp {
                        from: volts(from)?,
                        to: volts(to)?,
                        period_ns,
                    })
                }
                _ => Err(bad("ramp takes FROM:TO:PERIOD, e.g. ramp:0V:5V:10s".into())),
            },
            _ if args.is_empty() => match parse_volts(kind) {
                Ok(v) => ready(Source::Constant(v)),
                Err(_) => Err(bad(format!("unknown source; expected {SPEC_HELP}"))),
            },
            _ => Err(bad(format!(
                "unknown source `{kind}`; expected {SPEC_HELP}"
            ))),
        }
    }
}

/// Why a source spec or replay file was refused.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum SourceError {
    #[error("analog source `{spec}`: {why}")]
    Spec { spec: String, why: String },
    #[error("analog input `{arg}`: channel `{channel}` is out of range 1..4")]
    Channel { arg: String, channel: String },
    #[error("replay CSV line {line} `{text}`: {why}")]
    CsvLine {
        line: usize,
        text: String,
        why: String,
    },
    #[error("replay CSV has no `seconds,volts` rows")]
    CsvEmpty,
}

fn finite(s: &str) -> Result<f64, ()> {
    match s.trim().parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        _ => Err(()),
    }
}

fn parse_volts(s: &str) -> Result<f64, ()> {
    let s = s.trim();
    if let Some(mv) = s.strip_suffix("mV").or_else(|| s.strip_suffix("mv")) {
        return finite(mv).map(|v| v / 1000.0);
    }
    finite(s.strip_suffix(['V', 'v']).unwrap_or(s))
}

fn parse_hz(s: &str) -> Result<f64, ()> {
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

fn parse_seconds(s: &str) -> Result<Nanos, ()> {
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

#[cfg(test)]
mod tests {
    use super::*;

    fn ready(spec: &str) -> Source {
        match SourceSpec::parse(spec).unwrap() {
            SourceSpec::Ready(s) => s,
            other => panic!("{spec} gave {other:?}"),
        }
    }

    #[test]
    fn codes_cover_zero_to_five_volts() {
        assert_eq!(to_code(0.0), 0);
        assert_eq!(to_code(2.5), 128);
        assert_eq!(to_code(5.0), 255);
        assert_eq!(to_code(7.0), 255);
        assert_eq!(to_code(-1.0), 0);
        assert_eq!(to_code(f64::NAN), 0);
        assert!((to_volts(255) - 5.0).abs() < 1e-9);
    }

    #[test]
    fn sine_follows_its_parameters() {
        let s = ready("sine:1Hz:2V:2.5V");
        assert_eq!(s.code(Nanos::ZERO), to_code(2.5));
        assert_eq!(s.code(Nanos::new(250_000_000)), to_code(4.5)); // peak a quarter period in
        assert_eq!(s.code(Nanos::new(750_000_000)), to_code(0.5));
        assert_eq!(s.code(Nanos::new(1_250_000_000)), to_code(4.5)); // periodic
    }

    #[test]
    fn triangle_square_and_ramp_shapes() {
        let t = ready("triangle:10Hz:1V:2V");
        assert!((t.volts(Nanos::new(25_000_000)) - 3.0).abs() < 1e-9);
        assert!((t.volts(Nanos::new(75_000_000)) - 1.0).abs() < 1e-9);
        let q = ready("square:10Hz:1V:2V");
        assert_eq!(q.volts(Nanos::new(10_000_000)), 3.0);
        assert_eq!(q.volts(Nanos::new(60_000_000)), 1.0);
        let r = ready("ramp:0V:5V:10s");
        assert!((r.volts(Nanos::new(5_000_000_000)) - 2.5).abs() < 1e-9);
        assert!((r.volts(Nanos::new(12_000_000_000)) - 1.0).abs() < 1e-9);
    }

    #[test]
    fn constants_in_several_spellings() {
        assert_eq!(ready("2.5V"), Source::Constant(2.5));
        assert_eq!(ready("1200mV"), Source::Constant(1.2));
        assert_eq!(ready("const:3"), Source::Constant(3.0));
        let w = ready("sine:2kHz");
        assert_eq!(
            w,
            Source::Wave {
                shape: Shape::Sine,
                hz: 2000.0,
                amplitude: 2.5,
                offset: 2.5
            }
        );
    }

    #[test]
    fn channel_source_arguments_name_the_bad_part() {
        assert_eq!(
            parse_channel_source("2=3.3V").unwrap(),
            (2, SourceSpec::Ready(Source::Constant(3.3)))
        );
        for (arg, needle) in [
            ("9=1V", "channel `9` is out of range 1..4"),
            ("x=1V", "channel `x` is out of range 1..4"),
            ("1V", "must look like CH=SOURCE"),
            ("1=wobble", "analog source `wobble`"),
        ] {
            let err = parse_channel_source(arg).unwrap_err().to_string();
            assert!(err.contains(needle), "{arg}: {err}");
        }
    }

    #[test]
    fn csv_spec_names_a_file() {
        assert_eq!(
            SourceSpec::parse("csv:data/in.csv").unwrap(),
            SourceSpec::CsvFile("data/in.csv".into())
        );
    }

    #[test]
    fn garbage_specs_are_refused_with_the_spec_named() {
        for spec in [
            "",
            "sine",
            "sine:fast",
            "sine:1Hz:2V:2.5V:9",
            "ramp:0:5",
            "ramp:0:5:0s",
            "noise:1",
            "csv:",
            "const:",
            "NaN",
            "inf",
            "\u{0}\u{ff}",
        ] {
            let err = SourceSpec::parse(spec).unwrap_err();
            assert!(err.to_string().contains(spec), "{err}");
        }
    }

    #[test]
    fn replay_holds_values_between_and_after_points() {
        let s =
            Source::replay_from_csv("time,volts\n0,1.0\n0.5,2.0\n# comment\n\n1.0;3V\n").unwrap();
        assert_eq!(s.volts(Nanos::ZERO), 1.0);
        assert_eq!(s.volts(Nanos::new(499_999_999)), 1.0);
        assert_eq!(s.volts(Nanos::new(500_000_000)), 2.0);
        assert_eq!(s.volts(Nanos::new(9_000_000_000)), 3.0);
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
