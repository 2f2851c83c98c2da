//! SJA1000 configuration: every setting with a default, checked by [`Sja1000Config::validate`]
//! before a driver writes anything (the seed's `SjaConfig`/`BasicCANConfig`/`PeliCANConfig`).

use std::fmt;

use buslab_sja1000::regs::*;
use buslab_sja1000::{BitTiming, CanMode, FilterMode, TimingError};

/// The SJA1000's highest crystal frequency (datasheet: 24 MHz).
pub const MAX_CRYSTAL_HZ: u32 = 24_000_000;
/// The lowest crystal frequency accepted (a decision: below 1 MHz no useful bit rate exists).
pub const MIN_CRYSTAL_HZ: u32 = 1_000_000;

/// Everything `Sja1000Driver::init` programs.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Sja1000Config {
    /// BasicCAN (PCA82C200 compatible, 11-bit IDs) or PeliCAN (CAN 2.0B). Default PeliCAN.
    pub mode: CanMode,
    /// Bit timing. Default: the seed's registers BTR0 = 0x07, BTR1 = 0x4D (50 kbit/s from a
    /// 16 MHz crystal, sample point 75 %).
    pub timing: Timing,
    /// Crystal frequency in Hz; the CAN clock is half of it. Default 16 MHz.
    pub crystal_hz: u32,
    /// Which received frames reach the RX FIFO. Default: all.
    pub filter: AcceptanceFilter,
    /// OCR. Default 0xDA: normal output mode, TX0 push-pull (Kvaser PCI's value).
    pub output_control: u8,
    /// CLKOUT pin. Default: crystal / 2 (CDR.CD = 000, as after the seed's `CDR := 0x80`).
    pub clock_out: ClockOut,
    /// MOD.LOM: receive only, no ACK, no error flags (PeliCAN only). Default off.
    pub listen_only: bool,
    /// MOD.STM: a transmission needs no ACK (PeliCAN only). Default off.
    pub self_test: bool,
    /// Which interrupt sources set IR bits. Default: all (the seed's init writes IER 00h
    /// because its PC software polled: see [`Sja1000Config::seed_pelican`]).
    pub interrupts: InterruptEnables,
    /// EWLR: error warning limit (PeliCAN only; BasicCAN has a fixed 96). Default 96.
    pub error_warning_limit: u8,
    /// How [`Sja1000Driver::recover`](crate::Sja1000Driver::recover) brings the chip back
    /// after bus-off. Default: the seed's, the chip counting its way back.
    pub bus_off_recovery: BusOffRecovery,
}

/// How the driver brings a chip back after bus-off.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum BusOffRecovery {
    /// The seed's (and the datasheet's): the CPU clears reset mode and the chip waits 128 × 11
    /// recessive bits, TXERR counting down from 127 where the CPU can watch it, SR.ES clearing
    /// as it passes below the warning limit, SR.BS at the end. Seed 002 §5.4.7: "le compteur
    /// rediminue, mais plus lentement qu'il n'avait augmenté. Lorsqu'il atteint 96, le bit
    /// Error Status repasse à OK."
    #[default]
    Counted,
    /// Linux's `restart()`: TXERR := 0 in reset mode ends bus-off at once.
    Fast,
    /// None: the chip stays bus-off (in the reset mode it entered) until it is initialised
    /// again. Linux's default (`restart-ms 0`: until `ip link set down` and `up`) and a Lawicel
    /// CANUSB's (until the host closes and opens the channel, `C` then `O`).
    Manual,
}

impl Default for Sja1000Config {
    fn default() -> Self {
        Self {
            mode: CanMode::Peli,
            timing: Timing::Registers {
                btr0: 0x07,
                btr1: 0x4D,
            },
            crystal_hz: 16_000_000,
            filter: AcceptanceFilter::AcceptAll,
            output_control: 0xDA,
            clock_out: ClockOut::Divider(2),
            listen_only: false,
            self_test: false,
            interrupts: InterruptEnables::all(),
            error_warning_limit: 96,
            bus_off_recovery: BusOffRecovery::Counted,
        }
    }
}

/// `bit` if `on`, else 0.
const fn flag(on: bool, bit: u8) -> u8 {
    if on { bit } else { 0 }
}

