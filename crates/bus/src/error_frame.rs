//! SocketCAN error frames (`linux/can/error.h`) as typed values: decoded from the error class
//! (the CAN ID's low bits) and the 8 data bytes, encoded back, and put in can-utils' words.
//!
//! An error frame can carry several classes at once (Linux's SJA1000 driver reports a bus error
//! as protocol violation + bus error, `0x088`), so an [`ErrorFrame`] is a list of
//! [`CanError`]s plus the error counters. socketcand's raw mode sends the class alone
//! (`< error 088 SEC.USEC >`): the details are then "unspecified" (zero bytes), as in a
//! SocketCAN frame whose driver knows nothing more.
//!
//! A frame decoded from bytes encodes back to the same bytes, whatever they hold: the bytes no
//! class gives a meaning (`data[5]`, details without their class bit), counters without the
//! counters class (older kernels) and a data length other than 8 are kept beside the typed
//! fields. A log converter must not rewrite what it read (`20000088#…` with counters stays
//! `20000088#…`, not `20000288#…`).

use std::fmt;

use crate::state::ControllerState;

/// The class bits of an error frame's CAN ID (`CAN_ERR_*` in `linux/can/error.h`).
pub mod class {
    /// TX timeout (by the network device driver).
    pub const TX_TIMEOUT: u32 = 0x001;
    /// Lost arbitration; data\[0\] = the bit.
    pub const LOST_ARBITRATION: u32 = 0x002;
    /// Controller problems; data\[1\].
    pub const CONTROLLER: u32 = 0x004;
    /// Protocol violations; data\[2\] = type, data\[3\] = location.
    pub const PROTOCOL: u32 = 0x008;
    /// Transceiver status; data\[4\].
    pub const TRANSCEIVER: u32 = 0x010;
    /// No ACK on transmission.
    pub const NO_ACK: u32 = 0x020;
    pub const BUS_OFF: u32 = 0x040;
    /// Bus error (may flood).
    pub const BUS_ERROR: u32 = 0x080;
    /// The controller restarted (after bus-off).
    pub const RESTARTED: u32 = 0x100;
    /// data\[6\] = TX error counter, data\[7\] = RX error counter.
    pub const COUNTERS: u32 = 0x200;
    /// Every class this module knows.
    pub const KNOWN: u32 = 0x3FF;
}

/// The error flag of a SocketCAN CAN ID (`CAN_ERR_FLAG`): set in the ID of every error frame
/// (candump logs write error frames as `20000088#…`).
pub const ERROR_FLAG: u32 = 0x2000_0000;

/// Why bytes are not an error frame.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ErrorFrameError {
    #[error("an error frame has at most 8 data bytes, not {0}")]
    TooLong(usize),
    #[error("error class 0x{0:X} is wider than a 29-bit CAN ID")]
    ClassTooWide(u32),
}

/// One error frame: what went wrong (one entry per class bit, in class-bit order) and the
/// error counters when the frame carries them.
#[derive(Clone, Debug, Default, PartialEq, Eq, Hash)]
pub struct ErrorFrame {
    pub errors: Vec<CanError>,
    /// TXERR/RXERR in data\[6\]/data\[7\]: with the `COUNTERS` class, or (older kernels)
    /// whenever either byte is not zero.
    pub counters: Option<ErrorCounters>,
    /// What the bytes it was decoded from held beyond `errors` and `counters`.
    unexplained: Unexplained,
}

/// The parts of a decoded frame its typed fields do not carry, kept so that the frame encodes
/// back to the bytes it came from. All zero (the default) for a frame built from its fields.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
struct Unexplained {
    /// Data bytes at positions no class of the frame gives a meaning (always data\[5\];
    /// data\[0\] without lost arbitration, data\[1\] without controller problems, …).
    bytes: [u8; 8],
    /// The counters were in data\[6..8\] without the `COUNTERS` class.
    counters_without_class: bool,
    /// The data length, when it was not 8 (Linux's `CAN_ERR_DLC`).
    short: Option<u8>,
}

