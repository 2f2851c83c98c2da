//! The packet of LINKTYPE_CAN_SOCKETCAN (227), shared by pcap and pcapng: SocketCAN's
//! `can_frame` or `canfd_frame` with the CAN ID big-endian: ID and flags (4), length (1), FD
//! flags (1), two reserved bytes, then the data. Classic frames and error frames are 16 bytes
//! (8 data bytes); CAN FD frames are 72 (64 data bytes) with FDF (0x04) in the FD flags beside
//! BRS (0x01) and ESI (0x02). Written with FDF, which Wireshark needs to show a frame as FD
//! (tshark 4.0 shows a 72-byte record without it as classic); read as FD when FDF is set or
//! the record is longer than 16 bytes (the link type's rule for writers older than FDF).
//!
//! Wireshark's "Export PDUs" and `text2pcap -P` write LINKTYPE_WIRESHARK_UPPER_PDU (252):
//! each packet is a list of tags (type and length as big-endian u16, then the value; tag 0
//! ends it) naming the dissector of the bytes after them. Those of Wireshark's dissector for
//! LINKTYPE_CAN_SOCKETCAN (`can-bigendian`, or the old link-type tag saying 227) are read as
//! above, and those of its CAN FD dissector (`canfd`) as CAN FD records; any other is refused,
//! naming the dissector.

use std::ops::Deref;

use buslab_bus::ErrorFrame;
use buslab_can::{FD_MAX_LEN, FdFrame, Frame, Id};

use crate::Record;
use crate::error::{Problem, excerpt};

pub const LINKTYPE_CAN_SOCKETCAN: u16 = 227;
/// Wireshark's exported PDUs.
pub const LINKTYPE_WIRESHARK_UPPER_PDU: u16 = 252;
/// A classic CAN record's size.
pub const CLASSIC_LEN: usize = 16;
/// A CAN FD record's size.
pub const FD_LEN: usize = 8 + FD_MAX_LEN;

const EFF_FLAG: u32 = 0x8000_0000;
const RTR_FLAG: u32 = 0x4000_0000;
const ERR_FLAG: u32 = 0x2000_0000;
/// FD flags byte: bit rate switch, error state indicator, and FDF, which marks a CAN FD frame.
const BRS: u8 = 0x01;
const ESI: u8 = 0x02;
const FDF: u8 = 0x04;
/// CAN XL records set this bit in byte 4.
const XLF: u8 = 0x80;

/// One record as the link type carries it: 16 bytes, or 72 for a CAN FD frame.
#[derive(Clone, Copy)]
pub struct Packet {
    bytes: [u8; FD_LEN],
    len: usize,
}

impl Deref for Packet {
    type Target = [u8];
    fn deref(&self) -> &[u8] {
        &self.bytes[..self.len]
    }
}

/// The record of an entry's frame, FD frame or error frame.
pub fn encode(record: &Record) -> Packet {
    let mut out = Packet {
        bytes: [0; FD_LEN],
        len: CLASSIC_LEN,
    };
    let raw_id = |id: Id| match id {
        Id::Standard(id) => u32::from(id.as_raw()),
        Id::Extended(id) => id.as_raw() | EFF_FLAG,
    };
    let (can_id, len) = match record {
        Record::Frame(f) => {
            let mut id = raw_id(f.id());
            if f.is_remote() {
                id |= RTR_FLAG;
            }
            out.bytes[8..8 + f.payload().len()].copy_from_slice(f.payload());
            (id, f.dlc())
        }
        Record::Fd(f) => {
            out.len = FD_LEN;
            out.bytes[5] = FDF | if f.brs() { BRS } else { 0 } | if f.esi() { ESI } else { 0 };
            out.bytes[8..8 + f.payload().len()].copy_from_slice(f.payload());
            (raw_id(f.id()), f.payload().len() as u8)
        }
        Record::Error(e) => {
            let (class, data) = e.encode();
            out.bytes[8..16].copy_from_slice(&data);
            (ERR_FLAG | class, e.data_len() as u8)
        }
    };
    out.bytes[..4].copy_from_slice(&can_id.to_be_bytes());
    out.bytes[4] = len;
    out
}