/// How the bit timing is given.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Timing {
    /// A bit rate; the registers are chosen with Linux's algorithm
    /// ([`BitTiming::for_bitrate`]), the sample point defaulting to CiA's.
    Bitrate {
        bitrate: u32,
        sample_point_permille: Option<u32>,
    },
    /// BTR0/BTR1 as given (every pair of bytes is a valid timing).
    Registers { btr0: u8, btr1: u8 },
}

/// The acceptance filter (ACR/AMR). Mask bit 1 = "don't care".
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AcceptanceFilter {
    /// Every frame passes (code 0, all mask bits "don't care"). Valid in both modes.
    AcceptAll,
    /// BasicCAN: one 8-bit filter on ID bits 10..3.
    Basic { code: u8, mask: u8 },
    /// PeliCAN single filter (MOD.AFM = 1): ACR0..3 / AMR0..3 as one 32-bit filter.
    Single { code: [u8; 4], mask: [u8; 4] },
    /// PeliCAN dual filter (MOD.AFM = 0): two shorter filters, either may match.
    Dual { code: [u8; 4], mask: [u8; 4] },
}

impl AcceptanceFilter {
    /// PeliCAN single filter that accepts exactly the standard ID `id` (data and remote).
    pub fn standard_id(id: u16) -> Self {
        let id = id & 0x7FF;
        Self::Single {
            code: [(id >> 3) as u8, ((id & 7) << 5) as u8, 0, 0],
            mask: [0x00, 0x1F, 0xFF, 0xFF],
        }
    }

    /// PeliCAN single filter that accepts exactly the extended ID `id` (data and remote).
    pub fn extended_id(id: u32) -> Self {
        let id = id & 0x1FFF_FFFF;
        Self::Single {
            code: [
                (id >> 21) as u8,
                (id >> 13) as u8,
                (id >> 5) as u8,
                ((id & 0x1F) << 3) as u8,
            ],
            mask: [0x00, 0x00, 0x00, 0x07],
        }
    }

    /// ACR0..3, AMR0..3 (BasicCAN uses index 0 only).
    pub fn registers(&self) -> ([u8; 4], [u8; 4]) {
        match *self {
            AcceptanceFilter::AcceptAll => ([0; 4], [0xFF; 4]),
            AcceptanceFilter::Basic { code, mask } => ([code, 0, 0, 0], [mask, 0xFF, 0xFF, 0xFF]),
            AcceptanceFilter::Single { code, mask } | AcceptanceFilter::Dual { code, mask } => {
                (code, mask)
            }
        }
    }

    /// MOD.AFM (single filter) in PeliCAN mode.
    pub fn single(&self) -> bool {
        !matches!(self, AcceptanceFilter::Dual { .. })
    }
}

/// The CLKOUT pin (CDR bits 0..3).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ClockOut {
    /// CLKOUT disabled (CDR.3).
    Off,
    /// CLKOUT = crystal / divider; divider 1, 2, 4, 6, 8, 10, 12 or 14.
    Divider(u8),
}

impl ClockOut {
    /// CDR bits 3..0, or `None` for a divider the chip does not have.
    pub fn cdr_bits(&self) -> Option<u8> {
        match *self {
            ClockOut::Off => Some(0x08),
            ClockOut::Divider(1) => Some(0x07),
            ClockOut::Divider(d @ 2..=14) if d % 2 == 0 => Some(d / 2 - 1),
            ClockOut::Divider(_) => None,
        }
    }
}

/// Interrupt sources. In BasicCAN only receive, transmit, error and overrun have enables
/// (CR bits 1..4); wake-up is always on there and the others do not exist.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct InterruptEnables {
    pub receive: bool,
    pub transmit: bool,
    pub error_warning: bool,
    pub data_overrun: bool,
    pub wake_up: bool,
    pub error_passive: bool,
    pub arbitration_lost: bool,
    pub bus_error: bool,
}

impl InterruptEnables {
    pub const fn all() -> Self {
        Self::from_ier(0xFF)
    }

    pub const fn none() -> Self {
        Self::from_ier(0)
    }

    /// From a PeliCAN IER value.
    pub const fn from_ier(ier: u8) -> Self {
        Self {
            receive: ier & IR_RI != 0,
            transmit: ier & IR_TI != 0,
            error_warning: ier & IR_EI != 0,
            data_overrun: ier & IR_DOI != 0,
            wake_up: ier & IR_WUI != 0,
            error_passive: ier & IR_EPI != 0,
            arbitration_lost: ier & IR_ALI != 0,
            bus_error: ier & IR_BEI != 0,
        }
    }

