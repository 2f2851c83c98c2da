//! The seed's demo board around a P82C150 (seed 002 §2.2): how its pins are wired (LEDs, the
//! input and ID switches and their select, the DPM outputs, the two analog inputs), and what a
//! host knows of its outputs from the SLIO's frames. The board's behaviour is
//! `buslab_slio::DemoBoard`'s; these are the facts a host needs to drive it.

use super::registers::{Register, Reply};

pub use super::{LED_PINS, VDD};

/// The demo board's OUTPUT_ENABLE: LEDs, DPM outputs, the input select.
pub const OUTPUT_ENABLE: u16 = 0x3F90;
/// The pin that selects the input switches instead of the ID switches.
pub const SELECT_PIN: u8 = 13;
/// The demo board's digital outputs: the LEDs and the input select, that is OUTPUT_ENABLE
/// without the DPM pins (P10 and P4 follow their duty, not DATA_OUTPUT).
pub const DIGITAL_OUTPUTS: u16 = 0x3B80;
/// The input switches' pins, P0..P3 (while P13 selects them).
pub const SWITCH_PINS: u16 = 0x000F;
/// ANALOG_CONFIGURATION values that convert ADC1 (P5) and ADC2 (P6, the potentiometer).
pub const CONVERT_ADC1: u16 = 0xE0;
pub const CONVERT_ADC2: u16 = 0xC0;

/// What a host knows of a demo board's digital outputs (the LEDs and P13), learned from the
/// SLIO's frames, whoever asked for them: DATA_OUTPUT as the SLIO confirmed a write, or the
/// levels its output pins read back in DATA_INPUT (seed §2.1.2: the SLIO answers every
/// command with the register's content; a P82C150 has no read of DATA_OUTPUT). The newer
/// frame wins. A host that builds its DATA_OUTPUT write on [`OutputLevels::with_pin`] keeps
/// the outputs it does not mean to change, and writes none it does not know.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct OutputLevels(Option<u16>);

impl OutputLevels {
    /// A SLIO's frame (an answer to anyone, a sign-on, an edge report).
    pub fn reply(&mut self, reply: &Reply) {
        self.learn(reply.register, reply.value);
    }

    /// A register's content the SLIO sent.
    pub fn learn(&mut self, register: Register, value: u16) {
        match register {
            Register::DataOutput => self.0 = Some(value),
            // Input pins' bits drive nothing: written as zeros, as MoniCAN initialises them.
            Register::DataInput => self.0 = Some(value & DIGITAL_OUTPUTS),
            _ => {}
        }
    }

    /// DATA_OUTPUT as last known, if the SLIO told.
    pub fn get(self) -> Option<u16> {
        self.0
    }

    /// The DATA_OUTPUT that drives `pin` to `high` and keeps every other output; `None` while
    /// the SLIO has told neither.
    pub fn with_pin(self, pin: u8, high: bool) -> Option<u16> {
        self.0.map(|base| set_bit(base, pin, high))
    }
}

/// `value` with bit `pin` set to `high`.
pub fn set_bit(value: u16, pin: u8, high: bool) -> u16 {
    if high {
        value | 1 << pin
    } else {
        value & !(1 << pin)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::slio::registers::Status;

    fn reply(register: Register, value: u16) -> Reply {
        Reply {
            status: Status::default(),
            register,
            value,
        }
    }

    #[test]
    fn output_levels_come_from_the_slios_answers_newest_first() {
        let mut levels = OutputLevels::default();
        assert_eq!(levels.with_pin(8, true), None, "nothing told yet");
        levels.reply(&reply(Register::Dpm1, 0x200));
        assert_eq!(levels.get(), None);
        // DATA_INPUT: the switches (P0, P2) and the DPM pins are not DATA_OUTPUT's.
        levels.reply(&reply(Register::DataInput, 0x2C85));
        assert_eq!(levels.get(), Some(0x2880));
        assert_eq!(levels.with_pin(8, true), Some(0x2980));
        assert_eq!(levels.with_pin(11, false), Some(0x2080));
        levels.reply(&reply(Register::DataOutput, 0x2000));
        assert_eq!(levels.get(), Some(0x2000));
    }
}
