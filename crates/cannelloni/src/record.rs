//! One frame as cannelloni writes it: ID word, length byte, FD flags byte, data.

use buslab_can::{FdFrame, Frame, Id};

use crate::{DecodeError, EFF_FLAG, ERR_FLAG, FD_BRS, FD_ESI, FD_LENGTH_FLAG, RTR_FLAG};

/// The longest record: ID word, length, flags, 64 data bytes.
pub const MAX_RECORD: usize = 4 + 1 + 1 + 64;

/// A frame cannelloni carries.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CanFrame {
    Classic(Frame),
    Fd(FdFrame),
    /// A SocketCAN error frame (the ERR flag set): its class bits and 8 data bytes, passed on
    /// as they came.
    Error {
        class: u32,
        data: [u8; 8],
    },
}

/// The ID word with SocketCAN's flags.
fn id_word(id: Id) -> u32 {
    match id {
        Id::Standard(s) => u32::from(s.as_raw()),
        Id::Extended(e) => e.as_raw() | EFF_FLAG,
    }
}

/// Appends `frame`'s record to `out`.
pub fn encode_record(frame: &CanFrame, out: &mut Vec<u8>) {
    match frame {
        CanFrame::Classic(f) => {
            let mut word = id_word(f.id());
            if f.is_remote() {
                word |= RTR_FLAG;
            }
            out.extend_from_slice(&word.to_be_bytes());
            // A remote frame: its DLC, no data.
            out.push(f.dlc());
            out.extend_from_slice(f.payload());
        }
        CanFrame::Fd(f) => {
            out.extend_from_slice(&id_word(f.id()).to_be_bytes());
            out.push(f.payload().len() as u8 | FD_LENGTH_FLAG);
            out.push(if f.brs() { FD_BRS } else { 0 } | if f.esi() { FD_ESI } else { 0 });
            out.extend_from_slice(f.payload());
        }
        CanFrame::Error { class, data } => {
            out.extend_from_slice(&((class & 0x1FFF_FFFF) | ERR_FLAG).to_be_bytes());
            out.push(8);
            out.extend_from_slice(data);
        }
    }
}