/// The data bytes a class gives a meaning, one bit per byte.
fn claimed_bytes(class: u32, counters: bool) -> u8 {
    let mut mask = 0u8;
    if class & class::LOST_ARBITRATION != 0 {
        mask |= 0b0000_0001;
    }
    if class & class::CONTROLLER != 0 {
        mask |= 0b0000_0010;
    }
    if class & class::PROTOCOL != 0 {
        mask |= 0b0000_1100;
    }
    if class & class::TRANSCEIVER != 0 {
        mask |= 0b0001_0000;
    }
    if counters {
        mask |= 0b1100_0000;
    }
    mask
}

/// A bus error as a controller's error-code capture tells it, in SocketCAN's terms: what was
/// violated (with the direction) and where in the frame. The input of
/// [`ErrorFrame::sja1000_bus_error`]; a driver converts its own register into it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct CapturedBusError {
    pub violation: ProtocolViolation,
    pub location: ProtocolLocation,
}

/// The bit of a frame at which arbitration was lost (0 = the first bit after SOF), as
/// data\[0\] of a lost-arbitration frame carries it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct ArbitrationBit(pub u8);

/// TXERR and RXERR as an error frame carries them.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct ErrorCounters {
    pub tx: u8,
    pub rx: u8,
}

/// One error class with the data bytes that belong to it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum CanError {
    /// The driver gave up a transmission (`0x001`).
    TxTimeout,
    /// Arbitration lost at this bit of the frame (`0x002`; data\[0\]: the bit number, 0 also
    /// meaning "unspecified" as Linux cannot tell them apart).
    LostArbitration { bit: u8 },
    /// Controller problems (`0x004`): overflows, warning/passive levels, back to active.
    Controller(ControllerProblems),
    /// A protocol violation (`0x008`): what kind and where in the frame.
    Protocol {
        violation: ProtocolViolation,
        location: ProtocolLocation,
    },
    /// The transceiver reports a wiring problem (`0x010`).
    Transceiver(TransceiverStatus),
    /// Nobody acknowledged a transmitted frame (`0x020`).
    NoAck,
    /// The controller went bus-off (`0x040`).
    BusOff,
    /// A bus error (`0x080`); Linux reports it with a protocol violation.
    BusError,
    /// The controller restarted after bus-off (`0x100`).
    Restarted,
    /// Class bits this module does not know, kept so encoding gives them back.
    Unknown(u32),
}

impl CanError {
    /// The class bit(s) of this error.
    pub const fn class(self) -> u32 {
        match self {
            CanError::TxTimeout => class::TX_TIMEOUT,
            CanError::LostArbitration { .. } => class::LOST_ARBITRATION,
            CanError::Controller(_) => class::CONTROLLER,
            CanError::Protocol { .. } => class::PROTOCOL,
            CanError::Transceiver(_) => class::TRANSCEIVER,
            CanError::NoAck => class::NO_ACK,
            CanError::BusOff => class::BUS_OFF,
            CanError::BusError => class::BUS_ERROR,
            CanError::Restarted => class::RESTARTED,
            CanError::Unknown(bits) => bits,
        }
    }
}

/// Generates a set of flags in one data byte with can-utils' names.
macro_rules! flag_byte {
    ($(#[$doc:meta])* $name:ident { $($(#[$fdoc:meta])* $flag:ident = $bit:expr, $word:expr;)* }) => {
        $(#[$doc])*
        #[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
        pub struct $name(pub u8);

        impl $name {
            $($(#[$fdoc])* pub const $flag: u8 = $bit;)*
            const WORDS: &'static [(u8, &'static str)] = &[$(($bit, $word)),*];

            pub const fn contains(self, flag: u8) -> bool {
                self.0 & flag == flag
            }

            /// The flags that are set, in can-utils' words (unknown bits are left out).
            pub fn words(self) -> impl Iterator<Item = &'static str> {
                Self::WORDS
                    .iter()
                    .filter(move |(bit, _)| self.0 & bit != 0)
                    .map(|(_, word)| *word)
            }
        }

        /// The flags' words joined by `,` (empty when none is set).
        impl fmt::Display for $name {
            fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                for (i, word) in self.words().enumerate() {
                    if i > 0 {
                        f.write_str(",")?;
                    }
                    f.write_str(word)?;
                }
                Ok(())
            }
        }
    };
}

