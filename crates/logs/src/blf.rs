//! Vector BLF (binary logging format), as CANoe and python-can write it.
//!
//! A 144-byte file header (`LOGG`; counts, sizes and the start and stop times as SYSTEMTIME),
//! then `LOBJ` objects, mostly LOG_CONTAINERs (type 10) whose zlib-compressed data holds the
//! CAN objects; an object may continue in the next container. Each object has a 16-byte base
//! header (`LOBJ`, header size, header version, object size, type) and a version-1 or -2
//! header with flags (1: 10 µs units, 2: ns) and the time since the file's start.
//!
//! Read: CAN_MESSAGE (1) and CAN_MESSAGE2 (86) as frames, CAN_ERROR_EXT (73) as error frames
//! (the ID as the SocketCAN error class and the data bytes, as python-can writes them),
//! CAN_ERROR (2) as a bus error, CAN_FD_MESSAGE (100) and CAN_FD_MESSAGE_64 (101) as CAN FD
//! frames when their EDL flag is set (BRS and ESI from their flags; the valid data bytes, a
//! CAN_FD_MESSAGE_64 whose data ends early padded with zeros as CANoe and python-can do) and as
//! classic frames when not; other objects are skipped. The frame length CAN_MESSAGE2
//! and CAN_FD_MESSAGE carry (the frame's time on the wire, ns) gives the channel's bit rate
//! ([`LogReader::bit_rate`]). Written: CAN_MESSAGE, CAN_FD_MESSAGE_64 (CANoe's CAN FD object;
//! CAN_FD_MESSAGE, python-can's, for a channel above 255, which the former cannot number) and
//! CAN_ERROR_EXT in zlib containers (level 1) of about 128 KiB (python-can's size), nanosecond times
//! from the first entry's millisecond; each object is followed by its size modulo 4 in zero
//! bytes, as python-can pads them. The header is written at creation and rewritten at each
//! flush, so a writer killed at any moment leaves a file that reads up to its last whole object
//! (python-can reads objects to the end of the file and uses none of the header's counts).

use std::io::{self, Read, Seek, SeekFrom, Write};
use std::time::Duration;

use buslab_bus::ErrorFrame;
use buslab_can::{FD_MAX_LEN, FdFrame, Frame, Id};
use flate2::{Compress, Compression, Decompress, FlushCompress, FlushDecompress, Status};

use crate::asc::error_frame as bus_error;
use crate::bitrate::FrameLengths;
use crate::channel::{ChannelMap, channel_of, set_channel_name};
use crate::codec::{Encoder, LogReader};
use crate::codec::{read_full, truncated};
use crate::error::{Problem, ReadError};
use crate::time;
use crate::{Direction, Location, LogBitRate, Message, Record, Timestamp};

const FILE_SIGNATURE: &[u8; 4] = b"LOGG";
const OBJ_SIGNATURE: &[u8; 4] = b"LOBJ";
pub const FILE_HEADER_SIZE: usize = 144;
const BASE_HEADER: usize = 16;
const V1_HEADER: usize = 16;
const V2_HEADER: usize = 24;

const CAN_MESSAGE: u32 = 1;
const CAN_ERROR: u32 = 2;
const LOG_CONTAINER: u32 = 10;
const CAN_ERROR_EXT: u32 = 73;
const CAN_MESSAGE2: u32 = 86;
const CAN_FD_MESSAGE: u32 = 100;
const CAN_FD_MESSAGE_64: u32 = 101;

const NO_COMPRESSION: u16 = 0;
const ZLIB_DEFLATE: u16 = 2;
const TIME_TEN_MICS: u32 = 1;
const TIME_ONE_NANS: u32 = 2;

const EXT_FLAG: u32 = 0x8000_0000;
const REMOTE_FLAG: u8 = 0x80;
const DIR_TX: u8 = 0x01;
/// CAN_FD_MESSAGE's FD flags: extended data length (CAN FD), bit rate switch, error state
/// indicator.
const FD_EDL: u8 = 0x01;
const FD_BRS: u8 = 0x02;
const FD_ESI: u8 = 0x04;
/// CAN_FD_MESSAGE_64's flags: remote frame, EDL, BRS, ESI.
const FD64_REMOTE: u32 = 0x0010;
const FD64_EDL: u32 = 0x1000;
const FD64_BRS: u32 = 0x2000;
const FD64_ESI: u32 = 0x4000;
/// CAN_FD_MESSAGE_64's fixed part, before the data.
const FD64_HEADER: usize = 40;

/// The largest container (compressed or not) and object the reader accepts.
pub const MAX_OBJECT: u32 = 16 << 20;
/// The uncompressed size at which the writer closes a container (python-can's).
pub const CONTAINER_SIZE: usize = 128 * 1024;

fn u16_at(b: &[u8], i: usize) -> u16 {
    u16::from_le_bytes([b[i], b[i + 1]])
}

fn u32_at(b: &[u8], i: usize) -> u32 {
    u32::from_le_bytes([b[i], b[i + 1], b[i + 2], b[i + 3]])
}

fn u64_at(b: &[u8], i: usize) -> u64 {
    let mut a = [0u8; 8];
    a.copy_from_slice(&b[i..i + 8]);
    u64::from_le_bytes(a)
}

/// Reads a BLF file's CAN objects.
pub struct Reader<R> {
    input: R,
    started: bool,
    start: Duration,
    /// The file offset of the next top-level object.
    offset: u64,
    /// The file offset of the container `data` came from (for messages).
    container_at: u64,
    /// Uncompressed object bytes not yet parsed, from `pos` on.
    data: Vec<u8>,
    pos: usize,
    object: Vec<u8>,
    /// The error to give once the objects before a cut are read.
    cut: Option<ReadError>,
    done: bool,
    /// The frames' lengths on the wire, per channel.
    lengths: FrameLengths,
}