/// A record's frame, FD frame or error frame; a CAN XL record is refused.
pub fn decode(data: &[u8]) -> Result<Record, Problem> {
    decode_as(data, false)
}

/// [`decode`]; with `fd`, the record is CAN FD whatever its flags (Wireshark's `canfd` PDUs).
fn decode_as(data: &[u8], fd: bool) -> Result<Record, Problem> {
    let bad = |expected| Problem::Expected {
        expected,
        found: excerpt_hex(data),
    };
    if data.len() < 8 {
        return Err(bad("a SocketCAN record of at least 8 bytes"));
    }
    let can_id = u32::from_be_bytes([data[0], data[1], data[2], data[3]]);
    let (len, flags) = (data[4], data[5]);
    if len & XLF != 0 && can_id & (EFF_FLAG | RTR_FLAG | ERR_FLAG) == 0 && data.len() > CLASSIC_LEN
    {
        return Err(bad("a classic CAN or CAN FD record, not CAN XL"));
    }
    let payload = &data[8..];
    if fd || flags & FDF != 0 || data.len() > CLASSIC_LEN {
        return decode_fd(can_id, len, flags, payload).map_err(&bad);
    }
    if len > 8 {
        return Err(bad("a classic CAN record with a length 0..8"));
    }
    if can_id & ERR_FLAG != 0 {
        let take = usize::from(len).min(payload.len());
        return Ok(Record::Error(ErrorFrame::decode(
            can_id & 0x1FFF_FFFF,
            &payload[..take],
        )?));
    }
    let id = id_of(can_id).map_err(&bad)?;
    if can_id & RTR_FLAG != 0 {
        return Ok(Record::Frame(Frame::remote(id, len)?));
    }
    let len = usize::from(len);
    if payload.len() < len {
        return Err(bad("as many data bytes as the record's length"));
    }
    Ok(Record::Frame(Frame::data(id, &payload[..len])?))
}

/// A CAN FD record: `Err` says what was expected.
fn decode_fd(can_id: u32, len: u8, flags: u8, payload: &[u8]) -> Result<Record, &'static str> {
    if can_id & (RTR_FLAG | ERR_FLAG) != 0 {
        return Err("a CAN FD record without the RTR and error flags (CAN FD has neither)");
    }
    let id = id_of(can_id)?;
    let data = payload
        .get(..usize::from(len))
        .ok_or("as many data bytes as the CAN FD record's length")?;
    let frame = FdFrame::new(id, data)
        .map_err(|_| "a CAN FD length (0..8, 12, 16, 20, 24, 32, 48 or 64)")?;
    Ok(Record::Fd(
        frame.with_brs(flags & BRS != 0).with_esi(flags & ESI != 0),
    ))
}

fn id_of(can_id: u32) -> Result<Id, &'static str> {
    if can_id & EFF_FLAG != 0 {
        Id::extended(can_id & 0x1FFF_FFFF).map_err(|_| "an extended CAN ID")
    } else {
        u16::try_from(can_id & 0x1FFF_FFFF)
            .ok()
            .and_then(|raw| Id::standard(raw).ok())
            .ok_or("a standard CAN ID 0..0x7FF (or the EFF flag)")
    }
}

/// Whether buslab reads packets of `linktype`.
pub fn is_can(linktype: u32) -> bool {
    linktype == u32::from(LINKTYPE_CAN_SOCKETCAN)
        || linktype == u32::from(LINKTYPE_WIRESHARK_UPPER_PDU)
}

