//! The 18-byte acquisition configuration of the 80C196 (`ad_init[n]`, SPEC C4) and the `FA`
//! frame layout it implies.

use core::fmt;

use buslab_device::{LineSettings, Nanos};

/// Share of the line an acquisition may take (the rest is for replies and the watchdog).
pub const MAX_LINE_SHARE: f64 = 0.97;

/// Sample format of one channel (`cc` in `0scc ffff`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum SampleFormat {
    /// Filtered value scaled to 16 bits (10-bit conversion × 64), 2 bytes little-endian.
    Bits16,
    /// 10-bit value, 2 bytes little-endian.
    Bits10,
    /// Top 8 bits of the 10-bit value, 1 byte.
    Bits8,
    /// 16-bit value compressed to 8 bits through the programmable log table, 1 byte.
    Log8,
}

impl SampleFormat {
    pub fn from_bits(cc: u8) -> Self {
        match cc & 3 {
            0 => Self::Bits16,
            1 => Self::Bits10,
            2 => Self::Bits8,
            _ => Self::Log8,
        }
    }

    pub fn bits(self) -> u8 {
        match self {
            Self::Bits16 => 0,
            Self::Bits10 => 1,
            Self::Bits8 => 2,
            Self::Log8 => 3,
        }
    }

    /// Bytes this format takes in an `FA` frame.
    pub fn width(self) -> usize {
        match self {
            Self::Bits16 | Self::Bits10 => 2,
            Self::Bits8 | Self::Log8 => 1,
        }
    }

    /// Short user-facing name.
    pub fn name(self) -> &'static str {
        match self {
            Self::Bits16 => "16",
            Self::Bits10 => "10",
            Self::Bits8 => "8",
            Self::Log8 => "log8",
        }
    }
}

/// Filter of one channel (`ffff`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Filter {
    /// First-order low-pass of rank `r` (0 = none): `y += (x - y) / 2^r`.
    LowPass(u8),
    /// Moving average over this many samples (1, 2, 4, 8, 16, 32).
    Average(u8),
}

impl Filter {
    pub fn from_bits(ffff: u8) -> Self {
        match ffff & 0x0F {
            r @ 0..=8 => Self::LowPass(r),
            // The seed says "1 to 32": 9..=14 give 1..=32; 15 would be 64 and is held at 32.
            f => Self::Average(1 << (f - 9).min(5)),
        }
    }
}

/// Settings of one of the 8 channels.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct ChannelSetup {
    pub transmit: bool,
    pub format: SampleFormat,
    pub filter: Filter,
    /// The raw `0scc ffff` byte.
    pub raw: u8,
}

impl ChannelSetup {
    pub fn from_byte(b: u8) -> Self {
        Self {
            transmit: b & 0x40 != 0,
            format: SampleFormat::from_bits(b >> 4),
            filter: Filter::from_bits(b),
            raw: b,
        }
    }

    pub fn byte(transmit: bool, format: SampleFormat, ffff: u8) -> u8 {
        ((transmit as u8) << 6) | (format.bits() << 4) | (ffff & 0x0F)
    }
}

/// A decoded `ad_init` configuration.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct AdConfig {
    /// Channels converted in order, once per sampling period (at most 16 slots).
    pub sequence: Vec<u8>,
    pub channels: [ChannelSetup; 8],
    /// Time base T: sampling period (75 + 5·T) × 0.8 µs.
    pub time_base: u8,
    /// Power of two of the interrupt:cycle ratio (0..=4 for 1:1 ..= 1:16).
    pub ratio_pow: u8,
}

/// Why an `ad_init` block cannot run.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum AdConfigError {
    #[error("the interrupt:cycle ratio 2^{0} is out of range 2^0..2^4 (1:1 ..= 1:16)")]
    Ratio(u8),
    #[error("the conversion sequence is empty (slot 0 holds {0:#x}, channels are 0..7)")]
    EmptySequence(u8),
}

/// Why START refuses a configuration set's acquisition (the board answers only
/// `msg_ad_config_error`; the host finds the reason from the set's CFGAD).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum AdRefusal {
    #[error(transparent)]
    Config(#[from] AdConfigError),
    #[error(
        "the acquisition needs {percent:.0} % of the line at {baud} baud, at most {max:.0} % is \
         allowed (a longer sampling period, fewer channels or a faster line fit)",
        max = MAX_LINE_SHARE * 100.0
    )]
    LineShare { percent: f64, baud: u32 },
}

impl AdConfig {
    /// What START decides about `raw` with the 80C196 A/D on, on a line at `line`: the
    /// configuration, or why it cannot run.
    pub fn check_start(raw: &[u8; 18], line: LineSettings) -> Result<AdConfig, AdRefusal> {
        let cfg = AdConfig::parse(raw)?;
        let share = cfg.line_share(line);
        if share > MAX_LINE_SHARE {
            return Err(AdRefusal::LineShare {
                percent: share * 100.0,
                baud: line.baud,
            });
        }
        Ok(cfg)
    }

