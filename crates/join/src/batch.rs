//! Frames gathered into envelopes: a batch is sealed when it is full or a few milliseconds
//! old, so a broker carries hundreds of messages a second, not one per frame.

use crate::envelope::{Envelope, Stamped};

/// How long the first frame of a batch waits for company (µs).
pub const BATCH_INTERVAL_US: u64 = 2_000;
/// Frames in one envelope at most (about 17 KiB of classic frames, 71 KiB of FD frames
/// would pass [`crate::MAX_ENVELOPE`]: FD frames seal a batch by size first).
pub const MAX_BATCH_FRAMES: usize = 512;
/// Bytes of records in one batch at most, under [`crate::MAX_ENVELOPE`].
const MAX_BATCH_BYTES: usize = 48 * 1024;

/// One origin's outgoing batches, numbered.
#[derive(Debug)]
pub struct Batcher {
    origin: u64,
    next_seq: u64,
    frames: Vec<Stamped>,
    bytes: usize,
    /// When the batch's first frame came (the caller's monotonic µs).
    opened_at: Option<u64>,
}

impl Batcher {
    pub fn new(origin: u64) -> Self {
        Self {
            origin,
            next_seq: 0,
            frames: Vec::new(),
            bytes: 0,
            opened_at: None,
        }
    }

    pub fn origin(&self) -> u64 {
        self.origin
    }

    /// Adds a frame at monotonic time `now_us`; true when the batch is full (seal it now).
    pub fn push(&mut self, frame: Stamped, now_us: u64) -> bool {
        self.opened_at.get_or_insert(now_us);
        self.bytes += 4 + buslab_cannelloni::MAX_RECORD;
        self.frames.push(frame);
        self.frames.len() >= MAX_BATCH_FRAMES || self.bytes >= MAX_BATCH_BYTES
    }

    /// When the open batch is due (monotonic µs), if one is open.
    pub fn deadline(&self) -> Option<u64> {
        self.opened_at.map(|t| t + BATCH_INTERVAL_US)
    }

    /// The open batch as an envelope, numbered; `None` when empty. Its sequence numbers are
    /// spent even if the caller then cannot deliver it: receivers count them as lost.
    pub fn seal(&mut self, wall_us: u64) -> Option<Envelope> {
        if self.frames.is_empty() {
            return None;
        }
        self.opened_at = None;
        self.bytes = 0;
        let frames = std::mem::take(&mut self.frames);
        let first_seq = self.next_seq;
        self.next_seq += frames.len() as u64;
        // Bus times of one batch must not go backwards: a frame stamped earlier than the
        // first (clocks of different sources) takes the first's time.
        let base = frames[0].bus_us;
        let frames = frames
            .into_iter()
            .map(|f| Stamped {
                bus_us: f.bus_us.clamp(base, base + u64::from(u32::MAX)),
                ..f
            })
            .collect();
        Some(Envelope {
            origin: self.origin,
            hops: 0,
            first_seq,
            wall_us,
            frames,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::CanFrame;

    fn stamped(bus_us: u64) -> Stamped {
        Stamped {
            bus_us,
            frame: CanFrame::Classic("123#00".parse().unwrap()),
        }
    }

    #[test]
    fn batches_are_numbered_on_and_sealed_when_full_or_due() {
        let mut b = Batcher::new(7);
        assert_eq!(b.deadline(), None);
        assert!(!b.push(stamped(5), 100));
        assert!(!b.push(stamped(3), 150));
        assert_eq!(b.deadline(), Some(100 + BATCH_INTERVAL_US));
        let e = b.seal(42).unwrap();
        assert_eq!((e.origin, e.first_seq, e.frames.len()), (7, 0, 2));
        assert_eq!(e.frames[1].bus_us, 5, "never backwards within a batch");
        e.encode().unwrap();
        assert_eq!(b.seal(43), None);
        let full = (0..MAX_BATCH_FRAMES).map(|k| b.push(stamped(k as u64), 200));
        assert_eq!(full.filter(|&f| f).count(), 1);
        let e = b.seal(44).unwrap();
        assert_eq!(e.first_seq, 2);
        assert!(e.encode().unwrap().len() <= crate::MAX_ENVELOPE);
    }
}
