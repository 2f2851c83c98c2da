//! The nine 16-bit registers and the 3-byte frames that carry them.
//!
//! A frame to a SLIO carries the register number and a 16-bit value (high byte first, the
//! seed's `wr_reg_slio`), always 3 bytes (a read fills the value with zeros, see [`Request`]);
//! every frame from a SLIO carries four status bits and the register number in its first byte
//! and the register's content in the next two (`DATA1:23 DATA2:20 DATA3:00` on the MoniCAN screen of the seed's Fig. 4.2: status 2,
//! register 3 = DATA_OUTPUT, value 0x2000).
//!
//! The register numbers are not all known (the data sheet's section 7.2 was not reachable,
//! and the seed names DATA_OUTPUT both 7 and 3). They are kept in [`MAP`], this one table:
//! the seed lists the nine registers in the order below, DATA_OUTPUT is 3 in both its code
//! and its MoniCAN screen, so the listed order is taken as the numbering (docs/decisions.md).

use core::fmt;

use buslab_can::Frame;

use super::ids::SlioId;

/// One of the nine registers.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Register {
    /// The levels of the 16 pins (outputs read back what they drive). Read-only.
    DataInput,
    /// Pins whose rising edge sends the data input register by itself.
    PositiveEdge,
    /// Pins whose falling edge sends the data input register by itself.
    NegativeEdge,
    /// The levels driven on the output pins.
    DataOutput,
    /// Which pins are outputs (1) or inputs (0); 0 after reset: every pin floats.
    OutputEnable,
    /// The ADC input multiplexer and the convert bit ([`CONVERT`]).
    AnalogConfig,
    /// The duty of the first quasi-analog output (DPM1, pin P10), 10 bits.
    Dpm1,
    /// The duty of the second quasi-analog output (DPM2, pin P4), 10 bits.
    Dpm2,
    /// The result of the last conversion, 10 bits. Read-only; reading it converts again.
    Adc,
}

/// Whether the host may write a register.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Access {
    ReadWrite,
    ReadOnly,
}

/// The register map: number, register, the name the seed's `slio.h` would give it, access.
pub const MAP: [(u8, Register, &str, Access); 9] = [
    (0, Register::DataInput, "DATA_INPUT", Access::ReadOnly),
    (
        1,
        Register::PositiveEdge,
        "POSITIVE_EDGE",
        Access::ReadWrite,
    ),
    (
        2,
        Register::NegativeEdge,
        "NEGATIVE_EDGE",
        Access::ReadWrite,
    ),
    (3, Register::DataOutput, "DATA_OUTPUT", Access::ReadWrite),
    (
        4,
        Register::OutputEnable,
        "OUTPUT_ENABLE",
        Access::ReadWrite,
    ),
    (
        5,
        Register::AnalogConfig,
        "ANALOG_CONFIGURATION",
        Access::ReadWrite,
    ),
    (6, Register::Dpm1, "DPM1", Access::ReadWrite),
    (7, Register::Dpm2, "DPM2", Access::ReadWrite),
    (8, Register::Adc, "ADC", Access::ReadOnly),
];

/// ANALOG_CONFIGURATION's convert request (the seed's "bit 8", counting from 1): writing it
/// converts the selected input and answers with the ADC register.
pub const CONVERT: u16 = 0x80;
/// ANALOG_CONFIGURATION's input multiplexer, bits 6..4 (the ADC is "multiplexable on 6
/// inputs"): `0xE0` selects input 6, ADC1 on the demo board; `0xC0` input 4, ADC2.
pub const MUX_SHIFT: u16 = 4;
pub const MUX_MASK: u16 = 0x7;
/// The DPM and ADC registers hold 10 bits.
pub const TEN_BITS: u16 = 0x3FF;

impl Register {
    pub fn number(self) -> u8 {
        MAP.iter().find(|e| e.1 == self).map_or(0, |e| e.0)
    }

