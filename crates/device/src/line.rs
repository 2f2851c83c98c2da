//! UART line settings and their timing.

use core::fmt;

use buslab_can::{BitTime, Nanos};

/// Parity of a UART character.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Parity {
    None,
    Even,
    Odd,
}

/// How bytes are framed on an asynchronous serial line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct LineSettings {
    pub baud: u32,
    /// 5..=8.
    pub data_bits: u8,
    pub parity: Parity,
    /// 1 or 2.
    pub stop_bits: u8,
}

impl LineSettings {
    /// 8 data bits, no parity, one stop bit.
    pub const fn n81(baud: u32) -> Self {
        Self {
            baud,
            data_bits: 8,
            parity: Parity::None,
            stop_bits: 1,
        }
    }

    /// 8 data bits, no parity, two stop bits (the ZELLE cell's line).
    pub const fn n82(baud: u32) -> Self {
        Self {
            stop_bits: 2,
            ..Self::n81(baud)
        }
    }

    /// Bit-times one character occupies: start bit + data + parity + stop bits.
    pub const fn bits_per_byte(&self) -> u32 {
        1 + self.data_bits as u32
            + !matches!(self.parity, Parity::None) as u32
            + self.stop_bits as u32
    }

    /// The time one character occupies on the line (9600 8N2: 1 145 833 ns).
    pub const fn byte_time(&self) -> Nanos {
        BitTime::new(self.bits_per_byte() as u64).at_bitrate(self.baud)
    }

    /// Whether a receiver set to `self` decodes characters sent with `sender` correctly. The stop
    /// bit count does not matter for that: a UART receiver checks only the first stop bit.
    pub fn understands(&self, sender: &LineSettings) -> bool {
        self.baud == sender.baud
            && self.data_bits == sender.data_bits
            && self.parity == sender.parity
    }
}

impl fmt::Display for LineSettings {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let parity = match self.parity {
            Parity::None => 'N',
            Parity::Even => 'E',
            Parity::Odd => 'O',
        };
        write!(
            f,
            "{} {}{}{}",
            self.baud, self.data_bits, parity, self.stop_bits
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn zelle_line_is_eleven_bits_per_byte() {
        let line = LineSettings::n82(9600);
        assert_eq!(line.bits_per_byte(), 11);
        assert_eq!(line.byte_time(), Nanos::new(1_145_833));
        assert_eq!(line.to_string(), "9600 8N2");
    }

    #[test]
    fn stop_bits_do_not_break_understanding() {
        let cell = LineSettings::n82(9600);
        assert!(cell.understands(&LineSettings::n81(9600)));
        assert!(!cell.understands(&LineSettings::n82(19200)));
        let even = LineSettings {
            parity: Parity::Even,
            ..cell
        };
        assert!(!cell.understands(&even));
    }
}