flag_byte! {
    /// data\[1\] of a controller-problem frame (`CAN_ERR_CRTL_*`).
    ControllerProblems {
        RX_OVERFLOW = 0x01, "rx-overflow";
        TX_OVERFLOW = 0x02, "tx-overflow";
        RX_WARNING = 0x04, "rx-error-warning";
        TX_WARNING = 0x08, "tx-error-warning";
        RX_PASSIVE = 0x10, "rx-error-passive";
        TX_PASSIVE = 0x20, "tx-error-passive";
        /// Recovered to error-active.
        ACTIVE = 0x40, "back-to-error-active";
    }
}

flag_byte! {
    /// data\[2\] of a protocol-violation frame (`CAN_ERR_PROT_*`).
    ProtocolViolation {
        BIT = 0x01, "single-bit-error";
        FORM = 0x02, "frame-format-error";
        STUFF = 0x04, "bit-stuffing-error";
        /// Unable to send a dominant bit.
        BIT0 = 0x08, "tx-dominant-bit-error";
        /// Unable to send a recessive bit.
        BIT1 = 0x10, "tx-recessive-bit-error";
        OVERLOAD = 0x20, "bus-overload";
        /// Active error announcement.
        ACTIVE = 0x40, "active-error";
        /// The error occurred while transmitting.
        TX = 0x80, "error-on-tx";
    }
}

/// data\[3\] of a protocol-violation frame: where in the frame (`CAN_ERR_PROT_LOC_*`, which
/// are the SJA1000's ECC segment codes).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ProtocolLocation {
    Unspecified,
    StartOfFrame,
    /// ID bits 28..21 (standard frames: 10..3).
    Id28To21,
    /// ID bits 20..18 (standard frames: 2..0).
    Id20To18,
    /// Substitute RTR (standard frames: RTR).
    SubstituteRtr,
    IdExtension,
    Id17To13,
    Id12To5,
    Id4To0,
    Rtr,
    ReservedBit1,
    ReservedBit0,
    DataLengthCode,
    DataField,
    CrcSequence,
    CrcDelimiter,
    AckSlot,
    AckDelimiter,
    EndOfFrame,
    Intermission,
    /// SJA1000 codes Linux passes on unchanged.
    ActiveErrorFlag,
    ToleratedDominantBits,
    PassiveErrorFlag,
    ErrorDelimiter,
    OverloadFlag,
    /// A code neither `error.h` nor the SJA1000 defines.
    Other(u8),
}

/// (code, location, can-utils' word)
const LOCATIONS: &[(u8, ProtocolLocation, &str)] = &[
    (0x00, ProtocolLocation::Unspecified, "unspecified"),
    (0x03, ProtocolLocation::StartOfFrame, "start-of-frame"),
    (0x02, ProtocolLocation::Id28To21, "id.28-to-id.21"),
    (0x06, ProtocolLocation::Id20To18, "id.20-to-id.18"),
    (0x04, ProtocolLocation::SubstituteRtr, "bit-srtr"),
    (0x05, ProtocolLocation::IdExtension, "bit-ide"),
    (0x07, ProtocolLocation::Id17To13, "id.17-to-id.13"),
    (0x0F, ProtocolLocation::Id12To5, "id.12-to-id.5"),
    (0x0E, ProtocolLocation::Id4To0, "id.4-to-id.0"),
    (0x0C, ProtocolLocation::Rtr, "bit-rtr"),
    (0x0D, ProtocolLocation::ReservedBit1, "reserved-bit-1"),
    (0x09, ProtocolLocation::ReservedBit0, "reserved-bit-0"),
    (0x0B, ProtocolLocation::DataLengthCode, "data-length-code"),
    (0x0A, ProtocolLocation::DataField, "data-field"),
    (0x08, ProtocolLocation::CrcSequence, "crc-sequence"),
    (0x18, ProtocolLocation::CrcDelimiter, "crc-delimiter"),
    (0x19, ProtocolLocation::AckSlot, "acknowledge-slot"),
    (
        0x1B,
        ProtocolLocation::AckDelimiter,
        "acknowledge-delimiter",
    ),
    (0x1A, ProtocolLocation::EndOfFrame, "end-of-frame"),
    (0x12, ProtocolLocation::Intermission, "intermission"),
    (0x11, ProtocolLocation::ActiveErrorFlag, "active-error-flag"),
    (
        0x13,
        ProtocolLocation::ToleratedDominantBits,
        "tolerate-dominant-bits",
    ),
    (
        0x16,
        ProtocolLocation::PassiveErrorFlag,
        "passive-error-flag",
    ),
    (0x17, ProtocolLocation::ErrorDelimiter, "error-delimiter"),
    (0x1C, ProtocolLocation::OverloadFlag, "overload-flag"),
];

