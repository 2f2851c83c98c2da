//! SJA1000 registers decoded into words for users: SR, ECC, ALC, the error registers, and a
//! register dump.

use std::fmt;

use buslab_chips::sja1000::CanMode;
use buslab_chips::sja1000::regs::*;

use crate::error_frame::{ArbitrationBit, CapturedBusError, ProtocolLocation, ProtocolViolation};

/// The status register (SR), same layout in both modes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Status(pub u8);

impl Status {
    pub const fn bits(self) -> u8 {
        self.0
    }
    /// RBS: at least one message waits in the RX FIFO.
    pub const fn receive_buffer_full(self) -> bool {
        self.0 & SR_RBS != 0
    }
    /// DOS: a message was lost because the FIFO was full.
    pub const fn data_overrun(self) -> bool {
        self.0 & SR_DOS != 0
    }
    /// TBS: the CPU may write the TX buffer.
    pub const fn transmit_buffer_released(self) -> bool {
        self.0 & SR_TBS != 0
    }
    /// TCS: the last requested transmission completed.
    pub const fn transmission_complete(self) -> bool {
        self.0 & SR_TCS != 0
    }
    pub const fn receiving(self) -> bool {
        self.0 & SR_RS != 0
    }
    pub const fn transmitting(self) -> bool {
        self.0 & SR_TS != 0
    }
    /// ES: an error counter reached the warning limit.
    pub const fn error_status(self) -> bool {
        self.0 & SR_ES != 0
    }
    /// BS: bus-off.
    pub const fn bus_off(self) -> bool {
        self.0 & SR_BS != 0
    }
}

/// Every bit in words, e.g. "receive buffer empty, transmit buffer released, transmission
/// complete, idle, no error (< warning limit), bus on".
impl fmt::Display for Status {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let s = *self;
        let pick = |on: bool, yes: &'static str, no: &'static str| if on { yes } else { no };
        let activity = match (s.receiving(), s.transmitting()) {
            (false, false) => "bus idle",
            (true, false) => "receiving",
            (false, true) => "transmitting",
            (true, true) => "waiting for bus idle",
        };
        let parts = [
            pick(
                s.receive_buffer_full(),
                "receive buffer full",
                "receive buffer empty",
            ),
            pick(s.data_overrun(), "data overrun", "no overrun"),
            pick(
                s.transmit_buffer_released(),
                "transmit buffer released",
                "transmit buffer locked",
            ),
            pick(
                s.transmission_complete(),
                "transmission complete",
                "transmission incomplete",
            ),
            activity,
            pick(
                s.error_status(),
                "error status (≥ warning limit)",
                "no error status (< warning limit)",
            ),
            pick(s.bus_off(), "bus-off", "bus on"),
        ];
        write!(f, "SR=0x{:02X}: {}", s.0, parts.join(", "))
    }
}

/// The error code capture register (ECC, PeliCAN).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Ecc(pub u8);

/// ECC bits 7..6.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum EccKind {
    Bit,
    Form,
    Stuff,
    /// CRC, ACK and other errors.
    Other,
}

impl Ecc {
    pub const fn kind(self) -> EccKind {
        match self.0 >> 6 {
            0 => EccKind::Bit,
            1 => EccKind::Form,
            2 => EccKind::Stuff,
            _ => EccKind::Other,
        }
    }
    /// DIR = 0: the error happened while this node transmitted.
    pub const fn during_transmission(self) -> bool {
        self.0 & 0x20 == 0
    }
    /// Bits 4..0: where in the frame.
    pub const fn segment(self) -> u8 {
        self.0 & 0x1F
    }
    /// The segment in words ("data field"), or `None` for a code the datasheet does not list.
    pub fn segment_name(self) -> Option<&'static str> {
        Some(match self.segment() {
            0x03 => "start of frame",
            0x02 => "ID.28 to ID.21",
            0x06 => "ID.20 to ID.18",
            0x04 => "SRTR bit",
            0x05 => "IDE bit",
            0x07 => "ID.17 to ID.13",
            0x0F => "ID.12 to ID.5",
            0x0E => "ID.4 to ID.0",
            0x0C => "RTR bit",
            0x0D => "reserved bit 1",
            0x09 => "reserved bit 0",
            0x0B => "data length code",
            0x0A => "data field",
            0x08 => "CRC sequence",
            0x18 => "CRC delimiter",
            0x19 => "acknowledge slot",
            0x1B => "acknowledge delimiter",
            0x1A => "end of frame",
            0x12 => "intermission",
            0x11 => "active error flag",
            0x16 => "passive error flag",
            0x13 => "tolerate dominant bits",
            0x17 => "error delimiter",
            0x1C => "overload flag",
            _ => return None,
        })
    }
}