    /// The PeliCAN IER value.
    pub const fn ier(&self) -> u8 {
        flag(self.receive, IR_RI)
            | flag(self.transmit, IR_TI)
            | flag(self.error_warning, IR_EI)
            | flag(self.data_overrun, IR_DOI)
            | flag(self.wake_up, IR_WUI)
            | flag(self.error_passive, IR_EPI)
            | flag(self.arbitration_lost, IR_ALI)
            | flag(self.bus_error, IR_BEI)
    }

    /// The BasicCAN CR enable bits (1..4).
    pub const fn cr_bits(&self) -> u8 {
        flag(self.receive, CR_RIE)
            | flag(self.transmit, CR_TIE)
            | flag(self.error_warning, CR_EIE)
            | flag(self.data_overrun, CR_OIE)
    }
}

impl Default for InterruptEnables {
    fn default() -> Self {
        Self::all()
    }
}

/// A configuration the chip cannot take; the message names the value and what is allowed.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ConfigError {
    #[error("crystal frequency {hz} Hz is out of range {MIN_CRYSTAL_HZ}..={MAX_CRYSTAL_HZ} Hz")]
    Crystal { hz: u32 },
    #[error(transparent)]
    Timing(#[from] TimingError),
    #[error("clock-out divider {divider} is not available: use 1, 2, 4, 6, 8, 10, 12, 14 or off")]
    ClockDivider { divider: u8 },
    #[error("{what} exists only in PeliCAN mode, not in BasicCAN")]
    PeliOnly { what: &'static str },
    #[error("a {filter} acceptance filter does not fit {mode} mode; {allowed}")]
    FilterMode {
        filter: &'static str,
        mode: &'static str,
        allowed: &'static str,
    },
    #[error(
        "output control 0x{ocr:02X} selects the test output mode (OCMODE = 01); use normal (10), clock (11) or bi-phase (00)"
    )]
    OutputTestMode { ocr: u8 },
    #[error("listen-only and self-test cannot both be on: a listen-only node never transmits")]
    ListenOnlySelfTest,
}

impl Sja1000Config {
    /// The defaults in BasicCAN mode (PeliCAN-only interrupt sources off).
    pub fn basic_can() -> Self {
        Self {
            mode: CanMode::Basic,
            interrupts: InterruptEnables::from_ier(IR_RI | IR_TI | IR_EI | IR_DOI | IR_WUI),
            ..Self::default()
        }
    }

    /// The defaults (PeliCAN).
    pub fn peli_can() -> Self {
        Self::default()
    }

    /// Exactly the seed's `sja_init_pelican` (002 §4.1.2.1): BTR0 07h, BTR1 4Dh, accept all
    /// (AMR FFh), IER 00h ("Desactivation des interruptions"), OCR DBh, MOD 08h (single
    /// filter). Its software polls the chip; a driver serviced on interrupts (the default)
    /// needs IER.
    pub fn seed_pelican() -> Self {
        Self {
            interrupts: InterruptEnables::none(),
            output_control: 0xDB,
            ..Self::default()
        }
    }

    /// Checks every setting; the driver calls this before touching the chip.
    pub fn validate(&self) -> Result<(), ConfigError> {
        if !(MIN_CRYSTAL_HZ..=MAX_CRYSTAL_HZ).contains(&self.crystal_hz) {
            return Err(ConfigError::Crystal {
                hz: self.crystal_hz,
            });
        }
        self.bit_timing()?;
        if let ClockOut::Divider(divider) = self.clock_out
            && self.clock_out.cdr_bits().is_none()
        {
            return Err(ConfigError::ClockDivider { divider });
        }
        if self.output_control & 0x03 == 0x01 {
            return Err(ConfigError::OutputTestMode {
                ocr: self.output_control,
            });
        }
        match self.mode {
            CanMode::Basic => self.validate_basic()?,
            CanMode::Peli => {
                if let AcceptanceFilter::Basic { .. } = self.filter {
                    return Err(ConfigError::FilterMode {
                        filter: "BasicCAN 8-bit",
                        mode: "PeliCAN",
                        allowed: "use Single or Dual (or AcceptAll)",
                    });
                }
                if self.listen_only && self.self_test {
                    return Err(ConfigError::ListenOnlySelfTest);
                }
            }
        }
        Ok(())
    }

