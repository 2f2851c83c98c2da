//! Samples to CSV.

use std::io::{self, Write};
use std::time::Duration;

use crate::acquisition::{LogTable, decode_frame};
use crate::adconfig::AdConfig;
use crate::message::{AdSample, Message};
use crate::source::code10_to_volts;

/// Turns `FA`/`FB` traffic into CSV rows `t_s,source,channel,value,volts`.
pub struct Recorder<W: Write> {
    out: W,
    layout: Option<AdConfig>,
    table: LogTable,
    scans: u64,
    started: Duration,
    pub frames: u64,
    pub samples: u64,
}

impl<W: Write> Recorder<W> {
    /// Writes the header to `out`; `now` (the client's clock) is time 0 of `FB` samples.
    pub fn new(mut out: W, now: Duration) -> io::Result<Self> {
        writeln!(out, "t_s,source,channel,value,volts")?;
        Ok(Self {
            out,
            layout: None,
            table: LogTable::default(),
            scans: 0,
            started: now,
            frames: 0,
            samples: 0,
        })
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
                    let t = self.scans as f64 * cfg.period_ns() as f64 * 1e-9;
                    for (ch, v) in scan {
                        self.samples += 1;
                        writeln!(self.out, "{t:.6},c196,{ch},{v},{:.4}", code10_to_volts(v))?;
                    }
                }
                Ok(true)
            }
            Message::AdSample(s) => {
                let t = now.saturating_sub(self.started).as_secs_f64();
                self.samples += 1;
                match *s {
                    AdSample::Pic { channel, value } => writeln!(
                        self.out,
                        "{t:.6},pic,{channel},{value},{:.4}",
                        code10_to_volts(value as f64)
                    )?,
                    AdSample::Virtual { channel, value } => {
                        writeln!(self.out, "{t:.6},virtual,{channel},{value},")?
                    }
                }
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

    pub fn finish(mut self) -> io::Result<W> {
        self.out.flush()?;
        Ok(self.out)
    }
}
