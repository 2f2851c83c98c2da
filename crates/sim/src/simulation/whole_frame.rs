//! The frame-level fast path: when every node is lined up at a frame start on a clean bus, the
//! next frame is applied whole instead of bit by bit, with the same events at the same
//! bit-times and every node left exactly where stepping each bit leaves it.
//!
//! Conditions (anything else runs bit by bit): no fault active or starting inside the frame,
//! no level trace, every node [`FrameStart::Ready`] (waiting for SOF, error-active, a node
//! kind that supports it), at least one sending, the senders' arbitration fields distinct,
//! some node other than the winner acknowledging, and the whole frame with its intermission
//! before the end of the run.

use buslab_can::controller::{FrameRole, FrameStart, WireFrame};
use buslab_can::wire::Encoded;
use buslab_can::{Frame, Level};

use super::{Node, Simulation, handle_event};
use crate::time::BitTime;

/// Frames kept decoded: a saturated bus repeats a few frames over and over.
const CACHE_FRAMES: usize = 64;

/// State of the fast path.
#[derive(Debug)]
pub(super) struct WholeFrames {
    on: bool,
    /// The engine declined a frame start at this bit-time (it ran bit by bit from there).
    refused_at: Option<BitTime>,
    applied: u64,
    roles: Vec<FrameRole>,
    /// Where each node is to be moved on to, in order: (wire bit, node).
    stops: Vec<(u32, usize)>,
    /// How far each node has been moved on.
    done: Vec<u32>,
    /// Recently seen frames on the wire, most recent last.
    cache: Vec<(Frame, u8, WireFrame)>,
}

impl Default for WholeFrames {
    fn default() -> Self {
        Self {
            on: true,
            refused_at: None,
            applied: 0,
            roles: Vec::new(),
            stops: Vec::new(),
            done: Vec::new(),
            cache: Vec::new(),
        }
    }
}

impl WholeFrames {
    /// From which bit-time on the clean loop should stop at a frame start.
    pub(super) fn check_from(&self) -> BitTime {
        match (self.on, self.refused_at) {
            (false, _) => BitTime::MAX,
            (true, Some(t)) => t + 1,
            (true, None) => 0,
        }
    }

    fn wire_frame(&mut self, winner: &Encoded) -> Option<WireFrame> {
        let key = (*winner.frame(), winner.dlc());
        if let Some(at) = self.cache.iter().rposition(|(f, dlc, _)| (*f, *dlc) == key) {
            return Some(self.cache[at].2.clone());
        }
        let wire = WireFrame::new(winner)?;
        if self.cache.len() == CACHE_FRAMES {
            self.cache.remove(0);
        }
        self.cache.push((key.0, key.1, wire.clone()));
        Some(wire)
    }
}

/// Every node waits for SOF, error-active, and one of them sends: worth trying a whole frame.
pub(super) fn lined_up(nodes: &[Node]) -> bool {
    let mut sending = false;
    for node in nodes {
        match node.device.frame_start() {
            FrameStart::NotReady => return false,
            FrameStart::Ready { sends, .. } => sending |= sends.is_some(),
        }
    }
    sending
}

impl Simulation {
    /// Apply whole frames when every node is lined up at a frame start (on by default).
    /// Turning it off (`buslab sim --bit-level`) changes nothing but the speed: every frame is
    /// then stepped bit by bit.
    pub fn set_whole_frames(&mut self, on: bool) {
        self.whole.on = on;
    }

    /// Frames applied whole so far.
    pub fn whole_frames(&self) -> u64 {
        self.whole.applied
    }

    /// Applies the frame starting now, whole, if the conditions hold (see the module doc);
    /// false if it did nothing.
    pub(super) fn try_whole_frame(&mut self, end: BitTime) -> bool {
        if !self.whole.on || self.faulty || self.levels.is_some() {
            return false;
        }
        let applied = self.whole_frame(end);
        if !applied {
            self.whole.refused_at = Some(self.now);
        }
        applied
    }

