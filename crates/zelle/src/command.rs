//! The one-byte commands the cell's OS understands.

/// A command byte (1..19). Any other byte is ignored by the cell in the ready state.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[repr(u8)]
pub enum Command {
    /// Start a measurement series: 8 parameter bytes follow (after a 1 ms pause).
    Measure = 1,
    /// Read the data area from 0800h: `1` per byte wanted, `0` ends (after a 1 ms pause).
    ReadData = 2,
    /// Write the data area from 0800h: per byte a timing byte, then `1` + data or `0`.
    WriteData = 3,
    /// Read analog channels repeatedly: channel 1..4 → value, `0` ends.
    AnalogRepeat = 4,
    /// Load a program into 0400h, exchange as [`Command::WriteData`].
    LoadProgram = 5,
    /// Run the program at 0400h.
    RunProgram = 6,
    /// Read one analog channel once: channel → value.
    Analog = 7,
    /// Parallel interface bus: address (bit 7 = read), then data or the answer.
    Bus = 8,
    /// START: begins the next block of a running series.
    Start = 9,
    /// Start a series with the parameters already at 0800h.
    RepeatSeries = 10,
    /// Write port 1: one byte.
    WritePort1 = 11,
    /// Read port 1: one byte back.
    ReadPort1 = 12,
    /// Read the START key: `0` pressed, `1` not.
    ReadKey = 13,
    /// Write P2.6: `1` or `0`.
    WriteP26 = 14,
    /// Read P2.6: `1` or `0`.
    ReadP26 = 15,
    /// Read internal RAM (a processor register): address → content.
    ReadRegister = 16,
    /// Write internal RAM: address 0..127, data.
    WriteRegister = 17,
    /// Read any RAM address: high, low → content.
    Peek = 18,
    /// Write any RAM address: high, low, data.
    Poke = 19,
}

impl Command {
    /// The command a byte names, if any.
    pub fn from_byte(byte: u8) -> Option<Command> {
        use Command::*;
        Some(match byte {
            1 => Measure,
            2 => ReadData,
            3 => WriteData,
            4 => AnalogRepeat,
            5 => LoadProgram,
            6 => RunProgram,
            7 => Analog,
            8 => Bus,
            9 => Start,
            10 => RepeatSeries,
            11 => WritePort1,
            12 => ReadPort1,
            13 => ReadKey,
            14 => WriteP26,
            15 => ReadP26,
            16 => ReadRegister,
            17 => WriteRegister,
            18 => Peek,
            19 => Poke,
            _ => return None,
        })
    }

    /// Whether the OS sets up an address pointer for 1 ms after this command, during which the
    /// host must not start sending.
    pub fn needs_setup_pause(self) -> bool {
        matches!(
            self,
            Command::Measure | Command::ReadData | Command::WriteData | Command::LoadProgram
        )
    }

    /// Argument bytes that follow the command in the simple exchanges (not counting the loops
    /// of 1..5 or the direction-dependent byte of 8).
    pub(crate) fn fixed_args(self) -> usize {
        match self {
            Command::Analog
            | Command::Bus
            | Command::WritePort1
            | Command::WriteP26
            | Command::ReadRegister => 1,
            Command::WriteRegister | Command::Peek => 2,
            Command::Poke => 3,
            _ => 0,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_command_byte_round_trips() {
        for b in 0..=255u8 {
            match Command::from_byte(b) {
                Some(c) => assert_eq!(c as u8, b),
                None => assert!(b == 0 || b >= 20),
            }
        }
    }
}
