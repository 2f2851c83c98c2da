//! Typed kernel messages (SPEC C3), both directions, and their encoding.

use crate::codes::{Alert, MsgCode};
use crate::wire::{self, *};

/// How a THREAD display shows its values (sub-code bits 0..2).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum DisplayFormat {
    Text,
    Hex8,
    Hex16,
    Unsigned8,
    Unsigned16,
    Signed8,
    Signed16,
}

impl DisplayFormat {
    fn code(self) -> u8 {
        match self {
            Self::Text => 0,
            Self::Hex8 => 2,
            Self::Hex16 => 3,
            Self::Unsigned8 => 4,
            Self::Unsigned16 => 5,
            Self::Signed8 => 6,
            Self::Signed16 => 7,
        }
    }

    /// The format of a THREAD display sub-code (bits 0..2; 1 is no format).
    pub fn from_code(c: u8) -> Option<Self> {
        Some(match c & 7 {
            0 => Self::Text,
            2 => Self::Hex8,
            3 => Self::Hex16,
            4 => Self::Unsigned8,
            5 => Self::Unsigned16,
            6 => Self::Signed8,
            7 => Self::Signed16,
            _ => return None,
        })
    }

    /// Whether items are 16-bit words (2 bytes each, little-endian as in 80C196 memory).
    pub fn is_word(self) -> bool {
        matches!(self, Self::Hex16 | Self::Unsigned16 | Self::Signed16)
    }

    /// Renders the items as the PC monitor shows them (text with its control characters made
    /// visible: see [`printable`]).
    pub fn render(self, data: &[u8]) -> String {
        if self == Self::Text {
            return printable(data);
        }
        let words = data
            .chunks_exact(2)
            .map(|w| u16::from_le_bytes([w[0], w[1]]));
        let items: Vec<String> = match self {
            Self::Hex8 => data.iter().map(|b| format!("{b:02X}")).collect(),
            Self::Unsigned8 => data.iter().map(|b| b.to_string()).collect(),
            Self::Signed8 => data.iter().map(|&b| (b as i8).to_string()).collect(),
            Self::Hex16 => words.map(|w| format!("{w:04X}")).collect(),
            Self::Unsigned16 => words.map(|w| w.to_string()).collect(),
            Self::Signed16 => words.map(|w| (w as i16).to_string()).collect(),
            Self::Text => unreachable!(),
        };
        items.join(" ")
    }
}

/// Text from a board as it may be shown on a terminal (one helper for every text from
/// outside: `buslab_device::printable`).
pub use buslab_device::printable;

/// File open mode.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum FileMode {
    Read,
    Write,
}

/// `F0` THREAD: display and file service.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Thread {
    /// Board → PC: show values; `data` holds the raw bytes (2 per item for 16-bit formats).
    Display {
        format: DisplayFormat,
        newline: bool,
        data: Vec<u8>,
    },
    /// Board → PC: open file `name` as handle `file`.
    Open {
        mode: FileMode,
        name: Vec<u8>,
        file: u8,
    },
    /// Board → PC: close handle `file`.
    Close { file: u8 },
    /// Board → PC: send me up to `len` bytes of `file`.
    ReadRequest { len: u8, file: u8 },
    /// Board → PC: append `data` to `file`.
    Write { data: Vec<u8>, file: u8 },
    /// PC → board: bytes read from `file` (fewer than asked at end of file, none at its end).
    ReadData { data: Vec<u8>, file: u8 },
}

/// `F1 01` board identity.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct CpuInfo {
    /// Quartz in MHz.
    pub quartz: u8,
    pub version_196: u8,
    pub version_pic: u8,
    pub pic_revision: u8,
    pub serial: [u8; 8],
    pub address: u8,
    /// Supply voltage in tenths of a volt.
    pub supply: u8,
    /// Log-compression parameters.
    pub compression: [u8; 8],
}