impl<R: Read> Reader<R> {
    pub fn new(input: R) -> Self {
        Self {
            input,
            started: false,
            start: Duration::ZERO,
            offset: 0,
            container_at: 0,
            data: Vec::new(),
            pos: 0,
            object: Vec::new(),
            cut: None,
            done: false,
            lengths: FrameLengths::default(),
        }
    }

    fn read_file_header(&mut self) -> Result<(), ReadError> {
        let mut h = [0u8; FILE_HEADER_SIZE];
        let got = read_full(&mut self.input, &mut h[..8])?;
        self.offset += got as u64;
        if got < 4 || &h[..4] != FILE_SIGNATURE {
            return Err(ReadError::fatal(
                Some(Location::Offset(0)),
                Problem::NotFormat {
                    format: "BLF",
                    reason: "it does not start with LOGG".into(),
                },
            ));
        }
        if got < 8 {
            return Err(truncated(0, "the file header", got, FILE_HEADER_SIZE));
        }
        let size = u32_at(&h, 4) as usize;
        if !(72..=4096).contains(&size) {
            return Err(ReadError::fatal(
                Some(Location::Offset(4)),
                Problem::Expected {
                    expected: "a file header size of 72..4096 bytes",
                    found: size.to_string(),
                },
            ));
        }
        let mut rest = vec![0u8; size - 8];
        let got = read_full(&mut self.input, &mut rest)?;
        self.offset += got as u64;
        if got < rest.len() {
            return Err(truncated(0, "the file header", 8 + got, size));
        }
        h[8..72].copy_from_slice(&rest[..64]);
        let mut st = [0u16; 8];
        for (k, v) in st.iter_mut().enumerate() {
            *v = u16_at(&h, 40 + 2 * k);
        }
        self.start = time::from_systemtime(st);
        Ok(())
    }

    /// Reads the next entry into `entry`; `Ok(false)` at the end.
    pub fn read_into(&mut self, entry: &mut Message) -> Result<bool, ReadError> {
        if self.done {
            return Ok(false);
        }
        let result = self.next_entry(entry);
        match &result {
            Ok(false) => self.done = true,
            Err(e) if e.is_fatal() => self.done = true,
            _ => {}
        }
        result
    }

    fn next_entry(&mut self, entry: &mut Message) -> Result<bool, ReadError> {
        if !self.started {
            self.started = true;
            self.read_file_header()?;
        }
        loop {
            match self.next_object(entry)? {
                Some(true) => return Ok(true),
                Some(false) => continue,
                None => {}
            }
            // More objects are needed.
            if let Some(cut) = self.cut.take() {
                return Err(cut);
            }
            if !self.next_container()? {
                let left = &self.data[self.pos..];
                if left.iter().any(|&b| b != 0) {
                    return Err(ReadError::fatal(
                        Some(Location::Offset(self.container_at)),
                        Problem::Truncated {
                            what: "an object (its container ends before it)",
                            have: left.len() as u64,
                            need: u64::from(if left.len() >= 12 { u32_at(left, 8) } else { 0 }),
                        },
                    ));
                }
                return Ok(false);
            }
        }
    }

    /// Parses the object at `pos`: `Some(true)` an entry, `Some(false)` another object,
    /// `None` when the data ends before the next whole object.
    fn next_object(&mut self, entry: &mut Message) -> Result<Option<bool>, ReadError> {
        let at = Location::Offset(self.container_at);
        let avail = &self.data[self.pos..];
        if avail.len() < BASE_HEADER {
            return Ok(None);
        }
        // Objects are padded to 4 bytes; python-can looks for the signature that way.
        let Some(skip) = (0..=4).find(|&k| avail[k..].starts_with(OBJ_SIGNATURE)) else {
            // Lost: go to the next signature, if any.
            let next = memchr::memmem::find(&avail[1..], OBJ_SIGNATURE);
            self.pos += next.map_or(avail.len(), |n| n + 1);
            return Err(ReadError::expected(
                at,
                "an object (LOBJ) after the previous one",
                &avail[..avail.len().min(8)],
            ));
        };
        let obj = &avail[skip..];
        if obj.len() < BASE_HEADER {
            return Ok(None);
        }
        let version = u16_at(obj, 6);
        let size = u32_at(obj, 8);
        let ty = u32_at(obj, 12);
        let header = match version {
            1 => BASE_HEADER + V1_HEADER,
            2 => BASE_HEADER + V2_HEADER,
            _ => 0,
        };
        if size > MAX_OBJECT || (size as usize) < header.max(BASE_HEADER) {
            self.pos += skip + 4;
            return Err(ReadError::bad(
                at,
                Problem::Expected {
                    expected: "an object size that holds its header, up to 16 MiB",
                    found: size.to_string(),
                },
            ));
        }
        let size = size as usize;
        if obj.len() < size {
            return Ok(None);
        }
        let object = &obj[..size];
        self.pos += skip + size;
        if header == 0 {
            tracing::debug!("BLF object header version {version} skipped");
            return Ok(Some(false));
        }
        let flags = u32_at(object, BASE_HEADER);
        let ticks = u64_at(object, BASE_HEADER + 8);
        let since_start = match flags {
            TIME_TEN_MICS => Duration::from_micros(ticks.saturating_mul(10)),
            _ => Duration::from_nanos(ticks),
        };
        let body = &object[header..];
        let decoded = match ty {
            CAN_MESSAGE | CAN_MESSAGE2 => can_message(body).map(Some),
            CAN_ERROR_EXT => error_ext(body).map(Some),
            CAN_ERROR if body.len() >= 2 => {
                Ok(Some((u16_at(body, 0), Record::Error(bus_error()), None)))
            }
            CAN_FD_MESSAGE => fd_message(body).map(Some),
            CAN_FD_MESSAGE_64 => fd_message_64(body, header).map(Some),
            _ => Ok(None),
        };
        let Some((channel, record, direction)) = decoded.map_err(|p| ReadError::bad(at, p))? else {
            return Ok(Some(false));
        };
        // CAN_MESSAGE2: frame length u32 and bit count u8 after the data; CAN_FD_MESSAGE:
        // after the ID.
        let length = match ty {
            CAN_MESSAGE2 if body.len() >= 21 => Some((u32_at(body, 16), body[20])),
            CAN_FD_MESSAGE => Some((u32_at(body, 8), body[12])),
            _ => None,
        };
        if let (Record::Frame(frame), Some((ns, bits))) = (&record, length) {
            let bits = (bits > 0).then_some(u64::from(bits));
            self.lengths.add(channel, frame, u64::from(ns), bits);
        }
        entry.at = Timestamp::since_epoch(self.start + since_start);
        set_channel_name(&mut entry.channel, channel);
        entry.record = record;
        entry.direction = direction;
        Ok(Some(true))
    }

