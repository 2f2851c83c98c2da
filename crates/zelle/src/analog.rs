//! What feeds the cell's four A/D inputs: buslab's analog sources (`buslab-analog`: voltages
//! as functions of the cell's time, written as `2.5V`, `sine:1Hz:2V:2.5V`, `ramp:0V:5V:10s`,
//! `csv:input.csv`), read by the cell's 8-bit converter.
//!
//! The converter is 8-bit over 0..5 V: a reading is `round(volts / 5 * 255)`, clamped to
//! 0..255.

use std::ops::RangeInclusive;

pub use buslab_analog::{SPEC_HELP, Shape, Source, SourceError, SourceSpec};
use buslab_device::Nanos;

/// Full scale of the A/D converter.
pub const FULL_SCALE_VOLTS: f64 = 5.0;

/// The cell's analog inputs, as the seed numbers them.
pub const CHANNELS: RangeInclusive<u8> = 1..=4;

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

/// The converter's reading of `source` at `at`.
pub fn reading(source: &Source, at: Nanos) -> u8 {
    to_code(source.volts(at))
}

/// `CH=SOURCE` (`1=sine:1Hz:2V:2.5V`), as `serve --analog` takes it: the channel (1..4) and
/// the source spec.
pub fn parse_channel_source(arg: &str) -> Result<(u8, SourceSpec), SourceError> {
    buslab_analog::parse_channel_source(arg, CHANNELS)
}

#[cfg(test)]
mod tests {
    use super::*;

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
    fn a_sine_reads_as_its_8_bit_codes() {
        let SourceSpec::Ready(s) = SourceSpec::parse("sine:1Hz:2V:2.5V").unwrap() else {
            panic!("a sine is ready");
        };
        let at = Nanos::from_millis;
        assert_eq!(reading(&s, at(0)), to_code(2.5));
        assert_eq!(reading(&s, at(250)), to_code(4.5)); // peak a quarter period in
        assert_eq!(reading(&s, at(750)), to_code(0.5));
    }

    #[test]
    fn channels_are_the_cells_four() {
        assert_eq!(
            parse_channel_source("4=3.3V").unwrap(),
            (4, SourceSpec::Ready(Source::Constant(3.3)))
        );
        for arg in ["0=1V", "5=1V"] {
            let err = parse_channel_source(arg).unwrap_err().to_string();
            assert!(err.contains("out of range 1..4"), "{arg}: {err}");
        }
    }
}
