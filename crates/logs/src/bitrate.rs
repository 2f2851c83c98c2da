//! The bus's bit rate as a log gives it, per channel: from its header (PEAK TRC's connection
//! table: `;   1    Connection1   TestNet@pcan_usb   CAN   500 kBit/s`) or from the frames'
//! lengths on the wire that some loggers record (Vector ASC's `Length = 240015` nanoseconds
//! after a frame, BLF's CAN_MESSAGE2 frame length): the frames' bits over their time.
//! candump, CSV, SQLite and pcap logs do not carry it.

use std::fmt;

use buslab_can::Frame;

/// A log's bit rate and where it was read.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LogBitRate {
    pub bits_per_s: u32,
    pub source: BitRateSource,
}

/// Where a log says its bit rate.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BitRateSource {
    /// A header names it (TRC's connection table).
    Header,
    /// The frames' recorded lengths on the wire (ASC `Length = …`, BLF CAN_MESSAGE2).
    FrameLengths,
}

impl fmt::Display for BitRateSource {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            BitRateSource::Header => "the log's header",
            BitRateSource::FrameLengths => "the frames' lengths in the log",
        })
    }
}

/// The bit rates a log may name or imply: CAN's whole range.
const RATES: std::ops::RangeInclusive<u64> = 1_000..=1_000_000;

/// The usual bit rates (CiA 301's, and 33.3, 47.6, 83.3 and 95.2 kbit/s of vehicle buses): a
/// rate computed from frame lengths within 1 % of one of them is taken as that one.
const USUAL: [u32; 13] = [
    10_000, 20_000, 33_333, 47_619, 50_000, 83_333, 95_238, 100_000, 125_000, 250_000, 500_000,
    800_000, 1_000_000,
];

/// Reads a bit rate written for people: `500 kBit/s`, `1 MBit/s`, `83.333 kbit/s`,
/// `125000 bit/s`; in `Nominal 1 MBit/s, Data 2 Mbit/s` the first (the arbitration rate).
/// `None` when the text names none, or one outside 1 kbit/s..1 Mbit/s.
pub(crate) fn parse_rate(text: &str) -> Option<u32> {
    let words: Vec<&str> = text.split_whitespace().collect();
    for (i, word) in words.iter().enumerate() {
        let word = word.trim_end_matches([',', ';']);
        let lower = word.to_ascii_lowercase();
        let Some(unit_at) = lower.find("bit/s") else {
            continue;
        };
        // The number is this word's start (`500kBit/s`) or the word before (`500 kBit/s`).
        let (number, prefix) = match lower[..unit_at].char_indices().last() {
            Some((p, c @ ('k' | 'm'))) if p > 0 => (&word[..p], Some(c)),
            Some((_, c @ ('k' | 'm'))) => (*words.get(i.checked_sub(1)?)?, Some(c)),
            Some(_) => (&word[..unit_at], None),
            None => (*words.get(i.checked_sub(1)?)?, None),
        };
        let scale = match prefix {
            Some('k') => 1e3,
            Some(_) => 1e6,
            None => 1.0,
        };
        let value: f64 = number.parse().ok()?;
        let bits = (value * scale).round();
        return (bits.is_finite() && RATES.contains(&(bits as u64))).then_some(bits as u32);
    }
    None
}

/// How far a logger's bit count may be from the frame's bits plus the intermission (CANoe's
/// differ by one now and then).
const MAX_BIT_COUNT_GAP: u64 = 3;

/// Frames' bits on the wire and their recorded lengths, per channel.
#[derive(Debug, Default)]
pub(crate) struct FrameLengths {
    /// Channel, bits (start of frame to the end of EOF), nanoseconds.
    channels: Vec<(u16, u64, u64)>,
}

impl FrameLengths {
    /// A frame on `channel` the log says took `length_ns` on the wire (from its start of frame
    /// to the end of its end of frame, as CANoe records it) and, when it says, `logged_bits`
    /// (its bit count, which CANoe gives with the 3-bit intermission, give or take a bit). A
    /// length of 0 (not measured), one no bit rate explains, or a bit count that is not this
    /// frame's (the line's numbers belong to another frame) is left out.
    pub(crate) fn add(
        &mut self,
        channel: u16,
        frame: &Frame,
        length_ns: u64,
        logged_bits: Option<u64>,
    ) {
        let bits = buslab_can::wire::encode(frame).on_bus().len() as u64;
        // At least a bit at 1 Mbit/s and at most one at 1 kbit/s per bit.
        if length_ns < bits * 1_000 || length_ns > bits * 1_000_000 {
            return;
        }
        if logged_bits.is_some_and(|logged| logged.abs_diff(bits + 3) > MAX_BIT_COUNT_GAP) {
            return;
        }
        match self.channels.iter_mut().find(|c| c.0 == channel) {
            Some(c) => {
                c.1 = c.1.saturating_add(bits);
                c.2 = c.2.saturating_add(length_ns);
            }
            None => self.channels.push((channel, bits, length_ns)),
        }
    }

    /// The bit rate of `channel`'s frames: a usual rate when within 1 %, else to the bit/s.
    pub(crate) fn rate(&self, channel: u16) -> Option<LogBitRate> {
        let &(_, bits, ns) = self.channels.iter().find(|c| c.0 == channel)?;
        let measured = bits as f64 * 1e9 / ns as f64;
        let usual = USUAL
            .into_iter()
            .find(|&r| (measured - f64::from(r)).abs() <= f64::from(r) / 100.0);
        let bits_per_s = usual.unwrap_or(measured.round() as u32);
        RATES
            .contains(&u64::from(bits_per_s))
            .then_some(LogBitRate {
                bits_per_s,
                source: BitRateSource::FrameLengths,
            })
    }
}