    /// Reads the next top-level object into `data`: `false` at the end of the file.
    fn next_container(&mut self) -> Result<bool, ReadError> {
        // Drop what was parsed.
        self.data.drain(..self.pos);
        self.pos = 0;
        let start = self.offset;
        let mut base = [0u8; BASE_HEADER];
        let got = read_full(&mut self.input, &mut base)?;
        self.offset += got as u64;
        if got == 0 {
            return Ok(false);
        }
        if got < 4 || &base[..4] != OBJ_SIGNATURE {
            return Err(ReadError::fatal(
                Some(Location::Offset(start)),
                Problem::Expected {
                    expected: "an object (LOBJ)",
                    found: crate::error::excerpt(&base[..got.min(4)]),
                },
            ));
        }
        if got < BASE_HEADER {
            return Err(truncated(start, "an object header", got, BASE_HEADER));
        }
        let size = u32_at(&base, 8);
        let ty = u32_at(&base, 12);
        if size > MAX_OBJECT || (size as usize) < BASE_HEADER {
            return Err(ReadError::fatal(
                Some(Location::Offset(start)),
                Problem::TooBig {
                    what: "an object",
                    claimed: u64::from(size),
                    limit: u64::from(MAX_OBJECT),
                },
            ));
        }
        self.container_at = start;
        self.object.resize(size as usize - BASE_HEADER, 0);
        let got = read_full(&mut self.input, &mut self.object)?;
        self.offset += got as u64;
        let whole = got == self.object.len();
        if !whole {
            self.object.truncate(got);
            self.cut = Some(truncated(
                start,
                "an object",
                BASE_HEADER + got,
                size as usize,
            ));
        } else {
            // python-can's padding rule.
            let mut pad = [0u8; 4];
            let n = read_full(&mut self.input, &mut pad[..size as usize % 4])?;
            self.offset += n as u64;
        }
        if ty != LOG_CONTAINER {
            // An object outside a container (older files): parse it as it is.
            if whole {
                self.data.extend_from_slice(&base);
                self.data.extend_from_slice(&self.object);
            }
            return Ok(true);
        }
        if self.object.len() < 16 {
            return Ok(true);
        }
        let method = u16_at(&self.object, 0);
        let claimed = u32_at(&self.object, 8);
        if claimed > MAX_OBJECT {
            self.cut = None;
            return Err(ReadError::fatal(
                Some(Location::Offset(start)),
                Problem::TooBig {
                    what: "a container's uncompressed data",
                    claimed: u64::from(claimed),
                    limit: u64::from(MAX_OBJECT),
                },
            ));
        }
        let payload = &self.object[16..];
        match method {
            NO_COMPRESSION => self.data.extend_from_slice(payload),
            ZLIB_DEFLATE => {
                let before = self.data.len();
                self.data.reserve(claimed as usize);
                let mut z = Decompress::new(true);
                let status = z.decompress_vec(payload, &mut self.data, FlushDecompress::Finish);
                match status {
                    Ok(Status::StreamEnd) => {}
                    Ok(_) if !whole => {} // the cut: what inflated so far is kept
                    Ok(_) => {
                        if self.data.len() - before >= claimed as usize {
                            // More data than it claims: the rest is lost, say so.
                            return Err(ReadError::bad(
                                Location::Offset(start),
                                Problem::Inflate(format!(
                                    "the container inflates to more than the {claimed} bytes it claims"
                                )),
                            ));
                        }
                    }
                    Err(e) if whole => {
                        return Err(ReadError::bad(
                            Location::Offset(start),
                            Problem::Inflate(e.to_string()),
                        ));
                    }
                    Err(_) => {}
                }
            }
            other => {
                tracing::warn!(
                    "BLF container at byte {start}: unknown compression {other}, skipped"
                );
            }
        }
        Ok(true)
    }
}

type Decoded = (u16, Record, Option<Direction>);

fn short(what: &'static str, body: &[u8]) -> Problem {
    Problem::Expected {
        expected: what,
        found: format!("{} bytes", body.len()),
    }
}

fn id_of(raw: u32) -> Result<Id, Problem> {
    Ok(if raw & EXT_FLAG != 0 {
        Id::extended(raw & 0x1FFF_FFFF)?
    } else {
        Id::standard(u16::try_from(raw).map_err(|_| Problem::Expected {
            expected: "a standard CAN ID up to 0x7FF (or the extended flag)",
            found: format!("0x{raw:X}"),
        })?)?
    })
}

