//! What a log holds, counted as its entries go by (`buslab log info`): per interface, frames
//! by kind, error frames, the time span, the bits on the wire for the load, the busiest IDs.
//! Bounded: at most [`MAX_IDS`] distinct IDs are counted per interface. CAN FD frames are
//! counted (and among them in [`InterfaceStats::fd`]) but not in the load: an FD frame's time
//! on the wire depends on its data phase's bit rate, which no log gives.

use std::collections::{BTreeMap, HashMap};
use std::time::Duration;

use buslab_can::wire::frame_bits;

use crate::{Message, Record, Timestamp};

/// The most distinct IDs counted per interface (bounded memory).
pub const MAX_IDS: usize = 100_000;

/// One interface's counts.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct InterfaceStats {
    /// Frames, classic and CAN FD.
    pub frames: u64,
    /// CAN FD frames among them (their bits are not in [`bits`](Self::bits)).
    pub fd: u64,
    pub errors: u64,
    pub remote: u64,
    pub extended: u64,
    /// Bit-times the classic frames took on the wire, stuffing and intermission included.
    pub bits: u64,
    pub first: Option<Timestamp>,
    pub last: Option<Timestamp>,
    ids: HashMap<(bool, u32), u64>,
    /// More than [`MAX_IDS`] distinct IDs were seen: [`ids`](Self::ids) is a lower bound.
    pub ids_overflow: bool,
}

impl InterfaceStats {
    /// Distinct IDs counted (a lower bound when [`ids_overflow`](Self::ids_overflow)).
    pub fn ids(&self) -> usize {
        self.ids.len()
    }

    /// The `n` most frequent IDs, `(extended, id, count)`, most frequent first, then by ID.
    pub fn busiest(&self, n: usize) -> Vec<(bool, u32, u64)> {
        let mut all: Vec<(bool, u32, u64)> = self
            .ids
            .iter()
            .map(|(&(ext, id), &count)| (ext, id, count))
            .collect();
        all.sort_by(|a, b| b.2.cmp(&a.2).then((a.0, a.1).cmp(&(b.0, b.1))));
        all.truncate(n);
        all
    }

    /// From the first entry to the last.
    pub fn span(&self) -> Duration {
        self.last
            .unwrap_or_default()
            .saturating_since(self.first.unwrap_or_default())
    }

    /// The load at `bits_per_s` in percent; `None` over a span of one instant.
    pub fn load_percent(&self, bits_per_s: u32) -> Option<f64> {
        let span = self.span();
        (!span.is_zero())
            .then(|| 100.0 * self.bits as f64 / (span.as_secs_f64() * f64::from(bits_per_s)))
    }
}

/// A log's counts per interface, in name order.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct LogStats {
    pub interfaces: BTreeMap<String, InterfaceStats>,
}

impl LogStats {
    /// Counts `entry`; returns the bit-times a classic frame took on the wire (`None` for an
    /// error frame or a CAN FD frame).
    pub fn add(&mut self, entry: &Message) -> Option<u64> {
        let s = match self.interfaces.get_mut(&entry.channel) {
            Some(s) => s,
            None => self.interfaces.entry(entry.channel.clone()).or_default(),
        };
        s.first = Some(s.first.map_or(entry.at, |f| f.min(entry.at)));
        s.last = Some(s.last.map_or(entry.at, |l| l.max(entry.at)));
        let (extended, raw) = match &entry.record {
            Record::Error(_) => {
                s.errors += 1;
                return None;
            }
            Record::Fd(f) => (f.is_extended(), f.id().as_raw()),
            Record::Frame(f) => (f.is_extended(), f.id().as_raw()),
        };
        s.frames += 1;
        s.extended += u64::from(extended);
        let key = (extended, raw);
        if let Some(n) = s.ids.get_mut(&key) {
            *n += 1;
        } else if s.ids.len() < MAX_IDS {
            s.ids.insert(key, 1);
        } else {
            s.ids_overflow = true;
        }
        match &entry.record {
            Record::Frame(f) => {
                s.remote += u64::from(f.is_remote());
                let bits = frame_bits(f);
                s.bits += bits;
                Some(bits)
            }
            _ => {
                // Counted, but not in the bus load: an FD frame's time depends on its two
                // bit rates, which a log does not say.
                s.fd += 1;
                None
            }
        }
    }

