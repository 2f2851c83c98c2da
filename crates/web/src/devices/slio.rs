//! The SLIO boards' panels, sans-IO: what the bus shows of each demo board (its replies and
//! the requests other hosts send it), and the request frames a click makes.
//!
//! As on MoniCAN's screen, a value is shown only once the SLIO sent it: a click on an LED
//! sends a DATA_OUTPUT write and marks the LED *pending*; the LED changes when the SLIO's
//! reply (its register content) comes back on the bus.
//!
//! Every frame the panels send a SLIO has 3 bytes ([`Request::frame`], as the seed's
//! `make_slio_ffi` builds them), and only DATA_INPUT is read (a P82C150 has no read of its
//! writable registers): the outputs come from the SLIO's answers to writes, whoever made them,
//! or from the levels its output pins read back in DATA_INPUT ([`OutputLevels`]); the DPMs
//! and OUTPUT_ENABLE from the answers to writes.
//!
//! The board's own inputs (its switches and potentiometer, as a person at the bench sets
//! them) are the bench's, not the SLIO's: [`SlioPanels::bench`] keeps what the virtual bus
//! last said of them.

use buslab_bus::admin::BoardState;
use buslab_can::Frame;
use buslab_chips::slio::board::{
    CONVERT_ADC1, CONVERT_ADC2, LED_PINS, OutputLevels, SELECT_PIN, SWITCH_PINS, VDD, set_bit,
};
use buslab_chips::slio::registers::{
    CONVERT, MUX_MASK, MUX_SHIFT, Register, Reply, Request, Status, TEN_BITS,
};
use buslab_chips::slio::{Direction, SlioId};
use serde::Serialize;

/// Why a click cannot become a request.
#[derive(Debug, PartialEq, Eq, thiserror::Error)]
pub enum SlioRequestError {
    #[error("SLIO {0} is not one of this bench's boards")]
    UnknownBoard(SlioId),
    #[error("P{0} is not an LED of the demo board (its LEDs are P7, P8, P9, P11, P12)")]
    NotAnLed(u8),
    #[error(
        "SLIO {0} has not told its outputs yet (its pin levels are asked for): click again once it answered"
    )]
    OutputsUnknown(SlioId),
    #[error("DPM{0}: the demo board has DPM1 and DPM2")]
    NoDpm(u8),
    #[error("duty {0}: 0..1023 (/1024)")]
    Duty(u16),
    #[error("ADC{0}: the demo board converts ADC1 (P5) and ADC2 (P6, the potentiometer)")]
    NoAdc(u8),
}

/// One board as the bus shows it.
#[derive(Clone, Debug)]
struct Board {
    id: SlioId,
    /// Register contents the SLIO sent, by number.
    registers: [Option<u16>; 9],
    /// Its outputs as it last told them (DATA_OUTPUT answers, DATA_INPUT's levels).
    levels: OutputLevels,
    /// Its switches and potentiometer as the bench last said (the board, not the SLIO).
    bench: Option<BoardState>,
    /// The last ADC result of each input (ADC1, ADC2).
    adc: [Option<u16>; 2],
    /// The multiplexer input of the last conversion asked for (the ADC reply does not say).
    converting: Option<u16>,
    /// DATA_OUTPUT asked for and not yet confirmed.
    requested_outputs: Option<u16>,
    /// Frames the SLIO sent.
    replies: u64,
    /// Its last status nibble: bus mode, EW, reset detected.
    status: Option<Status>,
}

/// Every board of the bench.
#[derive(Clone, Debug, Default)]
pub struct SlioPanels {
    boards: Vec<Board>,
}

/// One LED in the JSON.
#[derive(Debug, Serialize, PartialEq)]
pub struct Led {
    pub pin: u8,
    /// What the SLIO confirmed; `None` before it told.
    pub on: Option<bool>,
    /// A change was asked for and the SLIO has not confirmed it yet.
    pub pending: bool,
}