/// CAN_MESSAGE: channel u16, flags u8, dlc u8, id u32, data\[8\].
fn can_message(body: &[u8]) -> Result<Decoded, Problem> {
    if body.len() < 16 {
        return Err(short("a CAN message of 16 bytes", body));
    }
    let channel = u16_at(body, 0);
    let flags = body[2];
    let dlc = body[3];
    let id = id_of(u32_at(body, 4))?;
    let direction = Some(if flags & DIR_TX != 0 {
        Direction::Tx
    } else {
        Direction::Rx
    });
    let frame = if flags & REMOTE_FLAG != 0 {
        Frame::remote(id, dlc.min(8))?
    } else {
        Frame::data(id, &body[8..8 + usize::from(dlc.min(8))])?
    };
    Ok((channel, Record::Frame(frame), direction))
}

/// CAN_ERROR_EXT: channel u16, length u16, flags u32, ecc, position, dlc, reserved,
/// frame length u32, id u32, flags ext u16, reserved u16, data\[8\].
fn error_ext(body: &[u8]) -> Result<Decoded, Problem> {
    if body.len() < 32 {
        return Err(short("a CAN error object of 32 bytes", body));
    }
    let channel = u16_at(body, 0);
    let dlc = usize::from(body[10]).min(8);
    let id = u32_at(body, 16) & 0x1FFF_FFFF;
    let error = ErrorFrame::decode(id, &body[24..24 + dlc])?;
    Ok((channel, Record::Error(error), Some(Direction::Rx)))
}

/// CAN_FD_MESSAGE: channel u16, flags u8, dlc u8, id u32, frame length u32, bit count u8,
/// FD flags u8 (EDL 1, BRS 2, ESI 4), valid bytes u8, 5 reserved, data\[64\].
fn fd_message(body: &[u8]) -> Result<Decoded, Problem> {
    if body.len() < 20 {
        return Err(short("a CAN FD message of at least 20 bytes", body));
    }
    let fd_flags = body[13];
    let channel = u16_at(body, 0);
    let flags = body[2];
    let id = id_of(u32_at(body, 4))?;
    let direction = Some(if flags & DIR_TX != 0 {
        Direction::Tx
    } else {
        Direction::Rx
    });
    if fd_flags & FD_EDL != 0 {
        if flags & REMOTE_FLAG != 0 {
            return Err(fd_remote(u32::from(flags)));
        }
        let valid = usize::from(body[14]);
        let data = body
            .get(20..20 + valid)
            .ok_or_else(|| short("its valid data bytes", body))?;
        let frame = FdFrame::new(id, data)?
            .with_brs(fd_flags & FD_BRS != 0)
            .with_esi(fd_flags & FD_ESI != 0);
        return Ok((channel, Record::Fd(frame), direction));
    }
    let dlc = body[3].min(8);
    let valid = usize::from(body[14]).min(8).min(usize::from(dlc));
    let data = body
        .get(20..20 + valid)
        .ok_or_else(|| short("its data bytes", body))?;
    let frame = if flags & REMOTE_FLAG != 0 {
        Frame::remote(id, dlc)?
    } else {
        Frame::data(id, data)?
    };
    Ok((channel, Record::Frame(frame), direction))
}

fn fd_remote(flags: u32) -> Problem {
    Problem::Expected {
        expected: "a CAN FD frame without the remote flag (CAN FD has no remote frames)",
        found: format!("flags 0x{flags:X}"),
    }
}

/// CAN_FD_MESSAGE_64: channel u8, dlc u8, valid bytes u8, tx count u8, id u32, frame length
/// u32, flags u32 (remote 0x10, EDL 0x1000, BRS 0x2000, ESI 0x4000), four bit-timing and
/// offset u32s, bit count u16, direction u8, extended data offset u8, crc u32, then the data
/// (up to the extended data's offset in the object, when there is one).
fn fd_message_64(body: &[u8], header: usize) -> Result<Decoded, Problem> {
    if body.len() < FD64_HEADER {
        return Err(short("a CAN FD 64 message of at least 40 bytes", body));
    }
    let flags = u32_at(body, 12);
    let channel = u16::from(body[0]);
    let id = id_of(u32_at(body, 4))?;
    let direction = Some(if body[34] != 0 {
        Direction::Tx
    } else {
        Direction::Rx
    });
    // The data, up to the extended data (an offset in the object) or the object's end.
    let ext_data = usize::from(body[35]);
    let end = if ext_data == 0 {
        body.len()
    } else {
        ext_data.saturating_sub(header).min(body.len())
    };
    let stored = body.get(FD64_HEADER..end).unwrap_or_default();
    if flags & FD64_EDL != 0 {
        if flags & FD64_REMOTE != 0 {
            return Err(fd_remote(flags));
        }
        let valid = usize::from(body[2]);
        if valid > FD_MAX_LEN {
            return Err(buslab_can::ParseError::FdLength { len: valid }.into());
        }
        // Valid bytes beyond the stored data are zeros (CANoe's and python-can's reading).
        let mut data = [0u8; FD_MAX_LEN];
        let have = stored.len().min(valid);
        data[..have].copy_from_slice(&stored[..have]);
        let frame = FdFrame::new(id, &data[..valid])?
            .with_brs(flags & FD64_BRS != 0)
            .with_esi(flags & FD64_ESI != 0);
        return Ok((channel, Record::Fd(frame), direction));
    }
    let dlc = body[1].min(8);
    let valid = usize::from(body[2]).min(usize::from(dlc));
    let mut data = [0u8; 8];
    let have = stored.len().min(valid);
    data[..have].copy_from_slice(&stored[..have]);
    let frame = if flags & FD64_REMOTE != 0 {
        Frame::remote(id, dlc)?
    } else {
        Frame::data(id, &data[..valid])?
    };
    Ok((channel, Record::Frame(frame), direction))
}