impl ProtocolLocation {
    pub fn from_code(code: u8) -> Self {
        LOCATIONS
            .iter()
            .find(|(c, _, _)| *c == code)
            .map_or(ProtocolLocation::Other(code), |(_, l, _)| *l)
    }

    pub fn code(self) -> u8 {
        match self {
            ProtocolLocation::Other(code) => code,
            known => LOCATIONS
                .iter()
                .find(|(_, l, _)| *l == known)
                .map_or(0, |(c, _, _)| *c),
        }
    }

    /// can-utils' word for the location; candump prints nothing for code 0 and for codes of
    /// 32 and above, "unspecified" for the other unknown ones.
    pub fn candump_word(self) -> &'static str {
        match self {
            ProtocolLocation::Unspecified => "",
            ProtocolLocation::Other(code) if code >= 32 => "",
            ProtocolLocation::Other(_) => "unspecified",
            known => LOCATIONS
                .iter()
                .find(|(_, l, _)| *l == known)
                .map_or("", |(_, _, w)| *w),
        }
    }
}

/// data\[4\] of a transceiver frame: CANH in the low nibble, CANL in the high one
/// (`CAN_ERR_TRX_*`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum TransceiverStatus {
    Unspecified,
    CanHNoWire,
    CanHShortToBattery,
    CanHShortToVcc,
    CanHShortToGround,
    CanLNoWire,
    CanLShortToBattery,
    CanLShortToVcc,
    CanLShortToGround,
    CanLShortToCanH,
    Other(u8),
}

const TRANSCEIVER: &[(u8, TransceiverStatus, &str)] = &[
    (0x00, TransceiverStatus::Unspecified, "unspecified"),
    (0x04, TransceiverStatus::CanHNoWire, "CANH no wire"),
    (
        0x05,
        TransceiverStatus::CanHShortToBattery,
        "CANH short to battery",
    ),
    (0x06, TransceiverStatus::CanHShortToVcc, "CANH short to VCC"),
    (
        0x07,
        TransceiverStatus::CanHShortToGround,
        "CANH short to ground",
    ),
    (0x40, TransceiverStatus::CanLNoWire, "CANL no wire"),
    (
        0x50,
        TransceiverStatus::CanLShortToBattery,
        "CANL short to battery",
    ),
    (0x60, TransceiverStatus::CanLShortToVcc, "CANL short to VCC"),
    (
        0x70,
        TransceiverStatus::CanLShortToGround,
        "CANL short to ground",
    ),
    (
        0x80,
        TransceiverStatus::CanLShortToCanH,
        "CANL short to CANH",
    ),
];

impl TransceiverStatus {
    pub fn from_code(code: u8) -> Self {
        TRANSCEIVER
            .iter()
            .find(|(c, _, _)| *c == code)
            .map_or(TransceiverStatus::Other(code), |(_, t, _)| *t)
    }

    pub fn code(self) -> u8 {
        match self {
            TransceiverStatus::Other(code) => code,
            known => TRANSCEIVER
                .iter()
                .find(|(_, t, _)| *t == known)
                .map_or(0, |(c, _, _)| *c),
        }
    }
}

