//! The frame-level fast path: when every node is lined up at a frame start on a clean bus, the
//! next frame is applied whole instead of bit by bit, with the same events at the same
//! bit-times and every node left exactly where stepping each bit leaves it.
//!
//! Conditions (anything else runs bit by bit): no fault active or starting inside the frame,
//! no level trace, every node [`FrameStart::Ready`] (waiting for SOF, error-active, a node
//! kind that supports it), at least one sending, the senders' arbitration fields distinct,
//! some node other than the winner acknowledging, and the whole frame with its intermission
//! before the end of the run.
//!
//! The frame is applied in stages, at the only bits where a node can report something or
//! change what others can see of it (its queue, its counters): each loser's lost bit (in time
//! order), the ACK slot, EOF bit 6, EOF bit 7 and the last intermission bit. Bare protocol
//! controllers take each stage as one call
//! ([`Controller::frame_ack`](buslab_can::controller::Controller::frame_ack) and friends), so between
//! stages every controller is where the bit-by-bit path has it as far as anything can look
//! (generators queueing frames, counter samples); other node kinds are moved on through the
//! frame's bits with [`BusNode::advance_frame`](buslab_can::node::BusNode::advance_frame) up to
//! each stage and each time something looks at them (a receiver whose REC is 0 has nothing to
//! report at the ACK slot: its ACK stage goes with the next one). Within a stage nodes go in index order,
//! as the bit-by-bit path steps them, so the trace comes out in the same order.

use std::sync::Arc;

use buslab_can::controller::{ArbitrationBits, Event, FrameRole, FrameStart, WireFrame};
use buslab_can::wire::Encoded;
use buslab_can::{Frame, Id};

use super::{Device, Node, Observers, Schedule, Simulation, handle_event};
use crate::observe::{BusStats, Happening, Record};
use crate::time::BitTime;

/// Frames kept decoded: a saturated bus repeats a few frames over and over.
const CACHE_FRAMES: usize = 64;

/// A frame seen on the wire, decoded once, with what it adds to the bus statistics.
#[derive(Debug)]
struct CachedFrame {
    wire: WireFrame,
    /// The frame with its intermission on a bus that was idle (it starts with a dominant SOF,
    /// so what came before changes nothing but the recessive run it ends).
    stats: BusStats,
}

impl CachedFrame {
    fn new(wire: WireFrame) -> Self {
        Self {
            stats: BusStats::of_frame(wire.bus(), wire.total()),
            wire,
        }
    }
}

/// The frame and DLC packed in one number, so the cache compares keys kept side by side
/// instead of following a pointer per entry: identifier (29 bits), IDE, RTR, raw DLC and
/// the data bytes (zero-padded; their number follows from RTR and the DLC).
fn cache_key(frame: &Frame, dlc: u8) -> u128 {
    let (raw, extended) = match frame.id() {
        Id::Standard(id) => (u32::from(id.as_raw()), false),
        Id::Extended(id) => (id.as_raw(), true),
    };
    let mut data = [0u8; 8];
    data[..frame.payload().len()].copy_from_slice(frame.payload());
    u128::from(raw)
        | u128::from(extended) << 29
        | u128::from(frame.is_remote()) << 30
        | u128::from(dlc) << 32
        | u128::from(u64::from_le_bytes(data)) << 64
}

/// State of the fast path.
#[derive(Debug)]
pub(super) struct WholeFrames {
    on: bool,
    /// The engine declined a frame start at this bit-time (it ran bit by bit from there).
    refused_at: Option<BitTime>,
    applied: u64,
    roles: Vec<FrameRole>,
    /// Nodes that send SOF, with the start of their frames.
    senders: Vec<(usize, ArbitrationBits)>,
    /// The losers in the order they lose: `wire_bit << 32 | node`, sorted.
    losers: Vec<u64>,
    sorted: Vec<u64>,
    /// How far each node of another kind than a bare controller has been moved on.
    done: Vec<u32>,
    /// Recently seen frames on the wire ([`cache_key`] of each beside it); when full, the
    /// oldest entry (at `cache_next`) makes room.
    cache_keys: Vec<u128>,
    cache: Vec<Arc<CachedFrame>>,
    cache_next: usize,
}

impl Default for WholeFrames {
    fn default() -> Self {
        Self {
            on: true,
            refused_at: None,
            applied: 0,
            roles: Vec::new(),
            senders: Vec::new(),
            losers: Vec::new(),
            sorted: Vec::new(),
            done: Vec::new(),
            cache_keys: Vec::new(),
            cache: Vec::new(),
            cache_next: 0,
        }
    }
}

