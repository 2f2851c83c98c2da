//! The transmit queue: frames in bus-priority order, the most important popped first.

use alloc::collections::VecDeque;

use crate::Frame;

#[derive(Debug, Clone)]
pub(super) struct TxQueue {
    /// Sorted from most to least important (arbitration field only: what follows it cannot
    /// change who wins), so the next frame to send is at the front. Frames with equal
    /// arbitration fields keep their enqueue order, as a controller's FIFO does. Each with the
    /// DLC to send (9..15 for some 8-byte frames). A deque, most important first: a frame no
    /// more important than the last one (a node queueing the same frame again and again, as
    /// periodic traffic on a saturated bus does) goes at the back without moving the others.
    frames: VecDeque<(Frame, u8)>,
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

    pub(super) fn push(&mut self, frame: Frame, dlc: u8) {
        // After any equal ones: those were queued earlier and go first.
        let key = frame.arbitration_key();
        let last_or_empty = self
            .frames
            .back()
            .is_none_or(|(last, _)| last.arbitration_key() <= key);
        if last_or_empty {
            return self.frames.push_back((frame, dlc));
        }
        let at = self
            .frames
            .partition_point(|(queued, _)| queued.arbitration_key() <= key);
        self.frames.insert(at, (frame, dlc));
    }

    pub(super) fn peek(&self) -> Option<&Frame> {
        self.frames.front().map(|(frame, _)| frame)
    }

    pub(super) fn pop(&mut self) -> Option<(Frame, u8)> {
        self.frames.pop_front()
    }

    pub(super) fn clear(&mut self) {
        self.frames.clear();
    }

    /// Most important first.
    pub(super) fn iter(&self) -> impl Iterator<Item = &Frame> {
        self.frames.iter().map(|(frame, _)| frame)
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
        for text in ["29D#232000", "300#", "29D#206001", "100#"] {
            let frame = f(text);
            let dlc = frame.dlc();
            q.push(frame, dlc);
        }
        let order: Vec<String> =
            core::iter::from_fn(|| q.pop().map(|(f, _)| f.to_string())).collect();
        assert_eq!(order, ["100#", "29D#232000", "29D#206001", "300#"]);
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
                        q.push(frame, frame.dlc());
                        model.push(frame);
                    }
                    None => {
                        let best = model.iter().map(Frame::arbitration_key).min();
                        let expected = best.map(|key| {
                            let at = model.iter().position(|f| f.arbitration_key() == key).unwrap();
                            model.remove(at)
                        });
                        prop_assert_eq!(q.pop().map(|(f, _)| f), expected);
                    }
                }
                prop_assert_eq!(q.len(), model.len());
            }
        }
    }
}