impl fmt::Display for TransceiverStatus {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            TransceiverStatus::Other(code) => write!(f, "transceiver code 0x{code:02X}"),
            known => f.write_str(
                TRANSCEIVER
                    .iter()
                    .find(|(_, t, _)| t == known)
                    .map_or("", |(_, _, w)| *w),
            ),
        }
    }
}

impl ErrorFrame {
    /// A frame from its typed parts (encoded with 8 data bytes, as Linux sends them).
    pub fn new(errors: Vec<CanError>, counters: Option<ErrorCounters>) -> Self {
        Self {
            errors,
            counters,
            unexplained: Unexplained::default(),
        }
    }

    /// Decodes an error frame from its class (the CAN ID; the error flag and bits above 29
    /// are ignored only if they are the flag) and up to 8 data bytes (the details read missing
    /// bytes as 0). [`encode`](Self::encode) and [`data_len`](Self::data_len) give back the
    /// same class, bytes and length.
    pub fn decode(id: u32, data: &[u8]) -> Result<Self, ErrorFrameError> {
        let class = id & !ERROR_FLAG;
        if class > 0x1FFF_FFFF {
            return Err(ErrorFrameError::ClassTooWide(id));
        }
        if data.len() > 8 {
            return Err(ErrorFrameError::TooLong(data.len()));
        }
        let mut d = [0u8; 8];
        d[..data.len()].copy_from_slice(data);
        let mut errors = Vec::new();
        for bit in 0..9 {
            let error = match (class & (1 << bit)) != 0 {
                false => continue,
                true => match 1 << bit {
                    class::TX_TIMEOUT => CanError::TxTimeout,
                    class::LOST_ARBITRATION => CanError::LostArbitration { bit: d[0] },
                    class::CONTROLLER => CanError::Controller(ControllerProblems(d[1])),
                    class::PROTOCOL => CanError::Protocol {
                        violation: ProtocolViolation(d[2]),
                        location: ProtocolLocation::from_code(d[3]),
                    },
                    class::TRANSCEIVER => CanError::Transceiver(TransceiverStatus::from_code(d[4])),
                    class::NO_ACK => CanError::NoAck,
                    class::BUS_OFF => CanError::BusOff,
                    class::BUS_ERROR => CanError::BusError,
                    _ => CanError::Restarted,
                },
            };
            errors.push(error);
        }
        let unknown = class & !class::KNOWN;
        if unknown != 0 {
            errors.push(CanError::Unknown(unknown));
        }
        let counters = (class & class::COUNTERS != 0 || d[6] != 0 || d[7] != 0)
            .then_some(ErrorCounters { tx: d[6], rx: d[7] });
        let claimed = claimed_bytes(class, counters.is_some());
        let mut bytes = [0u8; 8];
        for (i, (out, b)) in bytes.iter_mut().zip(d).enumerate() {
            if claimed & (1 << i) == 0 {
                *out = b;
            }
        }
        let unexplained = Unexplained {
            bytes,
            counters_without_class: counters.is_some() && class & class::COUNTERS == 0,
            short: (data.len() < 8).then_some(data.len() as u8),
        };
        Ok(Self {
            errors,
            counters,
            unexplained,
        })
    }

    /// The class (without the error flag) and the 8 data bytes (the first
    /// [`data_len`](Self::data_len) of them are the frame's). Counters set the `COUNTERS`
    /// class, unless the frame was decoded from counters without it; the bytes no class
    /// explains are the decoded frame's (0 for a frame built from its fields).
    pub fn encode(&self) -> (u32, [u8; 8]) {
        let mut class = 0;
        let mut d = [0u8; 8];
        for e in &self.errors {
            class |= e.class();
            match *e {
                CanError::LostArbitration { bit } => d[0] = bit,
                CanError::Controller(p) => d[1] |= p.0,
                CanError::Protocol {
                    violation,
                    location,
                } => {
                    d[2] |= violation.0;
                    d[3] = location.code();
                }
                CanError::Transceiver(t) => d[4] = t.code(),
                _ => {}
            }
        }
        let claimed = claimed_bytes(class, self.counters.is_some());
        if let Some(c) = self.counters {
            if !self.unexplained.counters_without_class {
                class |= class::COUNTERS;
            }
            d[6] = c.tx;
            d[7] = c.rx;
        }
        for (i, (out, b)) in d.iter_mut().zip(self.unexplained.bytes).enumerate() {
            if claimed & (1 << i) == 0 {
                *out = b;
            }
        }
        (class & 0x1FFF_FFFF, d)
    }