    fn validate_basic(&self) -> Result<(), ConfigError> {
        let peli_only = |what| Err(ConfigError::PeliOnly { what });
        if self.listen_only {
            return peli_only("listen-only mode");
        }
        if self.self_test {
            return peli_only("self-test mode");
        }
        if self.error_warning_limit != 96 {
            return peli_only("a settable error warning limit (BasicCAN's is fixed at 96)");
        }
        let irq = &self.interrupts;
        if irq.error_passive {
            return peli_only("the error-passive interrupt");
        }
        if irq.arbitration_lost {
            return peli_only("the arbitration-lost interrupt");
        }
        if irq.bus_error {
            return peli_only("the bus-error interrupt");
        }
        if let AcceptanceFilter::Single { .. } | AcceptanceFilter::Dual { .. } = self.filter {
            return Err(ConfigError::FilterMode {
                filter: "32-bit",
                mode: "BasicCAN",
                allowed: "use Basic { code, mask } (8 bits on ID.10..3) or AcceptAll",
            });
        }
        Ok(())
    }

    /// The CAN clock: half the crystal.
    pub fn can_clock_hz(&self) -> u32 {
        self.crystal_hz / 2
    }

    /// The bit timing to program.
    pub fn bit_timing(&self) -> Result<BitTiming, ConfigError> {
        Ok(match self.timing {
            Timing::Registers { btr0, btr1 } => BitTiming::from_registers(btr0, btr1),
            Timing::Bitrate {
                bitrate,
                sample_point_permille,
            } => BitTiming::for_bitrate(self.can_clock_hz(), bitrate, sample_point_permille)?,
        })
    }

    /// CDR: mode bit and clock-out bits (CBP and RXINTEN stay off).
    pub fn cdr(&self) -> u8 {
        let mode = match self.mode {
            CanMode::Peli => CDR_PELICAN,
            CanMode::Basic => 0,
        };
        mode | self.clock_out.cdr_bits().unwrap_or(0)
    }

    /// MOD in operating mode (RM = 0): LOM, STM, AFM.
    pub fn mod_bits(&self) -> u8 {
        flag(self.listen_only, MOD_LOM)
            | flag(self.self_test, MOD_STM)
            | flag(self.filter.single(), MOD_AFM)
    }
}

impl fmt::Display for Sja1000Config {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let mode = match self.mode {
            CanMode::Peli => "PeliCAN",
            CanMode::Basic => "BasicCAN",
        };
        write!(f, "{mode}, crystal {} Hz, ", self.crystal_hz)?;
        match self.bit_timing() {
            Ok(t) => write!(f, "{} bit/s ({t})", t.bitrate(self.can_clock_hz()))?,
            Err(e) => write!(f, "invalid timing ({e})")?,
        }
        if self.listen_only {
            f.write_str(", listen-only")?;
        }
        if self.self_test {
            f.write_str(", self-test")?;
        }
        Ok(())
    }
}

impl AcceptanceFilter {
    /// Whether a frame passes this filter as the chip applies it: the model's own logic
    /// ([`buslab_sja1000::filter::accepts`]). A BasicCAN filter also stands for BasicCAN mode,
    /// whose receiver drops every extended frame ("CAN 2.0B passive").
    pub fn accepts(&self, frame: &buslab_can::Frame) -> bool {
        let (code, mask) = self.registers();
        let mode = match self {
            AcceptanceFilter::AcceptAll => return true,
            AcceptanceFilter::Basic { .. } if frame.is_extended() => return false,
            AcceptanceFilter::Basic { .. } => FilterMode::Basic,
            AcceptanceFilter::Single { .. } => FilterMode::Single,
            AcceptanceFilter::Dual { .. } => FilterMode::Dual,
        };
        buslab_sja1000::filter::accepts(mode, code, mask, frame)
    }