    fn whole_frame(&mut self, end: BitTime) -> bool {
        // Nodes with a clock of their own (timestamps, timers) learn when the frame starts.
        for node in &mut self.nodes {
            if let super::Device::Other(n) = &mut node.device {
                n.frame_starts_at(self.now);
            }
        }
        // Who sends, who wins (the lowest arbitration key), who acknowledges.
        let mut winner: Option<(usize, u32)> = None;
        let mut tie = false;
        let mut ackers = 0usize;
        for (i, node) in self.nodes.iter().enumerate() {
            let FrameStart::Ready { sends, acks } = node.device.frame_start() else {
                return false;
            };
            ackers += acks as usize;
            if let Some(e) = sends {
                let key = e.frame().arbitration_key();
                match winner {
                    Some((_, best)) if key > best => {}
                    Some((_, best)) if key == best => tie = true,
                    _ => {
                        winner = Some((i, key));
                        tie = false;
                    }
                }
            }
        }
        let Some((w, _)) = winner else { return false };
        let FrameStart::Ready {
            sends: Some(winning),
            acks: winner_acks,
        } = self.nodes[w].device.frame_start()
        else {
            return false;
        };
        if tie || ackers <= winner_acks as usize {
            return false;
        }
        let winning = *winning;
        let roles = &mut self.whole.roles;
        roles.clear();
        for (i, node) in self.nodes.iter().enumerate() {
            let role = match node.device.frame_start() {
                FrameStart::Ready { sends: Some(_), .. } if i == w => FrameRole::Transmitter,
                FrameStart::Ready { sends: Some(e), .. } => {
                    match WireFrame::lost_bit(e, &winning) {
                        Some(role) => role,
                        None => return false,
                    }
                }
                _ => FrameRole::Receiver,
            };
            roles.push(role);
        }
        let Some(wire) = self.whole.wire_frame(&winning) else {
            return false;
        };
        let t0 = self.now;
        let total = wire.total();
        let done = t0 + total as BitTime;
        if done > end || self.next_fault_change < done {
            return false;
        }

        // Each node is moved on only up to the bits at which it reports something (its lost
        // bit, its ACK, reception at EOF 6, transmission at EOF 7) and to the end, in time
        // order and, within a bit-time, in node order: every event gets its exact bit-time.
        let stops = &mut self.whole.stops;
        stops.clear();
        stops.extend(
            self.whole
                .roles
                .iter()
                .enumerate()
                .filter_map(|(i, r)| match r {
                    FrameRole::LostArbitration { wire_bit, .. } => Some((wire_bit + 1, i)),
                    _ => None,
                }),
        );
        stops.sort_unstable();
        let [ack, eof6, eof7] = wire.event_bits();
        for (i, role) in self.whole.roles.iter().enumerate() {
            if *role != FrameRole::Transmitter {
                stops.push((ack + 1, i));
            }
        }
        for (i, role) in self.whole.roles.iter().enumerate() {
            if *role != FrameRole::Transmitter {
                stops.push((eof6 + 1, i));
            }
        }
        stops.push((eof7 + 1, w));
        stops.extend((0..self.nodes.len()).map(|i| (total, i)));
        let done = &mut self.whole.done;
        done.clear();
        done.resize(self.nodes.len(), 0);

        let mut at = 0u32;
        let mut k = 0;
        while k < self.whole.stops.len() {
            let stop = self.whole.stops[k].0;
            // Generators and counter samples due inside the frame act at their own bit-time,
            // with the nodes they look at moved on to just before it.
            let due = self.schedule.next.min(self.next_sample);
            if due >= t0 + at as BitTime && due < t0 + stop as BitTime {
                at = (due - t0) as u32;
                if self.next_sample <= due {
                    for i in 0..self.nodes.len() {
                        self.advance_node(&wire, i, at, t0);
                    }
                } else {
                    for g in 0..self.schedule.generators.len() {
                        let generator = &self.schedule.generators[g];
                        if generator.next().is_some_and(|t| t <= due) {
                            self.advance_node(&wire, generator.node, at, t0);
                        }
                    }
                }
                self.now = due;
                self.handle_due();
                continue;
            }
            while k < self.whole.stops.len() && self.whole.stops[k].0 == stop {
                let i = self.whole.stops[k].1;
                self.advance_node(&wire, i, stop, t0);
                k += 1;
            }
            at = stop;
            self.now = t0 + at as BitTime;
        }
        for i in 0..wire.len() as usize {
            self.obs.bus.bit(wire.bus().level(i));
        }
        for _ in wire.len()..total {
            self.obs.bus.bit(Level::Recessive);
        }
        self.whole.applied += 1;
        true
    }

    /// Moves node `i` on through the frame's bits up to `to` (exclusive) and handles its
    /// events, which happen at bit `to - 1`.
    #[inline]
    fn advance_node(&mut self, wire: &WireFrame, i: usize, to: u32, t0: BitTime) {
        let from = self.whole.done[i];
        if from >= to {
            return;
        }
        self.whole.done[i] = to;
        let node = &mut self.nodes[i];
        node.device
            .advance_frame(wire, self.whole.roles[i], from..to);
        let time = t0 + to as BitTime - 1;
        while let Some(event) = node.device.poll_event() {
            handle_event(&mut self.obs, &mut self.schedule, i, node, time, event);
        }
    }
}