    /// How many data bytes the frame has: 8 (`CAN_ERR_DLC`), or the number it was decoded
    /// from (never fewer than its last non-zero byte needs).
    pub fn data_len(&self) -> usize {
        let Some(short) = self.unexplained.short else {
            return 8;
        };
        let (_, d) = self.encode();
        let needed = d.iter().rposition(|&b| b != 0).map_or(0, |i| i + 1);
        usize::from(short).max(needed)
    }

    /// The SocketCAN CAN ID: the class with the error flag.
    pub fn can_id(&self) -> u32 {
        ERROR_FLAG | self.encode().0
    }

    /// The class bits (without the error flag).
    pub fn class(&self) -> u32 {
        self.encode().0
    }

    /// The classes and details in can-utils' words, separated by `sep` (candump `-e` uses a
    /// new line and a tab; `,` is the default of its library):
    /// `protocol-violation{{single-bit-error,error-on-tx}{data-field}},bus-error`.
    pub fn describe(&self, sep: &str) -> String {
        let mut parts: Vec<String> = Vec::new();
        for e in &self.errors {
            parts.push(match e {
                CanError::TxTimeout => "tx-timeout".into(),
                CanError::LostArbitration { bit } => format!("lost-arbitration{{at bit {bit}}}"),
                CanError::Controller(p) => format!("controller-problem{{{p}}}"),
                CanError::Protocol {
                    violation,
                    location,
                } => format!(
                    "protocol-violation{{{{{violation}}}{{{}}}}}",
                    location.candump_word()
                ),
                CanError::Transceiver(_) => "transceiver-status".into(),
                CanError::NoAck => "no-acknowledgement-on-tx".into(),
                CanError::BusOff => "bus-off".into(),
                CanError::BusError => "bus-error".into(),
                CanError::Restarted => "restarted-after-bus-off".into(),
                CanError::Unknown(bits) => format!("unknown-class-0x{bits:X}"),
            });
        }
        if let Some(c) = self.counters {
            parts.push(format!("error-counter-tx-rx{{{{{}}}{{{}}}}}", c.tx, c.rx));
        }
        parts.join(sep)
    }

    /// Linux's SJA1000 driver's frame for a bus error (IR.BEI): protocol violation + bus
    /// error, the captured kind and direction as the type, the segment as the location. The
    /// SJA1000 driver (`buslab-canbus`) turns its ECC into a [`CapturedBusError`].
    pub fn sja1000_bus_error(
        capture: impl Into<CapturedBusError>,
        counters: Option<ErrorCounters>,
    ) -> Self {
        let CapturedBusError {
            violation,
            location,
        } = capture.into();
        Self::new(
            vec![
                CanError::Protocol {
                    violation,
                    location,
                },
                CanError::BusError,
            ],
            counters,
        )
    }

    /// Linux's SJA1000 driver's frame for a lost arbitration (IR.ALI): the ALC bit.
    pub fn sja1000_arbitration_lost(
        bit: impl Into<ArbitrationBit>,
        counters: Option<ErrorCounters>,
    ) -> Self {
        Self::new(
            vec![CanError::LostArbitration { bit: bit.into().0 }],
            counters,
        )
    }

