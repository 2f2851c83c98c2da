//! Traffic generators: what each node's host software asks its controller to send, and when.

use buslab_can::node::BusNode;
use buslab_can::{Frame, Id};

use crate::time::BitTime;

/// One traffic source attached to a node.
#[derive(Clone, Debug, PartialEq)]
pub enum Traffic {
    /// `frame` every `period` bit-times from `start`; `count` frames in all (`None` = forever).
    Periodic {
        frame: Frame,
        period: BitTime,
        start: BitTime,
        count: Option<u64>,
    },
    /// `count` copies of `frame` queued at once (they go out back to back), every `period`
    /// from `start`; `period` 0 = one burst only.
    Burst {
        frame: Frame,
        count: u32,
        period: BitTime,
        start: BitTime,
    },
    /// A file sent with the file protocol (SPEC N5): 8-byte data frames, the last one shorter
    /// (empty when the length is a multiple of 8). One frame is queued at a time so the chunks
    /// stay in order; the next is queued when the previous one was transmitted.
    File {
        id: Id,
        data: Vec<u8>,
        start: BitTime,
    },
    /// One frame queued at `at`.
    Once { frame: Frame, at: BitTime },
}

impl Traffic {
    /// The frames of the file protocol for `data`.
    pub fn file_frames(id: Id, data: &[u8]) -> impl Iterator<Item = Frame> + '_ {
        buslab_can::file::frames(id, data)
    }

    fn first_time(&self) -> BitTime {
        match *self {
            Traffic::Periodic { start, .. }
            | Traffic::Burst { start, .. }
            | Traffic::File { start, .. } => start,
            Traffic::Once { at, .. } => at,
        }
    }
}

/// What a generator did, for the statistics.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct Queued {
    pub queued: u64,
    pub overflows: u64,
}

/// A traffic source with its progress.
#[derive(Clone, Debug)]
pub(crate) struct Generator {
    pub node: usize,
    traffic: Traffic,
    /// When it next wants to queue something; `None` = waiting for an event or done.
    next: Option<BitTime>,
    sent: u64,
    /// File protocol: index of the next chunk to queue, and the chunk on the bus.
    chunk: usize,
    in_flight: Option<Frame>,
    /// File protocol: bit-time the last chunk was transmitted.
    pub finished_at: Option<BitTime>,
}

impl Generator {
    pub fn new(node: usize, traffic: Traffic) -> Self {
        let next = Some(traffic.first_time());
        Self {
            node,
            traffic,
            next,
            sent: 0,
            chunk: 0,
            in_flight: None,
            finished_at: None,
        }
    }

    pub fn is_file(&self) -> bool {
        matches!(self.traffic, Traffic::File { .. })
    }

    pub fn next(&self) -> Option<BitTime> {
        self.next
    }

    /// Queue what is due at `now` (call when `next() <= now`).
    pub fn fire(&mut self, now: BitTime, controller: &mut dyn BusNode) -> Queued {
        self.fire_with(now, &mut |frame| controller.enqueue(frame).is_ok())
    }

    /// [`Self::fire`] into a queue known to be full: every frame is refused (a full queue
    /// changes nothing else), and the node need not be looked at.
    #[inline]
    pub fn refuse(&mut self, now: BitTime) -> Queued {
        self.fire_with(now, &mut |_| false)
    }

    /// [`Self::fire`] with `enqueue` offering each frame to the node (whether it took it).
    #[inline(always)]
    fn fire_with(&mut self, now: BitTime, enqueue: &mut impl FnMut(Frame) -> bool) -> Queued {
        let mut q = Queued::default();
        let mut push = |frame: Frame| {
            let taken = enqueue(frame);
            q.queued += taken as u64;
            q.overflows += !taken as u64;
            taken
        };
        match &self.traffic {
            Traffic::Periodic {
                frame,
                period,
                count,
                ..
            } => {
                push(*frame);
                self.sent += 1;
                let more = count.is_none_or(|c| self.sent < c);
                self.next = (more && *period > BitTime::ZERO).then(|| now + *period);
            }
            Traffic::Burst {
                frame,
                count,
                period,
                ..
            } => {
                for _ in 0..*count {
                    push(*frame);
                }
                self.next = (*period > BitTime::ZERO).then(|| now + *period);
            }
            Traffic::Once { frame, .. } => {
                push(*frame);
                self.next = None;
            }
            Traffic::File { .. } => {
                self.next = None;
                self.queue_chunk(now, enqueue, &mut q);
            }
        }
        q
    }

