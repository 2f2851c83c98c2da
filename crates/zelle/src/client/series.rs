//! Measurement series: the 8 parameter bytes, and splitting dumped values into channels.

use std::fmt::Write as _;

use buslab_device::Nanos;

use crate::analog::to_volts;
use crate::timing::{CONVERSION_NS, MS};

/// What a series measures: `cycles` scan cycles per block; in each cycle the enabled channel
/// slots are converted in order (about 1 ms each), then the cell waits out the rest of the
/// interval.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SeriesParams {
    /// Scan cycles per block ("block length"), 0..65535.
    pub cycles: u16,
    /// The four channel slots: 1..4, or 0 for off.
    pub slots: [u8; 4],
    /// Time from one cycle to the next, in ms. At least one ms per enabled channel.
    pub interval_ms: u32,
}

impl SeriesParams {
    /// A series over `channels` (1..4 each, at most four), `cycles` per block, one cycle every
    /// `interval_ms`.
    pub fn new(channels: &[u8], cycles: u16, interval_ms: u32) -> Result<Self, SeriesError> {
        if channels.len() > 4 {
            return Err(SeriesError::TooManyChannels(channels.len()));
        }
        let mut slots = [0; 4];
        slots[..channels.len()].copy_from_slice(channels);
        let params = SeriesParams {
            cycles,
            slots,
            interval_ms,
        };
        params.check()?;
        Ok(params)
    }

    /// [`new`](Self::new) with the interval as a duration, which must be a whole number of
    /// milliseconds.
    pub fn with_interval(
        channels: &[u8],
        cycles: u16,
        interval: std::time::Duration,
    ) -> Result<Self, SeriesError> {
        let interval_ms = u32::try_from(interval.as_millis())
            .ok()
            .filter(|_| interval.subsec_nanos().is_multiple_of(1_000_000))
            .ok_or(SeriesError::WholeMilliseconds(interval))?;
        Self::new(channels, cycles, interval_ms)
    }

    /// The enabled channels in slot order.
    pub fn channels(&self) -> Vec<u8> {
        self.slots.iter().copied().filter(|&c| c != 0).collect()
    }

    fn check(&self) -> Result<(), SeriesError> {
        if let Some(&bad) = self.slots.iter().find(|&&c| c > 4) {
            return Err(SeriesError::Channel(bad));
        }
        let n = self.channels().len() as u32;
        if n == 0 {
            return Err(SeriesError::NoChannels);
        }
        if self.interval_ms < n || self.interval_ms - n > u32::from(u16::MAX) {
            return Err(SeriesError::Interval {
                interval_ms: self.interval_ms,
                channels: n,
            });
        }
        Ok(())
    }

    /// The 8 bytes command 1 sends: block length, four channel slots, and the interval minus
    /// the number of channels (the conversions take a millisecond each), high byte first.
    pub fn to_bytes(&self) -> Result<[u8; 8], SeriesError> {
        self.check()?;
        let n = self.channels().len() as u32;
        let [bh, bl] = self.cycles.to_be_bytes();
        let [ih, il] = ((self.interval_ms - n) as u16).to_be_bytes();
        let s = self.slots;
        Ok([bh, bl, s[0], s[1], s[2], s[3], ih, il])
    }

    /// Reads the 8 parameter bytes back (as found at 0800h).
    pub fn from_bytes(p: [u8; 8]) -> Self {
        let slots = [p[2], p[3], p[4], p[5]];
        let n = slots.iter().filter(|&&c| c != 0).count() as u32;
        SeriesParams {
            cycles: u16::from_be_bytes([p[0], p[1]]),
            slots,
            interval_ms: u32::from(u16::from_be_bytes([p[6], p[7]])) + n,
        }
    }

    /// How long one block takes on the cell.
    pub fn block_ns(&self) -> Nanos {
        let n = self.channels().len() as u64;
        if self.cycles == 0 {
            return Nanos::ZERO;
        }
        MS * ((u64::from(self.cycles) - 1) * u64::from(self.interval_ms)) + CONVERSION_NS * n
    }
}

