//! Typing a command (seed §4.3.3.1): the SLIO (`0`..`F`), `I` or `O`, the pin, and for an
//! output its value (`00`/`01` for a digital output, `00`..`FF` for a DPM output).
//!
//! The pin is the SLIO's port pin as one hex digit (`B` = P11), and only the pins the demo
//! board wires (seed §3.2) are accepted:
//!
//! | I/O | pin | what | register |
//! |---|---|---|---|
//! | `O` | `7` `8` `9` `B` `C` | an LED (P7, P8, P9, P11, P12), value `00`/`01` | DATA_OUTPUT, that bit |
//! | `O` | `A` | DPM1 (P10), value `00`..`FF` | DPM1 = value × 4 |
//! | `O` | `4` | DPM2 (P4), value `00`..`FF` | DPM2 = value × 4 |
//! | `I` | `0`..`3` | the input switches (P0..P3) | DATA_INPUT read |
//! | `I` | `5` | ADC1 (P5) | ANALOG_CONFIGURATION = 0xE0 (convert) |
//! | `I` | `6` | ADC2 (P6, the potentiometer) | ANALOG_CONFIGURATION = 0xC0 (convert) |
//!
//! A key that does not fit the field being typed rings the bell and changes nothing.

use buslab_slio::SlioId;

/// One of the two ADC inputs of the demo board.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Adc {
    /// P5, ANALOG_CONFIGURATION 0xE0.
    Adc1,
    /// P6, the potentiometer, ANALOG_CONFIGURATION 0xC0.
    Adc2,
}

/// One of the two quasi-analog outputs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Dpm {
    /// P10.
    Dpm1,
    /// P4.
    Dpm2,
}

/// What a complete command does.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Action {
    /// Read DATA_INPUT (pins 0..3: the input switches).
    ReadInputs { pin: u8 },
    /// Convert an analog input; the SLIO answers with ADC.
    Convert(Adc),
    /// Light (`true`) or put out an LED on `pin`.
    Led { pin: u8, on: bool },
    /// Set a DPM output's duty to `value`/256.
    Dpm { output: Dpm, value: u8 },
}

/// A complete command.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Command {
    pub slio: SlioId,
    pub action: Action,
}

/// Whether the I/O field asks for an input or sets an output.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Direction {
    Input,
    Output,
}

/// What a pin can be, given the I/O field.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum PinKind {
    Switch,
    Adc(Adc),
    Led,
    Dpm(Dpm),
}

/// The board's wiring, one table: (I/O, pin, what it is).
const PINS: [(Direction, u8, PinKind); 11] = [
    (Direction::Input, 0x0, PinKind::Switch),
    (Direction::Input, 0x1, PinKind::Switch),
    (Direction::Input, 0x2, PinKind::Switch),
    (Direction::Input, 0x3, PinKind::Switch),
    (Direction::Input, 0x5, PinKind::Adc(Adc::Adc1)),
    (Direction::Input, 0x6, PinKind::Adc(Adc::Adc2)),
    (Direction::Output, 0x7, PinKind::Led),
    (Direction::Output, 0x8, PinKind::Led),
    (Direction::Output, 0x9, PinKind::Led),
    (Direction::Output, 0xB, PinKind::Led),
    (Direction::Output, 0xC, PinKind::Led),
];

/// The DPM pins: `A` = P10 (DPM1), `4` = P4 (DPM2).
const DPM_PINS: [(u8, Dpm); 2] = [(0xA, Dpm::Dpm1), (0x4, Dpm::Dpm2)];

fn pin_kind(dir: Direction, pin: u8) -> Option<PinKind> {
    PINS.iter()
        .find(|p| p.0 == dir && p.1 == pin)
        .map(|p| p.2)
        .or_else(|| {
            (dir == Direction::Output)
                .then(|| {
                    DPM_PINS
                        .iter()
                        .find(|d| d.0 == pin)
                        .map(|d| PinKind::Dpm(d.1))
                })
                .flatten()
        })
}

/// What a key did to the command line.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum KeyOutcome {
    /// The key filled a field or erased one; the line changed.
    Edited,
    /// The command is complete: send it. The line keeps showing it until the next key.
    Complete(Command),
    /// The key does not fit: ring the bell, nothing changed.
    Refused,
}

/// The command being typed.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct CommandLine {
    slio: Option<SlioId>,
    dir: Option<Direction>,
    pin: Option<u8>,
    value: Vec<u8>,
    /// The fields show a command already sent; the next key starts a new one.
    sent: bool,
}

const BACKSPACE: u8 = 0x08;
const DELETE: u8 = 0x7F;

fn hex(byte: u8) -> Option<u8> {
    (byte as char).to_digit(16).map(|d| d as u8)
}

impl CommandLine {
    pub fn new() -> Self {
        Self::default()
    }