    pub fn frames(&self) -> u64 {
        self.interfaces.values().map(|s| s.frames).sum()
    }

    pub fn errors(&self) -> u64 {
        self.interfaces.values().map(|s| s.errors).sum()
    }

    /// The earliest and the latest entry of any interface.
    pub fn first_last(&self) -> Option<(Timestamp, Timestamp)> {
        let first = self.interfaces.values().filter_map(|s| s.first).min()?;
        let last = self.interfaces.values().filter_map(|s| s.last).max()?;
        Some((first, last))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use buslab_bus::ErrorFrame;

    fn entry(t_ms: u64, channel: &str, frame: &str) -> Message {
        Message {
            at: Timestamp::since_epoch(Duration::from_millis(t_ms)),
            channel: channel.into(),
            record: Record::Frame(frame.parse().unwrap()),
            direction: None,
        }
    }

    #[test]
    fn counts_per_interface_with_the_busiest_ids_and_the_load() {
        let mut stats = LogStats::default();
        for (t, i, f) in [
            (0, "can0", "123#11"),
            (10, "can0", "123#22"),
            (20, "can0", "12345678#"),
            (30, "can0", "7FF#R"),
            (5, "can1", "100#"),
        ] {
            assert!(stats.add(&entry(t, i, f)).is_some());
        }
        let error = Message {
            at: Timestamp::since_epoch(Duration::from_millis(40)),
            channel: "can0".into(),
            record: Record::Error(ErrorFrame::default()),
            direction: None,
        };
        assert_eq!(stats.add(&error), None);
        assert_eq!((stats.frames(), stats.errors()), (5, 1));
        let can0 = &stats.interfaces["can0"];
        assert_eq!((can0.extended, can0.remote, can0.ids()), (1, 1, 3));
        assert_eq!(can0.busiest(2), [(false, 0x123, 2), (false, 0x7FF, 1)]);
        assert_eq!(can0.span(), Duration::from_millis(40));
        let bits: u64 = ["123#11", "123#22", "12345678#", "7FF#R"]
            .iter()
            .map(|f| frame_bits(&f.parse().unwrap()))
            .sum();
        assert_eq!(can0.bits, bits);
        let load = can0.load_percent(125_000).unwrap();
        assert!(
            (load - 100.0 * bits as f64 / 5_000.0).abs() < 1e-9,
            "{load}"
        );
        assert_eq!(stats.interfaces["can1"].load_percent(125_000), None);
        assert_eq!(
            stats.first_last(),
            Some((Timestamp::EPOCH, Timestamp::from_micros(40_000)))
        );
    }

    #[test]
    fn fd_frames_are_counted_but_not_in_the_load() {
        let mut stats = LogStats::default();
        assert!(stats.add(&entry(0, "can0", "123#11")).is_some());
        for (t, fd) in [(10, "123##1112233"), (20, "12345678##0")] {
            let e = Message {
                record: Record::Fd(fd.parse().unwrap()),
                ..entry(t, "can0", "123#")
            };
            assert_eq!(stats.add(&e), None);
        }
        let can0 = &stats.interfaces["can0"];
        assert_eq!(
            (can0.frames, can0.fd, can0.extended, can0.ids()),
            (3, 2, 1, 2)
        );
        assert_eq!(can0.busiest(1), [(false, 0x123, 2)]);
        assert_eq!(can0.bits, frame_bits(&"123#11".parse().unwrap()));
        assert_eq!(can0.span(), Duration::from_millis(20));
    }

    #[test]
    fn distinct_ids_are_bounded() {
        let mut stats = LogStats::default();
        for id in 0..(MAX_IDS as u32 + 10) {
            stats.add(&entry(0, "can0", &format!("{id:08X}#")));
        }
        let can0 = &stats.interfaces["can0"];
        assert_eq!(can0.ids(), MAX_IDS);
        assert!(can0.ids_overflow);
    }
}