impl core::fmt::Display for CpuInfo {
    /// The identity block `buslab cpu196 info` prints.
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        let compression: Vec<String> = self
            .compression
            .iter()
            .map(|b| format!("{b:02X}"))
            .collect();
        writeln!(f, "CPU196 board")?;
        writeln!(f, "  serial number   {}", printable(&self.serial))?;
        writeln!(f, "  quartz          {} MHz", self.quartz)?;
        writeln!(f, "  kernel 80C196   {}", self.version_196)?;
        writeln!(
            f,
            "  PIC             version {} revision {}",
            self.version_pic, self.pic_revision
        )?;
        writeln!(f, "  address         {}", self.address)?;
        writeln!(
            f,
            "  supply          {:.1} V",
            f64::from(self.supply) / 10.0
        )?;
        write!(f, "  compression     {}", compression.join(" "))
    }
}

/// The 2-byte START word `(pabb bnnn) (s00m thhh)`, kept raw so any byte pair round-trips;
/// [`Start::is_valid`] tells whether the kernel accepts it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Start(pub [u8; 2]);

impl Start {
    /// `0x8000` returned by a hook: no start.
    pub const NO_START: u16 = 0x8000;

    #[allow(clippy::too_many_arguments)]
    pub fn new(
        ad196: bool,
        adpic: bool,
        bank: u8,
        config: u8,
        high_bank: u8,
        pic_timer: bool,
        no_start: bool,
        page_change: bool,
    ) -> Self {
        Self([
            ((adpic as u8) << 7) | ((ad196 as u8) << 6) | ((bank & 7) << 3) | (config & 7),
            ((no_start as u8) << 7)
                | ((page_change as u8) << 4)
                | ((pic_timer as u8) << 3)
                | (high_bank & 7),
        ])
    }
    pub fn run(bank: u8, config: u8, ad196: bool) -> Self {
        Self::new(ad196, false, bank, config, 0, false, false, false)
    }
    /// From the 16-bit form hooks return and `csboot.boot` holds: `(s00m thhh)` is the high
    /// byte (so `0x8000` = no start), `(pabb bnnn)` the low byte.
    pub fn from_word(w: u16) -> Self {
        Self(w.to_le_bytes())
    }
    pub fn word(self) -> u16 {
        u16::from_le_bytes(self.0)
    }
    pub fn adpic(self) -> bool {
        self.0[0] & 0x80 != 0
    }
    pub fn ad196(self) -> bool {
        self.0[0] & 0x40 != 0
    }
    pub fn bank(self) -> u8 {
        (self.0[0] >> 3) & 7
    }
    pub fn config(self) -> u8 {
        self.0[0] & 7
    }
    pub fn no_start(self) -> bool {
        self.0[1] & 0x80 != 0
    }
    pub fn page_change(self) -> bool {
        self.0[1] & 0x10 != 0
    }
    pub fn pic_timer(self) -> bool {
        self.0[1] & 0x08 != 0
    }
    pub fn high_bank(self) -> u8 {
        self.0[1] & 7
    }
    /// Whether the two bits that must be 0 in the second byte are 0.
    pub fn is_valid(self) -> bool {
        self.0[1] & 0x60 == 0
    }
}

/// `F4` sub-codes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Power {
    /// PC → board: power down and cut the supply.
    PowerDown,
    /// PC → board: software reset.
    Reset,
    /// Board → PC: I powered down.
    PoweredDown,
    /// Board → PC: I have just been reset.
    WasReset,
}

/// `F7` CPUFORMAT (serial-number guarded).
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Format {
    ReadPicKernel {
        nsc: [u8; 8],
    },
    PicKernel(Box<[u8; PIC_BLOCK]>),
    WritePicKernel {
        nsc: [u8; 8],
        data: Box<[u8; PIC_BLOCK]>,
    },
    NewSerial {
        nsc: [u8; 8],
        new: [u8; 8],
    },
    ReadBootBlock {
        block: u8,
    },
    BootBlock(Box<[u8; BOOT_BLOCK]>),
    WriteBootBlock(Box<[u8; BOOT_BLOCK]>),
    EraseBoot,
    CompressionTable {
        table: Box<[u8; LOG_TABLE]>,
        comp: [u8; 8],
    },
    Emergency {
        xy: u8,
    },
}

