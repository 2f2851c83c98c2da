//! SJA1000 configuration: every setting with a default, checked by [`Sja1000Config::validate`]
//! before a driver writes anything (the seed's `SjaConfig`/`BasicCANConfig`/`PeliCANConfig`).

use std::fmt;

/// The settings a host asks of its controller are bus vocabulary (`buslab-bus`); these paths
/// stay for the users of this crate.
pub use buslab_bus::settings::{
    AcceptanceFilter, BusOffRecovery, ClockOut, ControllerMode, ControllerPart, ControllerSettings,
    TimingSetting,
};
use buslab_sja1000::regs::*;
use buslab_sja1000::{BitTiming, CanMode, TimingError};

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

impl Sja1000Config {
    /// This configuration with the parts `settings` gives in place of its own. Switching to
    /// BasicCAN also leaves out what BasicCAN does not have (the PeliCAN-only interrupt sources, a settable warning limit).
    pub fn with_settings(&self, settings: &ControllerSettings) -> Sja1000Config {
        let mut config = self.clone();
        if let Some(mode) = settings.mode {
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
        if let Some(t) = settings.timing {
            config.crystal_hz = t.crystal_hz;
            config.timing = Timing::Registers {
                btr0: t.btr0,
                btr1: t.btr1,
            };
        }
        if let Some(filter) = settings.filter {
            config.filter = filter;
        }
        if let Some(ocr) = settings.output_control {
            config.output_control = ocr;
        }
        if let Some(clock_out) = settings.clock_out {
            config.clock_out = clock_out;
        }
        config
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
        let config = base.with_settings(&settings);
        assert_eq!(config.mode, CanMode::Basic);
        assert_eq!(config.timing, base.timing);
        assert_eq!(config.output_control, base.output_control);
        config
            .validate()
            .expect("BasicCAN without PeliCAN-only interrupts");
        let listen = config.with_settings(&ControllerSettings {
            mode: Some(ControllerMode::ListenOnly),
            ..ControllerSettings::default()
        });
        assert!(listen.listen_only && listen.mode == CanMode::Peli);
        assert_eq!(
            settings.parts(),
            [ControllerPart::Mode, ControllerPart::Filter]
        );
        assert_eq!(settings.to_string(), "BasicCAN, filter basic ACR=E0 AMR=0F");
    }
}
