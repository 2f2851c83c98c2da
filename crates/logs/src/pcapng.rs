//! pcapng captures with LINKTYPE_CAN_SOCKETCAN (227) interfaces, or Wireshark's exported
//! SocketCAN PDUs (252, see the crate's `socketcan` module).
//!
//! Blocks: a Section Header (byte order), an Interface Description per interface (link type,
//! `if_name`, `if_tsresol`), then Enhanced Packet Blocks (interface, 64-bit timestamp, the
//! SocketCAN record, `epb_flags` for the direction). The writer describes each interface
//! when it first appears, with nanosecond timestamps, so names, directions and nanoseconds
//! survive. The reader takes any byte order and resolution, several sections, Simple Packet
//! Blocks, and skips the blocks that carry no packets. The first packet of an interface of
//! another link type is a bad record naming the link type (so a capture without CAN is an
//! error, not an empty log); with the error stepped over, that interface's later packets are
//! left out (a capture of CAN beside other interfaces reads with `--skip-bad`).

use std::io::{self, Read, Write};
use std::time::Duration;

use crate::codec::{Encoder, LogReader};
use crate::codec::{read_full, truncated};
use crate::error::{Problem, ReadError};
use crate::socketcan::{self, LINKTYPE_CAN_SOCKETCAN};
use crate::{Direction, Location, Message, Timestamp};

/// The Section Header Block's type (a palindrome: the same in both byte orders).
pub const BLOCK_SHB: u32 = 0x0A0D_0D0A;
const BLOCK_IDB: u32 = 1;
const BLOCK_SPB: u32 = 3;
const BLOCK_EPB: u32 = 6;
const BYTE_ORDER_MAGIC: u32 = 0x1A2B_3C4D;
/// The largest block the reader accepts.
pub const MAX_BLOCK: u32 = 1 << 20;
/// The most interfaces a section may describe.
const MAX_INTERFACES: usize = 4096;

const OPT_END: u16 = 0;
const IF_NAME: u16 = 2;
const IF_TSRESOL: u16 = 9;
const IF_TSOFFSET: u16 = 14;
const EPB_FLAGS: u16 = 2;

#[derive(Clone, Debug)]
struct Interface {
    linktype: u16,
    name: String,
    /// Timestamp resolution: 10^-n (`pow2` false) or 2^-n seconds.
    resolution: u8,
    pow2: bool,
    offset_secs: i64,
    /// Not CAN, and said so: its packets are left out.
    refused: bool,
}

impl Interface {
    fn timestamp(&self, ticks: u64) -> Duration {
        let ns: u128 = if self.pow2 {
            (u128::from(ticks) * 1_000_000_000) >> self.resolution.min(127)
        } else if self.resolution <= 9 {
            u128::from(ticks) * 10u128.pow(9 - u32::from(self.resolution))
        } else {
            u128::from(ticks) / 10u128.pow(u32::from(self.resolution.min(38)) - 9)
        };
        let ns = (ns as i128 + i128::from(self.offset_secs) * 1_000_000_000).max(0) as u128;
        let secs = (ns / 1_000_000_000).min(u128::from(u64::MAX)) as u64;
        Duration::new(secs, (ns % 1_000_000_000) as u32)
    }
}

/// Reads a pcapng file's CAN packets.
pub struct Reader<R> {
    input: R,
    offset: u64,
    big_endian: bool,
    started: bool,
    interfaces: Vec<Interface>,
    block: Vec<u8>,
    done: bool,
}

impl<R: Read> Reader<R> {
    pub fn new(input: R) -> Self {
        Self {
            input,
            offset: 0,
            big_endian: false,
            started: false,
            interfaces: Vec::new(),
            block: Vec::new(),
            done: false,
        }
    }

    /// Reads the next entry into `entry`; `Ok(false)` at the end.
    pub fn read_into(&mut self, entry: &mut Message) -> Result<bool, ReadError> {
        while !self.done {
            match self.next_block(entry) {
                Ok(Some(true)) => return Ok(true),
                Ok(Some(false)) => {}
                Ok(None) => self.done = true,
                Err(e) => {
                    self.done |= e.is_fatal();
                    return Err(e);
                }
            }
        }
        Ok(false)
    }

    fn u32(&self, b: &[u8]) -> u32 {
        let a = [b[0], b[1], b[2], b[3]];
        if self.big_endian {
            u32::from_be_bytes(a)
        } else {
            u32::from_le_bytes(a)
        }
    }

    fn u16(&self, b: &[u8]) -> u16 {
        let a = [b[0], b[1]];
        if self.big_endian {
            u16::from_be_bytes(a)
        } else {
            u16::from_le_bytes(a)
        }
    }