/// `F8` PWM / D-A.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Pwm {
    /// PWM `n` (0..2: 80C196 8-bit; 3: PIC 10-bit, `low` = the two low bits).
    Set { n: u8, low: u8, value: u8 },
    /// PIC 5-bit D/A (Vref).
    Dac(u8),
}

/// `F9` I2C/SPI/SCI/parallel bridge.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Bridge {
    SpiReceived(u8),
    SpiSend(u8),
    SciReceived(u8),
    SciSend(u8),
    ParallelRead(u8),
    ParallelWrite(u8),
    ParallelAddress(u8),
    ParallelReadRequest,
}

/// `FB` one sample of a PIC channel (10-bit) or a virtual channel (12-bit).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum AdSample {
    Pic { channel: u8, value: u16 },
    Virtual { channel: u8, value: u16 },
}

/// One message of the PC ↔ board protocol.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Message {
    Thread(Thread),
    CpuInfoRequest,
    CpuInfo(CpuInfo),
    Start(Start),
    Stop,
    Power(Power),
    FlashReadRequest {
        bank: u8,
        block: u8,
    },
    FlashData(Box<[u8; FLASH_BLOCK]>),
    FlashWrite {
        bank: u8,
        block: u8,
        data: Box<[u8; FLASH_BLOCK]>,
    },
    FlashErase {
        bank: u8,
    },
    PicReadRequest {
        block: u8,
    },
    PicData(Box<[u8; PIC_BLOCK]>),
    PicWrite {
        block: u8,
        data: Box<[u8; PIC_BLOCK]>,
    },
    EepromReadRequest,
    EepromData(Box<[u8; PIC_EEPROM]>),
    EepromWrite(Box<[u8; PIC_EEPROM]>),
    Format(Format),
    Pwm(Pwm),
    Bridge(Bridge),
    /// `FA` data (the checksum is computed when encoding and checked when parsing).
    AdCont(Vec<u8>),
    AdSample(AdSample),
    CfgAdRequest {
        bank: u8,
        config: u8,
    },
    CfgAd {
        c196: [u8; 18],
        pic: [u8; 3],
    },
    Alert(Alert),
    Msg(MsgCode),
    Watchdog,
    /// A user command 00h..EFh with its parameters (their count is the application's).
    User {
        cmd: u8,
        params: Vec<u8>,
    },
}

/// Why a message cannot be encoded.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum EncodeError {
    #[error("{what} has {len} items; at most {max} fit in one frame")]
    TooLong {
        what: &'static str,
        len: usize,
        max: usize,
    },
    #[error("{what} {value} is out of range {range}")]
    OutOfRange {
        what: &'static str,
        value: u32,
        range: &'static str,
    },
}

/// Why a complete frame's parameters are not a valid message.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ParseError {
    #[error("{name} ({cmd:02X}h): {detail}", name = command_name(*cmd))]
    InvalidParameter { cmd: u8, detail: String },
    #[error("ADCONT checksum {got:02X}h does not match the data ({want:02X}h)")]
    Checksum { got: u8, want: u8 },
}

/// Lengths for [`Message::parse`]'s check of kernel frames, which never asks for these.
struct AnyLength;

impl Lengths for AnyLength {
    fn user_len(&self, _: u8) -> usize {
        0
    }
    fn adcont_len(&self) -> Option<usize> {
        None
    }
}

fn boxed<const N: usize>(s: &[u8]) -> Box<[u8; N]> {
    let mut b = Box::new([0u8; N]);
    b.copy_from_slice(&s[..N]);
    b
}

fn arr<const N: usize>(s: &[u8]) -> [u8; N] {
    let mut b = [0u8; N];
    b.copy_from_slice(&s[..N]);
    b
}

