//! What a host asks of its own controller when it opens a bus (`buslab.toml`'s
//! `[controller]`): mode, bit timing, acceptance filter, output control, clock output, and how
//! the controller comes back after bus-off. SJA1000 terms, as every buslab bus speaks them;
//! no driver behind them (`buslab-canbus` turns them into a configuration).

use std::fmt;

use buslab_chips::sja1000::{BitTiming, CanMode, FilterMode};

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

impl AcceptanceFilter {
    /// Whether a frame passes this filter as the chip applies it: the model's own logic
    /// ([`buslab_chips::sja1000::filter::accepts`]). A BasicCAN filter also stands for BasicCAN mode,
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
        buslab_chips::sja1000::filter::accepts(mode, code, mask, frame)
    }

    /// ID filters (python-can's `can_id`/`can_mask`) that pass at least every frame this
    /// filter passes: its comparisons on ID bits, without those on RTR and data bytes. For
    /// kernel filters ahead of [`Self::accepts`]; empty for "everything".
    pub fn id_cover(&self) -> Vec<crate::Filter> {
        let care = |m: u8| !m;
        let filter = |id: u32, mask: u32, extended: bool| crate::Filter {
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