/// One board in the JSON (`devices.slio` of `/api/devices` and the live updates).
#[derive(Debug, Serialize)]
pub struct BoardView {
    pub slio: String,
    pub command_id: String,
    pub reply_id: String,
    /// Whether it ever answered.
    pub heard: bool,
    pub replies: u64,
    pub leds: Vec<Led>,
    /// DATA_INPUT, and the four input switches (P0..P3) read from it while P13 selects them
    /// (otherwise P0..P3 show the ID switches).
    pub inputs: Option<u16>,
    pub switches: Option<[bool; 4]>,
    /// DATA_OUTPUT as the SLIO confirmed it, or its output pins' levels read back.
    pub outputs: Option<u16>,
    pub output_enable: Option<u16>,
    /// ADC1 and ADC2: the 10-bit code and volts.
    pub adc: [Option<Analog>; 2],
    /// DPM1 and DPM2: the duty (/1024) and the mean volts.
    pub dpm: [Option<Analog>; 2],
    pub status: Option<String>,
    /// The board's switches and potentiometer as the bench set them (what a person at the
    /// bench sees), once the bus was asked.
    pub bench: Option<BenchView>,
}

/// The board's inputs as the bench has them.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct BenchView {
    pub switches: [bool; 4],
    /// Volts, as the next conversion of ADC2 would read them.
    pub potentiometer: f64,
}

#[derive(Clone, Copy, Debug, Serialize, PartialEq)]
pub struct Analog {
    pub code: u16,
    pub volts: f64,
}

impl SlioPanels {
    pub fn new(ids: &[SlioId]) -> Self {
        Self {
            boards: ids
                .iter()
                .map(|&id| Board {
                    id,
                    registers: [None; 9],
                    levels: OutputLevels::default(),
                    bench: None,
                    adc: [None; 2],
                    converting: None,
                    requested_outputs: None,
                    replies: 0,
                    status: None,
                })
                .collect(),
        }
    }

    pub fn is_empty(&self) -> bool {
        self.boards.is_empty()
    }

    fn board_mut(&mut self, id: SlioId) -> Option<&mut Board> {
        self.boards.iter_mut().find(|b| b.id == id)
    }

    /// A frame seen on the bus (or sent by this server); returns whether a panel changed.
    pub fn frame(&mut self, frame: &Frame) -> bool {
        let Some((id, direction)) = SlioId::from_id(frame.id()) else {
            return false;
        };
        let Some(board) = self.board_mut(id) else {
            return false;
        };
        match direction {
            Direction::ToSlio => {
                // Another host's (MoniCAN's) conversion: the next ADC reply is its input.
                if let Ok(Request::Write {
                    register: Register::AnalogConfig,
                    value,
                }) = Request::parse(frame.is_remote(), frame.payload())
                    && value & CONVERT != 0
                {
                    board.converting = Some((value >> MUX_SHIFT) & MUX_MASK);
                }
                false
            }
            Direction::FromSlio => {
                if frame.is_remote() {
                    return false;
                }
                let Ok(reply) = Reply::parse(frame.payload()) else {
                    return false;
                };
                board.replies += 1;
                board.status = Some(reply.status);
                board.registers[reply.register.index()] = Some(reply.value);
                board.levels.reply(&reply);
                match reply.register {
                    Register::DataOutput => board.requested_outputs = None,
                    Register::Adc => {
                        let code = reply.value & TEN_BITS;
                        match board.converting {
                            Some(m) if m == (CONVERT_ADC1 >> MUX_SHIFT) & MUX_MASK => {
                                board.adc[0] = Some(code)
                            }
                            Some(m) if m == (CONVERT_ADC2 >> MUX_SHIFT) & MUX_MASK => {
                                board.adc[1] = Some(code)
                            }
                            _ => {}
                        }
                    }
                    _ => {}
                }
                true
            }
        }
    }

    /// The request that turns LED `pin` of board `id` on or off, based on the outputs the
    /// SLIO confirmed (or a change still on its way); the LED shows pending until confirmed.
    pub fn output_request(
        &mut self,
        id: SlioId,
        pin: u8,
        on: bool,
    ) -> Result<Frame, SlioRequestError> {
        if !LED_PINS.contains(&pin) {
            return Err(SlioRequestError::NotAnLed(pin));
        }
        let board = self
            .board_mut(id)
            .ok_or(SlioRequestError::UnknownBoard(id))?;
        let base = board
            .requested_outputs
            .or(board.levels.get())
            .ok_or(SlioRequestError::OutputsUnknown(id))?;
        let value = set_bit(base, pin, on);
        board.requested_outputs = Some(value);
        Ok(write(id, Register::DataOutput, value))
    }