/// Series parameters out of range.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
pub enum SeriesError {
    #[error("channel {0} is out of range 1..4 (0 = slot off)")]
    Channel(u8),
    #[error("{0} channels given; the cell has four slots")]
    TooManyChannels(usize),
    #[error("no channel enabled; give 1 to 4 channels in 1..4")]
    NoChannels,
    #[error(
        "interval {interval_ms} ms is out of range {channels}..{} ms for {channels} channel(s) \
         (each conversion takes 1 ms of the interval)",
        u32::from(u16::MAX) + channels
    )]
    Interval { interval_ms: u32, channels: u32 },
    #[error("interval {} must be a whole number of ms", buslab_device::Human(*.0))]
    WholeMilliseconds(std::time::Duration),
}

/// A finished series: one row per scan cycle.
#[derive(Clone, Debug, PartialEq)]
pub struct Measurement {
    pub params: SeriesParams,
    /// The channel of each column.
    pub channels: Vec<u8>,
    pub rows: Vec<Row>,
    /// Readings the started blocks should have given: more than the rows hold when a block
    /// was cut short (the stop or the next START reached the cell before it ended) or the
    /// data area filled up.
    pub expected_values: usize,
}

/// One scan cycle.
#[derive(Clone, Debug, PartialEq)]
pub struct Row {
    /// When the cycle's first conversion started, from the start of the first block. Channel
    /// k of the cycle was sampled k ms later.
    pub time_ns: Nanos,
    /// One reading per column; a cycle cut short by a full data area has fewer.
    pub values: Vec<u8>,
}

impl Measurement {
    /// Splits `values` (as dumped after the 8 parameter bytes) into cycles. `block_starts`
    /// gives each block's start time; blocks hold `params.cycles` cycles each.
    pub fn split(params: SeriesParams, values: &[u8], block_starts: &[Nanos]) -> Measurement {
        let channels = params.channels();
        let per_row = channels.len().max(1);
        let per_block = usize::from(params.cycles).max(1);
        let period = MS * u64::from(params.interval_ms);
        let rows = values
            .chunks(per_row)
            .enumerate()
            .map(|(i, chunk)| {
                let (block, cycle) = (i / per_block, i % per_block);
                let start = block_starts.get(block).copied().unwrap_or_else(|| {
                    // More blocks than the host started (a START key on the cell): place them
                    // right after each other.
                    block_starts.last().copied().unwrap_or(Nanos::ZERO)
                        + params.block_ns() * (block + 1 - block_starts.len()) as u64
                });
                Row {
                    time_ns: start + period * cycle as u64,
                    values: chunk.to_vec(),
                }
            })
            .collect();
        Measurement {
            params,
            channels,
            rows,
            expected_values: block_starts.len() * per_block * per_row,
        }
    }

    /// Readings missing from the started blocks (0 for a whole series).
    pub fn missing_values(&self) -> usize {
        let got: usize = self.rows.iter().map(|r| r.values.len()).sum();
        self.expected_values.saturating_sub(got)
    }

    /// CSV: `time_s,ch1,ch2,...` with raw readings 0..255, or volts if `volts`.
    pub fn to_csv(&self, volts: bool) -> String {
        let mut out = String::from("time_s");
        for (i, ch) in self.channels.iter().enumerate() {
            let dup = self.channels[..i].iter().filter(|&c| c == ch).count();
            let _ = match dup {
                0 => write!(out, ",ch{ch}"),
                d => write!(out, ",ch{ch}_{}", d + 1),
            };
        }
        out.push('\n');
        for row in &self.rows {
            let _ = write!(out, "{:.3}", row.time_ns.get() as f64 * 1e-9);
            for i in 0..self.channels.len() {
                out.push(',');
                if let Some(&v) = row.values.get(i) {
                    let _ = if volts {
                        write!(out, "{:.3}", to_volts(v))
                    } else {
                        write!(out, "{v}")
                    };
                }
            }
            out.push('\n');
        }
        out
    }
}

