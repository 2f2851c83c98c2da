//! The transmit queue: frames in bus-priority order, the most important popped first.

use alloc::collections::VecDeque;

use crate::Frame;

#[derive(Debug, Clone)]
pub(super) struct TxQueue {
    /// Sorted from most to least important (arbitration field only: what follows it cannot
    /// change who wins), so the next frame to send is at the front. Frames with equal
    /// arbitration fields keep their enqueue order, as a controller's FIFO does: each carries
    /// the number it was queued with, which it keeps when a more important frame displaces
    /// it from the transmit slot and it comes back ([`Queued`]). A deque, most important
    /// first: a frame no more important than the last one (a node queueing the same frame
    /// again and again, as periodic traffic on a saturated bus does) goes at the back without
    /// moving the others.
    frames: VecDeque<Queued>,
}

/// A waiting frame: the frame, the DLC to send (9..15 for some 8-byte frames) and its place
/// in the order frames were queued.
#[derive(Debug, Clone, Copy)]
pub(super) struct Queued {
    pub frame: Frame,
    pub dlc: u8,
    pub seq: u64,
}

impl Queued {
    /// The order frames leave in: arbitration field, then the order they were queued in.
    fn order(&self) -> (u32, u64) {
        (self.frame.arbitration_key(), self.seq)
    }
}

impl TxQueue {
    pub(super) fn with_capacity(capacity: usize) -> Self {
        Self {
            frames: VecDeque::with_capacity(capacity),
        }
    }

    pub(super) fn len(&self) -> usize {
        self.frames.len()
    }

    /// Puts `queued` in its place: a frame queued now after the equal ones, a frame that
    /// comes back from the transmit slot where it was queued.
    pub(super) fn push(&mut self, queued: Queued) {
        let order = queued.order();
        if self.frames.back().is_none_or(|last| last.order() <= order) {
            return self.frames.push_back(queued);
        }
        let at = self.frames.partition_point(|q| q.order() <= order);
        self.frames.insert(at, queued);
    }

    pub(super) fn peek(&self) -> Option<&Frame> {
        self.frames.front().map(|q| &q.frame)
    }

    pub(super) fn pop(&mut self) -> Option<Queued> {
        self.frames.pop_front()
    }

    pub(super) fn clear(&mut self) {
        self.frames.clear();
    }

    /// Most important first.
    pub(super) fn iter(&self) -> impl Iterator<Item = &Frame> {
        self.frames.iter().map(|q| &q.frame)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Id;
    use alloc::string::{String, ToString};
    use alloc::vec::Vec;
    use proptest::prelude::*;

    fn f(text: &str) -> Frame {
        text.parse().unwrap()
    }

    #[test]
    fn priority_first_and_equal_identifiers_in_the_order_queued() {
        let mut q = TxQueue::with_capacity(8);
        // A SLIO answering two requests: DATA_OUTPUT first, then DATA_INPUT, same ID.
        for (seq, text) in ["29D#232000", "300#", "29D#206001", "100#"]
            .iter()
            .enumerate()
        {
            let frame = f(text);
            let dlc = frame.dlc();
            q.push(Queued {
                frame,
                dlc,
                seq: seq as u64,
            });
        }
        let order: Vec<String> =
            core::iter::from_fn(|| q.pop().map(|q| q.frame.to_string())).collect();
        assert_eq!(order, ["100#", "29D#232000", "29D#206001", "300#"]);
    }

    #[test]
    fn a_frame_put_back_goes_where_it_was_queued_among_equal_ones() {
        let mut q = TxQueue::with_capacity(8);
        let queued = |text: &str, seq| Queued {
            frame: f(text),
            dlc: f(text).dlc(),
            seq,
        };
        q.push(queued("29D#02", 2));
        q.push(queued("29D#03", 3));
        // Queued first, then displaced from the transmit slot by a more important frame.
        q.push(queued("29D#01", 1));
        let order: Vec<String> =
            core::iter::from_fn(|| q.pop().map(|q| q.frame.to_string())).collect();
        assert_eq!(order, ["29D#01", "29D#02", "29D#03"]);
    }

    proptest! {
        /// Whatever is queued and popped, frames leave by arbitration field, those with equal
        /// fields in the order they were queued (a model: the waiting frames in queue order,
        /// the first with the lowest field taken).
        #[test]
        fn pops_by_priority_then_in_queue_order(
            ops in prop::collection::vec(prop::option::of((0u16..6, any::<bool>(), any::<u8>())), 0..60)
        ) {
            let mut q = TxQueue::with_capacity(4);
            let mut model: Vec<Frame> = Vec::new();
            let mut pushed = 0;
            for op in ops {
                match op {
                    Some((id, remote, byte)) => {
                        // Few identifiers, data and remote: many equal and close fields.
                        let id = Id::standard(0x100 + id).unwrap();
                        let frame = if remote {
                            Frame::remote(id, 1).unwrap()
                        } else {
                            Frame::data(id, &[byte]).unwrap()
                        };
                        let seq = pushed;
                        pushed += 1;
                        q.push(Queued { frame, dlc: frame.dlc(), seq });
                        model.push(frame);
                    }
                    None => {
                        let best = model.iter().map(Frame::arbitration_key).min();
                        let expected = best.map(|key| {
                            let at = model.iter().position(|f| f.arbitration_key() == key).unwrap();
                            model.remove(at)
                        });
                        prop_assert_eq!(q.pop().map(|q| q.frame), expected);
                    }
                }
                prop_assert_eq!(q.len(), model.len());
            }
        }
    }
}