    /// Share of the line at `line` the `FA` frames take (0 when nothing is transmitted).
    pub fn line_share(&self, line: LineSettings) -> f64 {
        match self.frame_data_len() {
            Some(n) => {
                let frame_ns = self.period_ns() * self.scans_per_frame() as u64;
                (n + 3) as f64 * line.byte_time().get() as f64 / frame_ns.get() as f64
            }
            None => 0.0,
        }
    }

    /// Slot order of the packed nibbles: byte 0 = (slot 0, slot 15), byte i = (slot 16−2i,
    /// slot 15−2i) for i ≥ 1 (the seed's "(0 15) (14 13) … (2 1)").
    fn slot_of(byte: usize, high: bool) -> usize {
        match (byte, high) {
            (0, false) => 0,
            (0, true) => 15,
            (i, false) => 16 - 2 * i,
            (i, true) => 15 - 2 * i,
        }
    }

    /// Decodes the 18 bytes. A nibble ≥ 8 ends the sequence.
    pub fn parse(raw: &[u8; 18]) -> Result<Self, AdConfigError> {
        let mut slots = [0xFu8; 16];
        for (i, b) in raw[..8].iter().enumerate() {
            slots[Self::slot_of(i, false)] = b & 0x0F;
            slots[Self::slot_of(i, true)] = b >> 4;
        }
        let sequence: Vec<u8> = slots.iter().copied().take_while(|&c| c < 8).collect();
        if sequence.is_empty() {
            return Err(AdConfigError::EmptySequence(slots[0]));
        }
        let channels = core::array::from_fn(|ch| ChannelSetup::from_byte(raw[15 - ch]));
        let ratio_pow = raw[17];
        if ratio_pow > 4 {
            return Err(AdConfigError::Ratio(ratio_pow));
        }
        Ok(Self {
            sequence,
            channels,
            time_base: raw[16],
            ratio_pow,
        })
    }

    /// Encodes back to the 18 bytes (unused slots are `F`).
    pub fn encode(&self) -> [u8; 18] {
        let mut slots = [0xFu8; 16];
        for (s, &c) in slots.iter_mut().zip(&self.sequence) {
            *s = c & 7;
        }
        let mut raw = [0u8; 18];
        for (i, b) in raw[..8].iter_mut().enumerate() {
            *b = slots[Self::slot_of(i, false)] | (slots[Self::slot_of(i, true)] << 4);
        }
        for ch in 0..8 {
            raw[15 - ch] = self.channels[ch].raw;
        }
        raw[16] = self.time_base;
        raw[17] = self.ratio_pow;
        raw
    }

    /// A configuration converting `channels` in order, all transmitted in `format`, no filter.
    pub fn simple(channels: &[u8], format: SampleFormat, time_base: u8, ratio_pow: u8) -> Self {
        let mut setup = [ChannelSetup::from_byte(ChannelSetup::byte(false, format, 0)); 8];
        for &c in channels {
            setup[c as usize & 7] = ChannelSetup::from_byte(ChannelSetup::byte(true, format, 0));
        }
        Self {
            sequence: channels.iter().map(|c| c & 7).take(16).collect(),
            channels: setup,
            time_base,
            ratio_pow,
        }
    }

    /// Sampling period in nanoseconds: (75 + 5·T) × 0.8 µs.
    pub fn period_ns(&self) -> Nanos {
        Nanos::new(800) * (75 + 5 * self.time_base as u64)
    }

    /// Channels sent to the PC, ascending.
    pub fn transmitted(&self) -> impl Iterator<Item = (u8, ChannelSetup)> + '_ {
        (0u8..8)
            .map(|c| (c, self.channels[c as usize]))
            .filter(|(_, s)| s.transmit)
    }

    /// Bytes one scan of the transmitted channels takes.
    pub fn scan_bytes(&self) -> usize {
        self.transmitted().map(|(_, s)| s.format.width()).sum()
    }

    /// Scans carried by one `FA` frame: 2^ratio, at least 2 when a scan is a single byte (a
    /// frame carries at least 2 data bytes).
    pub fn scans_per_frame(&self) -> usize {
        let n = 1usize << self.ratio_pow;
        if self.scan_bytes() == 1 { n.max(2) } else { n }
    }

    /// Data bytes of one `FA` frame (checksum excluded); `None` when nothing is transmitted.
    pub fn frame_data_len(&self) -> Option<usize> {
        match self.scan_bytes() {
            0 => None,
            b => Some(b * self.scans_per_frame()),
        }
    }
}

/// A configuration set's acquisition as `buslab cpu196 cfgad` shows it: the raw bytes, the
/// 80C196 sequence, period and channels, and the PIC's masks.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ConfigReport {
    pub bank: u8,
    pub config: u8,
    /// `ad_init` of the set.
    pub c196: [u8; 18],
    /// PIC A/D mask, rate, forwarded mask.
    pub pic: [u8; 3],
}

