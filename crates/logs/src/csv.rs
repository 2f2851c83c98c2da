//! python-can's CSV log:
//!
//! ```text
//! timestamp,arbitration_id,extended,remote,error,dlc,data
//! 1700000000.001,0x12345678,1,0,0,4,3q2+7w==
//! ```
//!
//! Seconds as a decimal number, the ID in hex with `0x`, three 0/1 flags, the DLC, the data in
//! base64. An error frame is a row with `error` 1, the error class as its ID and its SocketCAN
//! data bytes, as many as it has (as python-can logs SocketCAN error frames). No interface and no
//! direction: entries read back on `can0`. The reader, like python-can's, takes the first line
//! for the header whatever it says.
//!
//! python-can's columns have no place for CAN FD: its writer puts an FD frame in a row like any
//! frame, its length as the `dlc` and its data (up to 64 bytes), and loses the FD mark, BRS and
//! ESI; buslab writes it so too (python-can reads such a file), and reads a row of more than 8
//! data bytes back as a CAN FD frame without BRS and ESI. An FD frame of 8 bytes or fewer
//! comes back classic. The columns stay python-can's so that python-can reads every file
//! buslab writes.

use std::io::{self, BufRead, Write};

use base64::Engine as _;
use base64::engine::general_purpose::STANDARD as BASE64;
use buslab_bus::ErrorFrame;
use buslab_can::{FD_MAX_LEN, FdFrame, Frame, Id};

use crate::codec::{Encoder, LogReader};
use crate::error::{Problem, ReadError};
use crate::text::{self, Lines, TooLong};
use crate::{Location, Message, Record, Timestamp};

pub const HEADER: &str = "timestamp,arbitration_id,extended,remote,error,dlc,data";
/// The interface name entries of a CSV file get.
pub const INTERFACE: &str = "can0";

/// Reads python-can CSV rows.
pub struct Reader<R> {
    lines: Lines<R>,
}

impl<R: BufRead> Reader<R> {
    pub fn new(input: R) -> Self {
        Self {
            lines: Lines::new(input),
        }
    }

    /// Reads the next entry into `entry`; `Ok(false)` at the end.
    pub fn read_into(&mut self, entry: &mut Message) -> Result<bool, ReadError> {
        loop {
            let step = self.lines.next(|number, line| {
                let at = Location::Line(number);
                if number == 1 {
                    return None;
                }
                match line {
                    Err(TooLong) => Some(Err(ReadError::expected(
                        at,
                        "a row shorter than 4096 bytes",
                        b"...",
                    ))),
                    Ok(line) if text::trim(line).is_empty() => None,
                    Ok(line) => Some(parse_row(line, entry).map_err(|p| ReadError::bad(at, p))),
                }
            })?;
            match step {
                None => return Ok(false),
                Some(None) => {}
                Some(Some(result)) => return result.map(|()| true),
            }
        }
    }
}

fn flag(text: &[u8], what: &'static str) -> Result<bool, Problem> {
    match text {
        b"1" | b"True" => Ok(true),
        b"0" | b"False" => Ok(false),
        _ => Err(Problem::Expected {
            expected: what,
            found: crate::error::excerpt(text),
        }),
    }
}

/// One row into `entry`.
pub fn parse_row(line: &[u8], entry: &mut Message) -> Result<(), Problem> {
    let bad = |expected, found: &[u8]| Problem::Expected {
        expected,
        found: crate::error::excerpt(found),
    };
    let mut cols = line.split(|&b| b == b',');
    let mut col = |what| cols.next().ok_or_else(|| bad(what, line));
    let timestamp = col("7 columns: timestamp,arbitration_id,extended,remote,error,dlc,data")?;
    let id = col("an arbitration_id column")?;
    let extended = col("an extended column")?;
    let remote = col("a remote column")?;
    let error = col("an error column")?;
    let dlc = col("a dlc column")?;
    let data = col("a data column")?;
    if cols.next().is_some() {
        return Err(bad("exactly 7 columns", line));
    }
    let timestamp = text::decimal_duration(text::trim(timestamp), buslab_can::Nanos::from_secs(1))
        .ok_or_else(|| bad("a timestamp in seconds, e.g. 1700000000.123456", timestamp))?;
    let id_text = text::trim(id);
    let raw = id_text
        .strip_prefix(b"0x")
        .or_else(|| id_text.strip_prefix(b"0X"))
        .and_then(text::hex_u32)
        .ok_or_else(|| bad("an arbitration_id in hex, e.g. 0x123", id))?;
    let extended = flag(text::trim(extended), "extended 0 or 1")?;
    let remote = flag(text::trim(remote), "remote 0 or 1")?;
    let error = flag(text::trim(error), "error 0 or 1")?;
    let dlc_text = dlc;
    let dlc = text::dec_u64(text::trim(dlc))
        .filter(|&d| d <= FD_MAX_LEN as u64)
        .ok_or_else(|| bad("a dlc 0..8 (or a CAN FD length up to 64)", dlc))? as u8;
    let mut bytes = [0u8; 96];
    let data = text::trim(data);
    let len = BASE64
        .decode_slice(data, &mut bytes)
        .map_err(|_| bad("data in base64 (at most 64 bytes)", data))?;
    let bytes = &bytes[..len];
    let record = if error {
        Record::Error(ErrorFrame::decode(raw & 0x1FFF_FFFF, bytes)?)
    } else {
        let id = if extended {
            Id::extended(raw)?
        } else {
            Id::standard(u16::try_from(raw).map_err(|_| bad("a standard ID 0x0..0x7ff", id))?)?
        };
        if remote {
            if dlc > 8 {
                return Err(bad("a remote frame's dlc 0..8", text::trim(dlc_text)));
            }
            Record::Frame(Frame::remote(id, dlc)?)
        } else {
            if usize::from(dlc) != len {
                return Err(Problem::Expected {
                    expected: "as many data bytes as the dlc",
                    found: format!("dlc {dlc} with {len} bytes"),
                });
            }
            frame_of_row(id, bytes)?
        }
    };
    entry.at = Timestamp::since_epoch(timestamp);
    entry.channel.clear();
    entry.channel.push_str(INTERFACE);
    entry.record = record;
    entry.direction = None;
    Ok(())
}

