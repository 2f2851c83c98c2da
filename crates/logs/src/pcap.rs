//! pcap captures with LINKTYPE_CAN_SOCKETCAN (227), as Wireshark, tcpdump and `candump`'s
//! kernel capture write them, or with Wireshark's exported SocketCAN PDUs (252, see
//! the crate's `socketcan` module); a file of any other link type is refused, naming it.
//!
//! A 24-byte file header (magic `a1b2c3d4` for microseconds or `a1b23c4d` for nanoseconds,
//! in the writer's byte order; version 2.4; snap length; link type), then per packet a 16-byte
//! header (seconds, fraction, captured and original length) and the SocketCAN record. pcap
//! has no interface names: entries read back on `can0`. The writer uses microseconds, the
//! most widely read variant; the reader takes both, in either byte order.

use std::io::{self, Read, Write};
use std::time::Duration;

use crate::codec::{Encoder, LogReader, read_full, truncated};
use crate::error::{Problem, ReadError};
use crate::socketcan;
use crate::{Location, Message, Timestamp};

const MAGIC_MICROS: u32 = 0xA1B2_C3D4;
const MAGIC_NANOS: u32 = 0xA1B2_3C4D;
/// The largest packet the reader accepts (a CAN XL record is at most 2060 bytes; Wireshark's
/// own ceiling for most link types is 262144).
pub const MAX_PACKET: u32 = 262_144;
/// The interface name entries of a pcap file get.
pub const INTERFACE: &str = "can0";

#[derive(Clone, Copy, Debug)]
struct Header {
    swapped: bool,
    nanos: bool,
    linktype: u32,
}

/// Reads a pcap file's CAN packets.
pub struct Reader<R> {
    input: R,
    header: Option<Header>,
    offset: u64,
    packet: Vec<u8>,
    done: bool,
}

impl<R: Read> Reader<R> {
    pub fn new(input: R) -> Self {
        Self {
            input,
            header: None,
            offset: 0,
            packet: Vec::new(),
            done: false,
        }
    }

    fn read_header(&mut self) -> Result<Header, ReadError> {
        let mut h = [0u8; 24];
        let got = read_full(&mut self.input, &mut h)?;
        self.offset += got as u64;
        if got == 0 {
            return Err(ReadError::fatal(
                None,
                Problem::NotFormat {
                    format: "pcap",
                    reason: "the file is empty".into(),
                },
            ));
        }
        let magic = u32::from_le_bytes([h[0], h[1], h[2], h[3]]);
        let (swapped, nanos) = match magic {
            MAGIC_MICROS => (false, false),
            MAGIC_NANOS => (false, true),
            m if m.swap_bytes() == MAGIC_MICROS => (true, false),
            m if m.swap_bytes() == MAGIC_NANOS => (true, true),
            crate::pcapng::BLOCK_SHB => {
                return Err(not_pcap(
                    "it is pcapng (read it as pcapng, or by its .pcapng name)".into(),
                ));
            }
            m => {
                return Err(not_pcap(format!(
                    "magic number {m:08x} is none of a1b2c3d4/a1b23c4d"
                )));
            }
        };
        if got < 24 {
            return Err(ReadError::fatal(
                Some(Location::Offset(0)),
                Problem::Truncated {
                    what: "the pcap file header",
                    have: got as u64,
                    need: 24,
                },
            ));
        }
        let mut header = Header {
            swapped,
            nanos,
            linktype: 0,
        };
        // The upper 16 bits hold FCS and reserved bits (pcap's LinkType and additional info).
        header.linktype = header.u32(&h[20..24]) & 0xFFFF;
        if !socketcan::is_can(header.linktype) {
            return Err(ReadError::fatal(
                Some(Location::Offset(20)),
                Problem::LinkType {
                    linktype: header.linktype,
                    name: socketcan::linktype_name(header.linktype),
                },
            ));
        }
        Ok(header)
    }

    /// Reads the next entry into `entry`; `Ok(false)` at the end.
    pub fn read_into(&mut self, entry: &mut Message) -> Result<bool, ReadError> {
        if self.done {
            return Ok(false);
        }
        let result = self.next_packet(entry);
        if let Err(e) = &result
            && e.is_fatal()
        {
            self.done = true;
        }
        if let Ok(false) = result {
            self.done = true;
        }
        result
    }