    /// ID filters (python-can's `can_id`/`can_mask`) that pass at least every frame this
    /// filter passes: its comparisons on ID bits, without those on RTR and data bytes. For
    /// kernel filters ahead of [`Self::accepts`]; empty for "everything".
    pub fn id_cover(&self) -> Vec<buslab_bus::Filter> {
        let care = |m: u8| !m;
        let filter = |id: u32, mask: u32, extended: bool| buslab_bus::Filter {
            id: id & mask,
            mask,
            extended: Some(extended),
        };
        // 11 bits from ACRn and the top 3 of ACRn+1; 16 top bits of an extended ID from two bytes.
        let sff = |c: [u8; 2], m: [u8; 2]| {
            let id = u32::from(c[0]) << 3 | u32::from(c[1] >> 5);
            let mask = u32::from(care(m[0])) << 3 | u32::from(care(m[1]) >> 5);
            filter(id, mask, false)
        };
        let eff16 = |c: [u8; 2], m: [u8; 2]| {
            let id = u32::from(c[0]) << 21 | u32::from(c[1]) << 13;
            let mask = u32::from(care(m[0])) << 21 | u32::from(care(m[1])) << 13;
            filter(id, mask, true)
        };
        match *self {
            AcceptanceFilter::AcceptAll => Vec::new(),
            AcceptanceFilter::Basic { code, mask } => {
                vec![filter(
                    u32::from(code) << 3,
                    u32::from(care(mask)) << 3,
                    false,
                )]
            }
            AcceptanceFilter::Single { code: c, mask: m } => {
                let id = u32::from_be_bytes(c) >> 3;
                let mask = u32::from_be_bytes(m.map(care)) >> 3;
                vec![sff([c[0], c[1]], [m[0], m[1]]), filter(id, mask, true)]
            }
            AcceptanceFilter::Dual { code: c, mask: m } => vec![
                sff([c[0], c[1]], [m[0], m[1]]),
                sff([c[2], c[3]], [m[2], m[3]]),
                eff16([c[0], c[1]], [m[0], m[1]]),
                eff16([c[2], c[3]], [m[2], m[3]]),
            ],
        }
    }

    /// The filter's kind, as `buslab.toml` and the socketcand extension name it.
    pub fn kind_name(&self) -> &'static str {
        match self {
            AcceptanceFilter::AcceptAll => "accept-all",
            AcceptanceFilter::Basic { .. } => "basic",
            AcceptanceFilter::Single { .. } => "single",
            AcceptanceFilter::Dual { .. } => "dual",
        }
    }
}

/// How a PeliCAN controller takes part in the bus (MOD.LOM, MOD.STM), or BasicCAN.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum ControllerMode {
    /// PeliCAN (CAN 2.0B), transmitting and acknowledging.
    #[default]
    PeliCan,
    /// BasicCAN (PCA82C200 compatible): 11-bit IDs, extended frames are not received.
    BasicCan,
    /// PeliCAN listen-only (MOD.LOM): receives, never acknowledges, sends nothing.
    ListenOnly,
    /// PeliCAN self-test (MOD.STM): a transmission needs no acknowledge.
    SelfTest,
}

impl ControllerMode {
    pub const ALL: [ControllerMode; 4] = [
        ControllerMode::PeliCan,
        ControllerMode::BasicCan,
        ControllerMode::ListenOnly,
        ControllerMode::SelfTest,
    ];

    /// The name `buslab.toml` and the socketcand extension use.
    pub fn name(self) -> &'static str {
        match self {
            ControllerMode::PeliCan => "PeliCAN",
            ControllerMode::BasicCan => "BasicCAN",
            ControllerMode::ListenOnly => "listen-only",
            ControllerMode::SelfTest => "self-test",
        }
    }

    /// The name read back (case does not matter).
    pub fn from_name(text: &str) -> Option<Self> {
        Self::ALL
            .into_iter()
            .find(|m| m.name().eq_ignore_ascii_case(text.trim()))
    }

    /// The register set: BasicCAN, or PeliCAN for the three others.
    pub fn can_mode(self) -> CanMode {
        match self {
            ControllerMode::BasicCan => CanMode::Basic,
            _ => CanMode::Peli,
        }
    }
}

/// The bit timing a host asks of its controller: the registers and the crystal they are for.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct TimingSetting {
    pub crystal_hz: u32,
    pub btr0: u8,
    pub btr1: u8,
}

impl TimingSetting {
    /// The bit rate these registers give with this crystal.
    pub fn bitrate(&self) -> u32 {
        BitTiming::from_registers(self.btr0, self.btr1).bitrate(self.crystal_hz / 2)
    }
}

/// A part of [`ControllerSettings`], for saying which were applied where.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ControllerPart {
    Mode,
    Timing,
    Filter,
    OutputControl,
    ClockOut,
}

impl ControllerPart {
    pub const ALL: [ControllerPart; 5] = [
        ControllerPart::Mode,
        ControllerPart::Timing,
        ControllerPart::Filter,
        ControllerPart::OutputControl,
        ControllerPart::ClockOut,
    ];

