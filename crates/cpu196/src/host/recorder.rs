//! Samples from `FA`/`FB` traffic, typed, to any sink: a CSV file, a plot, a web panel.

use std::fmt;
use std::io::{self, Write};
use std::time::Duration;

use crate::acquisition::{LogTable, decode_frame};
use crate::adconfig::AdConfig;
use crate::message::{AdSample, Message};
use crate::source::code10_to_volts;

/// Which converter took a sample.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum SampleSource {
    /// The 80C196's own A/D (`FA` frames, the set's conversion sequence).
    C196,
    /// The PIC's A/D (`FB`).
    Pic,
    /// A virtual channel (`FB`): a number the program computed, no volts.
    Virtual,
}

impl SampleSource {
    /// The name the CSV and the figures use.
    pub fn name(self) -> &'static str {
        match self {
            SampleSource::C196 => "c196",
            SampleSource::Pic => "pic",
            SampleSource::Virtual => "virtual",
        }
    }
}

impl fmt::Display for SampleSource {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// One sample as recorded.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample {
    /// Seconds from the recording's start: the scan's place in the conversion sequence for
    /// `FA` samples (board time), the client's clock for `FB` ones.
    pub t_s: f64,
    pub source: SampleSource,
    pub channel: u8,
    /// The converter's code (10 bits; a log8 sample expanded through the log table), or the
    /// virtual channel's number.
    pub value: f64,
    /// The code in volts; `None` for virtual channels.
    pub volts: Option<f64>,
}

/// Where a [`Recorder`] puts its samples.
pub trait SampleSink {
    fn sample(&mut self, sample: &Sample) -> io::Result<()>;
    /// The recording ended: write out what is buffered.
    fn flush(&mut self) -> io::Result<()> {
        Ok(())
    }
}

/// Both sinks, each sample to the first then the second (a CSV file and a figure).
impl<A: SampleSink, B: SampleSink> SampleSink for (A, B) {
    fn sample(&mut self, sample: &Sample) -> io::Result<()> {
        self.0.sample(sample)?;
        self.1.sample(sample)
    }

    fn flush(&mut self) -> io::Result<()> {
        self.0.flush()?;
        self.1.flush()
    }
}

/// Samples as CSV rows `t_s,source,channel,value,volts` (volts empty for virtual channels).
pub struct CsvSamples<W: Write> {
    out: W,
}

impl<W: Write> CsvSamples<W> {
    /// Writes the header to `out`.
    pub fn new(mut out: W) -> io::Result<Self> {
        writeln!(out, "t_s,source,channel,value,volts")?;
        Ok(Self { out })
    }

    pub fn into_inner(self) -> W {
        self.out
    }
}

impl<W: Write> SampleSink for CsvSamples<W> {
    fn sample(&mut self, s: &Sample) -> io::Result<()> {
        let (t, source, channel, value) = (s.t_s, s.source, s.channel, s.value);
        match s.volts {
            Some(volts) => writeln!(self.out, "{t:.6},{source},{channel},{value},{volts:.4}"),
            None => writeln!(self.out, "{t:.6},{source},{channel},{value},"),
        }
    }

    fn flush(&mut self) -> io::Result<()> {
        self.out.flush()
    }
}

/// Turns `FA`/`FB` traffic into [`Sample`]s for a sink.
pub struct Recorder<S: SampleSink> {
    sink: S,
    layout: Option<AdConfig>,
    table: LogTable,
    scans: u64,
    started: Duration,
    pub frames: u64,
    pub samples: u64,
}

impl<W: Write> Recorder<CsvSamples<W>> {
    /// A recorder writing CSV to `out` (its header first); `now` (the client's clock) is time
    /// 0 of `FB` samples.
    pub fn csv(out: W, now: Duration) -> io::Result<Self> {
        Ok(Self::new(CsvSamples::new(out)?, now))
    }
}

impl<S: SampleSink> Recorder<S> {
    /// A recorder into `sink`; `now` (the client's clock) is time 0 of `FB` samples.
    pub fn new(sink: S, now: Duration) -> Self {
        Self {
            sink,
            layout: None,
            table: LogTable::default(),
            scans: 0,
            started: now,
            frames: 0,
            samples: 0,
        }
    }

    /// Feeds a message that arrived at `now` (the client's clock); returns whether it was a
    /// sample.
    pub fn record(&mut self, m: &Message, now: Duration) -> io::Result<bool> {
        match m {
            Message::CfgAd { c196, .. } => {
                self.layout = AdConfig::parse(c196).ok();
                self.scans = 0;
                Ok(false)
            }
            Message::AdCont(data) => {
                let Some(cfg) = &self.layout else {
                    return Ok(false);
                };
                self.frames += 1;
                for scan in decode_frame(cfg, data, &self.table) {
                    self.scans += 1;
                    let t_s = self.scans as f64 * cfg.period_ns().get() as f64 * 1e-9;
                    for (channel, value) in scan {
                        self.samples += 1;
                        self.sink.sample(&Sample {
                            t_s,
                            source: SampleSource::C196,
                            channel,
                            value,
                            volts: Some(code10_to_volts(value)),
                        })?;
                    }
                }
                Ok(true)
            }
            Message::AdSample(s) => {
                let t_s = now.saturating_sub(self.started).as_secs_f64();
                self.samples += 1;
                let sample = match *s {
                    AdSample::Pic { channel, value } => Sample {
                        t_s,
                        source: SampleSource::Pic,
                        channel,
                        value: value.into(),
                        volts: Some(code10_to_volts(value.into())),
                    },
                    AdSample::Virtual { channel, value } => Sample {
                        t_s,
                        source: SampleSource::Virtual,
                        channel,
                        value: value.into(),
                        volts: None,
                    },
                };
                self.sink.sample(&sample)?;
                Ok(true)
            }
            _ => Ok(false),
        }
    }

    /// Expands log8 samples through this table (the board's, see
    /// [`Client::log_table`](super::Client::log_table)).
    pub fn set_log_table(&mut self, table: LogTable) {
        self.table = table;
    }

    /// Ends the recording: the sink, flushed.
    pub fn finish(mut self) -> io::Result<S> {
        self.sink.flush()?;
        Ok(self.sink)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn csv_rows_keep_their_layout() {
        let mut csv = CsvSamples::new(Vec::new()).unwrap();
        for s in [
            Sample {
                t_s: 0.0015,
                source: SampleSource::C196,
                channel: 3,
                value: 512.0,
                volts: Some(2.5),
            },
            Sample {
                t_s: 1.0,
                source: SampleSource::Virtual,
                channel: 1,
                value: 7.0,
                volts: None,
            },
        ] {
            csv.sample(&s).unwrap();
        }
        assert_eq!(
            String::from_utf8(csv.into_inner()).unwrap(),
            "t_s,source,channel,value,volts\n0.001500,c196,3,512,2.5000\n1.000000,virtual,1,7,\n"
        );
    }
}