    /// One block: `Some(true)` when it filled `entry`, `Some(false)` for another kind of
    /// block, `None` at the end of the file.
    fn next_block(&mut self, entry: &mut Message) -> Result<Option<bool>, ReadError> {
        let start = self.offset;
        let mut head = [0u8; 12];
        let got = read_full(&mut self.input, &mut head[..8])?;
        self.offset += got as u64;
        if got == 0 {
            if !self.started {
                return Err(not_pcapng(0, "the file is empty".into()));
            }
            return Ok(None);
        }
        if got < 8 {
            return Err(truncated(start, "a block header", got, 8));
        }
        let raw_type = u32::from_le_bytes([head[0], head[1], head[2], head[3]]);
        if raw_type == BLOCK_SHB {
            let got = read_full(&mut self.input, &mut head[8..12])?;
            self.offset += got as u64;
            if got < 4 {
                return Err(truncated(start, "a section header", 8 + got, 12));
            }
            self.big_endian = match u32::from_le_bytes([head[8], head[9], head[10], head[11]]) {
                BYTE_ORDER_MAGIC => false,
                m if m.swap_bytes() == BYTE_ORDER_MAGIC => true,
                m => {
                    return Err(not_pcapng(
                        start + 8,
                        format!("byte-order magic {m:08x} is not 1a2b3c4d"),
                    ));
                }
            };
            self.started = true;
            self.interfaces.clear();
        } else if !self.started {
            return Err(not_pcapng(
                0,
                format!("it starts with block type {raw_type:08x}, not a section header"),
            ));
        }
        let block_type = self.u32(&head[0..4]);
        let total = self.u32(&head[4..8]);
        if total > MAX_BLOCK {
            return Err(ReadError::fatal(
                Some(Location::Offset(start)),
                Problem::TooBig {
                    what: "a block",
                    claimed: u64::from(total),
                    limit: u64::from(MAX_BLOCK),
                },
            ));
        }
        let already = if block_type == BLOCK_SHB { 12 } else { 8 };
        if total < already + 4 || !total.is_multiple_of(4) {
            return Err(not_pcapng(
                start,
                format!("block length {total} is not a multiple of 4 of at least 12"),
            ));
        }
        // The body after what was read, with the trailing length.
        self.block.resize((total - already) as usize, 0);
        let got = read_full(&mut self.input, &mut self.block)?;
        self.offset += got as u64;
        if got < self.block.len() {
            return Err(truncated(
                start,
                "a block",
                already as usize + got,
                total as usize,
            ));
        }
        let body_len = self.block.len() - 4;
        let trailer = self.u32(&self.block[body_len..]);
        if trailer != total {
            return Err(not_pcapng(
                start,
                format!("block length {total} at the start but {trailer} at the end"),
            ));
        }
        let block = std::mem::take(&mut self.block);
        let body = &block[..body_len];
        let result = match block_type {
            BLOCK_SHB => Ok(false),
            BLOCK_IDB => self.interface(start, body).map(|()| false),
            BLOCK_EPB => self.enhanced_packet(start, body, entry),
            BLOCK_SPB => self.simple_packet(start, body, entry),
            _ => Ok(false),
        };
        self.block = block;
        result.map(Some)
    }

    fn interface(&mut self, start: u64, body: &[u8]) -> Result<(), ReadError> {
        if body.len() < 8 {
            return Err(not_pcapng(
                start,
                "an interface block shorter than 8 bytes".into(),
            ));
        }
        if self.interfaces.len() >= MAX_INTERFACES {
            return Err(ReadError::fatal(
                Some(Location::Offset(start)),
                Problem::TooBig {
                    what: "the interface list",
                    claimed: self.interfaces.len() as u64 + 1,
                    limit: MAX_INTERFACES as u64,
                },
            ));
        }
        let mut iface = Interface {
            linktype: self.u16(&body[0..2]),
            name: format!("can{}", self.interfaces.len()),
            resolution: 6,
            pow2: false,
            offset_secs: 0,
            refused: false,
        };
        for (code, value) in self.options(&body[8..]) {
            match code {
                IF_NAME => {
                    // A C string: the name ends at the first NUL, whatever padding follows.
                    let name = value.split(|&b| b == 0).next().unwrap_or_default();
                    let name = String::from_utf8_lossy(name);
                    let name = name.trim();
                    if !name.is_empty() && !name.contains(char::is_whitespace) {
                        iface.name = name.to_string();
                    }
                }
                IF_TSRESOL if !value.is_empty() => {
                    iface.pow2 = value[0] & 0x80 != 0;
                    iface.resolution = value[0] & 0x7F;
                }
                IF_TSOFFSET if value.len() >= 8 => {
                    let mut b = [0u8; 8];
                    b.copy_from_slice(&value[..8]);
                    iface.offset_secs = if self.big_endian {
                        i64::from_be_bytes(b)
                    } else {
                        i64::from_le_bytes(b)
                    };
                }
                _ => {}
            }
        }
        self.interfaces.push(iface);
        Ok(())
    }