/// The record at the start of `bytes`: the frame and the bytes it took, or `Ok(None)` when
/// `bytes` ends inside it.
pub fn decode_record(bytes: &[u8]) -> Result<Option<(CanFrame, usize)>, DecodeError> {
    let Some((&[a, b, c, d, length], rest)) = bytes.split_first_chunk::<5>() else {
        return Ok(None);
    };
    let word = u32::from_be_bytes([a, b, c, d]);
    let fd = length & FD_LENGTH_FLAG != 0;
    let len = length & !FD_LENGTH_FLAG;
    let (flags, data, header) = if fd {
        let Some((&flags, data)) = rest.split_first() else {
            return Ok(None);
        };
        (flags, data, 6)
    } else {
        (0, rest, 5)
    };
    let error = word & ERR_FLAG != 0;
    // An error frame's ID word is its class bits, not an ID.
    let id = if error {
        Id::standard(0)
    } else if word & EFF_FLAG != 0 {
        Id::extended(word & 0x1FFF_FFFF)
    } else if word & 0x1FFF_F800 == 0 {
        Id::standard((word & 0x7FF) as u16)
    } else {
        return Err(DecodeError::Id { id: word });
    }
    .map_err(|_| DecodeError::Id { id: word })?;
    let remote = word & RTR_FLAG != 0;
    if fd && remote && !error {
        return Err(DecodeError::FdRemote { id: word });
    }
    if !fd && len > 8 {
        return Err(DecodeError::ClassicLength { len });
    }
    if fd && buslab_can::dlc_of_len(len as usize).is_none() {
        return Err(DecodeError::FdLength { len });
    }
    let carried = if remote { 0 } else { len as usize };
    let Some(payload) = data.get(..carried) else {
        return Ok(None);
    };
    let frame = if error {
        let mut bytes = [0; 8];
        let n = payload.len().min(8);
        bytes[..n].copy_from_slice(&payload[..n]);
        CanFrame::Error {
            class: word & 0x1FFF_FFFF,
            data: bytes,
        }
    } else if fd {
        CanFrame::Fd(
            FdFrame::new(id, payload)
                .map_err(|_| DecodeError::FdLength { len })?
                .with_brs(flags & FD_BRS != 0)
                .with_esi(flags & FD_ESI != 0),
        )
    } else if remote {
        CanFrame::Classic(Frame::remote(id, len).map_err(|_| DecodeError::ClassicLength { len })?)
    } else {
        CanFrame::Classic(Frame::data(id, payload).map_err(|_| DecodeError::ClassicLength { len })?)
    };
    Ok(Some((frame, header + carried)))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn round_trip(frame: CanFrame) -> Vec<u8> {
        let mut out = Vec::new();
        encode_record(&frame, &mut out);
        assert_eq!(decode_record(&out), Ok(Some((frame, out.len()))));
        for cut in 0..out.len() {
            assert_eq!(
                decode_record(&out[..cut]),
                Ok(None),
                "{frame:?} cut at {cut}"
            );
        }
        out
    }

    #[test]
    fn records_are_cannellonis_bytes() {
        let classic = CanFrame::Classic("123#DEAD".parse().unwrap());
        assert_eq!(round_trip(classic), [0, 0, 1, 0x23, 2, 0xDE, 0xAD]);
        let extended = CanFrame::Classic("1ABCDEF0#01".parse().unwrap());
        assert_eq!(round_trip(extended), [0x9A, 0xBC, 0xDE, 0xF0, 1, 1]);
        // A remote frame: its DLC in the length byte, no data.
        let remote = CanFrame::Classic("321#R3".parse().unwrap());
        assert_eq!(round_trip(remote), [0x40, 0, 3, 0x21, 3]);
        let fd = CanFrame::Fd("7FF##3112233445566778899AABBCC".parse().unwrap());
        let bytes = round_trip(fd);
        assert_eq!(&bytes[..6], [0, 0, 7, 0xFF, 0x80 | 12, FD_BRS | FD_ESI]);
        let error = CanFrame::Error {
            class: 0x40,
            data: [1, 2, 3, 4, 5, 6, 7, 8],
        };
        assert_eq!(&round_trip(error)[..5], [0x20, 0, 0, 0x40, 8]);
    }

    #[test]
    fn error_frames_with_any_class_bits_decode_and_encode_again() {
        // Found by fuzzing: an error frame whose ID word also had the EFF bit and high class
        // bits decoded, then its record failed to decode ("a standard ID is at most 0x7FF").
        for word in [0xADBC_DEF0u32, 0x6000_0004, 0x2000_0040] {
            let mut bytes = word.to_be_bytes().to_vec();
            bytes.push(8);
            bytes.extend_from_slice(&[1, 2, 3, 4, 5, 6, 7, 8]);
            let (frame, _) = decode_record(&bytes).unwrap().unwrap();
            assert!(matches!(frame, CanFrame::Error { .. }), "{word:#X}");
            let mut again = Vec::new();
            encode_record(&frame, &mut again);
            assert_eq!(
                decode_record(&again).unwrap().unwrap().0,
                frame,
                "{word:#X}"
            );
        }
    }

    #[test]
    fn bad_records_are_named() {
        assert_eq!(
            decode_record(&[0, 0, 1, 0x23, 9]),
            Err(DecodeError::ClassicLength { len: 9 })
        );
        assert_eq!(
            decode_record(&[0, 0, 1, 0x23, 0x80 | 13, 0]),
            Err(DecodeError::FdLength { len: 13 })
        );
        assert_eq!(
            decode_record(&[0, 0, 8, 0, 0]),
            Err(DecodeError::Id { id: 0x800 })
        );
        assert_eq!(
            decode_record(&[0x40, 0, 1, 0x23, 0x80, 0]),
            Err(DecodeError::FdRemote { id: 0x4000_0123 })
        );
    }
}