    pub fn from_number(number: u8) -> Option<Self> {
        MAP.iter().find(|e| e.0 == number).map(|e| e.1)
    }

    pub fn name(self) -> &'static str {
        MAP.iter().find(|e| e.1 == self).map_or("?", |e| e.2)
    }

    pub fn access(self) -> Access {
        MAP.iter()
            .find(|e| e.1 == self)
            .map_or(Access::ReadOnly, |e| e.3)
    }

    /// Index into a register file.
    pub fn index(self) -> usize {
        self.number() as usize
    }

    /// Every register in number order.
    pub fn all() -> impl Iterator<Item = Register> {
        MAP.iter().map(|e| e.1)
    }
}

impl fmt::Display for Register {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A register name or number that is not one of the nine.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error(
    "register {0:?} is not one of DATA_INPUT, POSITIVE_EDGE, NEGATIVE_EDGE, DATA_OUTPUT, OUTPUT_ENABLE, ANALOG_CONFIGURATION, DPM1, DPM2, ADC (or their numbers 0..8)"
)]
pub struct RegisterError(pub String);

impl core::str::FromStr for Register {
    type Err = RegisterError;

    /// A name (any case, `ANALOG_CONFIG` and `-` for `_` too) or a number 0..8.
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let t = s.trim().to_ascii_uppercase().replace('-', "_");
        if let Ok(n) = t.parse::<u8>() {
            return Register::from_number(n).ok_or_else(|| RegisterError(s.to_string()));
        }
        if t == "ANALOG_CONFIG" {
            return Ok(Register::AnalogConfig);
        }
        MAP.iter()
            .find(|e| e.2 == t)
            .map(|e| e.1)
            .ok_or_else(|| RegisterError(s.to_string()))
    }
}

/// The four status bits of every frame a SLIO sends (data sheet table 14; their order in the
/// byte is this project's reading of the seed's screen, docs/decisions.md): bit 7 BM1, bit 6
/// BM0, bit 5 EW, bit 4 RSTD.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct Status {
    /// RSTD: a reset or a bus-mode change happened (reported once, in the sign-on).
    pub reset_detected: bool,
    /// EW: 1 after reset, 0 after a bus-mode change.
    pub ew: bool,
    /// BM1..BM0: the bus mode, one more after each bus-mode change (watchdog, bus-off).
    pub bus_mode: u8,
}

impl Status {
    /// The nibble, bits 3..0 = BM1 BM0 EW RSTD.
    pub const fn nibble(self) -> u8 {
        (self.bus_mode & 3) << 2 | (self.ew as u8) << 1 | self.reset_detected as u8
    }

    pub const fn from_nibble(n: u8) -> Self {
        Self {
            reset_detected: n & 1 != 0,
            ew: n & 2 != 0,
            bus_mode: (n >> 2) & 3,
        }
    }
}

/// What a frame to a SLIO asks for.
///
/// Every frame a P82C150 carries out is a data frame of 3 bytes, the register number and 16
/// bits ("Les trames envoyées ou reçues par le SLIO ont toujours 3 octets (sauf les remote
/// frame bien sûr)", seed 002 §2.1.2.1), or a remote frame, which reads DATA_INPUT. So only
/// the read-only registers can be read: a 3-byte frame addressed to DATA_INPUT or ADC stores
/// nothing and is answered with the register's content (docs/decisions.md); a writable
/// register is known from the SLIO's answer to a write.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Request {
    /// Write `value` into a writable register; the SLIO answers with its new content.
    Write { register: Register, value: u16 },
    /// Read a read-only register (DATA_INPUT, or ADC, which converts again): a 3-byte frame
    /// addressed to it, or a remote frame for DATA_INPUT.
    Read { register: Register },
}

