//! The seed's SLIO demo board (§3.2): a P82C150 with switches, a potentiometer and LEDs.
//!
//! - P0..P3: the ID switches, multiplexed with four digital input switches. The multiplexer
//!   (an EPLD on the board) is driven by P13, "sélection des entrées": P13 low (as at reset,
//!   floating) shows the ID switches, so the SLIO latches its ID; P13 driven high shows the
//!   input switches (MoniCAN drives DATA_OUTPUT = 0x2000 for that).
//! - P5: analog input ADC1, selected by ANALOG_CONFIGURATION 0xE0 (multiplexer input 6).
//! - P6: the potentiometer, ADC2, selected by 0xC0 (multiplexer input 4).
//! - P7, P8, P9, P11, P12: LEDs (digital outputs).
//! - P10 and P4: the DPM1 and DPM2 quasi-analog outputs.
//! - OUTPUT_ENABLE for all of these: 0x3F90.
//!
//! Its inputs can be changed while it runs ([`DemoBoard::set_switches`],
//! [`DemoBoard::set_potentiometer`], the [`Signal`]s on the analog inputs) and its outputs
//! observed ([`DemoBoard::leds`], [`DemoBoard::dpm_volts`]).
//!
//! A host that drives the LEDs needs the levels of the outputs it does not change:
//! [`OutputLevels`] learns them from what the SLIO sends.

use std::any::Any;
use std::ops::Range;

use buslab_can::controller::{ErrorState, Event, FrameRole, FrameStart, QueueFull, WireFrame};
use buslab_can::node::BusNode;
use buslab_can::{BitTime, Frame, Level, Nanos};

use crate::ids::SlioId;
use crate::registers::Register;
use crate::slio::{AnalogInputs, Slio, SlioError, SlioNotice, frame_level};

/// The demo board's wiring, the LED pins (in MoniCAN's order) and the supply, and what a host
/// knows of its outputs: facts shared with the hosts that drive it (buslab-chips).
pub use buslab_chips::slio::board::{
    CONVERT_ADC1, CONVERT_ADC2, DIGITAL_OUTPUTS, LED_PINS, OUTPUT_ENABLE, OutputLevels, SELECT_PIN,
    SWITCH_PINS, VDD, set_bit,
};
/// The multiplexer inputs the board wires to P5 and P6.
const ADC1_INPUT: u8 = 6;
const ADC2_INPUT: u8 = 4;

/// A voltage that changes with time: a constant, a waveform, a recording.
pub trait Signal: Send {
    /// The level in volts at `t` since the board started.
    fn volts(&mut self, t: Nanos) -> f64;
}

/// A constant level.
impl Signal for f64 {
    fn volts(&mut self, _t: Nanos) -> f64 {
        *self
    }
}

impl<F: FnMut(Nanos) -> f64 + Send> Signal for F {
    fn volts(&mut self, t: Nanos) -> f64 {
        self(t)
    }
}

/// The two analog inputs of the board.
pub(crate) struct BoardAnalog {
    adc1: Box<dyn Signal>,
    potentiometer: Box<dyn Signal>,
}

impl AnalogInputs for BoardAnalog {
    fn code(&mut self, input: u8, t: Nanos) -> u16 {
        let volts = match input {
            ADC1_INPUT => self.adc1.volts(t),
            ADC2_INPUT => self.potentiometer.volts(t),
            _ => 0.0,
        };
        volts_to_code(volts)
    }
}

/// A level in volts as the 10-bit ADC reads it (0..5 V → 0..1023, clamped).
pub fn volts_to_code(volts: f64) -> u16 {
    if volts.is_nan() {
        return 0;
    }
    (volts / VDD * 1023.0).round().clamp(0.0, 1023.0) as u16
}

/// The board: its SLIO and the switches.
pub struct DemoBoard {
    slio: Slio,
    id_switches: u8,
    input_switches: u8,
    notices: Vec<(BitTime, SlioNotice)>,
    /// The frame applied whole goes through [`BusNode::sample`] bit by bit (the SLIO only
    /// listened at its SOF).
    frame_by_bits: bool,
}

impl core::fmt::Debug for DemoBoard {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("DemoBoard")
            .field("slio", &self.slio)
            .field("input_switches", &self.input_switches)
            .finish()
    }
}

impl DemoBoard {
    /// A board whose ID switches are set to `id`, on a bus at `bitrate`, with these signals on
    /// ADC1 (P5) and the potentiometer (P6).
    pub fn new(
        id: SlioId,
        bitrate: u32,
        adc1: Box<dyn Signal>,
        potentiometer: Box<dyn Signal>,
    ) -> Result<Self, SlioError> {
        let slio = Slio::new(id, bitrate)?.with_analog(Box::new(BoardAnalog {
            adc1,
            potentiometer,
        }));
        let mut board = Self {
            slio,
            id_switches: id.number(),
            input_switches: 0,
            notices: Vec::new(),
            frame_by_bits: false,
        };
        board.update_pins(BitTime::ZERO);
        Ok(board)
    }

    pub fn slio(&self) -> &Slio {
        &self.slio
    }

    pub fn id(&self) -> SlioId {
        self.slio.id()
    }

    /// The four input switches (bit 0 = the switch on P0), as set at bit-time `now`. While
    /// P13 selects them their pins change, and a calibrated SLIO reports the edges its edge
    /// registers ask for.
    pub fn set_switches(&mut self, now: BitTime, switches: u8) {
        self.input_switches = switches & 0xF;
        self.update_pins(now);
    }

    pub fn switches(&self) -> u8 {
        self.input_switches
    }