impl Measurement {
    /// A character plot of every channel, `width` × `height` points, 0..255 on the y axis,
    /// with the time axis and a legend below.
    pub fn plot(&self, width: usize, height: usize) -> String {
        const MARKS: [char; 4] = ['*', '+', 'o', 'x'];
        let (width, height) = (width.max(8), height.max(2));
        let mut grid = vec![vec![' '; width]; height];
        let n = self.rows.len().max(1);
        for (i, row) in self.rows.iter().enumerate() {
            let x = i * (width - 1) / n.max(2).saturating_sub(1).max(1);
            for (c, &v) in row.values.iter().enumerate() {
                let y = (height - 1) - usize::from(v) * (height - 1) / 255;
                grid[y][x.min(width - 1)] = MARKS[c % MARKS.len()];
            }
        }
        let mut out = String::new();
        for (r, line) in grid.iter().enumerate() {
            out.push_str(match r {
                0 => "255 |",
                r if r == height - 1 => "  0 |",
                _ => "    |",
            });
            out.extend(line.iter());
            out.push('\n');
        }
        let last = self
            .rows
            .last()
            .map_or(0.0, |r| r.time_ns.get() as f64 * 1e-9);
        let _ = writeln!(out, "    +{}", "-".repeat(width));
        let _ = writeln!(out, "     0 s{:>w$}", format!("{last:.2} s"), w = width - 3);
        let legend: Vec<String> = self
            .channels
            .iter()
            .enumerate()
            .map(|(i, ch)| format!("{} ch{ch}", MARKS[i % MARKS.len()]))
            .collect();
        let _ = writeln!(out, "     {}", legend.join("   "));
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn intervals_must_be_whole_milliseconds() {
        use std::time::Duration;
        let p = SeriesParams::with_interval(&[1], 3, Duration::from_millis(10)).unwrap();
        assert_eq!(p.interval_ms, 10);
        let err = SeriesParams::with_interval(&[1], 3, Duration::from_micros(1500)).unwrap_err();
        assert_eq!(
            err.to_string(),
            "interval 1.50 ms must be a whole number of ms"
        );
        let err = SeriesParams::with_interval(&[1, 2, 3], 3, Duration::from_millis(2)).unwrap_err();
        assert!(
            err.to_string().starts_with("interval 2 ms is out of range"),
            "{err}"
        );
    }

    #[test]
    fn the_plot_marks_each_channel_and_names_the_span() {
        let p = SeriesParams::new(&[1, 2], 3, 10).unwrap();
        let m = Measurement::split(p, &[0, 255, 128, 128, 255, 0], &[Nanos::ZERO]);
        let plot = m.plot(20, 5);
        let lines: Vec<&str> = plot.lines().collect();
        assert_eq!(lines.len(), 5 + 3);
        assert!(
            lines[0].starts_with("255 |+") && lines[0].ends_with('*'),
            "{plot}"
        );
        assert!(
            lines[4].starts_with("  0 |*") && lines[4].ends_with('+'),
            "{plot}"
        );
        assert!(lines[6].trim_end().ends_with("0.02 s"), "{plot}");
        assert_eq!(lines[7].trim(), "* ch1   + ch2");
    }

    #[test]
    fn parameter_bytes_subtract_the_conversions() {
        let p = SeriesParams::new(&[1, 3], 300, 10).unwrap();
        let b = p.to_bytes().unwrap();
        assert_eq!(b, [0x01, 0x2C, 1, 3, 0, 0, 0, 8]);
        assert_eq!(SeriesParams::from_bytes(b), p);
    }

    #[test]
    fn bad_parameters_name_the_value() {
        assert_eq!(SeriesParams::new(&[5], 1, 10), Err(SeriesError::Channel(5)));
        assert_eq!(SeriesParams::new(&[], 1, 10), Err(SeriesError::NoChannels));
        assert_eq!(
            SeriesParams::new(&[1, 2, 3], 1, 2).unwrap_err().to_string(),
            "interval 2 ms is out of range 3..65538 ms for 3 channel(s) (each conversion takes 1 ms of the interval)"
        );
        assert_eq!(
            SeriesParams::new(&[1, 2, 3, 4, 1], 1, 20),
            Err(SeriesError::TooManyChannels(5))
        );
    }

    #[test]
    fn split_makes_rows_with_times_and_csv() {
        let p = SeriesParams::new(&[2, 1], 2, 10).unwrap();
        let m = Measurement::split(
            p,
            &[1, 2, 3, 4, 5, 6, 7],
            &[Nanos::ZERO, Nanos::from_secs(1)],
        );
        assert_eq!(m.rows.len(), 4);
        // Two blocks of 2 cycles of 2 channels: the last reading is missing.
        assert_eq!(m.missing_values(), 1);
        assert_eq!(m.rows[1].time_ns, Nanos::from_millis(10));
        assert_eq!(m.rows[2].time_ns, Nanos::from_secs(1));
        assert_eq!(
            m.to_csv(false),
            "time_s,ch2,ch1\n0.000,1,2\n0.010,3,4\n1.000,5,6\n1.010,7,\n"
        );
        assert!(m.to_csv(true).contains("0.000,0.020,0.039"));
    }
}