/// Why a frame to a SLIO means nothing to it (the SLIO ignores such frames).
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum RequestError {
    #[error("no register {0} (0..8)")]
    NoRegister(u8),
    #[error(
        "{0} data bytes: a P82C150 takes 3 (the register number, then 16 bits) or a remote frame"
    )]
    Length(u8),
}

/// A writable register cannot be read: the only frame that addresses it writes it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[error(
    "{0} cannot be read without writing it: a P82C150 takes 3-byte frames only (register and value) and answers with what it stored; readable are DATA_INPUT (output pins read back their levels) and ADC"
)]
pub struct NotReadable(pub Register);

/// The value bytes of a read: a read-only register does not store them.
const READ_FILLER: u16 = 0x0000;

impl Request {
    /// A read of `register`, if it has one (the read-only registers).
    pub fn read(register: Register) -> Result<Self, NotReadable> {
        match register.access() {
            Access::ReadOnly => Ok(Request::Read { register }),
            Access::ReadWrite => Err(NotReadable(register)),
        }
    }

    /// The request in a frame's data as a P82C150 takes it: a remote frame reads DATA_INPUT;
    /// a data frame must have 3 bytes, and addressed to a read-only register it reads it.
    pub fn parse(remote: bool, data: &[u8]) -> Result<Self, RequestError> {
        if remote {
            return Ok(Request::Read {
                register: Register::DataInput,
            });
        }
        let [r, hi, lo] = *data else {
            return Err(RequestError::Length(data.len() as u8));
        };
        let register = Register::from_number(r & 0x0F).ok_or(RequestError::NoRegister(r))?;
        Ok(match register.access() {
            Access::ReadOnly => Request::Read { register },
            Access::ReadWrite => Request::Write {
                register,
                value: u16::from_be_bytes([hi, lo]),
            },
        })
    }

    /// The 3 data bytes of this request, as the seed's `make_slio_ffi` (DLC = 3) and
    /// `wr_reg_slio` build them; a read fills the value with zeros.
    pub fn data(self) -> Result<[u8; 3], NotReadable> {
        let (register, value) = match self {
            Request::Write { register, value } => (register, value),
            Request::Read { register } if register.access() == Access::ReadOnly => {
                (register, READ_FILLER)
            }
            Request::Read { register } => return Err(NotReadable(register)),
        };
        let [hi, lo] = value.to_be_bytes();
        Ok([register.number(), hi, lo])
    }

    /// The frame that carries this request to `slio`.
    pub fn frame(self, slio: SlioId) -> Result<Frame, NotReadable> {
        Ok(Frame::data(slio.command_id(), &self.data()?).expect("3 bytes"))
    }

    pub fn register(self) -> Register {
        match self {
            Request::Read { register } | Request::Write { register, .. } => register,
        }
    }
}

/// A frame from a SLIO: its status, a register and its content.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Reply {
    pub status: Status,
    pub register: Register,
    pub value: u16,
}

/// Data from a SLIO that is not a 3-byte register frame.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ReplyError {
    #[error("a SLIO frame has 3 data bytes, this one {0}")]
    Length(usize),
    #[error("no register {0} (0..8)")]
    NoRegister(u8),
}

impl Reply {
    pub fn encode(self) -> [u8; 3] {
        let [hi, lo] = self.value.to_be_bytes();
        [self.status.nibble() << 4 | self.register.number(), hi, lo]
    }

