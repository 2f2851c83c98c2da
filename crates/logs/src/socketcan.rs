//! The packet of LINKTYPE_CAN_SOCKETCAN (227), shared by pcap and pcapng: SocketCAN's
//! `can_frame` with the CAN ID big-endian. Classic frames are 16 bytes: ID and flags (4),
//! length (1), FD flags (1), two reserved bytes, 8 data bytes.
//!
//! Wireshark's "Export PDUs" and `text2pcap -P` write LINKTYPE_WIRESHARK_UPPER_PDU (252):
//! each packet is a list of tags (type and length as big-endian u16, then the value; tag 0
//! ends it) naming the dissector of the bytes after them. Those of Wireshark's dissector for
//! LINKTYPE_CAN_SOCKETCAN (`can-bigendian`, or the old link-type tag saying 227) are read as
//! above; any other is refused, naming the dissector.

use buslab_bus::ErrorFrame;
use buslab_can::{Frame, Id};

use crate::Record;
use crate::error::{Problem, excerpt};

pub const LINKTYPE_CAN_SOCKETCAN: u16 = 227;
/// Wireshark's exported PDUs.
pub const LINKTYPE_WIRESHARK_UPPER_PDU: u16 = 252;
/// A classic CAN record's size.
pub const CLASSIC_LEN: usize = 16;

const EFF_FLAG: u32 = 0x8000_0000;
const RTR_FLAG: u32 = 0x4000_0000;
const ERR_FLAG: u32 = 0x2000_0000;
/// FD flags byte: FDF marks a CAN FD frame.
const FDF: u8 = 0x04;
/// CAN XL records set this bit in byte 4.
const XLF: u8 = 0x80;

/// The 16-byte record of an entry's frame or error frame; `None` for an FD frame (not yet
/// written: a 72-byte record).
pub fn encode(record: &Record) -> Option<[u8; CLASSIC_LEN]> {
    let mut out = [0u8; CLASSIC_LEN];
    let (can_id, len) = match record {
        Record::Fd(_) => return None,
        Record::Frame(f) => {
            let mut id = match f.id() {
                Id::Standard(id) => u32::from(id.as_raw()),
                Id::Extended(id) => id.as_raw() | EFF_FLAG,
            };
            if f.is_remote() {
                id |= RTR_FLAG;
            }
            out[8..8 + f.payload().len()].copy_from_slice(f.payload());
            (id, f.dlc())
        }
        Record::Error(e) => {
            let (class, data) = e.encode();
            out[8..16].copy_from_slice(&data);
            (ERR_FLAG | class, e.data_len() as u8)
        }
    };
    out[..4].copy_from_slice(&can_id.to_be_bytes());
    out[4] = len;
    Some(out)
}

/// A record's frame or error frame. CAN FD and CAN XL records are [`Problem::CanFd`] and
/// an unsupported record.
pub fn decode(data: &[u8]) -> Result<Record, Problem> {
    let bad = |expected| Problem::Expected {
        expected,
        found: excerpt_hex(data),
    };
    if data.len() < 8 {
        return Err(bad("a SocketCAN record of at least 8 bytes"));
    }
    let can_id = u32::from_be_bytes([data[0], data[1], data[2], data[3]]);
    let (len, flags) = (data[4], data[5]);
    if len & XLF != 0 && can_id & (EFF_FLAG | RTR_FLAG | ERR_FLAG) == 0 && data.len() > 16 {
        return Err(bad("a classic CAN record, not CAN XL"));
    }
    if flags & FDF != 0 || data.len() > CLASSIC_LEN {
        return Err(Problem::CanFd);
    }
    if len > 8 {
        return Err(bad("a classic CAN record with a length 0..8"));
    }
    let payload = &data[8..];
    if can_id & ERR_FLAG != 0 {
        let take = usize::from(len).min(payload.len());
        return Ok(Record::Error(ErrorFrame::decode(
            can_id & 0x1FFF_FFFF,
            &payload[..take],
        )?));
    }
    let id = if can_id & EFF_FLAG != 0 {
        Id::extended(can_id & 0x1FFF_FFFF)?
    } else {
        let raw = u16::try_from(can_id & 0x1FFF_FFFF)
            .map_err(|_| bad("a standard CAN ID 0..0x7FF (or the EFF flag)"))?;
        Id::standard(raw)?
    };
    if can_id & RTR_FLAG != 0 {
        return Ok(Record::Frame(Frame::remote(id, len)?));
    }
    let len = usize::from(len);
    if payload.len() < len {
        return Err(bad("as many data bytes as the record's length"));
    }
    Ok(Record::Frame(Frame::data(id, &payload[..len])?))
}

/// Whether buslab reads packets of `linktype`.
pub fn is_can(linktype: u32) -> bool {
    linktype == u32::from(LINKTYPE_CAN_SOCKETCAN)
        || linktype == u32::from(LINKTYPE_WIRESHARK_UPPER_PDU)
}

/// A packet of a link type [`is_can`] accepts.
pub fn decode_packet(linktype: u32, data: &[u8]) -> Result<Record, Problem> {
    if linktype == u32::from(LINKTYPE_WIRESHARK_UPPER_PDU) {
        decode(exported_can_pdu(data)?)
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

/// The SocketCAN record after an exported PDU's tags, if they name Wireshark's dissector for
/// LINKTYPE_CAN_SOCKETCAN.
fn exported_can_pdu(mut data: &[u8]) -> Result<&[u8], Problem> {
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
        (Some(name), _) if name == CAN_DISSECTOR.as_bytes() => Ok(data),
        (None, Some(l)) if l == u32::from(LINKTYPE_CAN_SOCKETCAN) => Ok(data),
        (Some(b"canfd"), _) => Err(Problem::CanFd),
        (Some(name), _) => Err(Problem::Expected {
            expected: "exported PDUs of Wireshark's SocketCAN dissector (can-bigendian)",
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
        let bytes = encode(&Record::Frame(f)).unwrap();
        assert_eq!(
            bytes,
            [0, 0, 1, 0x23, 3, 0, 0, 0, 0x11, 0x22, 0x33, 0, 0, 0, 0, 0]
        );
        assert_eq!(decode(&bytes).unwrap(), Record::Frame(f));
        let rtr: Frame = "12345678#R4".parse().unwrap();
        let bytes = encode(&Record::Frame(rtr)).unwrap();
        assert_eq!(&bytes[..5], &[0xD2, 0x34, 0x56, 0x78, 4]);
        assert_eq!(decode(&bytes).unwrap(), Record::Frame(rtr));
        let err = ErrorFrame::decode(0x088, &[0, 0, 0x02, 0x0A, 0, 0, 0, 0]).unwrap();
        let bytes = encode(&Record::Error(err.clone())).unwrap();
        assert_eq!(&bytes[..5], &[0x20, 0, 0, 0x88, 8]);
        assert_eq!(decode(&bytes).unwrap(), Record::Error(err));
        let mut fd = [0u8; 72];
        fd[5] = FDF;
        assert!(matches!(decode(&fd), Err(Problem::CanFd)));
        assert!(decode(&[0; 4]).is_err());
        let mut long = bytes;
        long[0] = 0;
        long[4] = 9;
        assert!(decode(&long).unwrap_err().to_string().contains("0..8"));
    }
}