impl Message {
    /// The command byte.
    pub fn command(&self) -> u8 {
        match self {
            Self::Thread(_) => THREAD,
            Self::CpuInfoRequest | Self::CpuInfo(_) => CPUINF,
            Self::Start(_) => START,
            Self::Stop => STOP,
            Self::Power(_) => POWERDOWN,
            Self::FlashReadRequest { .. }
            | Self::FlashData(_)
            | Self::FlashWrite { .. }
            | Self::FlashErase { .. } => PRGFLASH,
            Self::PicReadRequest { .. }
            | Self::PicData(_)
            | Self::PicWrite { .. }
            | Self::EepromReadRequest
            | Self::EepromData(_)
            | Self::EepromWrite(_) => PRGPIC,
            Self::Format(_) => CPUFORMAT,
            Self::Pwm(_) => PWM,
            Self::Bridge(_) => I2CSPI,
            Self::AdCont(_) => ADCONT,
            Self::AdSample(_) => ADSAMPLE,
            Self::CfgAdRequest { .. } | Self::CfgAd { .. } => CFGAD,
            Self::Alert(_) => ALERT,
            Self::Msg(_) => MSG,
            Self::Watchdog => WATCHDOG,
            Self::User { cmd, .. } => *cmd,
        }
    }

    /// Appends the whole frame (command, complement, parameters) to `out`. On error nothing
    /// is appended.
    pub fn encode(&self, out: &mut Vec<u8>) -> Result<(), EncodeError> {
        let mut p = Vec::new();
        self.encode_params(&mut p)?;
        out.extend_from_slice(&header(self.command()));
        out.extend_from_slice(&p);
        Ok(())
    }

    /// The whole frame as a new vector.
    pub fn to_bytes(&self) -> Result<Vec<u8>, EncodeError> {
        let mut v = Vec::new();
        self.encode(&mut v)?;
        Ok(v)
    }

