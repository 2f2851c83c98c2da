//! The board's analog inputs: buslab's analog sources (`buslab-analog`: voltages as functions
//! of the board's time, written as `2.5V`, `sine:1Hz:2V:2.5V`, `ramp:0V:5V:4s`, `csv:FILE`),
//! read by the 80C196's and the PIC's 10-bit converters.

use std::ops::RangeInclusive;

pub use buslab_analog::{SPEC_HELP, Shape, Source, SourceError, SourceSpec};
use buslab_device::Nanos;

/// Full scale of both converters: 0..5 V.
pub const FULL_SCALE_V: f64 = 5.0;

/// The channels of each converter.
pub const CHANNELS: RangeInclusive<u8> = 0..=7;

/// The 10-bit conversion of `source` at `at`.
pub fn reading10(source: &Source, at: Nanos) -> u16 {
    volts_to_code10(source.volts(at))
}

/// round(V × 1023 / 5) clamped to 0..=1023 (0 for NaN).
pub fn volts_to_code10(v: f64) -> u16 {
    if v.is_nan() {
        return 0;
    }
    (v * 1023.0 / FULL_SCALE_V).round().clamp(0.0, 1023.0) as u16
}

/// Volts of a 10-bit code.
pub fn code10_to_volts(code: f64) -> f64 {
    code * FULL_SCALE_V / 1023.0
}

/// The analog inputs of the board: 8 on the 80C196, 8 on the PIC (PIC channel 0 = battery).
#[derive(Clone, Debug, PartialEq)]
pub struct Inputs {
    pub c196: [Source; 8],
    pub pic: [Source; 8],
}

impl Default for Inputs {
    fn default() -> Self {
        let mut c196: [Source; 8] = Default::default();
        c196[0] = Source::Wave {
            shape: Shape::Sine,
            hz: 1.0,
            amplitude: 2.0,
            offset: 2.5,
        };
        c196[1] = Source::Ramp {
            from: 0.0,
            to: 5.0,
            period: Nanos::from_secs(4),
        };
        c196[2] = Source::Constant(1.25);
        // 1 V and 4 V, 2 Hz.
        c196[3] = Source::Wave {
            shape: Shape::Square,
            hz: 2.0,
            amplitude: 1.5,
            offset: 2.5,
        };
        let mut pic: [Source; 8] = Default::default();
        // A healthy battery: above the default "ok" threshold.
        pic[0] = Source::Constant(3.5);
        Self { c196, pic }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ten_bit_codes_cover_zero_to_five_volts() {
        assert_eq!(volts_to_code10(5.0), 1023);
        assert_eq!(volts_to_code10(9.0), 1023);
        assert_eq!(volts_to_code10(-1.0), 0);
        assert_eq!(volts_to_code10(f64::NAN), 0);
        let ramp = Source::Ramp {
            from: 0.0,
            to: 5.0,
            period: Nanos::from_secs(1),
        };
        assert_eq!(reading10(&ramp, Nanos::from_millis(500)), 512);
    }

    #[test]
    fn the_default_square_swings_between_1_and_4_volts() {
        let square = &Inputs::default().c196[3];
        assert_eq!(square.volts(Nanos::from_millis(100)), 4.0);
        assert_eq!(square.volts(Nanos::from_millis(300)), 1.0);
    }
}
