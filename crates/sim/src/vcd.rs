//! A Value Change Dump (IEEE 1364 §18) writer for [`LevelChange`]s: one 1-bit wire per
//! signal, only changes written. Opens in GTKWave, PulseView/sigrok (which can run its CAN
//! decoder on the `bus` signal) and other waveform viewers.

use std::io::{self, Write};

use buslab_can::{Level, Nanos};

use crate::observe::LevelChange;
use crate::time::BitTime;

/// Writes a VCD file as the simulation runs. Time is in nanoseconds.
pub struct VcdWriter<W: Write> {
    out: W,
    bitrate: u32,
    codes: Vec<String>,
    last_time: Option<Nanos>,
}

impl<W: Write> VcdWriter<W> {
    /// Writes the header declaring `names` (see [`crate::observe::signal_names`]) and their
    /// initial value (recessive = 1) at time 0.
    pub fn new(mut out: W, bitrate: u32, names: &[String]) -> io::Result<Self> {
        let codes: Vec<String> = (0..names.len()).map(code).collect();
        writeln!(
            out,
            "$version buslab-sim {} $end",
            env!("CARGO_PKG_VERSION")
        )?;
        writeln!(
            out,
            "$comment CAN bus at {bitrate} bit/s; 1 = recessive $end"
        )?;
        writeln!(out, "$timescale 1ns $end")?;
        writeln!(out, "$scope module can $end")?;
        for (name, code) in names.iter().zip(&codes) {
            writeln!(out, "$var wire 1 {code} {} $end", sanitize(name))?;
        }
        writeln!(out, "$upscope $end")?;
        writeln!(out, "$enddefinitions $end")?;
        writeln!(out, "#0")?;
        writeln!(out, "$dumpvars")?;
        for code in &codes {
            writeln!(out, "1{code}")?;
        }
        writeln!(out, "$end")?;
        Ok(Self {
            out,
            bitrate,
            codes,
            last_time: Some(Nanos::ZERO),
        })
    }

    /// Appends changes (in time order, as the simulation produces them).
    pub fn write_changes(&mut self, changes: &[LevelChange]) -> io::Result<()> {
        for change in changes {
            let t = change.time.at_bitrate(self.bitrate);
            if self.last_time != Some(t) {
                writeln!(self.out, "#{t}")?;
                self.last_time = Some(t);
            }
            let value = if change.level == Level::Recessive {
                '1'
            } else {
                '0'
            };
            writeln!(self.out, "{value}{}", self.codes[change.signal])?;
        }
        Ok(())
    }

    /// Marks the end of the run at bit-time `end` and returns the output.
    pub fn finish(mut self, end: BitTime) -> io::Result<W> {
        let t = end.at_bitrate(self.bitrate);
        if self.last_time.is_none_or(|last| t > last) {
            writeln!(self.out, "#{t}")?;
        }
        self.out.flush()?;
        Ok(self.out)
    }
}

/// Identifier code `n`: printable ASCII `!`..`~`, more characters beyond 94 signals.
fn code(mut n: usize) -> String {
    let mut s = String::new();
    loop {
        s.push((b'!' + (n % 94) as u8) as char);
        n /= 94;
        if n == 0 {
            return s;
        }
        n -= 1;
    }
}

/// VCD references cannot contain white space.
fn sanitize(name: &str) -> String {
    name.chars()
        .map(|c| if c.is_ascii_graphic() { c } else { '_' })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn codes_are_unique_and_printable() {
        let codes: Vec<String> = (0..10_000).map(code).collect();
        let set: std::collections::HashSet<&String> = codes.iter().collect();
        assert_eq!(set.len(), codes.len());
        assert!(
            codes
                .iter()
                .all(|c| c.bytes().all(|b| (33..=126).contains(&b)))
        );
        assert_eq!(code(0), "!");
        assert_eq!(code(93), "~");
    }

    #[test]
    fn writes_header_and_changes() {
        let names = vec!["bus".to_owned(), "a b_tx".to_owned()];
        let mut w = VcdWriter::new(Vec::new(), 1_000_000, &names).unwrap();
        w.write_changes(&[
            LevelChange {
                time: BitTime::ZERO,
                signal: 0,
                level: Level::Dominant,
            },
            LevelChange {
                time: BitTime::new(3),
                signal: 1,
                level: Level::Dominant,
            },
            LevelChange {
                time: BitTime::new(3),
                signal: 0,
                level: Level::Recessive,
            },
        ])
        .unwrap();
        let text = String::from_utf8(w.finish(BitTime::new(5)).unwrap()).unwrap();
        assert!(text.contains("$var wire 1 \" a_b_tx $end"));
        assert!(text.ends_with("#0\n$dumpvars\n1!\n1\"\n$end\n0!\n#3000\n0\"\n1!\n#5000\n"));
    }
}