    fn encode_params(&self, p: &mut Vec<u8>) -> Result<(), EncodeError> {
        fn count(what: &'static str, len: usize) -> Result<u8, EncodeError> {
            u8::try_from(len).map_err(|_| EncodeError::TooLong {
                what,
                len,
                max: 255,
            })
        }
        match self {
            Self::Thread(t) => match t {
                Thread::Display {
                    format,
                    newline,
                    data,
                } => {
                    let n = if format.is_word() {
                        if data.len() % 2 != 0 {
                            return Err(EncodeError::OutOfRange {
                                what: "16-bit display byte count",
                                value: data.len() as u32,
                                range: "even numbers",
                            });
                        }
                        count("THREAD display", data.len() / 2)?
                    } else {
                        count("THREAD display", data.len())?
                    };
                    p.extend([format.code() | ((*newline as u8) << 3), n]);
                    p.extend_from_slice(data);
                }
                Thread::Open { mode, name, file } => {
                    let sub = if *mode == FileMode::Read { 0x40 } else { 0x41 };
                    p.extend([sub, count("file name", name.len())?]);
                    p.extend_from_slice(name);
                    p.push(*file);
                }
                Thread::Close { file } => p.extend([0x18, *file]),
                Thread::ReadRequest { len, file } => p.extend([0x10, *len, *file]),
                Thread::Write { data, file } | Thread::ReadData { data, file } => {
                    let sub = if matches!(t, Thread::Write { .. }) {
                        0x20
                    } else {
                        0x30
                    };
                    p.extend([sub, count("file data", data.len())?]);
                    p.extend_from_slice(data);
                    p.push(*file);
                }
            },
            Self::CpuInfoRequest => p.push(0),
            Self::CpuInfo(i) => {
                p.extend([1, i.quartz, i.version_196, i.version_pic, i.pic_revision]);
                p.extend_from_slice(&i.serial);
                p.extend([i.address, i.supply]);
                p.extend_from_slice(&i.compression);
            }
            Self::Start(s) => p.extend(s.0),
            Self::Stop | Self::Watchdog => {}
            Self::Power(pw) => p.push(match pw {
                Power::PowerDown => 0,
                Power::Reset => 1,
                Power::PoweredDown => 2,
                Power::WasReset => 3,
            }),
            Self::FlashReadRequest { bank, block } => p.extend([0, *bank, *block]),
            Self::FlashData(d) => {
                p.push(1);
                p.extend_from_slice(&d[..]);
            }
            Self::FlashWrite { bank, block, data } => {
                p.extend([2, *bank, *block]);
                p.extend_from_slice(&data[..]);
            }
            Self::FlashErase { bank } => p.extend([3, *bank]),
            Self::PicReadRequest { block } => p.extend([0, *block]),
            Self::PicData(d) => {
                p.push(1);
                p.extend_from_slice(&d[..]);
            }
            Self::PicWrite { block, data } => {
                p.extend([2, *block]);
                p.extend_from_slice(&data[..]);
            }
            Self::EepromReadRequest => p.push(3),
            Self::EepromData(d) => {
                p.push(4);
                p.extend_from_slice(&d[..]);
            }
            Self::EepromWrite(d) => {
                p.push(5);
                p.extend_from_slice(&d[..]);
            }
            Self::Format(f) => match f {
                Format::ReadPicKernel { nsc } => {
                    p.push(0);
                    p.extend_from_slice(nsc);
                }
                Format::PicKernel(d) => {
                    p.push(1);
                    p.extend_from_slice(&d[..]);
                }
                Format::WritePicKernel { nsc, data } => {
                    p.push(2);
                    p.extend_from_slice(nsc);
                    p.extend_from_slice(&data[..]);
                }
                Format::NewSerial { nsc, new } => {
                    p.push(3);
                    p.extend_from_slice(nsc);
                    p.extend_from_slice(new);
                }
                Format::ReadBootBlock { block } => p.extend([4, *block]),
                Format::BootBlock(d) => {
                    p.push(5);
                    p.extend_from_slice(&d[..]);
                }
                Format::WriteBootBlock(d) => {
                    p.push(6);
                    p.extend_from_slice(&d[..]);
                }
                Format::EraseBoot => p.push(7),
                Format::CompressionTable { table, comp } => {
                    p.push(8);
                    p.extend_from_slice(&table[..]);
                    p.extend_from_slice(comp);
                }
                Format::Emergency { xy } => p.extend([0x55, 0xAA, *xy]),
            },
            Self::Pwm(Pwm::Set { n, low, value }) => {
                if *n > 3 || *low > 3 {
                    return Err(EncodeError::OutOfRange {
                        what: "PWM number/low bits",
                        value: (*n as u32) << 8 | *low as u32,
                        range: "n 0..3, low 0..3",
                    });
                }
                p.extend([(low << 6) | n, *value]);
            }
            Self::Pwm(Pwm::Dac(v)) => p.extend([0x04, *v]),
            Self::Bridge(b) => match *b {
                Bridge::SpiReceived(x) => p.extend([0, x]),
                Bridge::SpiSend(x) => p.extend([1, x]),
                Bridge::SciReceived(x) => p.extend([2, x]),
                Bridge::SciSend(x) => p.extend([3, x]),
                Bridge::ParallelRead(x) => p.extend([4, x]),
                Bridge::ParallelWrite(x) => p.extend([5, x]),
                Bridge::ParallelAddress(x) => p.extend([6, x]),
                Bridge::ParallelReadRequest => p.push(7),
            },
            Self::AdCont(data) => {
                if !(2..=256).contains(&data.len()) {
                    return Err(EncodeError::OutOfRange {
                        what: "ADCONT data length",
                        value: data.len() as u32,
                        range: "2..=256",
                    });
                }
                p.extend_from_slice(data);
                p.push(checksum(data));
            }
            Self::AdSample(s) => match *s {
                AdSample::Pic { channel, value } => {
                    if channel > 7 || value > 0x3FF {
                        return Err(EncodeError::OutOfRange {
                            what: "PIC sample (channel, value)",
                            value: value as u32,
                            range: "channel 0..7, value 0..1023",
                        });
                    }
                    p.extend([((value as u8 & 3) << 3) | channel, (value >> 2) as u8]);
                }
                AdSample::Virtual { channel, value } => {
                    if channel > 7 || value > 0xFFF {
                        return Err(EncodeError::OutOfRange {
                            what: "virtual sample (channel, value)",
                            value: value as u32,
                            range: "channel 0..7, value 0..4095",
                        });
                    }
                    p.extend([
                        0x80 | ((value as u8 & 0xF) << 3) | channel,
                        (value >> 4) as u8,
                    ]);
                }
            },
            Self::CfgAdRequest { bank, config } => {
                if *bank > 7 || *config > 7 {
                    return Err(EncodeError::OutOfRange {
                        what: "CFGAD bank/config",
                        value: (*bank as u32) << 8 | *config as u32,
                        range: "0..7 each",
                    });
                }
                p.extend([0, (bank << 3) | config]);
            }
            Self::CfgAd { c196, pic } => {
                p.push(1);
                p.extend_from_slice(c196);
                p.extend_from_slice(pic);
            }
            Self::Alert(a) => p.push(a.0),
            Self::Msg(m) => p.push(m.0),
            Self::User { params, .. } => p.extend_from_slice(params),
        }
        Ok(())
    }

