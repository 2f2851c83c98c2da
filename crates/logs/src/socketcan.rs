//! The packet of LINKTYPE_CAN_SOCKETCAN (227), shared by pcap and pcapng: SocketCAN's
//! `can_frame` with the CAN ID big-endian. Classic frames are 16 bytes: ID and flags (4),
//! length (1), FD flags (1), two reserved bytes, 8 data bytes.

use buslab_can::{Frame, Id};
use buslab_canbus::ErrorFrame;

use crate::Record;
use crate::error::{Problem, excerpt};

pub const LINKTYPE_CAN_SOCKETCAN: u16 = 227;
/// A classic CAN record's size.
pub const CLASSIC_LEN: usize = 16;

const EFF_FLAG: u32 = 0x8000_0000;
const RTR_FLAG: u32 = 0x4000_0000;
const ERR_FLAG: u32 = 0x2000_0000;
/// FD flags byte: FDF marks a CAN FD frame.
const FDF: u8 = 0x04;
/// CAN XL records set this bit in byte 4.
const XLF: u8 = 0x80;

/// The 16-byte record of an entry's frame or error frame.
pub fn encode(record: &Record) -> [u8; CLASSIC_LEN] {
    let mut out = [0u8; CLASSIC_LEN];
    let (can_id, len) = match record {
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
            (ERR_FLAG | class, 8)
        }
    };
    out[..4].copy_from_slice(&can_id.to_be_bytes());
    out[4] = len;
    out
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
            bytes,
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