/// A packet of a link type [`is_can`] accepts.
pub fn decode_packet(linktype: u32, data: &[u8]) -> Result<Record, Problem> {
    if linktype == u32::from(LINKTYPE_WIRESHARK_UPPER_PDU) {
        let (record, fd) = exported_can_pdu(data)?;
        decode_as(record, fd)
    } else {
        decode(data)
    }
}

/// Exported-PDU tags (`wsutil/exported_pdu_tlvs.h`).
const EXP_PDU_TAG_END_OF_OPT: u16 = 0;
const EXP_PDU_TAG_LINKTYPE: u16 = 11;
const EXP_PDU_TAG_DISSECTOR_NAME: u16 = 12;
/// Wireshark's dissector for LINKTYPE_CAN_SOCKETCAN records.
const CAN_DISSECTOR: &str = "can-bigendian";
/// Wireshark's dissector for SocketCAN's CAN FD records (big-endian, as 227's).
const CANFD_DISSECTOR: &str = "canfd";

/// The SocketCAN record after an exported PDU's tags, if they name Wireshark's dissector for
/// LINKTYPE_CAN_SOCKETCAN or its CAN FD dissector, and whether it is the latter's.
fn exported_can_pdu(mut data: &[u8]) -> Result<(&[u8], bool), Problem> {
    let mut dissector: Option<&[u8]> = None;
    let mut linktype = None;
    loop {
        let [t0, t1, l0, l1, rest @ ..] = data else {
            return Err(Problem::Expected {
                expected: "exported-PDU tags ending with tag 0",
                found: excerpt_hex(data),
            });
        };
        let (tag, len) = (
            u16::from_be_bytes([*t0, *t1]),
            usize::from(u16::from_be_bytes([*l0, *l1])),
        );
        let Some(value) = rest.get(..len) else {
            return Err(Problem::Expected {
                expected: "an exported-PDU tag within the packet",
                found: format!("tag {tag} of {len} bytes, {} left", rest.len()),
            });
        };
        data = &rest[len..];
        match tag {
            EXP_PDU_TAG_END_OF_OPT => break,
            // A string, maybe with NULs at its end.
            EXP_PDU_TAG_DISSECTOR_NAME => {
                dissector = Some(value.split(|&b| b == 0).next().unwrap_or_default());
            }
            EXP_PDU_TAG_LINKTYPE if len == 4 => {
                linktype = Some(u32::from_be_bytes([value[0], value[1], value[2], value[3]]));
            }
            _ => {}
        }
    }
    match (dissector, linktype) {
        (Some(name), _) if name == CAN_DISSECTOR.as_bytes() => Ok((data, false)),
        (Some(name), _) if name == CANFD_DISSECTOR.as_bytes() => Ok((data, true)),
        (None, Some(l)) if l == u32::from(LINKTYPE_CAN_SOCKETCAN) => Ok((data, false)),
        (Some(name), _) => Err(Problem::Expected {
            expected: "exported PDUs of Wireshark's SocketCAN dissectors (can-bigendian, canfd)",
            found: format!("dissector {}", excerpt(name)),
        }),
        (None, Some(l)) => Err(Problem::LinkType {
            linktype: l,
            name: linktype_name(l),
        }),
        (None, None) => Err(Problem::Expected {
            expected: "an exported PDU naming its dissector (tag 12)",
            found: "none".into(),
        }),
    }
}

/// The name of a link type a CAN user may meet, for a message.
pub fn linktype_name(linktype: u32) -> &'static str {
    match linktype {
        0 => "BSD loopback",
        1 => "Ethernet",
        101 => "raw IP",
        113 => "Linux cooked capture (SLL)",
        227 => "SocketCAN",
        252 => "Wireshark's exported PDUs",
        276 => "Linux cooked capture v2 (SLL2)",
        _ => "not one buslab knows",
    }
}

