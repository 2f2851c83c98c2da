//! The one spelling of a source, as every tool takes it on its command line, in its control
//! lines and in its configuration.

use std::ops::RangeInclusive;
use std::path::PathBuf;

use buslab_can::Nanos;

use crate::error::SourceError;
use crate::source::{Shape, Source};
use crate::units::{finite, parse_hz, parse_period, parse_volts};

/// A parsed source spec. A CSV replay names a file, which the caller reads (this crate does
/// no I/O) and hands to [`Source::replay_from_csv`].
#[derive(Clone, Debug, PartialEq)]
pub enum SourceSpec {
    Ready(Source),
    CsvFile(PathBuf),
}

/// The spec grammar, for error messages and help texts.
pub const SPEC_HELP: &str = "VOLTS | const:VOLTS | sine|triangle|square:FREQ[:AMPLITUDE[:OFFSET]] \
     | ramp:FROM:TO:PERIOD | csv:FILE  (e.g. 2.5V, sine:1Hz:2V:2.5V, ramp:0V:5V:10s)";

/// `CH=SOURCE` (`1=sine:1Hz:2V:2.5V`), as devices' `--analog`/`--input` options and control
/// lines take it: a channel within `channels` (decimal) and a source spec.
pub fn parse_channel_source(
    arg: &str,
    channels: RangeInclusive<u8>,
) -> Result<(u8, SourceSpec), SourceError> {
    let (ch, spec) = arg.split_once('=').ok_or_else(|| SourceError::Spec {
        spec: arg.to_owned(),
        why: "must look like CH=SOURCE, e.g. 1=sine:1Hz".into(),
    })?;
    let ch = ch.trim();
    // Digits only: `parse` would take a sign.
    let number = if ch.bytes().all(|b| b.is_ascii_digit()) {
        ch.parse::<u8>().ok()
    } else {
        None
    };
    match number {
        Some(channel) if channels.contains(&channel) => Ok((channel, SourceSpec::parse(spec)?)),
        _ => Err(SourceError::Channel {
            arg: arg.to_owned(),
            channel: ch.to_owned(),
            first: *channels.start(),
            last: *channels.end(),
        }),
    }
}