impl<R: Read + Send> LogReader for Reader<R> {
    fn read_into(&mut self, entry: &mut Message) -> Result<bool, ReadError> {
        Reader::read_into(self, entry)
    }
    fn bit_rate(&self, channel: &str) -> Option<LogBitRate> {
        self.lengths.rate(channel_of(channel)?)
    }
}

/// An FD frame's object body into `body`: CAN_FD_MESSAGE_64 (CANoe's), or CAN_FD_MESSAGE
/// (python-can's) for a channel the former's one byte cannot hold. Returns the type and size.
fn fd_body(
    body: &mut [u8; FD64_HEADER + FD_MAX_LEN],
    channel: u16,
    direction: Option<Direction>,
    f: &FdFrame,
) -> (u32, usize) {
    let tx = direction == Some(Direction::Tx);
    let id = match f.id() {
        Id::Standard(i) => u32::from(i.as_raw()),
        Id::Extended(i) => i.as_raw() | EXT_FLAG,
    };
    let payload = f.payload();
    if let Ok(channel) = u8::try_from(channel) {
        body[0] = channel;
        body[1] = f.dlc();
        body[2] = payload.len() as u8;
        body[4..8].copy_from_slice(&id.to_le_bytes());
        let flags =
            FD64_EDL | if f.brs() { FD64_BRS } else { 0 } | if f.esi() { FD64_ESI } else { 0 };
        body[12..16].copy_from_slice(&flags.to_le_bytes());
        body[34] = u8::from(tx);
        body[FD64_HEADER..FD64_HEADER + payload.len()].copy_from_slice(payload);
        (CAN_FD_MESSAGE_64, FD64_HEADER + payload.len())
    } else {
        body[0..2].copy_from_slice(&channel.to_le_bytes());
        body[2] = if tx { DIR_TX } else { 0 };
        body[3] = f.dlc();
        body[4..8].copy_from_slice(&id.to_le_bytes());
        body[13] = FD_EDL | if f.brs() { FD_BRS } else { 0 } | if f.esi() { FD_ESI } else { 0 };
        body[14] = payload.len() as u8;
        body[20..20 + payload.len()].copy_from_slice(payload);
        (CAN_FD_MESSAGE, 20 + FD_MAX_LEN)
    }
}

/// Writes a BLF file whose every state on disk reads: the header is valid from creation and
/// rewritten at each [`flush`](Writer::flush) (counts, sizes, start and stop times), and the
/// start time is in the header before the first object that counts from it.
pub struct Writer<W: Write + Seek> {
    out: W,
    channels: ChannelMap,
    /// Uncompressed objects of the open container.
    buf: Vec<u8>,
    compressed: Vec<u8>,
    start: Option<Duration>,
    /// Whether the header in the output carries `start` (objects count from it).
    start_written: bool,
    stop: Duration,
    objects: u32,
    uncompressed: u64,
    /// The bytes written so far: the header and every container.
    size: u64,
}

impl<W: Write + Seek> Writer<W> {
    /// Writes the header of an empty file (python-can and buslab read it as a file with no
    /// objects).
    pub fn new(out: W) -> io::Result<Self> {
        let mut w = Self {
            out,
            channels: ChannelMap::new(),
            buf: Vec::with_capacity(CONTAINER_SIZE + 256),
            compressed: Vec::new(),
            start: None,
            start_written: false,
            stop: Duration::ZERO,
            objects: 0,
            uncompressed: FILE_HEADER_SIZE as u64,
            size: FILE_HEADER_SIZE as u64,
        };
        let header = w.header();
        w.out.write_all(&header)?;
        Ok(w)
    }