fn excerpt_hex(data: &[u8]) -> String {
    let hex: String = data.iter().take(24).map(|b| format!("{b:02x}")).collect();
    excerpt(hex.as_bytes())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn records_as_wireshark_reads_them() {
        let f: Frame = "123#112233".parse().unwrap();
        let bytes = encode(&Record::Frame(f));
        assert_eq!(
            *bytes,
            [0, 0, 1, 0x23, 3, 0, 0, 0, 0x11, 0x22, 0x33, 0, 0, 0, 0, 0]
        );
        assert_eq!(decode(&bytes).unwrap(), Record::Frame(f));
        let rtr: Frame = "12345678#R4".parse().unwrap();
        let bytes = encode(&Record::Frame(rtr));
        assert_eq!(&bytes[..5], &[0xD2, 0x34, 0x56, 0x78, 4]);
        assert_eq!(decode(&bytes).unwrap(), Record::Frame(rtr));
        let err = ErrorFrame::decode(0x088, &[0, 0, 0x02, 0x0A, 0, 0, 0, 0]).unwrap();
        let bytes = encode(&Record::Error(err.clone()));
        assert_eq!(&bytes[..5], &[0x20, 0, 0, 0x88, 8]);
        assert_eq!(decode(&bytes).unwrap(), Record::Error(err));
        assert!(decode(&[0; 4]).is_err());
        let mut long = [0u8; CLASSIC_LEN];
        long[..16].copy_from_slice(&bytes);
        long[0] = 0;
        long[4] = 9;
        assert!(decode(&long).unwrap_err().to_string().contains("0..8"));
    }

    /// As tshark 4.0 reads them: 72 bytes, FDF beside BRS and ESI, the length in byte 4.
    #[test]
    fn fd_records_as_wireshark_reads_them() {
        let fd: FdFrame = "12345678##3112233445566778899AABBCC".parse().unwrap();
        let bytes = encode(&Record::Fd(fd));
        assert_eq!(bytes.len(), FD_LEN);
        assert_eq!(
            &bytes[..8],
            &[0x92, 0x34, 0x56, 0x78, 12, FDF | BRS | ESI, 0, 0]
        );
        assert_eq!(&bytes[8..20], fd.payload());
        assert!(bytes[20..].iter().all(|&b| b == 0));
        assert_eq!(decode(&bytes).unwrap(), Record::Fd(fd));
        // Without FDF a 72-byte record is FD (the link type's rule before FDF), flags kept.
        let mut old = [0u8; FD_LEN];
        old[..].copy_from_slice(&bytes);
        old[5] = BRS;
        let read = decode(&old).unwrap();
        assert_eq!(read, Record::Fd(fd.with_esi(false)));
        // A 16-byte record with FDF is FD too: its 8 bytes.
        let short: FdFrame = "123##00102030405060708".parse().unwrap();
        let mut rec = [0u8; CLASSIC_LEN];
        rec[..4].copy_from_slice(&0x123u32.to_be_bytes());
        rec[4] = 8;
        rec[5] = FDF;
        rec[8..].copy_from_slice(short.payload());
        assert_eq!(decode(&rec).unwrap(), Record::Fd(short));
    }

    #[test]
    fn bad_fd_records_say_what_was_expected() {
        let fd: FdFrame = "123##0112233".parse().unwrap();
        let good = encode(&Record::Fd(fd));
        let with = |i: usize, v: u8| {
            let mut b = [0u8; FD_LEN];
            b.copy_from_slice(&good);
            b[i] = v;
            decode(&b).unwrap_err().to_string()
        };
        assert!(with(4, 10).contains("a CAN FD length"), "{}", with(4, 10));
        assert!(with(4, 65).contains("a CAN FD length") || with(4, 65).contains("data bytes"));
        assert!(
            with(0, 0x40).contains("without the RTR"),
            "{}",
            with(0, 0x40)
        );
        assert!(
            with(2, 0x08).contains("standard CAN ID"),
            "{}",
            with(2, 0x08)
        );
        // Shorter than its length says.
        let err = decode(&good[..10]).unwrap_err().to_string();
        assert!(err.contains("as many data bytes"), "{err}");
    }
}