    /// The options of a block: (code, value) until the end option or the end of the bytes.
    fn options<'a>(&self, mut bytes: &'a [u8]) -> Vec<(u16, &'a [u8])> {
        let mut out = Vec::new();
        while bytes.len() >= 4 {
            let code = self.u16(&bytes[0..2]);
            let len = usize::from(self.u16(&bytes[2..4]));
            if code == OPT_END || 4 + len > bytes.len() {
                break;
            }
            out.push((code, &bytes[4..4 + len]));
            let padded = (len + 3) & !3;
            bytes = &bytes[(4 + padded).min(bytes.len())..];
        }
        out
    }

    fn enhanced_packet(
        &mut self,
        start: u64,
        body: &[u8],
        entry: &mut Message,
    ) -> Result<bool, ReadError> {
        if body.len() < 20 {
            return Err(ReadError::bad(
                Location::Offset(start),
                Problem::Expected {
                    expected: "an enhanced packet block of at least 28 bytes",
                    found: format!("{} bytes", body.len() + 12),
                },
            ));
        }
        let iface = self.u32(&body[0..4]) as usize;
        let ticks = (u64::from(self.u32(&body[4..8])) << 32) | u64::from(self.u32(&body[8..12]));
        let caplen = self.u32(&body[12..16]) as usize;
        if 20 + caplen > body.len() {
            return Err(ReadError::bad(
                Location::Offset(start),
                Problem::Expected {
                    expected: "a captured length within the block",
                    found: caplen.to_string(),
                },
            ));
        }
        let data = &body[20..20 + caplen];
        let padded = (caplen + 3) & !3;
        let mut direction = None;
        for (code, value) in self.options(&body[(20 + padded).min(body.len())..]) {
            if code == EPB_FLAGS && value.len() >= 4 {
                direction = match self.u32(value) & 3 {
                    1 => Some(Direction::Rx),
                    2 => Some(Direction::Tx),
                    _ => None,
                };
            }
        }
        self.packet(start, iface, Some(ticks), data, direction, entry)
    }

    fn simple_packet(
        &mut self,
        start: u64,
        body: &[u8],
        entry: &mut Message,
    ) -> Result<bool, ReadError> {
        if body.len() < 4 {
            return Err(ReadError::bad(
                Location::Offset(start),
                Problem::Expected {
                    expected: "a simple packet block of at least 16 bytes",
                    found: format!("{} bytes", body.len() + 12),
                },
            ));
        }
        let len = (self.u32(&body[0..4]) as usize).min(body.len() - 4);
        let data = &body[4..4 + len];
        self.packet(start, 0, None, data, None, entry)
    }

    fn packet(
        &mut self,
        start: u64,
        iface: usize,
        ticks: Option<u64>,
        data: &[u8],
        direction: Option<Direction>,
        entry: &mut Message,
    ) -> Result<bool, ReadError> {
        let Some(interface) = self.interfaces.get_mut(iface) else {
            return Err(ReadError::bad(
                Location::Offset(start),
                Problem::Expected {
                    expected: "a packet of a described interface",
                    found: format!("interface {iface}"),
                },
            ));
        };
        let linktype = u32::from(interface.linktype);
        if !socketcan::is_can(linktype) {
            if interface.refused {
                return Ok(false);
            }
            interface.refused = true;
            return Err(ReadError::bad(
                Location::Offset(start),
                Problem::Interface {
                    index: iface,
                    name: interface.name.clone(),
                    problem: Box::new(Problem::LinkType {
                        linktype,
                        name: socketcan::linktype_name(linktype),
                    }),
                },
            ));
        }
        let record = socketcan::decode_packet(linktype, data)
            .map_err(|p| ReadError::bad(Location::Offset(start), p))?;
        entry.at = Timestamp::since_epoch(ticks.map_or(Duration::ZERO, |t| interface.timestamp(t)));
        entry.channel.clear();
        entry.channel.push_str(&interface.name);
        entry.record = record;
        entry.direction = direction;
        Ok(true)
    }
}

fn not_pcapng(at: u64, reason: String) -> ReadError {
    ReadError::fatal(
        Some(Location::Offset(at)),
        Problem::NotFormat {
            format: "pcapng",
            reason,
        },
    )
}

impl<R: Read + Send> LogReader for Reader<R> {
    fn read_into(&mut self, entry: &mut Message) -> Result<bool, ReadError> {
        Reader::read_into(self, entry)
    }
}

/// Writes a pcapng file (little-endian, nanoseconds, one interface per name).
pub struct Writer<W> {
    out: W,
    interfaces: Vec<String>,
    last: usize,
    buf: Vec<u8>,
}