    /// Forgets what was typed (Escape).
    pub fn clear(&mut self) {
        *self = Self::default();
    }

    /// Takes one key (already upper-cased by the caller for letters).
    pub fn key(&mut self, key: u8) -> KeyOutcome {
        if key == BACKSPACE || key == DELETE {
            return self.erase();
        }
        if self.sent {
            // A new command starts with this key; if it does not fit the SLIO field the old
            // command stays on show.
            let mut fresh = Self::default();
            let outcome = fresh.key(key);
            if outcome != KeyOutcome::Refused {
                *self = fresh;
            }
            return outcome;
        }
        let digit = hex(key);
        match (self.slio, self.dir, self.pin) {
            (None, _, _) => match digit.and_then(|d| SlioId::new(d).ok()) {
                Some(slio) => {
                    self.slio = Some(slio);
                    KeyOutcome::Edited
                }
                None => KeyOutcome::Refused,
            },
            (Some(_), None, _) => {
                self.dir = match key {
                    b'I' => Some(Direction::Input),
                    b'O' => Some(Direction::Output),
                    _ => return KeyOutcome::Refused,
                };
                KeyOutcome::Edited
            }
            (Some(_), Some(dir), None) => {
                let Some(pin) = digit.filter(|&p| pin_kind(dir, p).is_some()) else {
                    return KeyOutcome::Refused;
                };
                self.pin = Some(pin);
                if dir == Direction::Input {
                    return self.complete();
                }
                KeyOutcome::Edited
            }
            (Some(_), Some(dir), Some(pin)) => {
                let kind = pin_kind(dir, pin);
                let allowed = match (kind, self.value.len(), digit) {
                    // 00 or 01 for an LED.
                    (Some(PinKind::Led), 0, Some(0)) => true,
                    (Some(PinKind::Led), 1, Some(0 | 1)) => true,
                    (Some(PinKind::Dpm(_)), _, Some(_)) => true,
                    _ => false,
                };
                if !allowed {
                    return KeyOutcome::Refused;
                }
                self.value.push(key);
                if self.value.len() == crate::layout::VALUE_WIDTH {
                    return self.complete();
                }
                KeyOutcome::Edited
            }
        }
    }

    fn erase(&mut self) -> KeyOutcome {
        self.sent = false;
        let erased = self.value.pop().is_some()
            || self.pin.take().is_some()
            || self.dir.take().is_some()
            || self.slio.take().is_some();
        if erased {
            KeyOutcome::Edited
        } else {
            KeyOutcome::Refused
        }
    }

    fn complete(&mut self) -> KeyOutcome {
        match self.command() {
            Some(command) => {
                self.sent = true;
                KeyOutcome::Complete(command)
            }
            None => KeyOutcome::Refused,
        }
    }

    /// The command the fields make, when complete.
    fn command(&self) -> Option<Command> {
        let (slio, dir, pin) = (self.slio?, self.dir?, self.pin?);
        let value = || {
            let text = std::str::from_utf8(&self.value).ok()?;
            (text.len() == crate::layout::VALUE_WIDTH)
                .then(|| u8::from_str_radix(text, 16).ok())
                .flatten()
        };
        let action = match pin_kind(dir, pin)? {
            PinKind::Switch => Action::ReadInputs { pin },
            PinKind::Adc(adc) => Action::Convert(adc),
            PinKind::Led => Action::Led {
                pin,
                on: value()? == 1,
            },
            PinKind::Dpm(output) => Action::Dpm {
                output,
                value: value()?,
            },
        };
        Some(Command { slio, action })
    }

    /// Whether the fields show a command that was sent.
    pub fn is_sent(&self) -> bool {
        self.sent
    }

    /// The four fields as shown: `_` where nothing was typed.
    pub fn fields(&self) -> [String; 4] {
        let one = |c: Option<char>| c.map_or("_".to_string(), |c| c.to_string());
        let mut value: String = self.value.iter().map(|&b| b as char).collect();
        while value.len() < crate::layout::VALUE_WIDTH {
            value.push('_');
        }
        [
            one(self
                .slio
                .map(|s| format!("{s}").chars().next().unwrap_or('?'))),
            one(self.dir.map(|d| match d {
                Direction::Input => 'I',
                Direction::Output => 'O',
            })),
            one(self
                .pin
                .and_then(|p| char::from_digit(u32::from(p), 16))
                .map(|c| c.to_ascii_uppercase())),
            value,
        ]
    }