impl SourceSpec {
    /// Parses `VOLTS`, `const:VOLTS`, `sine:FREQ[:AMPLITUDE[:OFFSET]]` (also `triangle`,
    /// `square`; amplitude and offset default to 2.5 V, i.e. 0..5 V), `ramp:FROM:TO:PERIOD`
    /// or `csv:FILE`. Volts may carry `V` or `mV`, frequencies `Hz`, `kHz` or `mHz`, periods
    /// `s` or `ms`. The CPU196 tools' former comma spelling (`sine:OFFSET,AMPLITUDE,HZ`, ...)
    /// is refused with its translation.
    pub fn parse(spec: &str) -> Result<SourceSpec, SourceError> {
        let bad = |why: String| SourceError::Spec {
            spec: spec.to_owned(),
            why,
        };
        let spec_t = spec.trim();
        let (kind, rest) = spec_t.split_once(':').unwrap_or((spec_t, ""));
        let kind_lower = kind.to_ascii_lowercase();
        if kind_lower != "csv" && rest.contains(',') {
            return Err(bad(comma_spelling_hint(&kind_lower, rest)));
        }
        let args: Vec<&str> = if rest.is_empty() {
            Vec::new()
        } else {
            rest.split(':').map(str::trim).collect()
        };
        let volts = |s: &str| parse_volts(s).map_err(|_| bad(format!("`{s}` is not a voltage")));
        let ready = |s| Ok(SourceSpec::Ready(s));
        match kind_lower.as_str() {
            "csv" if !rest.is_empty() => Ok(SourceSpec::CsvFile(PathBuf::from(rest))),
            "csv" => Err(bad("csv needs a file: csv:FILE".into())),
            "const" | "dc" => match args[..] {
                [v] => ready(Source::Constant(volts(v)?)),
                _ => Err(bad("const takes one voltage: const:2.5V".into())),
            },
            "sine" | "triangle" | "square" => {
                let shape = match kind_lower.as_str() {
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
                    let period = parse_period(period)
                        .map_err(|_| bad(format!("`{period}` is not a period like 10s")))?;
                    if period == Nanos::ZERO {
                        return Err(bad("the ramp period must be longer than 0".into()));
                    }
                    ready(Source::Ramp {
                        from: volts(from)?,
                        to: volts(to)?,
                        period,
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

/// What to write instead of the CPU196 tools' former spelling (numbers separated by commas,
/// parameters in another order), or the grammar when the numbers do not fit it.
fn comma_spelling_hint(kind: &str, rest: &str) -> String {
    let numbers: Option<Vec<f64>> = rest.split(',').map(|n| finite(n).ok()).collect();
    let written = match (kind, numbers.as_deref()) {
        ("sine", Some(&[offset, amplitude, hz])) => {
            Some(format!("sine:{hz}Hz:{amplitude}V:{offset}V"))
        }
        ("square", Some(&[low, high, hz])) => Some(format!(
            "square:{hz}Hz:{}V:{}V",
            (high - low) / 2.0,
            (high + low) / 2.0
        )),
        ("ramp", Some(&[from, to, period])) if period > 0.0 => {
            Some(format!("ramp:{from}V:{to}V:{period}s"))
        }
        _ => None,
    };
    match written {
        Some(new) => format!(
            "parameters are separated by `:` in FREQ:AMPLITUDE:OFFSET order now (the CPU196 tools' \
             former comma spelling); write {new}"
        ),
        None => format!("parameters are separated by `:`; expected {SPEC_HELP}"),
    }
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
    fn constants_in_several_spellings() {
        assert_eq!(ready("2.5V"), Source::Constant(2.5));
        assert_eq!(ready("1200mV"), Source::Constant(1.2));
        assert_eq!(ready("const:3"), Source::Constant(3.0));
        assert_eq!(ready("DC:4v"), Source::Constant(4.0));
        assert_eq!(
            ready("sine:2kHz"),
            Source::Wave {
                shape: Shape::Sine,
                hz: 2000.0,
                amplitude: 2.5,
                offset: 2.5
            }
        );
        assert_eq!(
            ready("ramp:0:5:250ms"),
            Source::Ramp {
                from: 0.0,
                to: 5.0,
                period: Nanos::from_millis(250)
            }
        );
    }

    #[test]
    fn channel_source_arguments_name_the_bad_part() {
        assert_eq!(
            parse_channel_source("2=3.3V", 1..=4).unwrap(),
            (2, SourceSpec::Ready(Source::Constant(3.3)))
        );
        assert_eq!(
            parse_channel_source(" 7 =1V", 0..=7).unwrap(),
            (7, SourceSpec::Ready(Source::Constant(1.0)))
        );
        for (arg, channels, needle) in [
            ("9=1V", 1..=4, "channel `9` is out of range 1..4"),
            ("0=1V", 1..=4, "channel `0` is out of range 1..4"),
            ("8=1V", 0..=7, "channel `8` is out of range 0..7"),
            ("x=1V", 1..=4, "channel `x` is out of range 1..4"),
            ("300=1V", 0..=7, "channel `300` is out of range 0..7"),
            ("+1=1V", 0..=7, "channel `+1` is out of range 0..7"),
            ("1V", 1..=4, "must look like CH=SOURCE"),
            ("1=wobble", 1..=4, "analog source `wobble`"),
        ] {
            let err = parse_channel_source(arg, channels).unwrap_err().to_string();
            assert!(err.contains(needle), "{arg}: {err}");
        }
    }

    #[test]
    fn csv_spec_names_a_file() {
        assert_eq!(
            SourceSpec::parse("csv:data/in,1.csv").unwrap(),
            SourceSpec::CsvFile("data/in,1.csv".into())
        );
    }

    #[test]
    fn the_former_cpu196_spelling_is_refused_with_its_translation() {
        for (old, new) in [
            ("sine:2.5,2,2", "write sine:2Hz:2V:2.5V"),
            ("square:1,4,2", "write square:2Hz:1.5V:2.5V"),
            ("ramp:0,5,4", "write ramp:0V:5V:4s"),
        ] {
            let err = SourceSpec::parse(old).unwrap_err().to_string();
            assert!(err.contains(new), "{old}: {err}");
            assert!(err.contains(old), "{old}: {err}");
            // The translation means what the old spelling meant.
            let translated = new.strip_prefix("write ").unwrap();
            assert!(SourceSpec::parse(translated).is_ok(), "{translated}");
        }
        let err = SourceSpec::parse("sine:1,x").unwrap_err().to_string();
        assert!(err.contains("separated by `:`"), "{err}");
    }

    #[test]
    fn the_translated_cpu196_spelling_gives_the_same_voltages() {
        // square:LOW,HIGH,HZ was HIGH in the first half period, LOW in the second.
        let square = ready("square:2Hz:1.5V:2.5V");
        assert_eq!(square.volts(Nanos::from_millis(100)), 4.0);
        assert_eq!(square.volts(Nanos::from_millis(300)), 1.0);
    }

    #[test]
    fn garbage_specs_are_refused_with_the_spec_named() {
        for spec in [
            "",
            "sine",
            "sine:fast",
            "sine:-1Hz",
            "sine:1Hz:2V:2.5V:9",
            "ramp:0:5",
            "ramp:0:5:0s",
            "ramp:0:5:1e300s",
            "noise:1",
            "csv:",
            "const:",
            "const:NaN",
            "NaN",
            "inf",
            "\u{0}\u{ff}",
        ] {
            let err = SourceSpec::parse(spec).unwrap_err();
            assert!(err.to_string().contains(spec), "{err}");
        }
    }
}
