//! A node's last encoded frame.

use super::{Encoded, encode, encode_with_dlc};
use crate::Frame;

/// The last encoding a node made, keyed by the frame and its raw DLC.
///
/// A node sends the same frame again and again: after lost arbitration, after an error, and
/// periodic messages; a simulator that asks this cache instead of [`super::encode`] encodes
/// each of those once. One entry, because a node has one frame in transmission at a time; a
/// different frame replaces it. The results are exactly [`super::encode`]'s and
/// [`super::encode_with_dlc`]'s.
#[derive(Clone, Debug, Default)]
pub struct EncodeCache {
    last: Option<Encoded>,
    hits: u64,
    misses: u64,
}

impl EncodeCache {
    pub const fn new() -> Self {
        Self {
            last: None,
            hits: 0,
            misses: 0,
        }
    }

    /// [`super::encode`]`(frame)`, reusing the last encoding if it was of the same frame with
    /// its own DLC.
    pub fn encode(&mut self, frame: &Frame) -> &Encoded {
        if self.holds(frame, frame.dlc()) {
            self.hits += 1;
        } else {
            self.misses += 1;
            self.last = None;
        }
        self.last.get_or_insert_with(|| encode(frame))
    }

    /// [`super::encode_with_dlc`]`(frame, dlc)`, reusing the last encoding if it matches.
    /// `None` (and the cache unchanged) when the DLC does not fit the frame.
    pub fn encode_with_dlc(&mut self, frame: &Frame, dlc: u8) -> Option<&Encoded> {
        if self.holds(frame, dlc) {
            self.hits += 1;
        } else {
            let encoded = encode_with_dlc(frame, dlc)?;
            self.misses += 1;
            self.last = Some(encoded);
        }
        self.last.as_ref()
    }

    fn holds(&self, frame: &Frame, dlc: u8) -> bool {
        matches!(&self.last, Some(e) if e.frame() == frame && e.dlc() == dlc)
    }

    /// The encoding kept, if any.
    pub const fn last(&self) -> Option<&Encoded> {
        self.last.as_ref()
    }

    /// Look-ups answered from the cache.
    pub const fn hits(&self) -> u64 {
        self.hits
    }

    /// Look-ups that encoded.
    pub const fn misses(&self) -> u64 {
        self.misses
    }

    /// Forget the kept encoding (the counts stay).
    pub fn clear(&mut self) {
        self.last = None;
    }
}
