//! The A/D converter on port 1 as a program drives it: a serial 4-channel 8-bit converter in
//! the manner of the ADC0834, on P1.0..P1.3 (the seed: "Bits 0...3 gehören zum A/D-Wandler").
//!
//! ```text
//! P1.0  /CS   chip select, low active (the LED hangs on it: lit while a conversion selects)
//! P1.1  CLK   clock from the 8051
//! P1.2  DI    multiplexer address from the 8051, taken on rising CLK edges
//! P1.3  DO    data to the 8051 (leave its latch at 1 to read it), changes on falling edges
//! ```
//!
//! With /CS low, DI is taken on each rising CLK edge: a start bit 1 (0s before it are
//! ignored), then SGL/DIF, ODD/SIGN and SELECT. Single-ended (SGL 1) the channel is
//! 1 + ODD + 2·SELECT; differential (SGL 0) the pair SELECT (channels 1,2 or 3,4), ODD giving
//! which one is the + input. The falling edge after SELECT samples the input and DO gives a
//! leading 0; each further falling edge the next bit of the reading, most significant first
//! (8 bits), then bits 1..7 again least significant first; then DO is released (high).
//! /CS high ends the exchange at any point and releases DO.
//!
//! The OS's own readings (commands 4 and 7, series) use the same inputs and scale but are done
//! by the model directly: they leave P1.0..3 high, as the seed says.

use buslab_device::Nanos;

use crate::analog::{Source, to_code};

/// Port 1 bits of the converter's lines.
pub(crate) mod line {
    pub const CS: u8 = 0x01;
    pub const CLK: u8 = 0x02;
    pub const DI: u8 = 0x04;
    pub const DO: u8 = 0x08;
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum State {
    /// Not selected, or selected and waiting for the start bit.
    Idle,
    /// Taking the three address bits: `got` of them so far.
    Address { bits: u8, got: u8 },
    /// Address complete: the next falling edge samples.
    Settling { bits: u8 },
    /// Giving bit `next` of the output sequence (0 = leading zero) on each falling edge.
    Output { value: u8, next: u8 },
}

/// The converter's state between two port writes.
#[derive(Clone, Debug)]
pub(crate) struct Converter {
    /// The levels of /CS, CLK and DI last seen.
    lines: u8,
    state: State,
    /// DO's level (true: released or a 1).
    data_out: bool,
}

impl Default for Converter {
    fn default() -> Self {
        Converter {
            lines: line::CS | line::CLK | line::DI,
            state: State::Idle,
            data_out: true,
        }
    }
}

impl Converter {
    /// DO's level now.
    pub fn data_out(&self) -> bool {
        self.data_out
    }

    /// Port 1's pins became `pins` at `at_ns` (a program's write); `inputs` feed the channels.
    /// Returns DO's new level if it changed.
    pub fn pins_changed(&mut self, pins: u8, at_ns: Nanos, inputs: &[Source; 4]) -> Option<bool> {
        let before = self.data_out;
        let was = self.lines;
        self.lines = pins & (line::CS | line::CLK | line::DI);
        if pins & line::CS != 0 {
            self.state = State::Idle;
            self.data_out = true;
        } else if was & line::CS != 0 {
            // Just selected: a new exchange.
            self.state = State::Idle;
            self.data_out = true;
        } else {
            let rose = was & line::CLK == 0 && pins & line::CLK != 0;
            let fell = was & line::CLK != 0 && pins & line::CLK == 0;
            let di = pins & line::DI != 0;
            if rose {
                self.rising(di);
            } else if fell {
                self.falling(at_ns, inputs);
            }
        }
        (self.data_out != before).then_some(self.data_out)
    }

    fn rising(&mut self, di: bool) {
        self.state = match self.state {
            State::Idle if di => State::Address { bits: 0, got: 0 },
            State::Address { bits, got } => {
                let bits = bits << 1 | u8::from(di);
                if got + 1 == 3 {
                    State::Settling { bits }
                } else {
                    State::Address { bits, got: got + 1 }
                }
            }
            other => other,
        };
    }