    /// In words, with the keys of `buslab.toml` that set it.
    pub fn describe(self) -> &'static str {
        match self {
            ControllerPart::Mode => "the mode (controller.mode)",
            ControllerPart::Timing => "the bit timing (controller.bitrate/btr0/btr1)",
            ControllerPart::Filter => {
                "the acceptance filter (controller.filter/acceptance_code/acceptance_mask)"
            }
            ControllerPart::OutputControl => "the output control (controller.output_control)",
            ControllerPart::ClockOut => "the clock output (controller.clock_out/clock_divider)",
        }
    }
}

/// What a host asks of its own controller when it opens a bus (`buslab.toml`'s
/// `[controller]`, JerryCAN's configuration assistant), part by part: a part left `None`
/// stays as the bus or the adapter has it. On buslab's bus every client has an SJA1000 of its
/// own that takes every part; an adapter takes what it has a command for.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ControllerSettings {
    pub mode: Option<ControllerMode>,
    pub timing: Option<TimingSetting>,
    pub filter: Option<AcceptanceFilter>,
    pub output_control: Option<u8>,
    pub clock_out: Option<ClockOut>,
}

impl ControllerSettings {
    /// Nothing asked: every part as the bus or adapter has it.
    pub fn is_empty(&self) -> bool {
        self.parts().is_empty()
    }

    /// The parts asked for, in [`ControllerPart::ALL`]'s order.
    pub fn parts(&self) -> Vec<ControllerPart> {
        ControllerPart::ALL
            .into_iter()
            .filter(|p| match p {
                ControllerPart::Mode => self.mode.is_some(),
                ControllerPart::Timing => self.timing.is_some(),
                ControllerPart::Filter => self.filter.is_some(),
                ControllerPart::OutputControl => self.output_control.is_some(),
                ControllerPart::ClockOut => self.clock_out.is_some(),
            })
            .collect()
    }

    /// `base` with these parts in place of its own. Switching to BasicCAN also leaves out what
    /// BasicCAN does not have (the PeliCAN-only interrupt sources, a settable warning limit).
    pub fn apply_to(&self, base: &Sja1000Config) -> Sja1000Config {
        let mut config = base.clone();
        if let Some(mode) = self.mode {
            config.mode = mode.can_mode();
            config.listen_only = mode == ControllerMode::ListenOnly;
            config.self_test = mode == ControllerMode::SelfTest;
            if mode == ControllerMode::BasicCan {
                let irq = config.interrupts;
                config.interrupts = InterruptEnables {
                    error_passive: false,
                    arbitration_lost: false,
                    bus_error: false,
                    ..irq
                };
                config.error_warning_limit = 96;
            }
        }
        if let Some(t) = self.timing {
            config.crystal_hz = t.crystal_hz;
            config.timing = Timing::Registers {
                btr0: t.btr0,
                btr1: t.btr1,
            };
        }
        if let Some(filter) = self.filter {
            config.filter = filter;
        }
        if let Some(ocr) = self.output_control {
            config.output_control = ocr;
        }
        if let Some(clock_out) = self.clock_out {
            config.clock_out = clock_out;
        }
        config
    }

    /// Whether a received frame reaches the host through the acceptance filter asked for
    /// (every frame when none is).
    pub fn accepts(&self, frame: &buslab_can::Frame) -> bool {
        self.filter.is_none_or(|f| f.accepts(frame))
    }
}

