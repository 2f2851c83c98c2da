//! cannelloni's UDP packets (version 2): a 5-byte header, then the records.

use crate::record::{CanFrame, MAX_RECORD, decode_record, encode_record};
use crate::{DecodeError, EncodeError};

/// The packet format's version.
pub const VERSION: u8 = 2;
/// Version, opcode, sequence number, frame count.
pub const HEADER_LEN: usize = 5;
/// The largest UDP payload (IPv4: 65535 less the IP and UDP headers).
pub const MAX_DATAGRAM: usize = 65_507;

/// What a packet is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OpCode {
    Data,
    Ack,
    Nack,
}

impl OpCode {
    fn byte(self) -> u8 {
        match self {
            OpCode::Data => 0,
            OpCode::Ack => 1,
            OpCode::Nack => 2,
        }
    }
}

/// One decoded datagram.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Packet {
    pub op: OpCode,
    /// The sender's sequence number, one more per packet (mod 256).
    pub seq: u8,
    pub frames: Vec<CanFrame>,
}

/// Reads one datagram.
pub fn decode_packet(datagram: &[u8]) -> Result<Packet, DecodeError> {
    if datagram.len() > MAX_DATAGRAM {
        return Err(DecodeError::TooLong {
            len: datagram.len(),
        });
    }
    let Some((&[version, opcode, seq, c0, c1], mut rest)) = datagram.split_first_chunk::<5>()
    else {
        return Err(DecodeError::ShortHeader {
            len: datagram.len(),
        });
    };
    if version != VERSION {
        return Err(DecodeError::Version { version });
    }
    let op = match opcode {
        0 => OpCode::Data,
        1 => OpCode::Ack,
        2 => OpCode::Nack,
        opcode => return Err(DecodeError::OpCode { opcode }),
    };
    let count = u16::from_be_bytes([c0, c1]);
    // At most as many frames as the datagram can hold: `count` is the peer's word.
    let mut frames = Vec::with_capacity((count as usize).min(rest.len() / 5));
    for decoded in 0..count {
        match decode_record(rest)? {
            Some((frame, used)) => {
                frames.push(frame);
                rest = &rest[used..];
            }
            None => return Err(DecodeError::Truncated { count, decoded }),
        }
    }
    if !rest.is_empty() {
        return Err(DecodeError::Trailing {
            count,
            extra: rest.len(),
        });
    }
    Ok(Packet { op, seq, frames })
}

/// DATA packets carrying `frames` in order, each at most `max_size` bytes, numbered from
/// `first_seq` on (mod 256); no frames, no packets.
pub fn encode_packets(
    first_seq: u8,
    frames: &[CanFrame],
    max_size: usize,
) -> Result<Vec<Vec<u8>>, EncodeError> {
    let min = HEADER_LEN + MAX_RECORD;
    if !(min..=MAX_DATAGRAM).contains(&max_size) {
        return Err(EncodeError::DatagramSize {
            size: max_size,
            min,
        });
    }
    let mut packets = Vec::new();
    let mut seq = first_seq;
    let mut record = Vec::with_capacity(MAX_RECORD);
    let mut current: Option<(Vec<u8>, u16)> = None;
    for frame in frames {
        record.clear();
        encode_record(frame, &mut record);
        let fits = current
            .as_ref()
            .is_some_and(|(p, n)| p.len() + record.len() <= max_size && *n < u16::MAX);
        if !fits {
            if let Some(done) = current.take() {
                packets.push(finish(done));
            }
            current = Some((vec![VERSION, OpCode::Data.byte(), seq, 0, 0], 0));
            seq = seq.wrapping_add(1);
        }
        let (packet, count) = current.as_mut().expect("a packet was just started");
        packet.extend_from_slice(&record);
        *count += 1;
    }
    packets.extend(current.map(finish));
    Ok(packets)
}

fn finish((mut packet, count): (Vec<u8>, u16)) -> Vec<u8> {
    packet[3..5].copy_from_slice(&count.to_be_bytes());
    packet
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frames(n: usize) -> Vec<CanFrame> {
        (0..n)
            .map(|k| {
                CanFrame::Classic(
                    buslab_can::Frame::data(
                        buslab_can::Id::standard((k % 0x800) as u16).unwrap(),
                        &(k as u64).to_be_bytes(),
                    )
                    .unwrap(),
                )
            })
            .collect()
    }

    #[test]
    fn packets_split_at_the_datagram_size_and_number_themselves() {
        let sent = frames(1000);
        // 13 bytes a frame: 100 frames in 1305 bytes.
        let datagrams = encode_packets(250, &sent, HEADER_LEN + 13 * 100).unwrap();
        assert_eq!(datagrams.len(), 10);
        let mut got = Vec::new();
        for (k, d) in datagrams.iter().enumerate() {
            assert!(d.len() <= HEADER_LEN + 1300);
            let p = decode_packet(d).unwrap();
            assert_eq!(p.seq, 250u8.wrapping_add(k as u8));
            assert_eq!(p.op, OpCode::Data);
            got.extend(p.frames);
        }
        assert_eq!(got, sent);
        assert!(encode_packets(0, &[], 1472).unwrap().is_empty());
    }

    #[test]
    fn the_header_is_cannellonis() {
        let d = &encode_packets(9, &frames(2), 1472).unwrap()[0];
        assert_eq!(&d[..5], [2, 0, 9, 0, 2]);
    }

    #[test]
    fn bad_datagrams_are_named() {
        let good = &encode_packets(0, &frames(3), 1472).unwrap()[0];
        assert_eq!(
            decode_packet(&good[..3]),
            Err(DecodeError::ShortHeader { len: 3 })
        );
        let mut v = good.clone();
        v[0] = 1;
        assert_eq!(decode_packet(&v), Err(DecodeError::Version { version: 1 }));
        let mut v = good.clone();
        v[1] = 7;
        assert_eq!(decode_packet(&v), Err(DecodeError::OpCode { opcode: 7 }));
        assert_eq!(
            decode_packet(&good[..good.len() - 1]),
            Err(DecodeError::Truncated {
                count: 3,
                decoded: 2
            })
        );
        let mut v = good.clone();
        v.push(0);
        assert_eq!(
            decode_packet(&v),
            Err(DecodeError::Trailing { count: 3, extra: 1 })
        );
        // A count of 65535 in a short datagram: refused without allocating for it.
        assert!(matches!(
            decode_packet(&[2, 0, 0, 0xFF, 0xFF]),
            Err(DecodeError::Truncated { .. })
        ));
        assert_eq!(
            decode_packet(&vec![0; MAX_DATAGRAM + 1]),
            Err(DecodeError::TooLong {
                len: MAX_DATAGRAM + 1
            })
        );
        assert!(matches!(
            encode_packets(0, &frames(1), 20),
            Err(EncodeError::DatagramSize { size: 20, .. })
        ));
    }

    proptest::proptest! {
        #[test]
        fn garbage_never_panics(bytes in proptest::collection::vec(proptest::num::u8::ANY, 0..300)) {
            let _ = decode_packet(&bytes);
        }
    }
}
