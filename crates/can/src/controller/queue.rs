//! The transmit queue: frames in bus-priority order, the most important popped first.

use alloc::vec::Vec;

use crate::Frame;

#[derive(Debug, Clone)]
pub(super) struct TxQueue {
    /// Sorted from least to most important (arbitration field only: what follows it cannot
    /// change who wins), so the next frame to send is `last()`. Frames with equal arbitration
    /// fields keep their enqueue order, as a controller's FIFO does. Each with the DLC to send
    /// (9..15 for some 8-byte frames).
    frames: Vec<(Frame, u8)>,
}

impl TxQueue {
    pub(super) fn with_capacity(capacity: usize) -> Self {
        Self {
            frames: Vec::with_capacity(capacity),
        }
    }

    pub(super) fn len(&self) -> usize {
        self.frames.len()
    }

    pub(super) fn push(&mut self, frame: Frame, dlc: u8) {
        // Before any equal ones: those were queued earlier and go first.
        let key = frame.arbitration_key();
        let at = self
            .frames
            .partition_point(|(queued, _)| queued.arbitration_key() > key);
        self.frames.insert(at, (frame, dlc));
    }

    pub(super) fn peek(&self) -> Option<&Frame> {
        self.frames.last().map(|(frame, _)| frame)
    }

    pub(super) fn pop(&mut self) -> Option<(Frame, u8)> {
        self.frames.pop()
    }

    pub(super) fn clear(&mut self) {
        self.frames.clear();
    }

    /// Most important first.
    pub(super) fn iter(&self) -> impl Iterator<Item = &Frame> {
        self.frames.iter().rev().map(|(frame, _)| frame)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use alloc::string::{String, ToString};

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
}