    fn falling(&mut self, at_ns: Nanos, inputs: &[Source; 4]) {
        match self.state {
            State::Settling { bits } => {
                let value = sample(bits, at_ns, inputs);
                self.data_out = false;
                self.state = State::Output { value, next: 1 };
            }
            State::Output { value, next } => {
                // 1..=8: bits 7..0; 9..=15: bits 1..7; then released.
                self.data_out = match next {
                    1..=8 => value >> (8 - next) & 1 != 0,
                    9..=15 => value >> (next - 8) & 1 != 0,
                    _ => true,
                };
                self.state = if next > 15 {
                    State::Idle
                } else {
                    State::Output {
                        value,
                        next: next + 1,
                    }
                };
            }
            _ => {}
        }
    }
}

/// The reading for address `bits` (SGL/DIF, ODD/SIGN, SELECT) at `at_ns`.
fn sample(bits: u8, at_ns: Nanos, inputs: &[Source; 4]) -> u8 {
    let single = bits & 0b100 != 0;
    let odd = usize::from(bits & 0b010 != 0);
    let select = usize::from(bits & 0b001 != 0);
    if single {
        crate::analog::reading(&inputs[odd + 2 * select], at_ns)
    } else {
        let plus = inputs[2 * select + odd].volts(at_ns);
        let minus = inputs[2 * select + (1 - odd)].volts(at_ns);
        to_code(plus - minus)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Clocks a whole exchange for `channel` (1..4, single-ended) and reads DO as a program
    /// would after each falling edge: the leading zero, 8 bits MSB first, 7 bits LSB first.
    fn exchange(c: &mut Converter, inputs: &[Source; 4], address: [bool; 4]) -> Vec<bool> {
        let mut t = Nanos::ZERO;
        let mut pins = line::CS | line::CLK | line::DI | line::DO;
        let mut set = |c: &mut Converter, p: u8| {
            pins = p;
            t += Nanos::new(1000);
            c.pins_changed(pins, t, inputs);
        };
        set(c, line::DI | line::DO); // select, CLK low
        for bit in address {
            let di = if bit { line::DI } else { 0 };
            set(c, di | line::DO);
            set(c, di | line::CLK | line::DO);
        }
        let mut out = Vec::new();
        for _ in 0..16 {
            set(c, line::DO); // CLK falls
            out.push(c.data_out());
            set(c, line::CLK | line::DO);
        }
        set(c, line::CS | line::CLK | line::DI | line::DO);
        assert!(c.data_out(), "released after /CS goes high");
        out
    }

    #[test]
    fn a_program_reads_each_channel_msb_first_then_lsb_first() {
        let inputs = [
            Source::Constant(1.0),
            Source::Constant(2.0),
            Source::Constant(3.0),
            Source::Constant(4.0),
        ];
        let mut c = Converter::default();
        for (channel, (odd, select)) in [(false, false), (true, false), (false, true), (true, true)]
            .into_iter()
            .enumerate()
        {
            let bits = exchange(&mut c, &inputs, [true, true, odd, select]);
            assert!(!bits[0], "leading zero");
            let msb_first = bits[1..9].iter().fold(0u8, |v, &b| v << 1 | u8::from(b));
            assert_eq!(
                msb_first,
                to_code(channel as f64 + 1.0),
                "channel {}",
                channel + 1
            );
            let lsb_first = bits[8..15]
                .iter()
                .enumerate()
                .fold(0u8, |v, (i, &b)| v | u8::from(b) << i);
            assert_eq!(lsb_first, msb_first & 0x7F);
        }
    }

    #[test]
    fn differential_pairs_read_the_difference_and_nothing_happens_unselected() {
        let inputs = [
            Source::Constant(4.0),
            Source::Constant(1.5),
            Source::default(),
            Source::default(),
        ];
        let mut c = Converter::default();
        let bits = exchange(&mut c, &inputs, [true, false, false, false]);
        let value = bits[1..9].iter().fold(0u8, |v, &b| v << 1 | u8::from(b));
        assert_eq!(value, to_code(2.5));
        // Clocking with /CS high changes nothing.
        for p in [line::CS, line::CS | line::CLK, line::CS] {
            assert_eq!(c.pins_changed(p | line::DO, Nanos::ZERO, &inputs), None);
        }
    }
}