    /// Builds the message from a complete frame's parameters (as delimited by
    /// [`wire::params_len`]); a slice of another length is refused.
    pub fn parse(cmd: u8, p: &[u8]) -> Result<Self, ParseError> {
        let bad = |detail: String| ParseError::InvalidParameter { cmd, detail };
        if cmd <= USER_MAX {
            return Ok(Self::User {
                cmd,
                params: p.to_vec(),
            });
        }
        let want = match cmd {
            // Any length the acquisition layout gives, plus the checksum.
            ADCONT => (!p.is_empty()).then_some(p.len()),
            _ => wire::params_len(cmd, p, &AnyLength).map_err(|e| bad(e.to_string()))?,
        };
        if want != Some(p.len()) {
            return Err(bad(match want {
                Some(n) => format!("{} parameter bytes, the frame has {n}", p.len()),
                None => format!("{} parameter bytes do not make a whole frame", p.len()),
            }));
        }
        Ok(match cmd {
            STOP => Self::Stop,
            WATCHDOG => Self::Watchdog,
            ALERT => Self::Alert(Alert(p[0])),
            MSG => Self::Msg(MsgCode(p[0])),
            START => Self::Start(Start([p[0], p[1]])),
            PWM => match p[0] {
                0x04 => Self::Pwm(Pwm::Dac(p[1])),
                c if c & 0x3C == 0 => Self::Pwm(Pwm::Set {
                    n: c & 3,
                    low: c >> 6,
                    value: p[1],
                }),
                c => {
                    return Err(bad(format!(
                        "control byte {c:02X}h is neither vv0000nn nor 04h"
                    )));
                }
            },
            ADSAMPLE => {
                let (c, d) = (p[0], p[1] as u16);
                if c & 0x80 != 0 {
                    Self::AdSample(AdSample::Virtual {
                        channel: c & 7,
                        value: (d << 4) | ((c >> 3) & 0xF) as u16,
                    })
                } else if c & 0x60 == 0 {
                    Self::AdSample(AdSample::Pic {
                        channel: c & 7,
                        value: (d << 2) | ((c >> 3) & 3) as u16,
                    })
                } else {
                    return Err(bad(format!(
                        "channel byte {c:02X}h is neither 000xxnnn nor 1xxxxnnn"
                    )));
                }
            }
            ADCONT => {
                let (data, sum) = p.split_at(p.len() - 1);
                let want = checksum(data);
                if sum[0] != want {
                    return Err(ParseError::Checksum { got: sum[0], want });
                }
                Self::AdCont(data.to_vec())
            }
            _ => Self::parse_sub(cmd, p[0], &p[1..]).map_err(bad)?,
        })
    }