impl WholeFrames {
    /// From which bit-time on the clean loop should stop at a frame start.
    pub(super) fn check_from(&self) -> BitTime {
        match (self.on, self.refused_at) {
            (false, _) => BitTime::MAX,
            (true, Some(t)) => t + BitTime::ONE,
            (true, None) => BitTime::ZERO,
        }
    }

    fn wire_frame(&mut self, winner: &Encoded) -> Option<Arc<CachedFrame>> {
        let key = cache_key(winner.frame(), winner.dlc());
        if let Some(hit) = self.cache_keys.iter().position(|&k| k == key) {
            return Some(self.cache[hit].clone());
        }
        let fresh = CachedFrame::new(WireFrame::new(winner)?);
        if self.cache.len() < CACHE_FRAMES {
            self.cache_keys.push(key);
            self.cache.push(Arc::new(fresh));
            return self.cache.last().cloned();
        }
        let slot = self.cache_next;
        self.cache_next = (slot + 1) % CACHE_FRAMES;
        self.cache_keys[slot] = key;
        // A saturated bus of ever-new frames (sequence numbers) replaces an entry per frame:
        // reuse its allocation when nobody holds it any more.
        match Arc::get_mut(&mut self.cache[slot]) {
            Some(entry) => *entry = fresh,
            None => self.cache[slot] = Arc::new(fresh),
        }
        Some(self.cache[slot].clone())
    }
}