impl fmt::Display for ConfigReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let raw: Vec<String> = self.c196.iter().map(|b| format!("{b:02X}")).collect();
        writeln!(f, "bank {} configuration {}", self.bank, self.config)?;
        writeln!(f, "  raw        {}", raw.join(" "))?;
        match AdConfig::parse(&self.c196) {
            Ok(cfg) => {
                writeln!(f, "  sequence   {:?}", cfg.sequence)?;
                writeln!(
                    f,
                    "  period     {:.1} µs (T = {}), {} scans per interrupt",
                    cfg.period_ns().get() as f64 / 1000.0,
                    cfg.time_base,
                    cfg.scans_per_frame()
                )?;
                for (ch, s) in cfg.transmitted() {
                    writeln!(
                        f,
                        "  channel {ch}  {}-bit format, filter {:?}",
                        s.format.name(),
                        s.filter
                    )?;
                }
            }
            Err(e) => writeln!(f, "  80C196 A/D not usable: {e}")?,
        }
        write!(
            f,
            "  PIC        A/D mask {:02X}h rate {:02X}h, forwarded {:02X}h",
            self.pic[0], self.pic[1], self.pic[2]
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sequence_nibbles_follow_the_seed_order() {
        let mut raw = [0u8; 18];
        // slots 0..=3 = channels 3,1,2,0 then end
        raw[0] = 0xF3; // slot 0 = 3, slot 15 = F
        raw[7] = (1u8 << 4) | 2; // byte 7: low = slot 2, high = slot 1
        raw[6] = 0x0F; // byte 6: low = slot 4 (F ends), high = slot 3
        for b in &mut raw[1..6] {
            *b = 0xFF;
        }
        raw[15] = ChannelSetup::byte(true, SampleFormat::Bits10, 0); // channel 0
        raw[12] = ChannelSetup::byte(true, SampleFormat::Bits8, 3); // channel 3
        let cfg = AdConfig::parse(&raw).unwrap();
        assert_eq!(cfg.sequence, vec![3, 1, 2, 0]);
        assert_eq!(cfg.channels[3].filter, Filter::LowPass(3));
        assert_eq!(cfg.scan_bytes(), 3);
        assert_eq!(AdConfig::parse(&cfg.encode()).unwrap(), cfg);
    }

    #[test]
    fn period_and_frame_length() {
        let cfg = AdConfig::simple(&[0, 1], SampleFormat::Bits16, 5, 2);
        assert_eq!(cfg.period_ns(), Nanos::new(100) * 800);
        assert_eq!(cfg.frame_data_len(), Some(4 * 4));
        let one = AdConfig::simple(&[0], SampleFormat::Bits8, 0, 0);
        assert_eq!(one.frame_data_len(), Some(2));
        let mut bad = one.encode();
        bad[17] = 5;
        assert_eq!(AdConfig::parse(&bad), Err(AdConfigError::Ratio(5)));
    }

    #[test]
    fn start_refusals_say_why() {
        let empty = [0xFF; 18];
        let err = AdConfig::check_start(&empty, LineSettings::n81(115_200)).unwrap_err();
        assert_eq!(err, AdRefusal::Config(AdConfigError::EmptySequence(0xF)));
        assert!(
            err.to_string().contains("conversion sequence is empty"),
            "{err}"
        );
        let fast = AdConfig::simple(&[0, 1, 2, 3, 4, 5, 6, 7], SampleFormat::Bits16, 0, 4);
        let err = AdConfig::check_start(&fast.encode(), LineSettings::n81(9600)).unwrap_err();
        assert!(
            err.to_string()
                .contains("% of the line at 9600 baud, at most 97 %"),
            "{err}"
        );
        let slow = AdConfig::simple(&[0], SampleFormat::Bits10, 235, 3);
        assert!(AdConfig::check_start(&slow.encode(), LineSettings::n81(115_200)).is_ok());
    }

    #[test]
    fn a_report_shows_the_sequence_period_and_channels() {
        let cfg = AdConfig::simple(&[0, 1], SampleFormat::Bits10, 235, 3);
        let report = ConfigReport {
            bank: 0,
            config: 1,
            c196: cfg.encode(),
            pic: [3, 3, 0],
        }
        .to_string();
        assert!(
            report.starts_with("bank 0 configuration 1\n  raw        "),
            "{report}"
        );
        assert!(report.contains("  sequence   [0, 1]\n"), "{report}");
        assert!(report.contains("  period     1000.0 µs (T = 235), 8 scans per interrupt"));
        assert!(report.contains("  channel 1  10-bit format, filter LowPass(0)"));
        assert!(report.ends_with("  PIC        A/D mask 03h rate 03h, forwarded 00h"));
        let empty = ConfigReport {
            c196: [0xFF; 18],
            ..ConfigReport {
                bank: 0,
                config: 4,
                c196: [0; 18],
                pic: [0; 3],
            }
        }
        .to_string();
        assert!(empty.contains("80C196 A/D not usable: the conversion sequence is empty"));
    }

    #[test]
    fn averaging_is_one_to_thirty_two() {
        assert_eq!(Filter::from_bits(9), Filter::Average(1));
        assert_eq!(Filter::from_bits(14), Filter::Average(32));
        assert_eq!(Filter::from_bits(15), Filter::Average(32));
    }
}