    fn parse_sub(cmd: u8, sub: u8, q: &[u8]) -> Result<Self, String> {
        Ok(match (cmd, sub) {
            (THREAD, 0x10) => Self::Thread(Thread::ReadRequest {
                len: q[0],
                file: q[1],
            }),
            (THREAD, 0x18) => Self::Thread(Thread::Close { file: q[0] }),
            (THREAD, 0x40 | 0x41) => Self::Thread(Thread::Open {
                mode: if sub == 0x40 {
                    FileMode::Read
                } else {
                    FileMode::Write
                },
                name: q[1..q.len() - 1].to_vec(),
                file: q[q.len() - 1],
            }),
            (THREAD, 0x20 | 0x30) => {
                let data = q[1..q.len() - 1].to_vec();
                let file = q[q.len() - 1];
                Self::Thread(if sub == 0x20 {
                    Thread::Write { data, file }
                } else {
                    Thread::ReadData { data, file }
                })
            }
            (THREAD, s) => Self::Thread(Thread::Display {
                format: DisplayFormat::from_code(s).ok_or("no display format 1")?,
                newline: s & 8 != 0,
                data: q[1..].to_vec(),
            }),
            (CPUINF, 0) => Self::CpuInfoRequest,
            (CPUINF, _) => Self::CpuInfo(CpuInfo {
                quartz: q[0],
                version_196: q[1],
                version_pic: q[2],
                pic_revision: q[3],
                serial: arr(&q[4..12]),
                address: q[12],
                supply: q[13],
                compression: arr(&q[14..22]),
            }),
            (POWERDOWN, s) => Self::Power(match s {
                0 => Power::PowerDown,
                1 => Power::Reset,
                2 => Power::PoweredDown,
                _ => Power::WasReset,
            }),
            (PRGFLASH, 0) => Self::FlashReadRequest {
                bank: q[0],
                block: q[1],
            },
            (PRGFLASH, 1) => Self::FlashData(boxed(q)),
            (PRGFLASH, 2) => Self::FlashWrite {
                bank: q[0],
                block: q[1],
                data: boxed(&q[2..]),
            },
            (PRGFLASH, _) => Self::FlashErase { bank: q[0] },
            (PRGPIC, 0) => Self::PicReadRequest { block: q[0] },
            (PRGPIC, 1) => Self::PicData(boxed(q)),
            (PRGPIC, 2) => Self::PicWrite {
                block: q[0],
                data: boxed(&q[1..]),
            },
            (PRGPIC, 3) => Self::EepromReadRequest,
            (PRGPIC, 4) => Self::EepromData(boxed(q)),
            (PRGPIC, _) => Self::EepromWrite(boxed(q)),
            (CPUFORMAT, s) => Self::Format(match s {
                0 => Format::ReadPicKernel { nsc: arr(q) },
                1 => Format::PicKernel(boxed(q)),
                2 => Format::WritePicKernel {
                    nsc: arr(q),
                    data: boxed(&q[8..]),
                },
                3 => Format::NewSerial {
                    nsc: arr(q),
                    new: arr(&q[8..]),
                },
                4 => Format::ReadBootBlock { block: q[0] },
                5 => Format::BootBlock(boxed(q)),
                6 => Format::WriteBootBlock(boxed(q)),
                7 => Format::EraseBoot,
                8 => Format::CompressionTable {
                    table: boxed(q),
                    comp: arr(&q[LOG_TABLE..]),
                },
                _ => {
                    if q[0] != 0xAA {
                        return Err(format!("emergency erase needs 55 AA, got 55 {:02X}", q[0]));
                    }
                    Format::Emergency { xy: q[1] }
                }
            }),
            (I2CSPI, s) => Self::Bridge(match s {
                0 => Bridge::SpiReceived(q[0]),
                1 => Bridge::SpiSend(q[0]),
                2 => Bridge::SciReceived(q[0]),
                3 => Bridge::SciSend(q[0]),
                4 => Bridge::ParallelRead(q[0]),
                5 => Bridge::ParallelWrite(q[0]),
                6 => Bridge::ParallelAddress(q[0]),
                _ => Bridge::ParallelReadRequest,
            }),
            (CFGAD, 0) => {
                if q[0] & 0xC0 != 0 {
                    return Err(format!("bank/config byte {:02X}h must be 00bbbnnn", q[0]));
                }
                Self::CfgAdRequest {
                    bank: (q[0] >> 3) & 7,
                    config: q[0] & 7,
                }
            }
            (CFGAD, _) => Self::CfgAd {
                c196: arr(q),
                pic: arr(&q[18..]),
            },
            _ => return Err(format!("no sub-command {sub:02X}h")),
        })
    }
}