    /// Linux's frame for an error-state change (`can_change_state`): bus-off, or a
    /// controller problem naming the side (TX, RX or both) whose counter is the higher one.
    pub fn state_change(to: ControllerState, counters: ErrorCounters) -> Self {
        let (tx_side, rx_side) = (counters.tx >= counters.rx, counters.rx >= counters.tx);
        let side = |tx: u8, rx: u8| (if tx_side { tx } else { 0 }) | (if rx_side { rx } else { 0 });
        let problems = match to {
            ControllerState::BusOff => {
                return Self::new(vec![CanError::BusOff], Some(counters));
            }
            ControllerState::Active => ControllerProblems::ACTIVE,
            ControllerState::Warning => side(
                ControllerProblems::TX_WARNING,
                ControllerProblems::RX_WARNING,
            ),
            ControllerState::Passive => side(
                ControllerProblems::TX_PASSIVE,
                ControllerProblems::RX_PASSIVE,
            ),
        };
        Self::new(
            vec![CanError::Controller(ControllerProblems(problems))],
            Some(counters),
        )
    }

    /// The frame Linux sends when a controller restarted after bus-off.
    pub fn restarted() -> Self {
        Self::new(vec![CanError::Restarted], None)
    }
}

/// can-utils' words separated by `,`: `protocol-violation{{}{}},bus-error`.
impl fmt::Display for ErrorFrame {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.describe(","))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn a_class_alone_decodes_with_unspecified_details() {
        // What socketcand's raw mode and buslab's server send for a bus error.
        let e = ErrorFrame::decode(0x088, &[]).unwrap();
        assert_eq!(
            e.errors,
            [
                CanError::Protocol {
                    violation: ProtocolViolation(0),
                    location: ProtocolLocation::Unspecified
                },
                CanError::BusError
            ]
        );
        assert_eq!(e.counters, None);
        assert_eq!(e.to_string(), "protocol-violation{{}{}},bus-error");
        assert_eq!(e.can_id(), 0x2000_0088);
    }

    #[test]
    fn details_print_in_can_utils_words() {
        let e = ErrorFrame::decode(
            ERROR_FLAG | 0x2 | 0x4 | 0x8 | 0x200,
            &[0x0A, 0x0C, 0x81, 0x0A, 0, 0, 96, 3],
        )
        .unwrap();
        assert_eq!(
            e.describe("\n\t"),
            "lost-arbitration{at bit 10}\n\t\
             controller-problem{rx-error-warning,tx-error-warning}\n\t\
             protocol-violation{{single-bit-error,error-on-tx}{data-field}}\n\t\
             error-counter-tx-rx{{96}{3}}"
        );
        // Older kernels put counters in data[6..8] without the class: shown all the same.
        let old = ErrorFrame::decode(0x040, &[0, 0, 0, 0, 0, 0, 255, 0]).unwrap();
        assert_eq!(old.to_string(), "bus-off,error-counter-tx-rx{{255}{0}}");
        let every = ErrorFrame::decode(0x1F1, &[0, 0, 0, 0, 0x70, 0, 0, 0]).unwrap();
        assert_eq!(
            every.to_string(),
            "tx-timeout,transceiver-status,no-acknowledgement-on-tx,bus-off,bus-error,restarted-after-bus-off"
        );
        assert_eq!(
            every.errors[1],
            CanError::Transceiver(TransceiverStatus::CanLShortToGround)
        );
    }

    #[test]
    fn locations_candump_cannot_name() {
        let at = |code: u8| {
            ErrorFrame::decode(0x8, &[0, 0, 0x04, code])
                .unwrap()
                .to_string()
        };
        assert_eq!(
            at(0x1C),
            "protocol-violation{{bit-stuffing-error}{overload-flag}}"
        );
        assert_eq!(
            at(0x01),
            "protocol-violation{{bit-stuffing-error}{unspecified}}"
        );
        assert_eq!(at(0x40), "protocol-violation{{bit-stuffing-error}{}}");
        assert_eq!(
            ProtocolLocation::from_code(0x40),
            ProtocolLocation::Other(0x40)
        );
    }

    #[test]
    fn garbage_is_refused_or_kept_never_lost() {
        assert_eq!(
            ErrorFrame::decode(0x8, &[0; 9]),
            Err(ErrorFrameError::TooLong(9))
        );
        assert!(matches!(
            ErrorFrame::decode(0x4000_0000, &[]),
            Err(ErrorFrameError::ClassTooWide(_))
        ));
        // Unknown class bits survive a round trip.
        let e = ErrorFrame::decode(0x0400 | 0x040, &[]).unwrap();
        assert_eq!(e.errors, [CanError::BusOff, CanError::Unknown(0x400)]);
        assert_eq!(e.encode().0, 0x440);
        assert_eq!(e.to_string(), "bus-off,unknown-class-0x400");
    }

    #[test]
    fn error_frames_from_logs_encode_back_byte_for_byte() {
        // Issue 25: a candump log's `20000088#…` with counters became `20000288#…`, and
        // `20000080#0000040200000001` lost its protocol bytes (no protocol class).
        let with_counters = [0, 0, 0x02, 0x0A, 0, 0, 0x01, 0x02];
        let e = ErrorFrame::decode(0x088, &with_counters).unwrap();
        assert_eq!(e.counters, Some(ErrorCounters { tx: 1, rx: 2 }));
        assert_eq!(e.encode(), (0x088, with_counters));
        let stray = [0, 0, 0x04, 0x02, 0, 0, 0, 0x01];
        let e = ErrorFrame::decode(0x080, &stray).unwrap();
        assert_eq!(e.errors, [CanError::BusError]);
        assert_eq!(e.encode(), (0x080, stray));
        assert_eq!(e.data_len(), 8);
        // data[5] (reserved) and a short frame.
        let e = ErrorFrame::decode(0x004, &[0, 0x04, 0, 0, 0, 0x5A]).unwrap();
        assert_eq!(
            (e.encode(), e.data_len()),
            ((0x004, [0, 4, 0, 0, 0, 0x5A, 0, 0]), 6)
        );
        let e = ErrorFrame::decode(0x040, &[]).unwrap();
        assert_eq!(e.data_len(), 0);
        // Built from its fields: 8 bytes, the counters with their class.
        let built = ErrorFrame::new(vec![CanError::BusOff], Some(ErrorCounters { tx: 1, rx: 0 }));
        assert_eq!(
            (built.encode(), built.data_len()),
            ((0x240, [0, 0, 0, 0, 0, 0, 1, 0]), 8)
        );
        // Fields changed after decoding win over what was decoded; a short frame grows to
        // hold them.
        let mut e = ErrorFrame::decode(0x040, &[]).unwrap();
        e.counters = Some(ErrorCounters { tx: 3, rx: 4 });
        assert_eq!(
            (e.encode(), e.data_len()),
            ((0x240, [0, 0, 0, 0, 0, 0, 3, 4]), 8)
        );
    }

    proptest! {
        /// Any class and any 0..8 data bytes decode, print, and encode back to themselves.
        #[test]
        fn decode_then_encode_is_identity(
            class in 0u32..=0x1FFF_FFFF,
            data in proptest::collection::vec(any::<u8>(), 0..=8),
        ) {
            let e = ErrorFrame::decode(class, &data).unwrap();
            let _ = e.to_string();
            let (got_class, got) = e.encode();
            prop_assert_eq!(got_class, class);
            prop_assert_eq!(&got[..e.data_len()], &data[..]);
            prop_assert!(got[e.data_len()..].iter().all(|&b| b == 0));
        }

        /// A frame built from its fields decodes back to the same fields.
        #[test]
        fn built_frames_decode_to_themselves(class in 0u32..0x1FFF_FFFF, data in any::<[u8; 8]>()) {
            let e = ErrorFrame::decode(class, &data).unwrap();
            let built = ErrorFrame::new(e.errors.clone(), e.counters);
            let (c, d) = built.encode();
            let again = ErrorFrame::decode(c, &d).unwrap();
            prop_assert_eq!(&again.errors, &built.errors);
            prop_assert_eq!(again.counters, built.counters);
        }

        #[test]
        fn any_bytes_decode_without_panic(id in any::<u32>(), data in proptest::collection::vec(any::<u8>(), 0..12)) {
            if let Ok(e) = ErrorFrame::decode(id, &data) {
                let _ = e.describe("\n\t");
            }
        }
    }
}
