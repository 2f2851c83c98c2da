//! The SLIO boards' panels, sans-IO: what the bus shows of each demo board (its replies and
//! the requests other hosts send it), and the request frames a click makes.
//!
//! As on MoniCAN's screen, a value is shown only once the SLIO sent it: a click on an LED
//! sends a DATA_OUTPUT write and marks the LED *pending*; the LED changes when the SLIO's
//! reply (its register content) comes back on the bus.

use buslab_can::Frame;
use buslab_slio::board::{CONVERT_ADC1, CONVERT_ADC2, LED_PINS, VDD};
use buslab_slio::registers::{CONVERT, MUX_MASK, MUX_SHIFT, TEN_BITS};
use buslab_slio::{Direction, Register, Reply, Request, SlioId};
use serde::Serialize;

/// The registers the server asks each board for until it has heard them.
pub const WATCHED: [Register; 5] = [
    Register::DataInput,
    Register::DataOutput,
    Register::OutputEnable,
    Register::Dpm1,
    Register::Dpm2,
];

/// Why a click cannot become a request.
#[derive(Debug, PartialEq, Eq, thiserror::Error)]
pub enum SlioRequestError {
    #[error("SLIO {0} is not one of this bench's boards")]
    UnknownBoard(SlioId),
    #[error("P{0} is not an LED of the demo board (its LEDs are P7, P8, P9, P11, P12)")]
    NotAnLed(u8),
    #[error("SLIO {0} has not told its DATA_OUTPUT yet: wait for its answer and click again")]
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
    /// The last ADC result of each input (ADC1, ADC2).
    adc: [Option<u16>; 2],
    /// The multiplexer input of the last conversion asked for (the ADC reply does not say).
    converting: Option<u16>,
    /// DATA_OUTPUT asked for and not yet confirmed.
    requested_outputs: Option<u16>,
    /// Frames the SLIO sent.
    replies: u64,
    /// Its last status nibble: bus mode, EW, reset detected.
    status: Option<buslab_slio::Status>,
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
    /// DATA_INPUT, and the four input switches (P0..P3) read from it.
    pub inputs: Option<u16>,
    pub switches: Option<[bool; 4]>,
    pub outputs: Option<u16>,
    pub output_enable: Option<u16>,
    /// ADC1 and ADC2: the 10-bit code and volts.
    pub adc: [Option<Analog>; 2],
    /// DPM1 and DPM2: the duty (/1024) and the mean volts.
    pub dpm: [Option<Analog>; 2],
    pub status: Option<String>,
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
            .or(board.registers[Register::DataOutput.index()])
            .ok_or(SlioRequestError::OutputsUnknown(id))?;
        let value = if on {
            base | 1 << pin
        } else {
            base & !(1 << pin)
        };
        board.requested_outputs = Some(value);
        Ok(request(
            id,
            Request::Write {
                register: Register::DataOutput,
                value,
            },
        ))
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
        Ok(request(
            id,
            Request::Write {
                register,
                value: duty,
            },
        ))
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
        Ok(request(
            id,
            Request::Write {
                register: Register::AnalogConfig,
                value,
            },
        ))
    }

    /// Reads of the watched registers not heard yet, for every board (all of them with
    /// `all`): what the server asks for so that the panels fill without anyone clicking.
    pub fn read_requests(&self, all: bool) -> Vec<Frame> {
        let mut frames = Vec::new();
        for board in &self.boards {
            for register in WATCHED {
                if all || board.registers[register.index()].is_none() {
                    frames.push(request(board.id, Request::Read { register }));
                }
            }
        }
        frames
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

fn request(id: SlioId, request: Request) -> Frame {
    Frame::data(id.command_id(), &request.encode()).expect("1 or 3 bytes")
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
        let outputs = reg(Register::DataOutput);
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
            switches: inputs.map(|i| std::array::from_fn(|k| i & (1 << k) != 0)),
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
            status: buslab_slio::Status::default(),
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

    #[test]
    fn reads_ask_for_what_is_not_known() {
        let s0 = slio(0);
        let mut p = SlioPanels::new(&[s0]);
        assert_eq!(p.read_requests(false).len(), WATCHED.len());
        p.frame(&reply(s0, Register::DataInput, 0x000F));
        let asked = p.read_requests(false);
        assert_eq!(asked.len(), WATCHED.len() - 1);
        assert!(asked.iter().all(|f| f.payload() != [0]));
        assert_eq!(p.view()[0].switches, Some([true; 4]));
    }
}