fn push_option(buf: &mut Vec<u8>, code: u16, value: &[u8]) {
    buf.extend_from_slice(&code.to_le_bytes());
    buf.extend_from_slice(&(value.len() as u16).to_le_bytes());
    buf.extend_from_slice(value);
    while !buf.len().is_multiple_of(4) {
        buf.push(0);
    }
}

/// Puts the block's total length in its header and at its end.
fn seal_block(buf: &mut Vec<u8>) {
    let total = (buf.len() + 4) as u32;
    buf[4..8].copy_from_slice(&total.to_le_bytes());
    buf.extend_from_slice(&total.to_le_bytes());
}

impl<W: Write> Writer<W> {
    /// Writes the section header.
    pub fn new(mut out: W) -> io::Result<Self> {
        let mut buf = Vec::with_capacity(64);
        buf.extend_from_slice(&BLOCK_SHB.to_le_bytes());
        buf.extend_from_slice(&0u32.to_le_bytes());
        buf.extend_from_slice(&BYTE_ORDER_MAGIC.to_le_bytes());
        buf.extend_from_slice(&1u16.to_le_bytes());
        buf.extend_from_slice(&0u16.to_le_bytes());
        buf.extend_from_slice(&(-1i64).to_le_bytes());
        push_option(&mut buf, 4, b"buslab"); // shb_userappl
        push_option(&mut buf, OPT_END, &[]);
        seal_block(&mut buf);
        out.write_all(&buf)?;
        Ok(Self {
            out,
            interfaces: Vec::new(),
            last: 0,
            buf,
        })
    }

    fn interface(&mut self, name: &str) -> io::Result<u32> {
        if self.interfaces.get(self.last).is_some_and(|n| n == name) {
            return Ok(self.last as u32);
        }
        if let Some(i) = self.interfaces.iter().position(|n| n == name) {
            self.last = i;
            return Ok(i as u32);
        }
        let buf = &mut self.buf;
        buf.clear();
        buf.extend_from_slice(&BLOCK_IDB.to_le_bytes());
        buf.extend_from_slice(&0u32.to_le_bytes());
        buf.extend_from_slice(&LINKTYPE_CAN_SOCKETCAN.to_le_bytes());
        buf.extend_from_slice(&0u16.to_le_bytes());
        buf.extend_from_slice(&0u32.to_le_bytes()); // snaplen: no limit
        push_option(buf, IF_NAME, name.as_bytes());
        push_option(buf, IF_TSRESOL, &[9]);
        push_option(buf, OPT_END, &[]);
        seal_block(buf);
        self.out.write_all(&self.buf)?;
        self.interfaces.push(name.to_string());
        self.last = self.interfaces.len() - 1;
        Ok(self.last as u32)
    }

    /// Writes one entry; an entry after 2554-07-21 23:34:33 UTC (nanoseconds in 64 bits) is
    /// refused with [`io::ErrorKind::InvalidInput`] and nothing is written.
    pub fn write(&mut self, entry: &Message) -> io::Result<()> {
        let Ok(ns) = u64::try_from(entry.at.since_epoch_duration().as_nanos()) else {
            return Err(crate::time::out_of_range(
                entry.at.since_epoch_duration(),
                "a pcapng file",
                "times up to 18446744073.709551615 s (2554-07-21 23:34:33 UTC, 64-bit nanoseconds)",
            ));
        };
        let iface = self.interface(&entry.channel)?;
        let record = socketcan::encode(&entry.record);
        let buf = &mut self.buf;
        buf.clear();
        buf.extend_from_slice(&BLOCK_EPB.to_le_bytes());
        buf.extend_from_slice(&0u32.to_le_bytes());
        buf.extend_from_slice(&iface.to_le_bytes());
        buf.extend_from_slice(&((ns >> 32) as u32).to_le_bytes());
        buf.extend_from_slice(&(ns as u32).to_le_bytes());
        buf.extend_from_slice(&(record.len() as u32).to_le_bytes());
        buf.extend_from_slice(&(record.len() as u32).to_le_bytes());
        buf.extend_from_slice(&record);
        if let Some(d) = entry.direction {
            let flags: u32 = match d {
                Direction::Rx => 1,
                Direction::Tx => 2,
            };
            push_option(buf, EPB_FLAGS, &flags.to_le_bytes());
            push_option(buf, OPT_END, &[]);
        }
        seal_block(buf);
        self.out.write_all(&self.buf)
    }

    pub fn finish(mut self) -> io::Result<W> {
        self.out.flush()?;
        Ok(self.out)
    }
}

impl<W: Write + Send> Encoder<W> for Writer<W> {
    fn write(&mut self, entry: &Message) -> io::Result<()> {
        Writer::write(self, entry)
    }
    fn flush(&mut self) -> io::Result<()> {
        self.out.flush()
    }
    fn finish(self) -> io::Result<W> {
        Writer::finish(self)
    }
}