    /// A DPM duty (output 1 or 2, 0..1023).
    pub fn dpm_request(
        &self,
        id: SlioId,
        output: u8,
        duty: u16,
    ) -> Result<Frame, SlioRequestError> {
        self.check(id)?;
        let register = match output {
            1 => Register::Dpm1,
            2 => Register::Dpm2,
            n => return Err(SlioRequestError::NoDpm(n)),
        };
        if duty > TEN_BITS {
            return Err(SlioRequestError::Duty(duty));
        }
        Ok(write(id, register, duty))
    }

    /// A conversion of ADC1 or ADC2; the result comes in the SLIO's ADC reply.
    pub fn convert_request(&mut self, id: SlioId, input: u8) -> Result<Frame, SlioRequestError> {
        let value = match input {
            1 => CONVERT_ADC1,
            2 => CONVERT_ADC2,
            n => return Err(SlioRequestError::NoAdc(n)),
        };
        let board = self
            .board_mut(id)
            .ok_or(SlioRequestError::UnknownBoard(id))?;
        board.converting = Some((value >> MUX_SHIFT) & MUX_MASK);
        Ok(write(id, Register::AnalogConfig, value))
    }

    /// Reads of DATA_INPUT (the pin levels: the switches, and the outputs read back) for the
    /// boards not heard yet (every board with `all`): what the server asks so that the panels
    /// fill without anyone clicking. The other registers have no read on a P82C150.
    pub fn read_requests(&self, all: bool) -> Vec<Frame> {
        self.boards
            .iter()
            .filter(|b| all || b.registers[Register::DataInput.index()].is_none())
            .map(|b| read_pins(b.id))
            .collect()
    }

    /// The read of one board's pins (DATA_INPUT), after a change on the bench.
    pub fn pins_request(&self, id: SlioId) -> Result<Frame, SlioRequestError> {
        self.check(id)?;
        Ok(read_pins(id))
    }

    /// What the bench said of a board's inputs (switches, potentiometer).
    pub fn bench(&mut self, state: BoardState) -> Result<(), SlioRequestError> {
        let board = self
            .board_mut(state.slio)
            .ok_or(SlioRequestError::UnknownBoard(state.slio))?;
        board.bench = Some(state);
        Ok(())
    }

    /// Whether a board is on this bench.
    pub fn has(&self, id: SlioId) -> bool {
        self.check(id).is_ok()
    }

    fn check(&self, id: SlioId) -> Result<(), SlioRequestError> {
        if self.boards.iter().any(|b| b.id == id) {
            Ok(())
        } else {
            Err(SlioRequestError::UnknownBoard(id))
        }
    }

    pub fn view(&self) -> Vec<BoardView> {
        self.boards.iter().map(Board::view).collect()
    }
}

/// The 3-byte frame of a write.
fn write(id: SlioId, register: Register, value: u16) -> Frame {
    Request::Write { register, value }
        .frame(id)
        .expect("a write always has its 3-byte frame")
}

/// `29C#000000`: a read of DATA_INPUT.
fn read_pins(id: SlioId) -> Frame {
    Request::Read {
        register: Register::DataInput,
    }
    .frame(id)
    .expect("DATA_INPUT is read-only: it has a read")
}

fn analog(code: u16, full: f64) -> Analog {
    Analog {
        code,
        volts: (f64::from(code) / full * VDD * 1000.0).round() / 1000.0,
    }
}

