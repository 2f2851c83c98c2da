//! The cell's memory map and the battery-backed RAM snapshot.
//!
//! ```text
//! 0000h..03FEh  system RAM (the OS in EPROM sits in code space, not here)
//! 03FFh         start byte: 0 ready, 129 measure mode, 130 program mode
//! 0400h..07FFh  user program area (command 5 loads here, command 6 runs it)
//! 0800h..0807h  measurement parameters (command 1 copies its 8 bytes here)
//! 0808h..7FFFh  measured values, ascending
//! 8000h..FFFFh  nothing decoded: reads FFh, writes are ignored
//! ```
//! The whole 32 KiB external RAM is battery-backed. The processor's internal RAM (0..127) is
//! not: it is cleared at power-on.

use serde::{Deserialize, Serialize};

/// Size of the battery-backed external RAM (a 62256 at 0000h..7FFFh).
pub const EXT_RAM_SIZE: usize = 0x8000;
/// Size of the 8051's internal RAM reachable by commands 16 and 17.
pub const INTERNAL_RAM_SIZE: usize = 128;
/// Address of the start byte that selects the mode after power-on or reset.
pub const START_BYTE: u16 = 0x03FF;
/// Start of the user program area.
pub const PROGRAM_AREA: u16 = 0x0400;
/// Start of the data area: 8 parameter bytes, then the values.
pub const DATA_AREA: u16 = 0x0800;
/// Number of parameter bytes at the start of the data area.
pub const PARAMS_LEN: u16 = 8;

/// What reading an address no chip answers gives.
pub(crate) const OPEN_BUS: u8 = 0xFF;

/// The battery-backed external RAM: survives power-off, and is what the state file holds.
#[derive(Clone, PartialEq, Eq)]
pub struct BatteryRam {
    bytes: Box<[u8]>,
}

impl Default for BatteryRam {
    /// A fresh cell: all zero, so the start byte says "ready".
    fn default() -> Self {
        Self {
            bytes: vec![0; EXT_RAM_SIZE].into_boxed_slice(),
        }
    }
}

impl std::fmt::Debug for BatteryRam {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "BatteryRam {{ start byte {} }}", self.read(START_BYTE))
    }
}

impl BatteryRam {
    /// The byte at `addr`; addresses above the RAM read as open bus (FFh).
    pub fn read(&self, addr: u16) -> u8 {
        self.bytes
            .get(usize::from(addr))
            .copied()
            .unwrap_or(OPEN_BUS)
    }

    /// Writes `value` at `addr`; writes above the RAM go nowhere.
    pub fn write(&mut self, addr: u16, value: u8) {
        if let Some(b) = self.bytes.get_mut(usize::from(addr)) {
            *b = value;
        }
    }

    /// All of it, from 0000h.
    pub fn as_bytes(&self) -> &[u8] {
        &self.bytes
    }

    /// The state file's text (TOML with the RAM as hex, 64 bytes a line).
    pub fn to_state_file(&self) -> String {
        let file = StateFile {
            format: FORMAT.into(),
            version: VERSION,
            ram: self
                .bytes
                .chunks(64)
                .map(|chunk| chunk.iter().map(|b| format!("{b:02x}")).collect())
                .collect(),
        };
        toml::to_string_pretty(&file).expect("a state file always serialises")
    }

    /// Reads a state file written by [`to_state_file`](Self::to_state_file).
    pub fn from_state_file(text: &str) -> Result<Self, StateFileError> {
        let file: StateFile =
            toml::from_str(text).map_err(|e| StateFileError::Syntax(e.to_string()))?;
        if file.format != FORMAT {
            return Err(StateFileError::Format(file.format));
        }
        if file.version != VERSION {
            return Err(StateFileError::Version(file.version));
        }
        let mut bytes = Vec::with_capacity(EXT_RAM_SIZE);
        for (n, line) in file.ram.iter().enumerate() {
            let digits = line.as_bytes();
            // Hex digits only: `from_str_radix` would take a sign (`+f`).
            if digits.len() % 2 != 0 || !digits.iter().all(u8::is_ascii_hexdigit) {
                return Err(StateFileError::Hex { line: n });
            }
            for pair in digits.chunks(2) {
                let hex = std::str::from_utf8(pair).map_err(|_| StateFileError::Hex { line: n })?;
                let b = u8::from_str_radix(hex, 16).map_err(|_| StateFileError::Hex { line: n })?;
                bytes.push(b);
            }
        }
        if bytes.len() != EXT_RAM_SIZE {
            return Err(StateFileError::Size(bytes.len()));
        }
        Ok(Self {
            bytes: bytes.into_boxed_slice(),
        })
    }
}