    /// Writes one entry; an entry whose time the file cannot hold (after the year 65535, the
    /// last a SYSTEMTIME names, or more than 584 years after the file's start, the most its
    /// nanosecond offsets count) is refused with [`io::ErrorKind::InvalidInput`] and nothing
    /// is written.
    pub fn write(&mut self, entry: &Message) -> io::Result<()> {
        if !time::fits_systemtime(entry.at.since_epoch_duration()) {
            return Err(time::out_of_range(
                entry.at.since_epoch_duration(),
                "a BLF file",
                "times up to the year 65535 (its SYSTEMTIME)",
            ));
        }
        if let Some(start) = self.start
            && u64::try_from(
                entry
                    .at
                    .since_epoch_duration()
                    .saturating_sub(start)
                    .as_nanos(),
            )
            .is_err()
        {
            return Err(time::out_of_range(
                entry.at.since_epoch_duration(),
                "a BLF file",
                "times up to 584 years after its first entry (nanoseconds in 64 bits)",
            ));
        }
        let start = *self.start.get_or_insert_with(|| {
            // python-can's start: the first time cut to the millisecond, none before 1990.
            if entry.at.since_epoch_duration().as_secs() < 631_152_000 {
                Duration::ZERO
            } else {
                Duration::from_millis(
                    (entry.at.since_epoch_duration().as_millis()).min(u128::from(u64::MAX)) as u64,
                )
            }
        });
        self.stop = self.stop.max(entry.at.since_epoch_duration());
        // Checked above (the first entry's offset is below a millisecond).
        let ticks = entry
            .at
            .since_epoch_duration()
            .saturating_sub(start)
            .as_nanos()
            .min(u128::from(u64::MAX)) as u64;
        let channel = self.channels.number(&entry.channel);
        let mut body = [0u8; FD64_HEADER + FD_MAX_LEN];
        let (ty, len) = match &entry.record {
            Record::Fd(f) => fd_body(&mut body, channel, entry.direction, f),
            Record::Frame(f) => {
                body[0..2].copy_from_slice(&channel.to_le_bytes());
                let mut flags = if f.is_remote() { REMOTE_FLAG } else { 0 };
                if entry.direction == Some(Direction::Tx) {
                    flags |= DIR_TX;
                }
                body[2] = flags;
                body[3] = f.dlc();
                let id = match f.id() {
                    Id::Standard(i) => u32::from(i.as_raw()),
                    Id::Extended(i) => i.as_raw() | EXT_FLAG,
                };
                body[4..8].copy_from_slice(&id.to_le_bytes());
                body[8..8 + f.payload().len()].copy_from_slice(f.payload());
                (CAN_MESSAGE, 16)
            }
            Record::Error(e) => {
                let (class, data) = e.encode();
                body[0..2].copy_from_slice(&channel.to_le_bytes());
                body[10] = e.data_len() as u8; // dlc
                body[16..20].copy_from_slice(&class.to_le_bytes());
                body[24..32].copy_from_slice(&data);
                (CAN_ERROR_EXT, 32)
            }
        };
        let size = (BASE_HEADER + V1_HEADER + len) as u32;
        let b = &mut self.buf;
        b.extend_from_slice(OBJ_SIGNATURE);
        b.extend_from_slice(&((BASE_HEADER + V1_HEADER) as u16).to_le_bytes());
        b.extend_from_slice(&1u16.to_le_bytes());
        b.extend_from_slice(&size.to_le_bytes());
        b.extend_from_slice(&ty.to_le_bytes());
        b.extend_from_slice(&TIME_ONE_NANS.to_le_bytes());
        b.extend_from_slice(&0u16.to_le_bytes()); // client index
        b.extend_from_slice(&0u16.to_le_bytes()); // object version
        b.extend_from_slice(&ticks.to_le_bytes());
        b.extend_from_slice(&body[..len]);
        // python-can's padding: the object's size modulo 4 in zero bytes.
        b.extend_from_slice(&[0u8; 4][..len % 4]);
        self.objects = self.objects.saturating_add(1);
        if self.buf.len() >= CONTAINER_SIZE {
            self.write_container()?;
        }
        Ok(())
    }

    /// Compresses the open container and writes it (after the header's start time, the first
    /// time).
    fn write_container(&mut self) -> io::Result<()> {
        if self.buf.is_empty() {
            return Ok(());
        }
        if !self.start_written {
            self.rewrite_header()?;
            self.start_written = true;
        }
        // Level 1: several times faster than zlib's default for a few per cent more bytes.
        let mut z = Compress::new(Compression::fast(), true);
        self.compressed.clear();
        self.compressed.reserve(self.buf.len() + 1024);
        loop {
            let status = z
                .compress_vec(
                    &self.buf[z.total_in() as usize..],
                    &mut self.compressed,
                    FlushCompress::Finish,
                )
                .map_err(io::Error::other)?;
            if status == Status::StreamEnd {
                break;
            }
            self.compressed
                .reserve(self.compressed.capacity().max(4096));
        }
        let size = (BASE_HEADER + 16 + self.compressed.len()) as u32;
        let mut head = Vec::with_capacity(32);
        head.extend_from_slice(OBJ_SIGNATURE);
        head.extend_from_slice(&(BASE_HEADER as u16).to_le_bytes());
        head.extend_from_slice(&1u16.to_le_bytes());
        head.extend_from_slice(&size.to_le_bytes());
        head.extend_from_slice(&LOG_CONTAINER.to_le_bytes());
        head.extend_from_slice(&ZLIB_DEFLATE.to_le_bytes());
        head.extend_from_slice(&[0u8; 6]);
        head.extend_from_slice(&(self.buf.len() as u32).to_le_bytes());
        head.extend_from_slice(&[0u8; 4]);
        let pad = size as usize % 4;
        self.out.write_all(&head)?;
        self.out.write_all(&self.compressed)?;
        self.out.write_all(&[0u8; 4][..pad])?;
        self.size += u64::from(size) + pad as u64;
        self.uncompressed += (BASE_HEADER + 16 + self.buf.len()) as u64;
        self.buf.clear();
        Ok(())
    }

    /// The file header for what was written so far.
    fn header(&self) -> [u8; FILE_HEADER_SIZE] {
        let start = self.start.unwrap_or_default();
        let mut h = Vec::with_capacity(FILE_HEADER_SIZE);
        h.extend_from_slice(FILE_SIGNATURE);
        h.extend_from_slice(&(FILE_HEADER_SIZE as u32).to_le_bytes());
        h.extend_from_slice(&[5, 0, 0, 0, 2, 6, 8, 1]); // application and BL versions
        h.extend_from_slice(&self.size.to_le_bytes());
        h.extend_from_slice(&self.uncompressed.to_le_bytes());
        h.extend_from_slice(&self.objects.to_le_bytes());
        h.extend_from_slice(&0u32.to_le_bytes());
        for v in time::systemtime(start) {
            h.extend_from_slice(&v.to_le_bytes());
        }
        let stop = if self.start.is_some() && start > Duration::ZERO {
            self.stop
        } else {
            Duration::ZERO
        };
        for v in time::systemtime(stop) {
            h.extend_from_slice(&v.to_le_bytes());
        }
        let mut header = [0u8; FILE_HEADER_SIZE];
        header[..h.len()].copy_from_slice(&h);
        header
    }