    /// Turns the potentiometer (P6, ADC2): from now on it gives `signal` (a level in volts,
    /// a waveform); the next conversion reads it.
    pub fn set_potentiometer(&mut self, signal: Box<dyn Signal>) {
        self.analog_mut().potentiometer = signal;
    }

    /// The potentiometer's level at bit-time `now` (what a conversion then would read,
    /// before the ADC's rounding).
    pub fn potentiometer_volts(&mut self, now: BitTime) -> f64 {
        let t = now.at_bitrate(self.slio.bitrate());
        self.analog_mut().potentiometer.volts(t)
    }

    /// The level on ADC1 (P5) at bit-time `now`.
    pub fn adc1_volts(&mut self, now: BitTime) -> f64 {
        let t = now.at_bitrate(self.slio.bitrate());
        self.analog_mut().adc1.volts(t)
    }

    fn analog_mut(&mut self) -> &mut BoardAnalog {
        (self.slio.analog_mut() as &mut dyn Any)
            .downcast_mut::<BoardAnalog>()
            .expect("a demo board's SLIO has the board's analog inputs")
    }

    /// What the SLIO did since the last call (calibration, bus-mode changes, registers).
    pub fn take_notices(&mut self) -> Vec<(BitTime, SlioNotice)> {
        std::mem::take(&mut self.notices)
    }

    /// The five LEDs (P7, P8, P9, P11, P12): lit while the SLIO drives them high.
    pub fn leds(&self) -> [bool; 5] {
        let driven = self.slio.driven();
        LED_PINS.map(|pin| driven & (1 << pin) != 0)
    }

    /// The mean voltage of DPM1 (P10) and DPM2 (P4), `None` while the pin floats.
    pub fn dpm_volts(&self) -> [Option<f64>; 2] {
        [Register::Dpm1, Register::Dpm2].map(|r| self.slio.dpm_fraction(r).map(|f| f * VDD))
    }

    /// What the board does after its SLIO saw the bus up to bit-time `now`: it keeps the
    /// SLIO's news and follows its outputs on the pins.
    fn after_slio(&mut self, now: BitTime) {
        let before = self.notices.len();
        // Bounded: a board nobody asks keeps the latest news only.
        if before > 4096 {
            self.notices.drain(..before - 1024);
        }
        let start = self.notices.len();
        self.notices.extend(self.slio.take_notices());
        let outputs_changed = self.notices[start..].iter().any(|(_, n)| {
            matches!(
                n,
                SlioNotice::Register {
                    register: Register::DataOutput | Register::OutputEnable,
                    ..
                } | SlioNotice::BusModeChange(_)
            )
        });
        if outputs_changed {
            self.update_pins(now);
        }
    }

    /// The levels on P0..P3 follow the multiplexer: the input switches while P13 is driven
    /// high, the ID switches otherwise.
    fn update_pins(&mut self, now: BitTime) {
        let select = self.slio.driven() & (1 << SELECT_PIN) != 0;
        let low = if select {
            self.input_switches
        } else {
            self.id_switches
        };
        self.slio.set_inputs(now, u16::from(low & 0xF));
    }
}

impl BusNode for DemoBoard {
    fn output(&self) -> Level {
        self.slio.output()
    }

    fn sample(&mut self, now: BitTime, bus: Level) {
        self.slio.sample(now, bus);
        self.after_slio(now);
    }

    fn frame_starts_at(&mut self, now: BitTime) {
        self.slio.frame_starts_at(now);
    }

    fn frame_start(&self) -> FrameStart<'_> {
        self.slio.frame_start()
    }

    fn advance_frame(&mut self, frame: &WireFrame, role: FrameRole, bits: Range<u32>) {
        if bits.is_empty() {
            return;
        }
        if bits.start == 0 {
            self.frame_by_bits = self.slio.listens();
        }
        let sof = self.slio.frame_sof();
        if self.frame_by_bits {
            for bit in bits {
                self.sample(sof + BitTime::from(bit), frame_level(frame, bit));
            }
            return;
        }
        let now = sof + BitTime::from(bits.end) - BitTime::ONE;
        self.slio.advance_frame(frame, role, bits);
        self.after_slio(now);
    }

    fn poll_event(&mut self) -> Option<Event> {
        self.slio.poll_event()
    }
    fn tec(&self) -> u16 {
        self.slio.tec()
    }
    fn rec(&self) -> u16 {
        self.slio.rec()
    }
    fn state(&self) -> ErrorState {
        self.slio.state()
    }
    fn quiet_until(&self) -> Option<BitTime> {
        self.slio.quiet_until()
    }
    fn enqueue(&mut self, frame: Frame) -> Result<(), QueueFull> {
        self.slio.enqueue(frame)
    }
    fn pending(&self) -> usize {
        self.slio.pending()
    }
    fn as_any(&self) -> &dyn Any {
        self
    }
    fn as_any_mut(&mut self) -> &mut dyn Any {
        self
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_potentiometer_turns_while_the_board_runs() {
        let id = SlioId::new(3).unwrap();
        let mut board = DemoBoard::new(id, 125_000, Box::new(1.25), Box::new(0.5)).unwrap();
        assert_eq!(board.potentiometer_volts(BitTime::ZERO), 0.5);
        board.set_potentiometer(Box::new(|t: Nanos| t.get() as f64 / 1e9));
        // 125000 bit-times: one second.
        assert_eq!(board.potentiometer_volts(BitTime::new(125_000)), 1.0);
        assert_eq!(board.adc1_volts(BitTime::new(125_000)), 1.25);
    }
}