    pub fn parse(data: &[u8]) -> Result<Self, ReplyError> {
        let [first, hi, lo] = *data else {
            return Err(ReplyError::Length(data.len()));
        };
        let register =
            Register::from_number(first & 0x0F).ok_or(ReplyError::NoRegister(first & 0x0F))?;
        Ok(Reply {
            status: Status::from_nibble(first >> 4),
            register,
            value: u16::from_be_bytes([hi, lo]),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_seed_screen_frame_decodes() {
        // "Last frame received : ID1:53 ID2:A0 DATA1:23 DATA2:20 DATA3:00" and
        // "Data_output:2000" (seed 002, Fig. 4.2).
        let r = Reply::parse(&[0x23, 0x20, 0x00]).unwrap();
        assert_eq!(r.register, Register::DataOutput);
        assert_eq!(r.value, 0x2000);
        assert_eq!(
            r.status,
            Status {
                reset_detected: false,
                ew: true,
                bus_mode: 0
            }
        );
        assert_eq!(r.encode(), [0x23, 0x20, 0x00]);
    }

    #[test]
    fn the_seed_write_example_is_big_endian() {
        // wr_reg_slio: r4 = register << 24 | value << 8, sent high byte first.
        let w = Request::parse(false, &[0x03, 0x32, 0xE5]).unwrap();
        assert_eq!(
            w,
            Request::Write {
                register: Register::DataOutput,
                value: 0x32E5
            }
        );
        assert_eq!(w.data(), Ok([0x03, 0x32, 0xE5]));
    }

    #[test]
    fn the_map_is_one_table_of_nine_and_names_parse() {
        for (number, register, name, _) in MAP {
            assert_eq!(register.number(), number);
            assert_eq!(Register::from_number(number), Some(register));
            assert_eq!(name.parse::<Register>(), Ok(register));
            assert_eq!(number.to_string().parse::<Register>(), Ok(register));
        }
        assert_eq!("analog-config".parse(), Ok(Register::AnalogConfig));
        assert!("nine".parse::<Register>().is_err());
        assert!("9".parse::<Register>().is_err());
        assert_eq!(Register::from_number(9), None);
    }

    #[test]
    fn requests_of_other_lengths_and_registers_are_refused() {
        assert_eq!(
            Request::parse(true, &[]),
            Ok(Request::Read {
                register: Register::DataInput
            })
        );
        // The one-byte read of the past is not a P82C150 frame (seed §2.1.2.1: always 3
        // bytes), nor are other lengths.
        for len in [0, 1, 2, 4, 8] {
            let data = vec![Register::DataInput.number(); len];
            assert_eq!(
                Request::parse(false, &data),
                Err(RequestError::Length(len as u8))
            );
        }
        assert_eq!(
            Request::parse(false, &[0x09, 0, 0]),
            Err(RequestError::NoRegister(9))
        );
        assert!(Reply::parse(&[0x0F, 0, 0]).is_err());
        assert!(Reply::parse(&[1, 2]).is_err());
    }

    #[test]
    fn every_request_a_host_builds_has_three_bytes_and_writable_registers_have_no_read() {
        let slio = SlioId::new(3).unwrap();
        for register in Register::all() {
            let write = Request::Write {
                register,
                value: 0x1234,
            };
            let frame = write.frame(slio).unwrap();
            assert_eq!(
                frame.to_string(),
                format!("29C#{:02X}1234", register.number())
            );
            match Request::read(register) {
                Ok(read) => {
                    assert_eq!(register.access(), Access::ReadOnly);
                    let frame = read.frame(slio).unwrap();
                    assert_eq!(
                        frame.to_string(),
                        format!("29C#{:02X}0000", register.number())
                    );
                    // The SLIO reads it as a read of that register.
                    assert_eq!(Request::parse(false, frame.payload()), Ok(read));
                }
                Err(e) => {
                    assert_eq!(register.access(), Access::ReadWrite);
                    assert_eq!(e, NotReadable(register));
                    assert_eq!(Request::Read { register }.frame(slio), Err(e));
                    assert!(e.to_string().contains(register.name()), "{e}");
                }
            }
        }
        // A "write" to a read-only register is its read: nothing is stored.
        assert_eq!(
            Request::parse(false, &[0x08, 0x12, 0x34]),
            Ok(Request::Read {
                register: Register::Adc
            })
        );
    }

    #[test]
    fn status_nibbles_round_trip() {
        for n in 0..16 {
            assert_eq!(Status::from_nibble(n).nibble(), n);
        }
    }
}
