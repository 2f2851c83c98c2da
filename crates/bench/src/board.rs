//! The SLIO demo boards of a bench: a P82C150 on the seed's board, its ADC1 input (P5) and
//! potentiometer (P6) driven by analog sources in the ZELLE's grammar.

use buslab_slio::{DemoBoard, SlioError, SlioId};
use buslab_zelle::analog::{Source, SourceSpec};

/// The lab's potentiometer: a 0..5 V sine, 10 s a turn (`bus serve --slio-pot`'s default).
pub const POTENTIOMETER: &str = "sine:100mHz:2.5V:2.5V";
/// The lab's ADC1 input (`bus serve --slio-adc1`'s default).
pub const ADC1: &str = "1.25V";

/// The name a demo board has on the bus: `slio` and its number (`slioA`).
pub fn name(id: SlioId) -> String {
    format!("slio{id}")
}

/// A demo board with these sources on ADC1 and the potentiometer.
pub fn demo_board(
    id: SlioId,
    bitrate: u32,
    adc1: Source,
    potentiometer: Source,
) -> Result<DemoBoard, SlioError> {
    DemoBoard::new(
        id,
        bitrate,
        Box::new(move |t| adc1.volts(t)),
        Box::new(move |t| potentiometer.volts(t)),
    )
}

/// A demo board as the lab puts it on the bus: ADC1 reads [`ADC1`], the potentiometer turns
/// slowly ([`POTENTIOMETER`]).
pub fn lab_board(id: SlioId, bitrate: u32) -> Result<DemoBoard, SlioError> {
    demo_board(id, bitrate, built_in(ADC1), built_in(POTENTIOMETER))
}

/// A source of this module's own (no file to read).
fn built_in(spec: &str) -> Source {
    match SourceSpec::parse(spec) {
        Ok(SourceSpec::Ready(source)) => source,
        other => unreachable!("built-in source {spec:?}: {other:?}"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_built_in_sources_are_what_the_lab_says() {
        assert_eq!(built_in(ADC1).volts(0), 1.25);
        // A sine around 2.5 V of 2.5 V: 2.5 V at 0, 5 V a quarter turn (2.5 s) later.
        let pot = built_in(POTENTIOMETER);
        assert!((pot.volts(0) - 2.5).abs() < 1e-9);
        assert!((pot.volts(2_500_000_000) - 5.0).abs() < 1e-9);
    }
}
