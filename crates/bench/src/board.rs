//! The SLIO demo boards of a bench: a P82C150 on the seed's board, its ADC1 input (P5) and
//! potentiometer (P6) driven by analog sources in the ZELLE's grammar, on the virtual bus as a
//! [`Device`] ([`BoardDevice`]): the bus changes its inputs and reads it through [`Board`],
//! and hears its calibration and bus-mode changes as typed notices.

use buslab_analog::{Source, SourceSpec};
use buslab_can::node::BusNode;
use buslab_can::{BitTime, Nanos};
use buslab_canbus::NodeInfo;
use buslab_canbus::admin::{BoardInput, BoardState};
use buslab_sim::Node;
use buslab_slio::board::{LED_PINS, VDD};
use buslab_slio::{DemoBoard, SlioError, SlioId, SlioNotice};
use buslab_vbus::{Board, Device, DeviceNode, DeviceNotice};

/// The lab's potentiometer: a 0..5 V sine, 10 s a turn (`bus serve --slio-pot`'s default).
pub const POTENTIOMETER: &str = "sine:100mHz:2.5V:2.5V";
/// The lab's ADC1 input (`bus serve --slio-adc1`'s default).
pub const ADC1: &str = "1.25V";

/// The name a demo board has on the bus: `slio` and its number (`slioA`).
pub fn name(id: SlioId) -> String {
    format!("slio{id}")
}

/// A demo board with these sources on ADC1 and the potentiometer, ready for the bus.
pub fn demo_board(
    id: SlioId,
    bitrate: u32,
    adc1: Source,
    potentiometer: Source,
) -> Result<DeviceNode, SlioError> {
    let board = DemoBoard::new(
        id,
        bitrate,
        Box::new(move |t: Nanos| adc1.volts(t)),
        Box::new(move |t: Nanos| potentiometer.volts(t)),
    )?;
    Ok(on_bus(board))
}

/// A demo board as the lab puts it on the bus: ADC1 reads [`ADC1`], the potentiometer turns
/// slowly ([`POTENTIOMETER`]).
pub fn lab_board(id: SlioId, bitrate: u32) -> Result<DeviceNode, SlioError> {
    demo_board(id, bitrate, built_in(ADC1), built_in(POTENTIOMETER))
}

/// `board` as a node of the bus: the virtual bus reaches its inputs and hears its notices.
pub fn on_bus(board: DemoBoard) -> DeviceNode {
    DeviceNode::new(BoardDevice(board))
}

/// The demo board a node of the engine is, put there bare or by [`on_bus`].
pub fn of(node: &mut Node) -> Option<&mut DemoBoard> {
    if node.get::<DeviceNode>().is_some() {
        return node.get_mut::<DeviceNode>()?.get_mut();
    }
    node.get_mut()
}

/// A demo board as a device of the virtual bus.
pub struct BoardDevice(pub DemoBoard);

impl Device for BoardDevice {
    fn node(&self) -> &dyn BusNode {
        &self.0
    }

    fn node_mut(&mut self) -> &mut dyn BusNode {
        &mut self.0
    }

    /// Calibration and bus-mode changes; register values are the board's own business (a
    /// conversion changes one every few milliseconds).
    fn take_notices(&mut self) -> Vec<(BitTime, DeviceNotice)> {
        self.0
            .take_notices()
            .into_iter()
            .filter(|(_, n)| !matches!(n, SlioNotice::Register { .. }))
            .map(|(time, n)| (time, DeviceNotice::Slio(n)))
            .collect()
    }

    fn board(&mut self) -> Option<&mut dyn Board> {
        Some(self)
    }
}

impl Board for BoardDevice {
    fn slio(&self) -> SlioId {
        self.0.id()
    }

    fn change(&mut self, now: BitTime, input: BoardInput) {
        let board = &mut self.0;
        match input {
            BoardInput::Switch { switch, on } => {
                let bit = 1 << switch.number();
                let switches = if on {
                    board.switches() | bit
                } else {
                    board.switches() & !bit
                };
                board.set_switches(now, switches);
            }
            BoardInput::Switches(bits) => board.set_switches(now, bits),
            BoardInput::Potentiometer(volts) => board.set_potentiometer(Box::new(volts.get())),
        }
    }

    fn state(&mut self, now: BitTime, node: NodeInfo) -> BoardState {
        let board = &mut self.0;
        // As the ADC reads them (it clamps to its supply).
        let level = |v: f64| if v.is_nan() { 0.0 } else { v.clamp(0.0, VDD) };
        BoardState {
            slio: board.id(),
            node,
            switches: board.switches(),
            potentiometer: level(board.potentiometer_volts(now)),
            adc1: level(board.adc1_volts(now)),
            leds: LED_PINS
                .iter()
                .zip(board.leds())
                .filter(|(_, lit)| *lit)
                .fold(0, |mask, (pin, _)| mask | 1 << pin),
            dpm: board.dpm_volts(),
        }
    }
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
        assert_eq!(built_in(ADC1).volts(buslab_can::Nanos::ZERO), 1.25);
        // A sine around 2.5 V of 2.5 V: 2.5 V at 0, 5 V a quarter turn (2.5 s) later.
        let pot = built_in(POTENTIOMETER);
        assert!((pot.volts(buslab_can::Nanos::ZERO) - 2.5).abs() < 1e-9);
        assert!((pot.volts(buslab_can::Nanos::from_millis(2_500)) - 5.0).abs() < 1e-9);
    }
}