impl fmt::Display for EccKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            EccKind::Bit => "bit error",
            EccKind::Form => "form error",
            EccKind::Stuff => "stuff error",
            EccKind::Other => "other error (CRC or ACK)",
        })
    }
}

/// "bit error during transmission in data field".
impl fmt::Display for Ecc {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let dir = if self.during_transmission() {
            "transmission"
        } else {
            "reception"
        };
        write!(f, "{} during {dir} in ", self.kind())?;
        match self.segment_name() {
            Some(name) => f.write_str(name),
            None => write!(f, "unknown segment 0x{:02X}", self.segment()),
        }
    }
}

/// The arbitration lost capture register (ALC, PeliCAN).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Alc(pub u8);

impl Alc {
    /// Bits 4..0: the bit position (0 = ID.28, the first bit after SOF).
    pub const fn bit(self) -> u8 {
        self.0 & 0x1F
    }

    /// The bit in words: "ID.18", "SRTR", "IDE", "RTR". An SFF frame's ID.10..ID.0 are the
    /// EFF names ID.28..ID.18, as the datasheet numbers them.
    pub fn bit_name(self) -> String {
        match self.bit() {
            b @ 0..=10 => format!("ID.{}", 28 - b),
            11 => "SRTR".into(),
            12 => "IDE".into(),
            b @ 13..=30 => format!("ID.{}", 30 - b),
            _ => "RTR".into(),
        }
    }
}

/// "arbitration lost at bit 10 (ID.18)".
impl fmt::Display for Alc {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "arbitration lost at bit {} ({})",
            self.bit(),
            self.bit_name()
        )
    }
}

/// The error registers of a PeliCAN controller (the seed's "Error" property): the last
/// captured ALC and ECC (`None` until one was captured) and the two counters.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct ErrorRegisters {
    pub alc: Option<Alc>,
    pub ecc: Option<Ecc>,
    pub rxerr: u8,
    pub txerr: u8,
}

impl fmt::Display for ErrorRegisters {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "RXERR={} TXERR={}", self.rxerr, self.txerr)?;
        match self.alc {
            Some(alc) => write!(f, ", ALC=0x{:02X} {alc}", alc.0)?,
            None => f.write_str(", ALC none")?,
        }
        match self.ecc {
            Some(ecc) => write!(f, ", ECC=0x{:02X} {ecc}", ecc.0),
            None => f.write_str(", ECC none"),
        }
    }
}

/// A snapshot of the register file. `values[addr]` is `None` where reading would change the
/// chip (IR, ALC, ECC on hardware that cannot peek) or for a write-only register (CMR).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RegisterDump {
    pub mode: CanMode,
    pub reset_mode: bool,
    /// 128 addresses in PeliCAN, 32 in BasicCAN.
    pub values: Vec<Option<u8>>,
}

impl RegisterDump {
    pub fn get(&self, addr: u8) -> Option<u8> {
        self.values.get(addr as usize).copied().flatten()
    }

    /// `(address, name, value)` for every named register.
    pub fn named(&self) -> impl Iterator<Item = (u8, &'static str, Option<u8>)> + '_ {
        (0..self.values.len() as u8).filter_map(|addr| {
            register_name(self.mode, self.reset_mode, addr).map(|name| (addr, name, self.get(addr)))
        })
    }
}

/// One line per named register, then the rest as a hex table; `--` for values not read.
impl fmt::Display for RegisterDump {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let hex = |v: Option<u8>| v.map_or("--".to_string(), |v| format!("{v:02X}"));
        let mode = match self.mode {
            CanMode::Peli => "PeliCAN",
            CanMode::Basic => "BasicCAN",
        };
        let state = if self.reset_mode {
            "reset"
        } else {
            "operating"
        };
        writeln!(f, "{mode} registers, {state} mode")?;
        for (addr, name, value) in self.named() {
            writeln!(f, "{addr:3} {name:<6} {}", hex(value))?;
        }
        for (row, chunk) in self.values.chunks(16).enumerate() {
            write!(f, "{:3}:", row * 16)?;
            for &v in chunk {
                write!(f, " {}", hex(v))?;
            }
            writeln!(f)?;
        }
        Ok(())
    }
}

