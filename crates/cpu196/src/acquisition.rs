//! The 80C196 acquisition at run time (SPEC C4): conversion sequence, filters, formats and
//! the `FA` frames, in virtual time.
//!
//! One *scan* converts every channel of the sequence, once per sampling period
//! (75 + 5·T) × 0.8 µs. Every 2^ratio scans the A/D interrupt fires: the kernel appends those
//! scans to one `FA` frame (transmitted channels in ascending order, each in its format, 16-bit
//! values little-endian) and calls `AD_prog`.

use std::collections::VecDeque;

use buslab_device::Nanos;

use crate::adconfig::{AdConfig, Filter, SampleFormat};
use crate::source::Source;

/// The programmable 16 → 8 bit compression (`tab_lin_log16_8[256]`): `table[i]` is the lowest
/// 16-bit value coded `i`; the code of `v` is the largest `i` with `table[i] ≤ v`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct LogTable(pub [u16; 256]);

impl Default for LogTable {
    /// Logarithmic, centred on 8000h: code 128 + c above the centre and 127 − c below, with
    /// c = ⌊127 · ln(1 + d/256) / ln(129)⌋ for the distance d to the centre.
    fn default() -> Self {
        let code = |v: u32| -> u8 {
            let (d, up) = if v >= 0x8000 {
                (v - 0x8000, true)
            } else {
                (0x8000 - v, false)
            };
            // (The epsilon keeps d = 32768 on code 0 despite rounding.)
            let c = (127.0 * (1.0 + d as f64 / 256.0).ln() / 129f64.ln() + 1e-9)
                .floor()
                .min(127.0) as u8;
            if up { 128 + c } else { 127 - c }
        };
        let mut t = [u16::MAX; 256];
        for v in (0..=0xFFFFu32).rev() {
            t[code(v) as usize] = v as u16;
        }
        // Codes no value reaches take their successor's threshold (keeps the table monotonic).
        for i in (0..255).rev() {
            if t[i] == u16::MAX {
                t[i] = t[i + 1];
            }
        }
        t[0] = 0;
        Self(t)
    }
}

impl LogTable {
    pub fn compress(&self, v: u16) -> u8 {
        (self.0.partition_point(|&t| t <= v).max(1) - 1) as u8
    }

    /// Middle of the values coded `code`.
    pub fn expand(&self, code: u8) -> u16 {
        let lo = self.0[code as usize] as u32;
        let hi = self.0.get(code as usize + 1).map_or(0x10000, |&t| t as u32);
        ((lo + hi.max(lo + 1) - 1) / 2) as u16
    }

    pub fn from_bytes(b: &[u8; 512]) -> Self {
        Self(core::array::from_fn(|i| {
            u16::from_le_bytes([b[2 * i], b[2 * i + 1]])
        }))
    }
}

#[derive(Clone, Debug)]
enum FilterState {
    LowPass { rank: u8, y: Option<i32> },
    Average { window: VecDeque<u16>, size: usize },
}

impl FilterState {
    fn new(f: Filter) -> Self {
        match f {
            Filter::LowPass(rank) => Self::LowPass { rank, y: None },
            Filter::Average(n) => Self::Average {
                window: VecDeque::new(),
                size: n as usize,
            },
        }
    }

    /// Feeds a 10-bit conversion; returns the filtered value on the 16-bit scale (× 64).
    fn update(&mut self, code: u16) -> u16 {
        let x = code as i32 * 64;
        match self {
            // A first-order IIR, α = 2^−rank; it starts at the first sample.
            Self::LowPass { rank, y } => {
                let prev = y.unwrap_or(x);
                let next = prev + ((x - prev) >> *rank);
                *y = Some(next);
                next.clamp(0, 0xFFFF) as u16
            }
            Self::Average { window, size } => {
                window.push_back(code);
                if window.len() > *size {
                    window.pop_front();
                }
                // Before the window is full, the average is over what has arrived.
                let sum: u32 = window.iter().map(|&v| v as u32).sum();
                ((sum * 64) / window.len() as u32).min(0xFFFF) as u16
            }
        }
    }
}

/// Encodes one value on the 16-bit scale into its format.
pub fn format_value(format: SampleFormat, v16: u16, table: &LogTable, out: &mut Vec<u8>) {
    match format {
        SampleFormat::Bits16 => out.extend_from_slice(&v16.to_le_bytes()),
        SampleFormat::Bits10 => {
            out.extend_from_slice(&((v16 as u32 + 32) >> 6).min(1023).to_le_bytes()[..2])
        }
        SampleFormat::Bits8 => out.push((v16 >> 8) as u8),
        SampleFormat::Log8 => out.push(table.compress(v16)),
    }
}

/// Decodes one `FA` frame into scans of (channel, value in 10-bit units as f64).
pub fn decode_frame(cfg: &AdConfig, data: &[u8], table: &LogTable) -> Vec<Vec<(u8, f64)>> {
    let mut scans = Vec::new();
    if cfg.scan_bytes() == 0 {
        // Nothing is transmitted: the loop below would never move through `data`.
        return scans;
    }
    let mut at = 0;
    while at < data.len() {
        let mut scan = Vec::new();
        for (ch, setup) in cfg.transmitted() {
            let w = setup.format.width();
            let Some(b) = data.get(at..at + w) else {
                return scans;
            };
            at += w;
            let v = match setup.format {
                SampleFormat::Bits16 => u16::from_le_bytes([b[0], b[1]]) as f64 / 64.0,
                SampleFormat::Bits10 => u16::from_le_bytes([b[0], b[1]]) as f64,
                SampleFormat::Bits8 => b[0] as f64 * 4.0,
                SampleFormat::Log8 => table.expand(b[0]) as f64 / 64.0,
            };
            scan.push((ch, v));
        }
        scans.push(scan);
    }
    scans
}