/// A TRC header's connection table: the rates by bus number, or one for the whole file (a
/// table without a bus column names one connection).
#[derive(Debug, Default)]
pub(crate) struct HeaderRates {
    /// Inside a table whose heading names `Bit rate`: whether its rows start with the bus.
    table: Option<bool>,
    by_bus: Vec<(u16, u32)>,
    all: Option<u32>,
}

impl HeaderRates {
    /// One comment line of the header (without its `;`).
    pub(crate) fn comment(&mut self, text: &str) {
        let text = text.trim();
        let heading = text.to_ascii_lowercase();
        if heading.contains("bit rate") {
            self.table = Some(heading.starts_with("bus"));
            return;
        }
        let Some(bus_column) = self.table else {
            return;
        };
        if text.starts_with('-') || text.is_empty() {
            self.table = None;
            return;
        }
        let Some(rate) = parse_rate(text) else {
            return;
        };
        if !bus_column {
            self.all.get_or_insert(rate);
        } else if let Some(bus) = text.split_whitespace().next().and_then(|b| b.parse().ok())
            && self.by_bus.len() < 256
            && !self.by_bus.iter().any(|(b, _)| *b == bus)
        {
            self.by_bus.push((bus, rate));
        }
    }

    /// The rate of bus `bus` (channel numbers count from 1, as TRC's bus column).
    pub(crate) fn rate(&self, bus: u16) -> Option<LogBitRate> {
        let rate = self
            .by_bus
            .iter()
            .find(|(b, _)| *b == bus)
            .map(|(_, r)| *r)
            .or(self.all)?;
        Some(LogBitRate {
            bits_per_s: rate,
            source: BitRateSource::Header,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rates_written_for_people_read() {
        for (text, rate) in [
            ("500 kBit/s", Some(500_000)),
            ("1 MBit/s", Some(1_000_000)),
            ("83.333 kbit/s", Some(83_333)),
            ("125000 bit/s", Some(125_000)),
            ("250kBit/s", Some(250_000)),
            ("PCAN_USB  Nominal 1 MBit/s, Data 2 Mbit/s", Some(1_000_000)),
            (
                "1    Connection1       TestNet@pcan_usb       CAN       500 kBit/s",
                Some(500_000),
            ),
            ("N/A                        N/A", None),
            ("kBit/s", None),
            ("x kBit/s", None),
            ("99999999999999999999 MBit/s", None),
            ("2 MBit/s", None),
            ("0.5 bit/s", None),
            ("NaN kbit/s", None),
            ("-500 kbit/s", None),
        ] {
            assert_eq!(parse_rate(text), rate, "{text:?}");
        }
    }

    #[test]
    fn frame_lengths_give_the_rate() {
        let mut l = FrameLengths::default();
        // 6F9#050C000000000000 is 120 bits; CANoe recorded 240015 ns at 500 kbit/s.
        let frame: Frame = "6F9#050C000000000000".parse().unwrap();
        l.add(1, &frame, 240_015, Some(124));
        assert_eq!(
            l.rate(1),
            Some(LogBitRate {
                bits_per_s: 500_000,
                source: BitRateSource::FrameLengths
            })
        );
        assert_eq!(l.rate(2), None);
        // Unmeasured (0) and impossible lengths are left out.
        l.add(2, &frame, 0, None);
        l.add(2, &frame, 5, None);
        assert_eq!(l.rate(2), None);
        // A bit count that is not this frame's: the line's numbers are another frame's.
        l.add(2, &frame, 1_704_000, Some(145));
        assert_eq!(l.rate(2), None);
        // An unusual rate is given to the bit/s.
        l.add(3, &frame, 1_000_000, None);
        assert_eq!(l.rate(3).unwrap().bits_per_s, 120_000);
    }

    #[test]
    fn a_trc_connection_table_gives_each_bus_its_rate() {
        let mut h = HeaderRates::default();
        for line in [
            "   Start time: 29.07.2009 12:35:20.701.0",
            "-------------------------------------------------------------------------------",
            "   Bus  Name              Connection             Protocol  Bit rate",
            "   1    Connection1       TestNet@pcan_usb       CAN       500 kBit/s",
            "   2    Connection2       USB-Internal@pcan_usb  CAN       1 MBit/s",
            "-------------------------------------------------------------------------------",
            "   3    not a row: after the table             CAN       250 kBit/s",
        ] {
            h.comment(line);
        }
        assert_eq!(h.rate(1).unwrap().bits_per_s, 500_000);
        assert_eq!(h.rate(2).unwrap().bits_per_s, 1_000_000);
        assert_eq!(h.rate(3), None);

        let mut one = HeaderRates::default();
        for line in [
            "   Connection                 Bit rate",
            "   PCANLight_USB_16@pcan_usb  Nominal 1 MBit/s, Data 2 Mbit/s",
            "----------------------------------------",
        ] {
            one.comment(line);
        }
        assert_eq!(one.rate(1).unwrap().bits_per_s, 1_000_000);
        assert_eq!(one.rate(7).unwrap().source, BitRateSource::Header);

        let mut none = HeaderRates::default();
        for line in [
            "   Connection                 Bit rate",
            "   N/A   N/A",
            "---",
        ] {
            none.comment(line);
        }
        assert_eq!(none.rate(1), None);
    }
}
