//! The envelope: one origin's numbered batch of frames.
//!
//! | bytes | field |
//! |---|---|
//! | 2 | `BJ` |
//! | 1 | version (1) |
//! | 1 | hops: gateways passed so far |
//! | 8 | origin ID |
//! | 8 | sequence number of the first frame (each frame one more) |
//! | 8 | wall time when the batch was sealed (µs since the Unix epoch) |
//! | 8 | the origin's bus time of the first frame (µs) |
//! | 2 | frame count |
//! | per frame | bus time after the first frame's (µs, u32), then the frame as a cannelloni record |
//!
//! All numbers big-endian.

use buslab_cannelloni::{CanFrame, decode_record, encode_record};

const MAGIC: &[u8; 2] = b"BJ";
const VERSION: u8 = 1;
const HEADER_LEN: usize = 2 + 1 + 1 + 8 + 8 + 8 + 8 + 2;

/// The largest envelope read or written.
pub const MAX_ENVELOPE: usize = 64 * 1024;
/// Gateways a frame may pass before it is dropped (a loop that origin IDs did not stop).
pub const MAX_HOPS: u8 = 8;

/// A frame with the origin's bus time.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Stamped {
    pub bus_us: u64,
    pub frame: CanFrame,
}

/// One batch from one origin.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Envelope {
    pub origin: u64,
    pub hops: u8,
    pub first_seq: u64,
    pub wall_us: u64,
    pub frames: Vec<Stamped>,
}

/// Why bytes are not an envelope.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum EnvelopeError {
    #[error("{len} bytes: an envelope has a {HEADER_LEN}-byte header starting with \"BJ\"")]
    Header { len: usize },
    #[error("{len} bytes: an envelope is at most {MAX_ENVELOPE}")]
    TooLong { len: usize },
    #[error("envelope version {0}: only version {VERSION} is read")]
    Version(u8),
    #[error("the envelope says {count} frames but ends after {decoded}")]
    Truncated { count: u16, decoded: u16 },
    #[error("{extra} bytes after the envelope's {count} frames")]
    Trailing { count: u16, extra: usize },
    #[error("frame {index}: {source}")]
    Frame {
        index: u16,
        source: buslab_cannelloni::DecodeError,
    },
    #[error("frame bus times go backwards or past 4295 s within one batch")]
    Time,
}

impl Envelope {
    /// The envelope's bytes (the batcher keeps them under [`MAX_ENVELOPE`]).
    pub fn encode(&self) -> Result<Vec<u8>, EnvelopeError> {
        let count = u16::try_from(self.frames.len()).map_err(|_| EnvelopeError::TooLong {
            len: self.frames.len(),
        })?;
        let base = self.frames.first().map_or(0, |f| f.bus_us);
        let mut out = Vec::with_capacity(HEADER_LEN + self.frames.len() * 17);
        out.extend_from_slice(MAGIC);
        out.push(VERSION);
        out.push(self.hops);
        out.extend_from_slice(&self.origin.to_be_bytes());
        out.extend_from_slice(&self.first_seq.to_be_bytes());
        out.extend_from_slice(&self.wall_us.to_be_bytes());
        out.extend_from_slice(&base.to_be_bytes());
        out.extend_from_slice(&count.to_be_bytes());
        for f in &self.frames {
            let offset = f
                .bus_us
                .checked_sub(base)
                .and_then(|d| u32::try_from(d).ok())
                .ok_or(EnvelopeError::Time)?;
            out.extend_from_slice(&offset.to_be_bytes());
            encode_record(&f.frame, &mut out);
        }
        if out.len() > MAX_ENVELOPE {
            return Err(EnvelopeError::TooLong { len: out.len() });
        }
        Ok(out)
    }

