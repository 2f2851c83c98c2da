//! The transmit queue: frames in bus-priority order, the most important popped first.

use alloc::vec::Vec;

use crate::Frame;

#[derive(Debug, Clone)]
pub(super) struct TxQueue {
    /// Sorted from least to most important, so the next frame to send is `last()`. Equal frames
    /// keep their enqueue order. Each with the DLC to send (9..15 for some 8-byte frames).
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
        // Before any equal frames: those were queued earlier and go first.
        let at = self.frames.partition_point(|(queued, _)| *queued > frame);
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