/// One line describing a message for logs and the CLI (long payloads are cut at 120
/// characters).
pub fn describe(m: &Message) -> String {
    match m {
        Message::Msg(c) => format!("MSG {c}"),
        Message::Alert(a) => format!("ALERTE {a}"),
        Message::User { cmd, params } => {
            let bytes: Vec<String> = params.iter().map(|b| format!("{b:02X}")).collect();
            format!("user command {cmd:02X}h [{}]", bytes.join(" "))
        }
        Message::Thread(Thread::Display { format, data, .. }) => {
            format!("THREAD {}", format.render(data))
        }
        other => {
            let text = format!("{} {:?}", wire::command_name(other.command()), other);
            match text.char_indices().nth(120) {
                Some((cut, _)) => format!("{}…", &text[..cut]),
                None => text,
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn board_text_shows_control_characters_visibly() {
        // A board's THREAD text reached the terminal raw: `\x1B[2J` cleared the user's screen.
        let text = DisplayFormat::Text.render(b"ok\x1B[2J\r\n\x7F\xC2\x9B\xFF!");
        assert_eq!(text, "ok\\x1B[2J\\x0D\\x0A\\x7F\\u{9B}\u{FFFD}!");
        assert!(!text.chars().any(char::is_control));
    }

    #[test]
    fn parse_refuses_wrong_lengths_instead_of_panicking() {
        for cmd in 0xF0..=0xFF {
            for sub in 0..=255u8 {
                for len in [0, 1, 2, 3, 4, 5, 9, 17, 22, 23, 24, 257, 300, 4098] {
                    let mut p = vec![0u8; len];
                    if let Some(first) = p.first_mut() {
                        *first = sub;
                    }
                    let _ = Message::parse(cmd, &p);
                }
            }
        }
        assert_eq!(
            Message::parse(MSG, &[]).unwrap_err().to_string(),
            "MSG (FEh): 0 parameter bytes, the frame has 1"
        );
        assert!(Message::parse(ADCONT, &[]).is_err());
        assert!(Message::parse(PRGFLASH, &[0x02, 0, 0x28]).is_err());
        // The right length still parses.
        assert_eq!(
            Message::parse(MSG, &[3]),
            Ok(Message::Msg(MsgCode::COMPLETED))
        );
    }

    #[test]
    fn describe_is_one_bounded_line() {
        assert_eq!(
            describe(&Message::User {
                cmd: 0x10,
                params: vec![1, 0x2C]
            }),
            "user command 10h [01 2C]"
        );
        assert_eq!(
            describe(&Message::Msg(MsgCode::COMPLETED)),
            "MSG msg_completed (03h)"
        );
        let long = describe(&Message::FlashData(Box::new([0xAB; 256])));
        assert!(
            long.starts_with("PRGFLASH FlashData") && long.ends_with('…'),
            "{long}"
        );
        assert_eq!(long.chars().count(), 121);
        let words = Message::Thread(Thread::Display {
            format: DisplayFormat::Signed16,
            newline: true,
            data: vec![0xFF, 0xFF, 0x02, 0x00],
        });
        assert_eq!(describe(&words), "THREAD -1 2");
    }
}