impl Board {
    fn view(&self) -> BoardView {
        let reg = |r: Register| self.registers[r.index()];
        let outputs = self.levels.get();
        let leds = LED_PINS
            .iter()
            .map(|&pin| {
                let on = outputs.map(|o| o & (1 << pin) != 0);
                let pending = self
                    .requested_outputs
                    .is_some_and(|r| Some(r & (1 << pin) != 0) != on);
                Led { pin, on, pending }
            })
            .collect();
        let inputs = reg(Register::DataInput);
        BoardView {
            slio: self.id.to_string(),
            command_id: format!("{:03X}", self.id.command_id().as_raw()),
            reply_id: format!("{:03X}", self.id.reply_id().as_raw()),
            heard: self.replies > 0,
            replies: self.replies,
            leds,
            inputs,
            switches: inputs
                .filter(|i| i & (1 << SELECT_PIN) != 0)
                .map(|i| std::array::from_fn(|k| i & SWITCH_PINS & (1 << k) != 0)),
            outputs,
            output_enable: reg(Register::OutputEnable),
            adc: self.adc.map(|c| c.map(|c| analog(c, 1023.0))),
            dpm: [reg(Register::Dpm1), reg(Register::Dpm2)].map(|d| d.map(|d| analog(d, 1024.0))),
            status: self.status.map(|s| {
                format!(
                    "bus mode {}, EW {}, RSTD {}",
                    s.bus_mode,
                    u8::from(s.ew),
                    u8::from(s.reset_detected)
                )
            }),
            bench: self.bench.as_ref().map(|b| BenchView {
                switches: std::array::from_fn(|k| b.switches & (1 << k) != 0),
                potentiometer: b.potentiometer,
            }),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn slio(n: u8) -> SlioId {
        SlioId::new(n).unwrap()
    }

    fn reply(id: SlioId, register: Register, value: u16) -> Frame {
        let r = Reply {
            status: Status::default(),
            register,
            value,
        };
        Frame::data(id.reply_id(), &r.encode()).unwrap()
    }

    #[test]
    fn an_led_changes_only_when_the_slio_confirms_it() {
        let s3 = slio(3);
        let mut p = SlioPanels::new(&[s3]);
        assert_eq!(
            p.output_request(s3, 7, true),
            Err(SlioRequestError::OutputsUnknown(s3))
        );
        assert!(p.frame(&reply(s3, Register::DataOutput, 0x2000)));
        let frame = p.output_request(s3, 7, true).unwrap();
        assert_eq!(frame.to_string(), "29C#032080");
        let led = |p: &SlioPanels| {
            let v = p.view();
            let l = v[0].leds.iter().find(|l| l.pin == 7).unwrap();
            (l.on, l.pending)
        };
        // Asked for, not confirmed: still off, pending.
        assert_eq!(led(&p), (Some(false), true));
        // Our own request seen on the bus changes nothing.
        assert!(!p.frame(&frame));
        assert_eq!(led(&p), (Some(false), true));
        p.frame(&reply(s3, Register::DataOutput, 0x2080));
        assert_eq!(led(&p), (Some(true), false));
        // A second click builds on the confirmed value.
        assert_eq!(
            p.output_request(s3, 8, true).unwrap().to_string(),
            "29C#032180"
        );
    }

    #[test]
    fn a_slio_that_refuses_keeps_its_led_and_the_pending_mark_ends() {
        let s0 = slio(0);
        let mut p = SlioPanels::new(&[s0]);
        p.frame(&reply(s0, Register::DataOutput, 0x2000));
        p.output_request(s0, 9, true).unwrap();
        // The SLIO answers with the old content (say another host wrote it meanwhile).
        p.frame(&reply(s0, Register::DataOutput, 0x2000));
        let v = p.view();
        let l = v[0].leds.iter().find(|l| l.pin == 9).unwrap();
        assert_eq!((l.on, l.pending), (Some(false), false));
    }

    #[test]
    fn conversions_are_told_apart_by_the_request_before_them() {
        let s10 = slio(10);
        let mut p = SlioPanels::new(&[s10]);
        // MoniCAN converts ADC2 (the potentiometer): its request is on the bus.
        let other = Frame::data(
            s10.command_id(),
            &[Register::AnalogConfig.number(), 0, 0xC0],
        )
        .unwrap();
        p.frame(&other);
        p.frame(&reply(s10, Register::Adc, 0x8000 | 512));
        let v = p.view();
        assert_eq!(v[0].adc[0], None);
        assert_eq!(v[0].adc[1].unwrap().code, 512);
        // Ours converts ADC1.
        let f = p.convert_request(s10, 1).unwrap();
        assert_eq!(f.payload(), &[5, 0, 0xE0]);
        p.frame(&reply(s10, Register::Adc, 1023));
        assert_eq!(p.view()[0].adc[0].unwrap().volts, 5.0);
    }

    #[test]
    fn bad_clicks_say_why() {
        let s0 = slio(0);
        let mut p = SlioPanels::new(&[s0]);
        assert_eq!(
            p.output_request(s0, 13, true),
            Err(SlioRequestError::NotAnLed(13))
        );
        assert_eq!(
            p.output_request(slio(5), 7, true),
            Err(SlioRequestError::UnknownBoard(slio(5)))
        );
        assert_eq!(p.dpm_request(s0, 3, 1), Err(SlioRequestError::NoDpm(3)));
        assert_eq!(
            p.dpm_request(s0, 1, 1024),
            Err(SlioRequestError::Duty(1024))
        );
        assert_eq!(p.convert_request(s0, 0), Err(SlioRequestError::NoAdc(0)));
        // Frames of boards not on the bench, and other frames, change nothing.
        assert!(!p.frame(&reply(slio(4), Register::DataInput, 1)));
        assert!(!p.frame(&"123#00".parse().unwrap()));
    }

    /// Issue 26: the panel asked for DATA_OUTPUT, OUTPUT_ENABLE, DPM1 and DPM2 with 1-byte
    /// frames, which a P82C150 (and the model) ignores. It reads DATA_INPUT only, with the
    /// seed's 3-byte frame, and only until the board answered it.
    #[test]
    fn reads_are_three_byte_reads_of_data_input_until_heard() {
        let s0 = slio(0);
        let s3 = slio(3);
        let mut p = SlioPanels::new(&[s0, s3]);
        let asked: Vec<String> = p
            .read_requests(false)
            .iter()
            .map(Frame::to_string)
            .collect();
        assert_eq!(asked, ["284#000000", "29C#000000"]);
        p.frame(&reply(s0, Register::DataInput, 0x000F));
        let asked: Vec<String> = p
            .read_requests(false)
            .iter()
            .map(Frame::to_string)
            .collect();
        assert_eq!(asked, ["29C#000000"]);
        assert_eq!(p.read_requests(true).len(), 2, "the read button asks again");
        for f in p.read_requests(true) {
            assert_eq!(f.payload().len(), 3, "{f}");
        }
        // P13 low: P0..P3 show the ID switches, not the input switches.
        assert_eq!(p.view()[0].switches, None);
        p.frame(&reply(s0, Register::DataInput, 0x2005));
        assert_eq!(p.view()[0].switches, Some([true, false, true, false]));
        assert_eq!(p.pins_request(s3).unwrap().to_string(), "29C#000000");
        assert_eq!(
            p.pins_request(slio(5)),
            Err(SlioRequestError::UnknownBoard(slio(5)))
        );
    }

    /// The outputs a board never confirmed to this server come from the levels its pins read
    /// back (another host, MoniCAN, lit P7 and P11): a click keeps them.
    #[test]
    fn an_led_click_keeps_the_outputs_the_pins_read_back() {
        let s3 = slio(3);
        let mut p = SlioPanels::new(&[s3]);
        p.frame(&reply(s3, Register::DataInput, 0x2885));
        let v = p.view();
        assert_eq!(v[0].outputs, Some(0x2880));
        let lit: Vec<u8> = v[0]
            .leds
            .iter()
            .filter(|l| l.on == Some(true))
            .map(|l| l.pin)
            .collect();
        assert_eq!(lit, [7, 11]);
        assert_eq!(
            p.output_request(s3, 8, true).unwrap().to_string(),
            "29C#032980"
        );
    }

    #[test]
    fn the_bench_says_what_the_board_has() {
        let s3 = slio(3);
        let mut p = SlioPanels::new(&[s3]);
        assert_eq!(p.view()[0].bench, None);
        let state = BoardState {
            slio: s3,
            node: buslab_bus::NodeInfo {
                number: 6,
                name: "slio3".into(),
            },
            switches: 0b0100,
            potentiometer: 2.5,
            adc1: 1.25,
            leds: 0,
            dpm: [None, None],
        };
        p.bench(state.clone()).unwrap();
        assert_eq!(
            p.view()[0].bench,
            Some(BenchView {
                switches: [false, false, true, false],
                potentiometer: 2.5
            })
        );
        let other = BoardState {
            slio: slio(4),
            ..state
        };
        assert_eq!(p.bench(other), Err(SlioRequestError::UnknownBoard(slio(4))));
    }
}
