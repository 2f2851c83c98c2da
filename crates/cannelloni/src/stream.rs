//! cannelloni over TCP: `CANNELLONIv1` from each side, then records back to back.

use crate::DecodeError;
use crate::record::{CanFrame, MAX_RECORD, decode_record};

/// What each side sends first on a TCP connection.
pub const GREETING: &[u8] = b"CANNELLONIv1";

/// Reads a TCP stream: the peer's greeting, then frames. It keeps at most one partial record
/// ([`MAX_RECORD`] bytes) between calls.
#[derive(Debug, Default)]
pub struct StreamDecoder {
    greeted: bool,
    pending: Vec<u8>,
}

impl StreamDecoder {
    pub fn new() -> Self {
        Self::default()
    }

    /// Whether the peer's greeting came.
    pub fn greeted(&self) -> bool {
        self.greeted
    }

    /// Takes bytes as they came off the socket; the frames they complete go to `out`. After
    /// an error the stream is not cannelloni: close it.
    pub fn push(&mut self, mut bytes: &[u8], out: &mut Vec<CanFrame>) -> Result<(), DecodeError> {
        if !self.greeted {
            let want = GREETING.len() - self.pending.len();
            let take = want.min(bytes.len());
            self.pending.extend_from_slice(&bytes[..take]);
            bytes = &bytes[take..];
            if !GREETING.starts_with(&self.pending) {
                return Err(DecodeError::Greeting {
                    got: String::from_utf8_lossy(&self.pending).into_owned(),
                });
            }
            if self.pending.len() < GREETING.len() {
                return Ok(());
            }
            self.greeted = true;
            self.pending.clear();
        }
        // Complete the partial record first, a byte at a time (at most MAX_RECORD of them).
        while !self.pending.is_empty() && !bytes.is_empty() {
            self.pending.push(bytes[0]);
            bytes = &bytes[1..];
            if let Some((frame, _)) = decode_record(&self.pending)? {
                out.push(frame);
                self.pending.clear();
            }
        }
        while let Some((frame, used)) = decode_record(bytes)? {
            out.push(frame);
            bytes = &bytes[used..];
        }
        debug_assert!(bytes.len() < MAX_RECORD);
        self.pending.extend_from_slice(bytes);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::encode_record;

    #[test]
    fn any_split_of_the_stream_gives_the_frames() {
        let frames: Vec<CanFrame> = ["123#DEAD", "1ABCDEF0#0102030405060708", "321#R3", "000#"]
            .iter()
            .map(|t| CanFrame::Classic(t.parse().unwrap()))
            .chain([CanFrame::Fd("7FF##1AB".parse().unwrap())])
            .collect();
        let mut stream = GREETING.to_vec();
        for f in &frames {
            encode_record(f, &mut stream);
        }
        for chunk in 1..stream.len() {
            let mut d = StreamDecoder::new();
            let mut got = Vec::new();
            for piece in stream.chunks(chunk) {
                d.push(piece, &mut got).unwrap();
            }
            assert!(d.greeted());
            assert_eq!(got, frames, "chunks of {chunk}");
        }
    }

    #[test]
    fn a_wrong_greeting_is_refused_at_its_first_wrong_byte() {
        let mut d = StreamDecoder::new();
        let mut out = Vec::new();
        assert_eq!(
            d.push(b"CANX", &mut out),
            Err(DecodeError::Greeting { got: "CANX".into() })
        );
        let mut d = StreamDecoder::new();
        assert_eq!(
            d.push(b"< hi >", &mut out),
            Err(DecodeError::Greeting {
                got: "< hi >".into()
            })
        );
    }

    proptest::proptest! {
        #[test]
        fn garbage_never_panics_and_stays_bounded(
            chunks in proptest::collection::vec(
                proptest::collection::vec(proptest::num::u8::ANY, 0..100), 0..20)
        ) {
            let mut d = StreamDecoder::new();
            let _ = d.push(GREETING, &mut Vec::new());
            let mut out = Vec::new();
            for c in chunks {
                if d.push(&c, &mut out).is_err() {
                    break;
                }
                proptest::prop_assert!(d.pending.len() < MAX_RECORD);
            }
        }
    }
}