    /// Writes the header over the first bytes and goes back to the end. One write of 144
    /// bytes at offset 0: a kill cannot leave half of it.
    fn rewrite_header(&mut self) -> io::Result<()> {
        let header = self.header();
        self.out.seek(SeekFrom::Start(0))?;
        self.out.write_all(&header)?;
        self.out.seek(SeekFrom::Start(self.size))?;
        Ok(())
    }

    /// Writes the open container and the header that counts it, and flushes: what was
    /// written so far reads back, and the header says so.
    pub fn flush(&mut self) -> io::Result<()> {
        if !self.buf.is_empty() {
            self.write_container()?;
            self.rewrite_header()?;
        }
        self.out.flush()
    }

    /// Writes the last container and the completed header.
    pub fn finish(mut self) -> io::Result<W> {
        self.write_container()?;
        self.rewrite_header()?;
        self.out.flush()?;
        Ok(self.out)
    }
}

impl<W: Write + Seek + Send> Encoder<W> for Writer<W> {
    fn write(&mut self, entry: &Message) -> io::Result<()> {
        Writer::write(self, entry)
    }
    fn flush(&mut self) -> io::Result<()> {
        Writer::flush(self)
    }
    fn finish(self) -> io::Result<W> {
        Writer::finish(self)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::BitRateSource;
    use crate::ReadError;

    /// A CAN_MESSAGE2 object (header version 1, ns) with `frame` on `channel`, recorded as
    /// taking `length_ns` on the wire.
    fn message2(channel: u16, frame: &Frame, length_ns: u32) -> Vec<u8> {
        let mut o = Vec::new();
        o.extend_from_slice(OBJ_SIGNATURE);
        o.extend_from_slice(&32u16.to_le_bytes());
        o.extend_from_slice(&1u16.to_le_bytes());
        o.extend_from_slice(&56u32.to_le_bytes());
        o.extend_from_slice(&CAN_MESSAGE2.to_le_bytes());
        o.extend_from_slice(&TIME_ONE_NANS.to_le_bytes());
        o.extend_from_slice(&[0; 4]);
        o.extend_from_slice(&1_000u64.to_le_bytes());
        o.extend_from_slice(&channel.to_le_bytes());
        o.push(0);
        o.push(frame.dlc());
        o.extend_from_slice(&frame.id().as_raw().to_le_bytes());
        let mut data = [0u8; 8];
        data[..frame.payload().len()].copy_from_slice(frame.payload());
        o.extend_from_slice(&data);
        o.extend_from_slice(&length_ns.to_le_bytes());
        o.extend_from_slice(&[0; 4]);
        o
    }

    /// An object of type `ty` (header version 1, ns) with `body`.
    fn object(ty: u32, body: &[u8]) -> Vec<u8> {
        let mut o = Vec::new();
        o.extend_from_slice(OBJ_SIGNATURE);
        o.extend_from_slice(&32u16.to_le_bytes());
        o.extend_from_slice(&1u16.to_le_bytes());
        o.extend_from_slice(&(32 + body.len() as u32).to_le_bytes());
        o.extend_from_slice(&ty.to_le_bytes());
        o.extend_from_slice(&TIME_ONE_NANS.to_le_bytes());
        o.extend_from_slice(&[0; 4]);
        o.extend_from_slice(&1_000u64.to_le_bytes());
        o.extend_from_slice(body);
        o
    }

    /// A CAN_FD_MESSAGE_64 body: channel, DLC, valid bytes, ID word, flags, direction, data.
    fn fd64(
        channel: u8,
        dlc: u8,
        valid: u8,
        id: u32,
        flags: u32,
        tx: bool,
        data: &[u8],
    ) -> Vec<u8> {
        let mut b = vec![0u8; FD64_HEADER];
        b[0] = channel;
        b[1] = dlc;
        b[2] = valid;
        b[4..8].copy_from_slice(&id.to_le_bytes());
        b[12..16].copy_from_slice(&flags.to_le_bytes());
        b[34] = u8::from(tx);
        b.extend_from_slice(data);
        b
    }

    fn read_objects(objects: &[Vec<u8>]) -> Vec<Result<Message, ReadError>> {
        let mut reader = Reader::new(io::empty());
        reader.data = objects.concat();
        let mut out = Vec::new();
        loop {
            let mut entry = Message::default();
            match reader.next_object(&mut entry) {
                Ok(Some(true)) => out.push(Ok(entry)),
                Ok(Some(false)) => {}
                Ok(None) => return out,
                Err(e) => out.push(Err(e)),
            }
        }
    }

    /// CANoe's CAN_FD_MESSAGE_64: the direction at byte 34, BRS/ESI in the flags, the valid
    /// bytes padded with zeros past the stored data (issue 1905 of python-can: 64 valid bytes,
    /// 48 stored), the data ending at the extended data's offset.
    #[test]
    fn can_fd_message_64_objects() {
        let got = read_objects(&[
            object(
                CAN_FD_MESSAGE_64,
                &fd64(2, 9, 12, 0x123, FD64_EDL | FD64_BRS, true, &[7; 12]),
            ),
            object(
                CAN_FD_MESSAGE_64,
                &fd64(
                    1,
                    15,
                    64,
                    0x8000_0ABC,
                    FD64_EDL | FD64_ESI,
                    false,
                    &[0xFF; 48],
                ),
            ),
            object(CAN_FD_MESSAGE_64, &{
                // Extended data at object offset 32 + 40 + 4: 4 stored bytes of 8.
                let mut b = fd64(1, 8, 8, 0x100, FD64_EDL, false, &[1, 2, 3, 4, 9, 9, 9, 9]);
                b[35] = 76;
                b
            }),
            object(
                CAN_FD_MESSAGE_64,
                &fd64(1, 3, 3, 0x100, 0, false, &[1, 2, 3]),
            ),
        ]);
        let text: Vec<String> = got
            .iter()
            .map(|r| {
                let e = r.as_ref().unwrap();
                format!("{} {} {:?}", e.channel, e.record, e.direction.unwrap())
            })
            .collect();
        let mut long = String::from("00000ABC##2");
        long.push_str(&"FF".repeat(48));
        long.push_str(&"00".repeat(16));
        assert_eq!(
            text,
            [
                "can1 123##1070707070707070707070707 Tx".to_string(),
                format!("can0 {long} Rx"),
                "can0 100##00102030400000000 Rx".into(),
                "can0 100#010203 Rx".into(),
            ]
        );
    }

    #[test]
    fn bad_fd_objects_say_what_was_expected() {
        let got = read_objects(&[
            object(
                CAN_FD_MESSAGE_64,
                &fd64(1, 10, 10, 0x100, FD64_EDL, false, &[0; 10]),
            ),
            object(
                CAN_FD_MESSAGE_64,
                &fd64(1, 15, 65, 0x100, FD64_EDL, false, &[0; 65]),
            ),
            object(
                CAN_FD_MESSAGE_64,
                &fd64(1, 0, 0, 0x100, FD64_EDL | FD64_REMOTE, false, &[]),
            ),
            object(CAN_FD_MESSAGE_64, &[0; 20]),
            object(CAN_FD_MESSAGE, &{
                let mut b = vec![0u8; 20 + 64];
                b[13] = FD_EDL;
                b[14] = 20;
                b[4..8].copy_from_slice(&0x900u32.to_le_bytes());
                b
            }),
            object(CAN_FD_MESSAGE, &{
                let mut b = vec![0u8; 20 + 4];
                b[13] = FD_EDL;
                b[14] = 12;
                b
            }),
        ]);
        let errors: Vec<String> = got
            .iter()
            .map(|r| r.as_ref().unwrap_err().to_string())
            .collect();
        let wants = [
            "10 data bytes given",
            "65 data bytes given",
            "without the remote flag",
            "a CAN FD 64 message of at least 40 bytes",
            "standard ID 0x900 is out of range",
            "its valid data bytes",
        ];
        assert_eq!(errors.len(), wants.len(), "{errors:?}");
        for (e, want) in errors.iter().zip(wants) {
            assert!(e.contains(want), "{e}");
        }
    }

    /// FD frames are written as CAN_FD_MESSAGE_64, or CAN_FD_MESSAGE for a channel above 255;
    /// each object is padded with its size modulo 4 in zeros (python-can's rule).
    #[test]
    fn fd_frames_are_written_as_can_fd_message_64() {
        let mut w = Writer::new(io::Cursor::new(Vec::new())).unwrap();
        let fd: FdFrame = "123##3112233".parse().unwrap();
        for channel in ["can1", "can300"] {
            w.write(&Message {
                at: Timestamp::since_epoch(Duration::from_secs(1_700_000_000)),
                channel: channel.into(),
                direction: Some(Direction::Tx),
                record: Record::Fd(fd),
            })
            .unwrap();
        }
        let b = &w.buf;
        assert_eq!(u32_at(b, 8), 32 + 40 + 3);
        assert_eq!(u32_at(b, 12), CAN_FD_MESSAGE_64);
        let body = &b[32..75];
        assert_eq!((body[0], body[1], body[2], body[34]), (2, 3, 3, 1));
        assert_eq!(u32_at(body, 12), FD64_EDL | FD64_BRS | FD64_ESI);
        assert_eq!(&body[40..43], &[0x11, 0x22, 0x33]);
        assert_eq!(&b[75..78], &[0, 0, 0]);
        let second = &b[78..];
        assert_eq!(u32_at(second, 8), 32 + 84);
        assert_eq!(u32_at(second, 12), CAN_FD_MESSAGE);
        let body = &second[32..];
        assert_eq!(u16_at(body, 0), 301);
        assert_eq!((body[2], body[3], body[13], body[14]), (DIR_TX, 3, 7, 3));
        assert_eq!(second.len(), 32 + 84);
        let back = read_objects(std::slice::from_ref(b));
        let back: Vec<String> = back
            .iter()
            .map(|e| e.as_ref().unwrap().record.to_string())
            .collect();
        assert_eq!(back, ["123##3112233", "123##3112233"]);
    }

    #[test]
    fn can_message2_frame_lengths_give_the_channels_bit_rate() {
        let frame: Frame = "6F9#050C000000000000".parse().unwrap();
        let mut reader = Reader::new(io::empty());
        // 120 bits: 240 µs at 500 kbit/s on channel 1, 960 µs at 125 kbit/s on channel 2; a
        // length of 0 (not measured) on channel 3.
        reader.data = [
            message2(1, &frame, 240_000),
            message2(2, &frame, 960_000),
            message2(3, &frame, 0),
        ]
        .concat();
        let mut entry = Message::default();
        for _ in 0..3 {
            assert_eq!(reader.next_object(&mut entry).unwrap(), Some(true));
        }
        let rate = |name: &str| LogReader::bit_rate(&reader, name);
        assert_eq!(
            rate("can0"),
            Some(LogBitRate {
                bits_per_s: 500_000,
                source: BitRateSource::FrameLengths
            })
        );
        assert_eq!(rate("can1").unwrap().bits_per_s, 125_000);
        assert_eq!(rate("can2"), None);
        assert_eq!(rate("vcan0"), None);
    }
}