/// A running acquisition.
#[derive(Clone, Debug)]
pub struct Acquisition {
    config: AdConfig,
    /// `config`'s scans per `FA` frame and scan period: asked at every step of the board
    /// (`Board::next_deadline`), so worked out once.
    scans_per_frame: u64,
    period_ns: Nanos,
    filters: Vec<FilterState>,
    next_scan_at: Nanos,
    /// Latest filtered value of each channel on the 16-bit scale (`ad_voie[n].donnee`).
    pub values: [u16; 8],
    pub scans: u64,
}

impl Acquisition {
    pub fn new(config: AdConfig, start_ns: Nanos) -> Self {
        let filters = config
            .channels
            .iter()
            .map(|c| FilterState::new(c.filter))
            .collect();
        let period_ns = config.period_ns();
        Self {
            scans_per_frame: config.scans_per_frame() as u64,
            period_ns,
            next_scan_at: start_ns + period_ns,
            config,
            filters,
            values: [0; 8],
            scans: 0,
        }
    }

    /// When the scan completing the next interrupt happens.
    pub fn next_interrupt_at(&self) -> Nanos {
        let spf = self.scans_per_frame;
        let done = self.scans % spf;
        self.next_scan_at + (spf - 1 - done) * self.period_ns
    }

    fn scan(&mut self, inputs: &[Source; 8], table: &LogTable, frame: &mut Vec<u8>) {
        let t = self.next_scan_at;
        for &ch in &self.config.sequence {
            let code = crate::source::reading10(&inputs[ch as usize], t);
            self.values[ch as usize] = self.filters[ch as usize].update(code);
        }
        for (ch, setup) in self.config.transmitted() {
            format_value(setup.format, self.values[ch as usize], table, frame);
        }
        self.scans += 1;
        self.next_scan_at += self.period_ns;
    }

    /// Runs the scans of one interrupt (the caller checks [`next_interrupt_at`] first);
    /// returns the `FA` data (empty when no channel is transmitted).
    ///
    /// [`next_interrupt_at`]: Self::next_interrupt_at
    pub fn run_interrupt(&mut self, inputs: &[Source; 8], table: &LogTable) -> Vec<u8> {
        let spf = self.scans_per_frame;
        let mut frame = Vec::with_capacity(self.config.frame_data_len().unwrap_or(0));
        loop {
            self.scan(inputs, table, &mut frame);
            if self.scans.is_multiple_of(spf) {
                return frame;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn log_table_is_monotonic_and_centred() {
        let t = LogTable::default();
        assert!(t.0.windows(2).all(|w| w[0] <= w[1]));
        assert_eq!(t.compress(0), 0);
        assert_eq!(t.compress(0xFFFF), 255);
        assert_eq!(t.compress(0x8000), 128);
        assert_eq!(t.compress(0x7FFF), 127);
        // Near the centre the steps are fine, far away coarse.
        for v in [0x8000u16, 0x8100, 0x9000, 0xC000, 0x4000, 0x100] {
            let back = t.expand(t.compress(v)) as i32;
            let step = (v as i32 - 0x8000).abs() / 20 + 16;
            assert!((back - v as i32).abs() <= step, "{v:#x} -> {back:#x}");
        }
    }

    #[test]
    fn low_pass_converges_and_average_smooths() {
        let mut lp = FilterState::new(Filter::LowPass(2));
        assert_eq!(lp.update(100), 6400);
        let mut v = 0;
        for _ in 0..60 {
            v = lp.update(500);
        }
        assert!((v as i32 - 32000).abs() <= 64, "{v}");
        let mut avg = FilterState::new(Filter::Average(4));
        assert_eq!(avg.update(100), 6400);
        assert_eq!(avg.update(300), 12800);
        avg.update(100);
        assert_eq!(avg.update(300), 12800);
        assert_eq!(avg.update(500), (300 + 100 + 300 + 500) * 16);
    }

    #[test]
    fn frames_carry_the_configured_channels() {
        let cfg = AdConfig::simple(&[0, 2], SampleFormat::Bits10, 0, 1);
        let mut inputs: [Source; 8] = Default::default();
        inputs[0] = Source::Constant(5.0);
        inputs[2] = Source::Constant(2.5);
        let mut acq = Acquisition::new(cfg.clone(), Nanos::ZERO);
        assert_eq!(acq.next_interrupt_at(), Nanos::new(2) * 60_000);
        let table = LogTable::default();
        let frame = acq.run_interrupt(&inputs, &table);
        assert_eq!(frame, vec![0xFF, 0x03, 0x00, 0x02, 0xFF, 0x03, 0x00, 0x02]);
        assert_eq!(acq.next_interrupt_at(), Nanos::new(4) * 60_000);
        let scans = decode_frame(&cfg, &frame, &table);
        assert_eq!(scans, vec![vec![(0, 1023.0), (2, 512.0)]; 2]);
        // A frame for a layout that transmits nothing has no scans (it looped forever).
        let silent = AdConfig::simple(&[], SampleFormat::Bits10, 0, 1);
        assert!(decode_frame(&silent, &frame, &table).is_empty());
        // A short tail is left out.
        assert_eq!(decode_frame(&cfg, &frame[..5], &table).len(), 1);
    }
}