/// The datasheet name of a register, or `None` for buffer bytes and reserved addresses.
pub fn register_name(mode: CanMode, reset_mode: bool, addr: u8) -> Option<&'static str> {
    let addr = addr as usize;
    Some(match mode {
        CanMode::Peli => match addr {
            peli::MOD => "MOD",
            peli::CMR => "CMR",
            peli::SR => "SR",
            peli::IR => "IR",
            peli::IER => "IER",
            peli::BTR0 => "BTR0",
            peli::BTR1 => "BTR1",
            peli::OCR => "OCR",
            peli::ALC => "ALC",
            peli::ECC => "ECC",
            peli::EWLR => "EWLR",
            peli::RXERR => "RXERR",
            peli::TXERR => "TXERR",
            16..=19 if reset_mode => ["ACR0", "ACR1", "ACR2", "ACR3"][addr - 16],
            20..=23 if reset_mode => ["AMR0", "AMR1", "AMR2", "AMR3"][addr - 20],
            peli::RMC => "RMC",
            peli::RBSA => "RBSA",
            peli::CDR => "CDR",
            _ => return None,
        },
        CanMode::Basic => match addr {
            basic::CR => "CR",
            basic::CMR => "CMR",
            basic::SR => "SR",
            basic::IR => "IR",
            basic::ACR => "ACR",
            basic::AMR => "AMR",
            basic::BTR0 => "BTR0",
            basic::BTR1 => "BTR1",
            basic::OCR => "OCR",
            basic::CDR => "CDR",
            _ => return None,
        },
    })
}

/// The ECC's kind and direction as the violation type, its segment as the location.
impl From<Ecc> for CapturedBusError {
    fn from(ecc: Ecc) -> Self {
        let mut violation = match ecc.kind() {
            EccKind::Bit => ProtocolViolation::BIT,
            EccKind::Form => ProtocolViolation::FORM,
            EccKind::Stuff => ProtocolViolation::STUFF,
            EccKind::Other => 0,
        };
        if ecc.during_transmission() {
            violation |= ProtocolViolation::TX;
        }
        Self {
            violation: ProtocolViolation(violation),
            location: ProtocolLocation::from_code(ecc.segment()),
        }
    }
}

/// ALC bits 4..0: the bit position.
impl From<Alc> for ArbitrationBit {
    fn from(alc: Alc) -> Self {
        ArbitrationBit(alc.bit())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn status_in_words() {
        assert_eq!(
            Status(0x0C).to_string(),
            "SR=0x0C: receive buffer empty, no overrun, transmit buffer released, \
             transmission complete, bus idle, no error status (< warning limit), bus on"
        );
        let s = Status(0xC3).to_string();
        assert!(
            s.contains("receive buffer full, data overrun, transmit buffer locked"),
            "{s}"
        );
        assert!(s.contains("error status (≥ warning limit), bus-off"), "{s}");
        assert!(Status(0x3C).to_string().contains("waiting for bus idle"));
    }

    #[test]
    fn ecc_in_words() {
        assert_eq!(
            Ecc(0x0A).to_string(),
            "bit error during transmission in data field"
        );
        assert_eq!(
            Ecc(0xD9).to_string(),
            "other error (CRC or ACK) during transmission in acknowledge slot"
        );
        assert_eq!(
            Ecc(0xA2).to_string(),
            "stuff error during reception in ID.28 to ID.21"
        );
        assert_eq!(
            Ecc(0x41).to_string(),
            "form error during transmission in unknown segment 0x01"
        );
    }

    #[test]
    fn alc_in_words() {
        assert_eq!(Alc(10).to_string(), "arbitration lost at bit 10 (ID.18)");
        assert_eq!(Alc(0).to_string(), "arbitration lost at bit 0 (ID.28)");
        assert_eq!(Alc(11).bit_name(), "SRTR");
        assert_eq!(Alc(12).bit_name(), "IDE");
        assert_eq!(Alc(13).bit_name(), "ID.17");
        assert_eq!(Alc(30).bit_name(), "ID.0");
        assert_eq!(Alc(31).bit_name(), "RTR");
        assert_eq!(Alc(0xEA).bit(), 10, "bits 7..5 ignored");
    }
}