impl fmt::Display for ControllerSettings {
    /// `BasicCAN, 125000 bit/s (BTR0=0x03 BTR1=0x1C, crystal 16000000 Hz), filter basic
    /// ACR=E0 AMR=0F, OCR=0x1A, CLKOUT off`; `nothing` when empty.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let mut parts: Vec<String> = Vec::new();
        if let Some(mode) = self.mode {
            parts.push(mode.name().to_string());
        }
        if let Some(t) = self.timing {
            parts.push(format!(
                "{} bit/s (BTR0=0x{:02X} BTR1=0x{:02X}, crystal {} Hz)",
                t.bitrate(),
                t.btr0,
                t.btr1,
                t.crystal_hz
            ));
        }
        if let Some(filter) = self.filter {
            let (code, mask) = filter.registers();
            let hex = |b: [u8; 4], n: usize| {
                b[..n]
                    .iter()
                    .map(|x| format!("{x:02X}"))
                    .collect::<String>()
            };
            parts.push(match filter {
                AcceptanceFilter::AcceptAll => "filter accept-all".to_string(),
                AcceptanceFilter::Basic { .. } => {
                    format!("filter basic ACR={} AMR={}", hex(code, 1), hex(mask, 1))
                }
                _ => format!(
                    "filter {} ACR={} AMR={}",
                    filter.kind_name(),
                    hex(code, 4),
                    hex(mask, 4)
                ),
            });
        }
        if let Some(ocr) = self.output_control {
            parts.push(format!("OCR=0x{ocr:02X}"));
        }
        match self.clock_out {
            Some(ClockOut::Off) => parts.push("CLKOUT off".into()),
            Some(ClockOut::Divider(d)) => parts.push(format!("CLKOUT crystal/{d}")),
            None => {}
        }
        if parts.is_empty() {
            return f.write_str("nothing");
        }
        f.write_str(&parts.join(", "))
    }
}

#[cfg(test)]
mod controller_tests {
    use super::*;
    use buslab_can::Frame;

    fn frames() -> Vec<Frame> {
        let mut out = Vec::new();
        for id in 0..0x800u32 {
            for text in [
                format!("{id:03X}#"),
                format!("{id:03X}#5A01"),
                format!("{id:03X}#R"),
            ] {
                out.push(text.parse().unwrap());
            }
        }
        for id in [
            0u32,
            0x123,
            0x0480_0000,
            0x1234_5678,
            0x1FFF_FFFF,
            0x0002_4000,
        ] {
            out.push(format!("{id:08X}#11").parse().unwrap());
            out.push(format!("{id:08X}#R").parse().unwrap());
        }
        out
    }

    #[test]
    fn the_id_cover_passes_every_frame_the_filter_passes() {
        let filters = [
            AcceptanceFilter::Basic {
                code: 0x24,
                mask: 0x03,
            },
            AcceptanceFilter::standard_id(0x123),
            AcceptanceFilter::extended_id(0x1234_5678),
            AcceptanceFilter::Single {
                code: [0x00, 0x00, 0x01, 0x23],
                mask: [0x00, 0x1F, 0xFF, 0xFF],
            },
            AcceptanceFilter::Dual {
                code: [0x20, 0x05, 0x40, 0x00],
                mask: [0x00, 0x00, 0x00, 0x1F],
            },
        ];
        for filter in filters {
            let cover = filter.id_cover();
            let mut passed = 0;
            for frame in frames() {
                if filter.accepts(&frame) {
                    passed += 1;
                    assert!(
                        buslab_bus::matches_any(&cover, &frame),
                        "{filter:?} passes {frame} but its cover {cover:?} does not"
                    );
                }
            }
            assert!(passed > 0, "{filter:?} passes none of the test frames");
        }
        assert!(AcceptanceFilter::AcceptAll.id_cover().is_empty());
    }

    #[test]
    fn a_basic_filter_stands_for_basiccan_which_drops_extended_frames() {
        let basic = AcceptanceFilter::Basic {
            code: 0,
            mask: 0xFF,
        };
        assert!(basic.accepts(&"123#".parse().unwrap()));
        assert!(!basic.accepts(&"00000123#".parse().unwrap()));
    }

    #[test]
    fn settings_change_only_the_parts_given() {
        let base = Sja1000Config::default();
        let settings = ControllerSettings {
            mode: Some(ControllerMode::BasicCan),
            filter: Some(AcceptanceFilter::Basic {
                code: 0xE0,
                mask: 0x0F,
            }),
            ..ControllerSettings::default()
        };
        let config = settings.apply_to(&base);
        assert_eq!(config.mode, CanMode::Basic);
        assert_eq!(config.timing, base.timing);
        assert_eq!(config.output_control, base.output_control);
        config
            .validate()
            .expect("BasicCAN without PeliCAN-only interrupts");
        let listen = ControllerSettings {
            mode: Some(ControllerMode::ListenOnly),
            ..ControllerSettings::default()
        }
        .apply_to(&config);
        assert!(listen.listen_only && listen.mode == CanMode::Peli);
        assert_eq!(
            settings.parts(),
            [ControllerPart::Mode, ControllerPart::Filter]
        );
        assert_eq!(settings.to_string(), "BasicCAN, filter basic ACR=E0 AMR=0F");
    }
}