/// A data row's frame, as python-can's files hold them: up to 8 bytes a classic frame, more
/// a CAN FD frame (python-can writes one so and keeps no BRS or ESI).
pub(crate) fn frame_of_row(id: Id, data: &[u8]) -> Result<Record, Problem> {
    Ok(if data.len() <= 8 {
        Record::Frame(Frame::data(id, data)?)
    } else {
        Record::Fd(FdFrame::new(id, data)?)
    })
}

/// Warns, once per writer, of what python-can's columns lose of CAN FD frames.
pub(crate) fn warn_fd_loss(warned: &mut bool, format: &str) {
    if !*warned {
        *warned = true;
        tracing::warn!(
            "{format} (python-can's columns) keeps a CAN FD frame's ID and data but not BRS, ESI or, for 8 bytes or fewer, that it is FD: candump, ASC, BLF, TRC 2.1, pcap and pcapng keep them"
        );
    }
}

impl<R: BufRead + Send> LogReader for Reader<R> {
    fn read_into(&mut self, entry: &mut Message) -> Result<bool, ReadError> {
        Reader::read_into(self, entry)
    }
}

/// Writes python-can CSV rows.
pub struct Writer<W> {
    out: W,
    header: bool,
    fd_warned: bool,
    line: Vec<u8>,
}

impl<W: Write> Writer<W> {
    pub fn new(out: W) -> Self {
        Self {
            out,
            header: false,
            fd_warned: false,
            line: Vec::with_capacity(160),
        }
    }

    fn header(&mut self) -> io::Result<()> {
        if !self.header {
            self.header = true;
            self.out.write_all(HEADER.as_bytes())?;
            self.out.write_all(b"\n")?;
        }
        Ok(())
    }

    pub fn write(&mut self, entry: &Message) -> io::Result<()> {
        self.header()?;
        let line = &mut self.line;
        line.clear();
        push_seconds(line, entry.at.since_epoch_duration());
        line.extend_from_slice(b",0x");
        let mut data = [0u8; FD_MAX_LEN];
        let (raw, extended, remote, error, dlc, len) = match &entry.record {
            Record::Fd(f) => {
                warn_fd_loss(&mut self.fd_warned, "CSV");
                let payload = f.payload();
                data[..payload.len()].copy_from_slice(payload);
                let len = payload.len();
                (
                    f.id().as_raw(),
                    f.is_extended(),
                    false,
                    false,
                    len as u8,
                    len,
                )
            }
            Record::Frame(f) => {
                let payload = f.payload();
                data[..payload.len()].copy_from_slice(payload);
                let (id, ext, rtr) = (f.id().as_raw(), f.is_extended(), f.is_remote());
                (id, ext, rtr, false, f.dlc(), payload.len())
            }
            Record::Error(e) => {
                let (class, bytes) = e.encode();
                data[..8].copy_from_slice(&bytes);
                let len = e.data_len();
                (class, false, false, true, len as u8, len)
            }
        };
        push_lower_hex(line, raw);
        for f in [extended, remote, error] {
            line.extend_from_slice(if f { b",1" } else { b",0" });
        }
        line.push(b',');
        text::push_u64(line, u64::from(dlc));
        line.push(b',');
        let mut b64 = [0u8; FD_MAX_LEN.div_ceil(3) * 4];
        let n = BASE64
            .encode_slice(&data[..len], &mut b64)
            .map_err(io::Error::other)?;
        line.extend_from_slice(&b64[..n]);
        line.push(b'\n');
        self.out.write_all(line)
    }

    pub fn finish(mut self) -> io::Result<W> {
        self.header()?;
        self.out.flush()?;
        Ok(self.out)
    }
}

/// `v` in lowercase hex without leading zeros (Python's `hex()` after the `0x`).
fn push_lower_hex(out: &mut Vec<u8>, v: u32) {
    let start = out.len();
    text::push_hex(out, v, 1);
    out[start..].make_ascii_lowercase();
}

/// Seconds with as many decimals as needed (at least one, at most nine): `1700000000.5`.
pub(crate) fn push_seconds(out: &mut Vec<u8>, t: std::time::Duration) {
    text::push_u64(out, t.as_secs());
    out.push(b'.');
    let mut nanos = t.subsec_nanos();
    let mut width = 9;
    while width > 1 && nanos.is_multiple_of(10) {
        nanos /= 10;
        width -= 1;
    }
    text::push_u64_zeros(out, u64::from(nanos), width);
}

impl<W: Write + Send> Encoder<W> for Writer<W> {
    fn write(&mut self, entry: &Message) -> io::Result<()> {
        Writer::write(self, entry)
    }
    fn flush(&mut self) -> io::Result<()> {
        self.header()?;
        self.out.flush()
    }
    fn finish(self) -> io::Result<W> {
        Writer::finish(self)
    }
}