    /// A node's frame left the bus (or was dropped by a single-shot controller): the file
    /// sender moves on to the next chunk.
    pub fn on_done(&mut self, frame: &Frame, now: BitTime, controller: &mut dyn BusNode) -> Queued {
        let mut q = Queued::default();
        if self.in_flight.as_ref() == Some(frame) {
            self.in_flight = None;
            self.chunk += 1;
            self.queue_chunk(now, &mut |frame| controller.enqueue(frame).is_ok(), &mut q);
        }
        q
    }

    fn queue_chunk(
        &mut self,
        now: BitTime,
        enqueue: &mut impl FnMut(Frame) -> bool,
        q: &mut Queued,
    ) {
        let Traffic::File { id, data, .. } = &self.traffic else {
            return;
        };
        let Some(frame) = buslab_can::file::frame(*id, data, self.chunk) else {
            self.finished_at = Some(now);
            return;
        };
        if enqueue(frame) {
            q.queued += 1;
            self.in_flight = Some(frame);
        } else {
            // Queue full: try again a little later.
            q.overflows += 1;
            self.next = Some(now + BitTime::ONE);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use buslab_can::controller::{Controller, ControllerConfig};

    fn frame(text: &str) -> Frame {
        text.parse().unwrap()
    }

    #[test]
    fn periodic_stops_after_count_and_burst_queues_copies() {
        let mut c = Controller::new(ControllerConfig::default());
        let mut g = Generator::new(
            0,
            Traffic::Periodic {
                frame: frame("123#01"),
                period: BitTime::new(10),
                start: BitTime::new(5),
                count: Some(2),
            },
        );
        assert_eq!(g.next(), Some(BitTime::new(5)));
        assert_eq!(g.fire(BitTime::new(5), &mut c).queued, 1);
        assert_eq!(g.next(), Some(BitTime::new(15)));
        g.fire(BitTime::new(15), &mut c);
        assert_eq!(g.next(), None);

        let mut c = Controller::new(ControllerConfig {
            tx_queue_capacity: 4,
            ..Default::default()
        });
        let mut g = Generator::new(
            0,
            Traffic::Burst {
                frame: frame("200#"),
                count: 6,
                period: BitTime::new(100),
                start: BitTime::ZERO,
            },
        );
        let q = g.fire(BitTime::ZERO, &mut c);
        assert_eq!((q.queued, q.overflows), (4, 2));
        assert_eq!(c.pending(), 4);
        assert_eq!(g.next(), Some(BitTime::new(100)));
    }

    #[test]
    fn file_sender_keeps_one_chunk_in_flight() {
        let id = Id::standard(0x100).unwrap();
        let mut c = Controller::new(ControllerConfig::default());
        let data: Vec<u8> = (0..12).collect();
        let mut g = Generator::new(
            0,
            Traffic::File {
                id,
                data,
                start: BitTime::ZERO,
            },
        );
        g.fire(BitTime::ZERO, &mut c);
        assert_eq!(c.pending(), 1);
        let first = frame("100#0001020304050607");
        // Some other frame of the node does not move it on.
        g.on_done(&frame("100#AA"), BitTime::new(50), &mut c);
        assert_eq!(c.pending(), 1);
        // (The controller here never sends, so the first chunk is still queued too.)
        g.on_done(&first, BitTime::new(100), &mut c);
        assert_eq!(c.pending(), 2);
        assert!(c.queued().any(|f| *f == frame("100#08090A0B")));
        g.on_done(&frame("100#08090A0B"), BitTime::new(200), &mut c);
        assert_eq!(g.finished_at, Some(BitTime::new(200)));
    }

    #[test]
    fn file_protocol_chunks() {
        let id = Id::standard(0x100).unwrap();
        let lens = |n: usize| {
            let data: Vec<u8> = (0..n as u8).collect();
            Traffic::file_frames(id, &data)
                .map(|f| f.dlc())
                .collect::<Vec<_>>()
        };
        assert_eq!(lens(0), [0]);
        assert_eq!(lens(5), [5]);
        assert_eq!(lens(8), [8, 0]);
        assert_eq!(lens(19), [8, 8, 3]);
        let data: Vec<u8> = (0..19).collect();
        let joined: Vec<u8> = Traffic::file_frames(id, &data)
            .flat_map(|f| f.payload().to_vec())
            .collect();
        assert_eq!(joined, data);
    }
}