    /// The column the next key goes to (for the cursor).
    pub fn cursor_col(&self) -> u8 {
        use crate::layout::{IO_FIELD, PIN_FIELD, SLIO_FIELD, VALUE_FIELD};
        if self.sent || self.slio.is_none() {
            return SLIO_FIELD.1;
        }
        if self.dir.is_none() {
            return IO_FIELD.1;
        }
        if self.pin.is_none() {
            return PIN_FIELD.1;
        }
        VALUE_FIELD.1 + self.value.len() as u8
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn typed(keys: &str) -> (CommandLine, Vec<KeyOutcome>) {
        let mut line = CommandLine::new();
        let outcomes = keys.bytes().map(|k| line.key(k)).collect();
        (line, outcomes)
    }

    fn complete(keys: &str) -> Option<Command> {
        typed(keys).1.into_iter().find_map(|o| match o {
            KeyOutcome::Complete(c) => Some(c),
            _ => None,
        })
    }

    fn slio(n: u8) -> SlioId {
        SlioId::new(n).unwrap()
    }

    #[test]
    fn every_wired_pin_makes_its_command() {
        assert_eq!(
            complete("3O701"),
            Some(Command {
                slio: slio(3),
                action: Action::Led { pin: 7, on: true }
            })
        );
        assert_eq!(
            complete("AOC00").map(|c| c.action),
            Some(Action::Led { pin: 12, on: false })
        );
        assert_eq!(
            complete("0OA80").map(|c| c.action),
            Some(Action::Dpm {
                output: Dpm::Dpm1,
                value: 0x80
            })
        );
        assert_eq!(
            complete("FO4FF").map(|c| c.action),
            Some(Action::Dpm {
                output: Dpm::Dpm2,
                value: 0xFF
            })
        );
        assert_eq!(
            complete("3I2").map(|c| c.action),
            Some(Action::ReadInputs { pin: 2 })
        );
        assert_eq!(
            complete("3I5").map(|c| c.action),
            Some(Action::Convert(Adc::Adc1))
        );
        assert_eq!(
            complete("3I6").map(|c| c.action),
            Some(Action::Convert(Adc::Adc2))
        );
    }

    #[test]
    fn keys_that_do_not_fit_are_refused_and_change_nothing() {
        use KeyOutcome::*;
        let (line, outcomes) = typed("G3XI4");
        assert_eq!(outcomes, [Refused, Edited, Refused, Edited, Refused]);
        assert_eq!(line.fields(), ["3", "I", "_", "__"]);
        // LED values are 00 or 01 only; unwired pins refused either way.
        let (_, outcomes) = typed("3O72");
        assert_eq!(outcomes[3], Refused);
        let (line, outcomes) = typed("3O7022");
        assert_eq!(outcomes[3..], [Edited, Refused, Refused]);
        assert_eq!(line.fields(), ["3", "O", "7", "0_"]);
        for pin in "012356DEF".bytes() {
            assert_eq!(
                typed(&format!("3O{}", pin as char)).1[2],
                Refused,
                "O{}",
                pin as char
            );
        }
        for pin in "4789ABCDEF".bytes() {
            assert_eq!(
                typed(&format!("3I{}", pin as char)).1[2],
                Refused,
                "I{}",
                pin as char
            );
        }
    }

    #[test]
    fn backspace_erases_the_last_field_and_a_new_command_replaces_a_sent_one() {
        let (mut line, _) = typed("3OA8");
        assert_eq!(line.key(DELETE), KeyOutcome::Edited);
        assert_eq!(line.fields(), ["3", "O", "A", "__"]);
        assert_eq!(line.key(BACKSPACE), KeyOutcome::Edited);
        assert_eq!(line.key(BACKSPACE), KeyOutcome::Edited);
        assert_eq!(line.key(BACKSPACE), KeyOutcome::Edited);
        assert_eq!(line.key(BACKSPACE), KeyOutcome::Refused);
        let (mut line, _) = typed("3I0");
        assert!(line.is_sent());
        assert_eq!(line.fields(), ["3", "I", "0", "__"]);
        // A key that cannot start a command leaves the sent one on show.
        assert_eq!(line.key(b'Z'), KeyOutcome::Refused);
        assert_eq!(line.fields(), ["3", "I", "0", "__"]);
        assert_eq!(line.key(b'5'), KeyOutcome::Edited);
        assert_eq!(line.fields(), ["5", "_", "_", "__"]);
    }

    #[test]
    fn the_cursor_follows_the_field_to_type() {
        use crate::layout::*;
        let (line, _) = typed("");
        assert_eq!(line.cursor_col(), SLIO_FIELD.1);
        let (line, _) = typed("3");
        assert_eq!(line.cursor_col(), IO_FIELD.1);
        let (line, _) = typed("3O");
        assert_eq!(line.cursor_col(), PIN_FIELD.1);
        let (line, _) = typed("3OA");
        assert_eq!(line.cursor_col(), VALUE_FIELD.1);
        let (line, _) = typed("3OA8");
        assert_eq!(line.cursor_col(), VALUE_FIELD.1 + 1);
        let (line, _) = typed("3OA80");
        assert_eq!(line.cursor_col(), SLIO_FIELD.1);
    }
}