/// Every node waits for SOF, error-active, and one of them sends: worth trying a whole frame.
pub(super) fn lined_up(nodes: &[super::Node]) -> bool {
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

    /// Who sends, who wins (the lowest arbitration key) and whether someone else acknowledges;
    /// fills `whole.senders`. The winner and its frame; `None` if the frame cannot be applied
    /// whole.
    fn arbitration(&mut self) -> Option<(usize, Encoded)> {
        let senders = &mut self.whole.senders;
        senders.clear();
        let mut winner: Option<(usize, u32)> = None;
        let mut tie = false;
        let mut ackers = 0usize;
        for (i, node) in self.nodes.iter().enumerate() {
            let FrameStart::Ready { sends, acks } = node.device.frame_start() else {
                return None;
            };
            ackers += acks as usize;
            if let Some(e) = sends {
                senders.push((i, ArbitrationBits::of(e)));
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
        let (w, _) = winner?;
        let FrameStart::Ready {
            sends: Some(winning),
            acks: winner_acks,
        } = self.nodes[w].device.frame_start()
        else {
            return None;
        };
        (!tie && ackers > winner_acks as usize).then_some((w, *winning))
    }

    fn whole_frame(&mut self, end: BitTime) -> bool {
        // Nodes with a clock of their own (timestamps, timers) learn when the frame starts.
        if self.others > 0 {
            for node in &mut self.nodes {
                if let super::Device::Other(n) = &mut node.device {
                    n.frame_starts_at(self.now);
                }
            }
        }
        let Some((w, winning)) = self.arbitration() else {
            return false;
        };
        let Some(cached) = self.whole.wire_frame(&winning) else {
            return false;
        };
        let wire = &cached.wire;
        let t0 = self.now;
        let total = wire.total();
        let done = t0 + BitTime::from(total);
        if done > end || self.next_fault_change < done {
            return false;
        }
        let n = self.nodes.len();
        let whole = &mut self.whole;
        if whole.roles.len() == n {
            whole.roles.fill(FrameRole::Receiver);
        } else {
            whole.roles.clear();
            whole.roles.resize(n, FrameRole::Receiver);
        }
        whole.roles[w] = FrameRole::Transmitter;
        whole.losers.clear();
        let mut last_lost = 0;
        let winner_bits = ArbitrationBits::of(&winning);
        for &(i, bits) in &whole.senders {
            if i == w {
                continue;
            }
            match bits.lost_to(winner_bits) {
                Some(role @ FrameRole::LostArbitration { wire_bit, .. }) => {
                    whole.roles[i] = role;
                    whole.losers.push(u64::from(wire_bit) << 32 | i as u64);
                    last_lost = last_lost.max(wire_bit);
                }
                _ => return false,
            }
        }
        // In which order the losers lose shows only in the trace and to generators and samples
        // due in between; a loser's own events (a single-shot frame dropped) touch only it
        // and its own generators. With no trace, nothing due before the last lost bit and
        // only bare controllers (no node moved on bit by bit), node order does as well.
        let in_order = self.obs.record_events
            || self.others > 0
            || self.schedule.next.min(self.next_sample) <= t0 + BitTime::from(last_lost);
        if in_order {
            order_losers(&mut whole.losers, &mut whole.sorted, last_lost);
        }
        if self.others > 0 {
            whole.done.clear();
            whole.done.resize(n, 0);
        }

        // SOF: every controller takes part in the frame (nothing to report).
        for (node, role) in self.nodes.iter_mut().zip(&self.whole.roles) {
            if let Device::Controller(c) = &mut node.device {
                c.frame_begin(*role);
            }
        }
        let mut at = 0u32;
        for k in 0..self.whole.losers.len() {
            let key = self.whole.losers[k];
            let (bit, i) = ((key >> 32) as u32, key as u32 as usize);
            if in_order {
                self.handle_due_inside(wire, t0, &mut at, bit);
            }
            let Self {
                nodes,
                obs,
                schedule,
                whole,
                ..
            } = self;
            let node = &mut nodes[i];
            match (&mut node.device, whole.roles[i]) {
                (Device::Controller(c), FrameRole::LostArbitration { index, .. }) => {
                    let time = t0 + BitTime::from(bit);
                    if let Some(event) = c.frame_lost(index) {
                        record(obs, i, node, time, event);
                    }
                    if matches!(&node.device, Device::Controller(c) if c.has_events()) {
                        drain_node(obs, schedule, i, node, time);
                    }
                }
                _ => self.advance_other(wire, i, bit + 1, t0),
            }
        }
        let [ack, eof6, eof7] = wire.event_bits();
        self.handle_due_inside(wire, t0, &mut at, ack);
        for i in 0..n {
            if i == w {
                continue;
            }
            let Self {
                nodes,
                obs,
                schedule,
                ..
            } = self;
            let node = &mut nodes[i];
            match &mut node.device {
                Device::Controller(c) => {
                    c.frame_ack();
                    if c.has_events() {
                        drain_node(obs, schedule, i, node, t0 + BitTime::from(ack));
                    }
                }
                // With REC at 0 the ACK slot changes nothing a node could report (a successful
                // reception only lowers a REC above 0, rule 8): the slot goes with the next
                // stage's bits, one call fewer per receiver and frame.
                Device::Other(other) if other.rec() == 0 => {}
                Device::Other(_) => self.advance_other(wire, i, ack + 1, t0),
            }
        }
        self.handle_due_inside(wire, t0, &mut at, eof6);
        for i in 0..n {
            if i == w {
                continue;
            }
            let Self {
                nodes,
                obs,
                schedule: _,
                ..
            } = self;
            let node = &mut nodes[i];
            if let Device::Controller(c) = &mut node.device {
                // Handed on at once rather than queued in the controller and polled.
                if let Some(event) = c.frame_received(wire) {
                    let time = t0 + BitTime::from(eof6);
                    record(obs, i, node, time, event);
                }
            } else {
                self.advance_other(wire, i, eof6 + 1, t0);
            }
        }
        self.handle_due_inside(wire, t0, &mut at, eof7);
        if let Device::Controller(c) = &mut self.nodes[w].device {
            c.frame_eof7();
        }
        self.stage_done(wire, t0, w, eof7);
        let last = total - 1;
        self.handle_due_inside(wire, t0, &mut at, last);
        for i in 0..n {
            let Self {
                nodes,
                obs,
                schedule,
                ..
            } = self;
            let node = &mut nodes[i];
            if let Device::Controller(c) = &mut node.device {
                // The others' EOF bit 7 changes nothing anybody looks at before now.
                if i != w {
                    c.frame_eof7();
                }
                c.frame_end(wire);
                if c.has_events() {
                    drain_node(obs, schedule, i, node, t0 + BitTime::from(last));
                }
            } else {
                self.advance_other(wire, i, total, t0);
            }
        }
        self.obs.bus.add_frame(&cached.stats);
        self.now = done;
        self.whole.applied += 1;
        true
    }

    /// Generators and counter samples due before wire bit `bit` is sampled (and not before
    /// `at`, where the frame has got to) act at their own bit-time, with the nodes they look
    /// at moved on to just before it.
    #[inline(always)]
    fn handle_due_inside(&mut self, wire: &WireFrame, t0: BitTime, at: &mut u32, bit: u32) {
        if self.schedule.next.min(self.next_sample) <= t0 + BitTime::from(bit) {
            self.handle_due_inside_slow(wire, t0, at, bit);
        }
    }

    #[inline(never)]
    fn handle_due_inside_slow(&mut self, wire: &WireFrame, t0: BitTime, at: &mut u32, bit: u32) {
        loop {
            let due = self.schedule.next.min(self.next_sample);
            if due < t0 + BitTime::from(*at) || due > t0 + BitTime::from(bit) {
                return;
            }
            *at = (due - t0).get() as u32;
            // Controllers are up to date at every stage; other nodes are moved on here.
            if self.others > 0 && self.next_sample <= due {
                for i in 0..self.nodes.len() {
                    self.advance_other(wire, i, *at, t0);
                }
            } else if self.others > 0 {
                for g in 0..self.schedule.generators.len() {
                    let generator = &self.schedule.generators[g];
                    if generator.next().is_some_and(|t| t <= due) {
                        self.advance_other(wire, generator.node, *at, t0);
                    }
                }
            }
            self.now = due;
            self.handle_due();
        }
    }

    /// Node `i` has taken wire bit `bit` of the frame: a node of another kind is moved on
    /// through it; the events are handled at that bit-time.
    #[inline(always)]
    fn stage_done(&mut self, wire: &WireFrame, t0: BitTime, i: usize, bit: u32) {
        let node = &mut self.nodes[i];
        match &mut node.device {
            Device::Controller(c) => {
                if c.has_events() {
                    drain(self, i, t0 + BitTime::from(bit));
                }
            }
            Device::Other(_) => self.advance_other(wire, i, bit + 1, t0),
        }
    }

    /// Moves node `i`, if it is not a bare controller, on through the frame's bits up to `to`
    /// (exclusive) and handles its events, which happen at bit `to - 1`.
    fn advance_other(&mut self, wire: &WireFrame, i: usize, to: u32, t0: BitTime) {
        let node = &mut self.nodes[i];
        let Device::Other(device) = &mut node.device else {
            return;
        };
        let from = self.whole.done[i];
        if from >= to {
            return;
        }
        self.whole.done[i] = to;
        device.advance_frame(wire, self.whole.roles[i], from..to);
        drain(self, i, t0 + BitTime::from(to) - BitTime::ONE);
    }
}

/// Handles every event node `i` has, at `time`.
fn drain(sim: &mut Simulation, i: usize, time: BitTime) {
    let node = &mut sim.nodes[i];
    drain_node(&mut sim.obs, &mut sim.schedule, i, node, time);
}

/// Handles every event `node` (index `i`) has, at `time`.
#[inline(never)]
fn drain_node(
    obs: &mut Observers,
    schedule: &mut Schedule,
    i: usize,
    node: &mut Node,
    time: BitTime,
) {
    while let Some(event) = node.device.poll_event() {
        handle_event(obs, schedule, i, node, time, event);
    }
}

/// What [`handle_event`] does with an event that only counts (a received frame, a lost
/// arbitration): count it, record it.
#[inline(always)]
fn record(obs: &mut Observers, i: usize, node: &mut Node, time: BitTime, event: Event) {
    debug_assert!(matches!(
        event,
        Event::Received(_) | Event::ArbitrationLost { .. }
    ));
    node.stats.count(&event);
    if obs.record_events {
        obs.records.push(Record {
            time,
            what: Happening::Node { node: i, event },
        });
    }
}

/// Sorts `losers` (`wire_bit << 32 | node`, pushed in node order) by wire bit, then node: a
/// counting sort, as lost bits are few and small (below 64: arbitration is decided in the
/// first 64 wire bits, see [`ArbitrationBits`]); `last` is the latest of them and `sorted`
/// scratch space.
fn order_losers(losers: &mut Vec<u64>, sorted: &mut Vec<u64>, last: u32) {
    const BITS: usize = 64;
    let bit = |key: u64| (key >> 32) as usize % BITS;
    if losers.len() < 2 {
        return;
    }
    // start[b]: where the losers at bit b go.
    let mut start = [0u16; BITS + 1];
    for &key in losers.iter() {
        start[bit(key) + 1] += 1;
    }
    for b in 0..(last as usize % BITS) {
        start[b + 1] += start[b];
    }
    sorted.clear();
    sorted.resize(losers.len(), 0);
    for &key in losers.iter() {
        let at = &mut start[bit(key)];
        sorted[*at as usize] = key;
        *at += 1;
    }
    core::mem::swap(losers, sorted);
}