    /// Reads an envelope.
    pub fn decode(bytes: &[u8]) -> Result<Self, EnvelopeError> {
        if bytes.len() > MAX_ENVELOPE {
            return Err(EnvelopeError::TooLong { len: bytes.len() });
        }
        let Some((header, mut rest)) = bytes.split_first_chunk::<HEADER_LEN>() else {
            return Err(EnvelopeError::Header { len: bytes.len() });
        };
        if &header[..2] != MAGIC {
            return Err(EnvelopeError::Header { len: bytes.len() });
        }
        if header[2] != VERSION {
            return Err(EnvelopeError::Version(header[2]));
        }
        let u64_at = |at: usize| u64::from_be_bytes(header[at..at + 8].try_into().unwrap());
        let base = u64_at(28);
        let count = u16::from_be_bytes([header[36], header[37]]);
        let mut frames = Vec::with_capacity((count as usize).min(rest.len() / 9));
        let mut previous = 0;
        for index in 0..count {
            let Some((offset, after)) = rest.split_first_chunk::<4>() else {
                return Err(EnvelopeError::Truncated {
                    count,
                    decoded: index,
                });
            };
            // As `encode` writes them: the first at 0, none going backwards.
            let offset = u32::from_be_bytes(*offset);
            if offset < previous || (index == 0 && offset != 0) {
                return Err(EnvelopeError::Time);
            }
            previous = offset;
            match decode_record(after).map_err(|source| EnvelopeError::Frame { index, source })? {
                Some((frame, used)) => {
                    frames.push(Stamped {
                        bus_us: base
                            .checked_add(u64::from(offset))
                            .ok_or(EnvelopeError::Time)?,
                        frame,
                    });
                    rest = &after[used..];
                }
                None => {
                    return Err(EnvelopeError::Truncated {
                        count,
                        decoded: index,
                    });
                }
            }
        }
        if !rest.is_empty() {
            return Err(EnvelopeError::Trailing {
                count,
                extra: rest.len(),
            });
        }
        Ok(Self {
            origin: u64_at(4),
            hops: header[3],
            first_seq: u64_at(12),
            wall_us: u64_at(20),
            frames,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> Envelope {
        Envelope {
            origin: 0x1122_3344_5566_7788,
            hops: 1,
            first_seq: u64::MAX - 1,
            wall_us: 1_700_000_000_000_000,
            frames: vec![
                Stamped {
                    bus_us: 10,
                    frame: CanFrame::Classic("123#DEAD".parse().unwrap()),
                },
                Stamped {
                    bus_us: 250,
                    frame: CanFrame::Fd("1ABCDEF0##1000102030405060708090A0B".parse().unwrap()),
                },
            ],
        }
    }

    #[test]
    fn envelopes_round_trip() {
        let e = sample();
        let bytes = e.encode().unwrap();
        assert_eq!(&bytes[..4], b"BJ\x01\x01");
        assert_eq!(Envelope::decode(&bytes), Ok(e));
    }

    #[test]
    fn bad_envelopes_are_named() {
        let bytes = sample().encode().unwrap();
        assert_eq!(
            Envelope::decode(&bytes[..10]),
            Err(EnvelopeError::Header { len: 10 })
        );
        let mut v = bytes.clone();
        v[2] = 9;
        assert_eq!(Envelope::decode(&v), Err(EnvelopeError::Version(9)));
        assert!(matches!(
            Envelope::decode(&bytes[..bytes.len() - 1]),
            Err(EnvelopeError::Truncated {
                count: 2,
                decoded: 1
            })
        ));
        let mut v = bytes.clone();
        v.push(1);
        assert_eq!(
            Envelope::decode(&v),
            Err(EnvelopeError::Trailing { count: 2, extra: 1 })
        );
        let mut backwards = sample();
        backwards.frames[1].bus_us = 1;
        assert_eq!(backwards.encode(), Err(EnvelopeError::Time));
    }

    proptest::proptest! {
        #[test]
        fn garbage_never_panics(bytes in proptest::collection::vec(proptest::num::u8::ANY, 0..200)) {
            let mut v = b"BJ\x01".to_vec();
            v.extend(bytes);
            let _ = Envelope::decode(&v);
        }
    }
}