/// A hex listing of `data` as read from `start`: 16 bytes a line, `0800: 00 64 01 ...`.
pub fn hex_listing(start: u16, data: &[u8]) -> String {
    let mut listing = String::new();
    for (i, chunk) in data.chunks(16).enumerate() {
        let hex: Vec<String> = chunk.iter().map(|b| format!("{b:02x}")).collect();
        listing.push_str(&format!(
            "{:04x}: {}\n",
            usize::from(start) + i * 16,
            hex.join(" ")
        ));
    }
    listing
}

const FORMAT: &str = "buslab-zelle-battery-ram";
const VERSION: u32 = 1;

#[derive(Serialize, Deserialize)]
struct StateFile {
    format: String,
    version: u32,
    ram: Vec<String>,
}

/// Why a state file could not be read.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum StateFileError {
    #[error("state file is not valid TOML: {0}")]
    Syntax(String),
    #[error("state file format is `{0}`, expected `{FORMAT}`")]
    Format(String),
    #[error("state file version {0} is not supported (this buslab reads version {VERSION})")]
    Version(u32),
    #[error("state file RAM line {line} is not an even number of hex digits")]
    Hex { line: usize },
    #[error("state file holds {0} bytes of RAM, expected {EXT_RAM_SIZE}")]
    Size(usize),
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hex_listing_is_sixteen_bytes_a_line_from_the_start_address() {
        let data: Vec<u8> = (0..18).collect();
        assert_eq!(
            hex_listing(DATA_AREA, &data),
            "0800: 00 01 02 03 04 05 06 07 08 09 0a 0b 0c 0d 0e 0f\n0810: 10 11\n"
        );
    }

    #[test]
    fn state_file_round_trips() {
        let mut ram = BatteryRam::default();
        ram.write(START_BYTE, 129);
        ram.write(0x7FFF, 0xAB);
        ram.write(0x9000, 1); // nowhere
        let text = ram.to_state_file();
        let back = BatteryRam::from_state_file(&text).unwrap();
        assert_eq!(back, ram);
        assert_eq!(back.read(START_BYTE), 129);
        assert_eq!(back.read(0x7FFF), 0xAB);
        assert_eq!(back.read(0x9000), OPEN_BUS);
    }

    #[test]
    fn broken_state_files_are_refused() {
        let good = BatteryRam::default().to_state_file();
        assert!(matches!(
            BatteryRam::from_state_file("\u{0}garbage = = ["),
            Err(StateFileError::Syntax(_))
        ));
        assert!(matches!(
            BatteryRam::from_state_file(&good.replace("buslab-zelle", "other")),
            Err(StateFileError::Format(_))
        ));
        assert_eq!(
            BatteryRam::from_state_file(&good.replace("version = 1", "version = 7")),
            Err(StateFileError::Version(7))
        );
        assert_eq!(
            BatteryRam::from_state_file(&good.replacen("\"00", "\"zz", 1)),
            Err(StateFileError::Hex { line: 0 })
        );
        assert_eq!(
            BatteryRam::from_state_file(&good.replacen("\"00", "\"0", 1)),
            Err(StateFileError::Hex { line: 0 })
        );
        assert_eq!(
            BatteryRam::from_state_file(&good.replacen("\"0000", "\"", 1)),
            Err(StateFileError::Size(EXT_RAM_SIZE - 2))
        );
    }
}