    fn next_packet(&mut self, entry: &mut Message) -> Result<bool, ReadError> {
        let header = match self.header {
            Some(h) => h,
            None => {
                let h = self.read_header()?;
                self.header = Some(h);
                h
            }
        };
        let start = self.offset;
        let mut ph = [0u8; 16];
        let got = read_full(&mut self.input, &mut ph)?;
        self.offset += got as u64;
        if got == 0 {
            return Ok(false);
        }
        if got < 16 {
            return Err(truncated(start, "a packet header", got, 16));
        }
        let secs = header.u32(&ph[0..4]);
        let frac = header.u32(&ph[4..8]);
        let caplen = header.u32(&ph[8..12]);
        if caplen > MAX_PACKET {
            return Err(ReadError::fatal(
                Some(Location::Offset(start)),
                Problem::TooBig {
                    what: "a packet",
                    claimed: u64::from(caplen),
                    limit: u64::from(MAX_PACKET),
                },
            ));
        }
        self.packet.resize(caplen as usize, 0);
        let got = read_full(&mut self.input, &mut self.packet)?;
        self.offset += got as u64;
        if got < caplen as usize {
            return Err(truncated(start, "a packet", 16 + got, 16 + caplen as usize));
        }
        let record = socketcan::decode_packet(header.linktype, &self.packet)
            .map_err(|p| ReadError::bad(Location::Offset(start), p))?;
        let unit = if header.nanos { 1 } else { 1_000 };
        entry.at = Timestamp::since_epoch(
            Duration::from_secs(u64::from(secs)) + Duration::from_nanos(u64::from(frac) * unit),
        );
        entry.channel.clear();
        entry.channel.push_str(INTERFACE);
        entry.record = record;
        entry.direction = None;
        Ok(true)
    }
}

fn not_pcap(reason: String) -> ReadError {
    ReadError::fatal(
        Some(Location::Offset(0)),
        Problem::NotFormat {
            format: "pcap",
            reason,
        },
    )
}

impl Header {
    fn u32(self, b: &[u8]) -> u32 {
        let v = u32::from_le_bytes([b[0], b[1], b[2], b[3]]);
        if self.swapped { v.swap_bytes() } else { v }
    }
}

impl<R: Read + Send> LogReader for Reader<R> {
    fn read_into(&mut self, entry: &mut Message) -> Result<bool, ReadError> {
        Reader::read_into(self, entry)
    }
}

/// Writes a pcap file (little-endian, microseconds).
pub struct Writer<W> {
    out: W,
    buf: Vec<u8>,
}

impl<W: Write> Writer<W> {
    /// Writes the file header.
    pub fn new(mut out: W) -> io::Result<Self> {
        let mut h = Vec::with_capacity(24);
        h.extend_from_slice(&MAGIC_MICROS.to_le_bytes());
        h.extend_from_slice(&2u16.to_le_bytes());
        h.extend_from_slice(&4u16.to_le_bytes());
        h.extend_from_slice(&0i32.to_le_bytes()); // thiszone
        h.extend_from_slice(&0u32.to_le_bytes()); // sigfigs
        h.extend_from_slice(&65_535u32.to_le_bytes()); // snaplen
        h.extend_from_slice(&u32::from(socketcan::LINKTYPE_CAN_SOCKETCAN).to_le_bytes());
        out.write_all(&h)?;
        Ok(Self {
            out,
            buf: Vec::with_capacity(16 + socketcan::FD_LEN),
        })
    }

    /// Writes one entry; an entry after 2106-02-07 06:28:15 UTC (pcap's seconds are 32 bits)
    /// is refused with [`io::ErrorKind::InvalidInput`] and nothing is written.
    pub fn write(&mut self, entry: &Message) -> io::Result<()> {
        let t = entry.at.since_epoch_duration();
        let Ok(secs) = u32::try_from(t.as_secs()) else {
            return Err(crate::time::out_of_range(
                t,
                "a pcap file",
                "times up to 4294967295 s (2106-02-07 06:28:15 UTC, 32-bit seconds)",
            ));
        };
        let record = socketcan::encode(&entry.record);
        self.buf.clear();
        self.buf.extend_from_slice(&secs.to_le_bytes());
        self.buf.extend_from_slice(&t.subsec_micros().to_le_bytes());
        self.buf
            .extend_from_slice(&(record.len() as u32).to_le_bytes());
        self.buf
            .extend_from_slice(&(record.len() as u32).to_le_bytes());
        self.buf.extend_from_slice(&record);
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
