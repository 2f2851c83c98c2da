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
//! report at the ACK slot: its ACK stage goes with the next one; one that only counts the frame,
//! [`BusNode::count_frame`](buslab_can::node::BusNode::count_frame), takes all of it at EOF bit
//! 6 in one call when nothing is due before the frame's end). Within a stage nodes go in index order,
//! as the bit-by-bit path steps them, so the trace comes out in the same order.
//!
//! With no trace recorded and only bare controllers on the bus, the *bystanders* of a frame —
//! error-active controllers with REC 0 that only receive it, or that lose arbitration with
//! the same frame again and again ([`Controller::bystander`](buslab_can::controller::Controller::bystander)) —
//! are not moved at all: after a frame they join a group whose members' controllers and
//! counters stand where they were when they joined, and the group counts the frames applied
//! since. A member is filled in ([`Controller::bystander_frames`](buslab_can::controller::Controller::bystander_frames),
//! one `received` and, for a loser, one `arbitration lost` per frame) when it wins
//! arbitration, when a generator gives it a frame its queue has room for (in the middle of a
//! frame it then goes on through the frame's bits in ranges, as other node kinds do), and for
//! everybody when the frame cannot be applied whole or the run ends (whoever looks at a
//! node next sees it filled in). Counter samples read members as they are: a bystander's
//! counters and state do not move. The losers in the group are kept in priority order, so
//! arbitration compares the best of them with the few nodes taken one by one: a frame costs
//! about the same whatever the number of nodes.

use std::sync::Arc;

use buslab_can::controller::{ArbitrationBits, Bystander, Event, FrameRole, FrameStart, WireFrame};
use buslab_can::node::Counting;
use buslab_can::wire::Encoded;
use buslab_can::{Frame, Id};

use super::{Device, Node, Observers, Schedule, Simulation, handle_event};
use crate::observe::{BusStats, Happening, Record, RecordedEvents};
use crate::time::BitTime;

/// Frames kept decoded: a saturated bus repeats a few frames over and over. (At most 256:
/// slots are kept in a byte.)
const CACHE_FRAMES: usize = 64;
const _: () = assert!(CACHE_FRAMES <= 256);

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
/// the data bytes as a number (their number follows from RTR and the DLC).
#[inline]
fn cache_key(frame: &Frame, dlc: u8) -> u128 {
    let (raw, extended) = match frame.id() {
        Id::Standard(id) => (u32::from(id.as_raw()), false),
        Id::Extended(id) => (id.as_raw(), true),
    };
    u128::from(raw)
        | u128::from(extended) << 29
        | u128::from(frame.is_remote()) << 30
        | u128::from(dlc) << 32
        | u128::from(frame.payload_bits()) << 64
}

/// A node's group frame count when it joined: it is no member.
const NOT_LAZY: u64 = u64::MAX;

/// The bystanders (`Controller::bystander`) advanced together: a member's controller and
/// counters stand where they were when it joined; it has since taken every frame applied
/// (`frames` minus its `joined`), the last of them `last`, as a plain receiver or as a loser
/// retrying the same frame. `Simulation::leave_group` fills it in.
#[derive(Debug, Default)]
struct Group {
    /// Per node: `frames` when it joined, or [`NOT_LAZY`].
    joined: Vec<u64>,
    /// Per node: what a member does in each frame, and whether it acknowledges.
    kind: Vec<Bystander>,
    acks: Vec<bool>,
    frames: u64,
    /// Frames taken by members, summed over members (what [`Simulation::frames_in_group`]
    /// reports).
    taken: u64,
    last: Option<Arc<CachedFrame>>,
    /// The losers by priority: `(arbitration key, node)`, the best last (it competes with
    /// the nodes taken one by one; the rest lose to it). A sorted vector: a winner usually
    /// comes from its end and goes back near it.
    losers: Losers,
    /// Members that acknowledge (not listen-only).
    ackers: usize,
    members: usize,
}

impl Group {
    #[inline]
    fn is_member(&self, i: usize) -> bool {
        self.joined.get(i).is_some_and(|&j| j != NOT_LAZY)
    }
}

/// `(arbitration key, node)` of the group's losers, sorted, the best last.
///
/// Entries come and go near the end as a rule (a node that wins leaves from there, and goes
/// back among the best when given its next frame): both look from the end, moving the few
/// entries after the place one by one. An entry that goes deep (many nodes given their
/// frames at once, each worse than the last) is placed by a binary search instead.
#[derive(Debug, Default)]
struct Losers(Vec<(u32, u32)>);

/// How deep from the end [`Losers::insert`] moves entries one by one; deeper, it searches.
const LOSERS_FROM_END: usize = 16;

impl Losers {
    fn insert(&mut self, entry: (u32, u32)) {
        let v = &mut self.0;
        let len = v.len();
        if len > LOSERS_FROM_END && v[len - LOSERS_FROM_END] < entry {
            return self.insert_deep(entry);
        }
        let mut at = len;
        while at > 0 && v[at - 1] < entry {
            at -= 1;
        }
        if at > 0 && v[at - 1] == entry {
            return;
        }
        v.push(entry);
        let mut k = len;
        while k > at {
            v[k] = v[k - 1];
            k -= 1;
        }
        v[at] = entry;
    }

    /// [`Self::insert`] of an entry that goes deeper than [`LOSERS_FROM_END`].
    #[inline(never)]
    fn insert_deep(&mut self, entry: (u32, u32)) {
        let v = &mut self.0;
        // Sorted best last: the worse entries come first.
        let at = v.partition_point(|&e| e > entry);
        if v.get(at) != Some(&entry) {
            v.insert(at, entry);
        }
    }

    fn remove(&mut self, entry: (u32, u32)) {
        let v = &mut self.0;
        let Some(at) = v.iter().rposition(|&e| e == entry) else {
            return;
        };
        for k in at..v.len() - 1 {
            v[k] = v[k + 1];
        }
        v.pop();
    }

    /// The best two (fewer if there are fewer), best first.
    #[inline]
    fn best_two(&self) -> impl Iterator<Item = &(u32, u32)> {
        self.0.iter().rev().take(2)
    }
}

/// The winner of an arbitration ([`Simulation::arbitration`]).
struct Winner {
    node: usize,
    bits: ArbitrationBits,
    /// Its frame decoded, and the frame's slot in the cache.
    slot: usize,
    cached: Arc<CachedFrame>,
}

/// The frame being applied, for a member filled in in the middle of it: its slot in the
/// cache, which nothing changes before the frame ends (a slot, not a count on the `Arc`: two
/// atomic counts per frame fewer).
#[derive(Debug)]
struct InFrame {
    slot: usize,
}

/// State of the fast path.
#[derive(Debug)]
pub(super) struct WholeFrames {
    on: bool,
    /// The engine declined a frame start at this bit-time (it ran bit by bit from there).
    refused_at: Option<BitTime>,
    applied: u64,
    /// Per node (valid for `ind`): its part in the frame being applied.
    roles: Vec<FrameRole>,
    /// Nodes that send SOF, with the start of their frames.
    senders: Vec<(usize, ArbitrationBits)>,
    /// The losers in the order they lose: `wire_bit << 32 | node`, sorted.
    losers: Vec<u64>,
    sorted: Vec<u64>,
    /// Per node: how far it has been moved on through the frame, when `ranged`.
    done: Vec<u32>,
    /// Per node: moved on through ranges of wire bits (`BusNode::advance_frame`), not
    /// stage by stage: nodes of another kind than a bare controller.
    ranged: Vec<bool>,
    /// The nodes taken one by one (every node not in `group`), in index order.
    ind: Vec<usize>,
    group: Group,
    frame: Option<InFrame>,
    /// A node was added or removed since the tables were sized ([`Self::prepare`]).
    pub(super) nodes_changed: bool,
    /// Recently seen frames on the wire ([`cache_key`] of each beside it); when full, the
    /// oldest entry (at `cache_next`) makes room.
    cache_keys: Vec<u128>,
    cache: Vec<Arc<CachedFrame>>,
    cache_next: usize,
    /// Per node: the slot of the frame it sent last (checked: nodes come and go).
    cache_hints: Vec<u8>,
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
            ranged: Vec::new(),
            ind: Vec::new(),
            group: Group::default(),
            frame: None,
            nodes_changed: true,
            cache_keys: Vec::new(),
            cache: Vec::new(),
            cache_next: 0,
            cache_hints: Vec::new(),
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

    /// Whether node `i` is advanced with the group (its state not filled in).
    #[inline]
    pub(super) fn is_member(&self, i: usize) -> bool {
        self.group.is_member(i)
    }

    /// Whether the group is empty: every node is taken one by one.
    #[inline]
    pub(super) fn no_members(&self) -> bool {
        self.group.members == 0
    }

    /// Sizes the per-node tables for `n` nodes; with no member, every node is taken one by
    /// one.
    #[inline]
    fn prepare(&mut self, n: usize) {
        if !self.nodes_changed && self.group.members + self.ind.len() == n && self.roles.len() == n
        {
            return;
        }
        self.resize(n);
    }

    #[inline(never)]
    fn resize(&mut self, n: usize) {
        self.nodes_changed = false;
        debug_assert_eq!(
            self.group.members, 0,
            "nodes changed with members in the group"
        );
        self.ind.clear();
        self.ind.extend(0..n);
        self.roles.resize(n, FrameRole::Receiver);
        self.done.resize(n, 0);
        self.ranged.clear();
        self.ranged.resize(n, false);
        self.group.joined.clear();
        self.group.joined.resize(n, NOT_LAZY);
        self.group.kind.resize(n, Bystander::Receiver);
        self.group.acks.resize(n, false);
        self.cache_hints.resize(n, 0);
    }

    /// The winner's frame (`node` sends it) decoded, from the cache if it is there, and its
    /// slot there.
    #[inline]
    fn wire_frame(&mut self, winner: &Encoded, node: usize) -> Option<(usize, Arc<CachedFrame>)> {
        let key = cache_key(winner.frame(), winner.dlc());
        // A saturated bus sends the same frames again and again, each node its own: try the
        // node's last hit first.
        let hint = self.cache_hints.get(node).map_or(0, |&h| usize::from(h));
        if let (Some(&k), Some(hit)) = (self.cache_keys.get(hint), self.cache.get(hint))
            && k == key
        {
            return Some((hint, hit.clone()));
        }
        self.wire_frame_looked_up(winner, node, key)
    }

    /// [`Self::wire_frame`] when the node's last hit is not it: looked up, or decoded.
    #[inline(never)]
    fn wire_frame_looked_up(
        &mut self,
        winner: &Encoded,
        node: usize,
        key: u128,
    ) -> Option<(usize, Arc<CachedFrame>)> {
        let slot = match self.cache_keys.iter().position(|&k| k == key) {
            Some(hit) => hit,
            None => self.insert_frame(winner, key)?,
        };
        if let Some(h) = self.cache_hints.get_mut(node) {
            *h = slot as u8;
        }
        Some((slot, self.cache[slot].clone()))
    }

    /// Decodes the winner's frame into the cache; its slot.
    fn insert_frame(&mut self, winner: &Encoded, key: u128) -> Option<usize> {
        let fresh = CachedFrame::new(WireFrame::new(winner)?);
        if self.cache.len() < CACHE_FRAMES {
            self.cache_keys.push(key);
            self.cache.push(Arc::new(fresh));
            return Some(self.cache.len() - 1);
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
        Some(slot)
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

/// Keeps the lowest `key` seen in `best`, noting in `tie` whether another node has it too.
#[inline(always)]
fn consider(best: &mut Option<(u32, usize)>, tie: &mut bool, key: u32, i: usize) {
    match *best {
        Some((b, _)) if key > b => {}
        Some((b, _)) if key == b => *tie = true,
        _ => {
            *best = Some((key, i));
            *tie = false;
        }
    }
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

    /// Frames that nodes took as members of the group of bystanders (summed over the nodes):
    /// node-frames that cost nothing one by one.
    pub fn frames_in_group(&self) -> u64 {
        self.whole.group.taken
    }

    /// Applies the frame starting now, whole, if the conditions hold (see the module doc);
    /// false if it did nothing (every node is then filled in, to go on bit by bit).
    pub(super) fn try_whole_frame(&mut self, end: BitTime) -> bool {
        if !self.whole.on || self.faulty || self.levels.is_some() {
            self.dissolve_group();
            return false;
        }
        let applied = self.whole_frame(end);
        if !applied {
            self.whole.refused_at = Some(self.now);
            self.dissolve_group();
        }
        applied
    }

    /// Whether bystanders may be advanced as a group: nothing needs their reports one by one
    /// in order (the trace records neither receptions nor lost arbitrations, the only events
    /// of a bystander), and every node is a bare controller.
    fn grouping(&self) -> bool {
        !self
            .obs
            .record_events
            .intersects(RecordedEvents::RECEIVED | RecordedEvents::ARBITRATION_LOST)
            && self.others == 0
    }

    /// Fills in every member of the group (see [`Self::leave_group`]): every node is then
    /// taken one by one again.
    pub(super) fn dissolve_group(&mut self) {
        if self.whole.group.members == 0 {
            return;
        }
        for i in 0..self.nodes.len() {
            if self.whole.group.is_member(i) {
                self.leave_group(i, false);
            }
        }
        let n = self.nodes.len();
        self.whole.ind.clear();
        self.whole.ind.extend(0..n);
    }

    /// Fills in member `i` up to the end of the last frame applied (its controller, its
    /// counters) and takes it one by one from now on (`insert`: into `ind`).
    fn leave_group(&mut self, i: usize, insert: bool) {
        let group = &mut self.whole.group;
        let joined = group.joined[i];
        if joined == NOT_LAZY {
            return;
        }
        group.joined[i] = NOT_LAZY;
        group.members -= 1;
        group.ackers -= group.acks[i] as usize;
        let kind = group.kind[i];
        if let Bystander::Loser { key } = kind {
            group.losers.remove((key, i as u32));
        }
        // A member filled in up to the end of the frame being applied has taken it already.
        let frames = group.frames.saturating_sub(joined);
        let node = &mut self.nodes[i];
        if frames > 0
            && let (Some(last), Device::Controller(c)) = (&group.last, &mut node.device)
        {
            c.bystander_frames(&last.wire);
            node.stats.received += frames;
            if matches!(kind, Bystander::Loser { .. }) {
                node.stats.arbitration_lost += frames;
            }
        }
        if insert {
            let at = self.whole.ind.partition_point(|&k| k < i);
            self.whole.ind.insert(at, i);
        }
    }

    /// Node `i` joins the group if it is a bystander; whether it did. The `winner` of the
    /// frame just applied stays out while it has another frame to send: it is likely to win
    /// the next one too, and would only leave the group again at once.
    #[inline]
    fn try_join(&mut self, i: usize, winner: bool) -> bool {
        let Device::Controller(c) = &self.nodes[i].device else {
            return false;
        };
        let Some(kind) = c.bystander() else {
            return false;
        };
        if winner && matches!(kind, Bystander::Loser { .. }) {
            return false;
        }
        let acks = !c.config().listen_only;
        let group = &mut self.whole.group;
        group.joined[i] = group.frames;
        group.kind[i] = kind;
        group.acks[i] = acks;
        group.ackers += acks as usize;
        group.members += 1;
        if let Bystander::Loser { key } = kind {
            group.losers.insert((key, i as u32));
        }
        self.whole.ranged[i] = false;
        true
    }

    /// A generator is about to queue a frame on node `i`, a member: it is filled in first,
    /// unless its queue is full, which refuses the frame without looking further (then
    /// false: the generator's frames are refused, nothing else changes). It stays
    /// in the group ([`Self::after_enqueue`]): with no trace, a frame queued in the middle of
    /// a frame shows nowhere before the frame's end, where the controller picks the frame to
    /// send next. So a member is filled in up to the end of the frame being applied, then
    /// given the frame: the same state as queueing it mid-frame and taking the frame's end.
    #[inline]
    pub(super) fn before_enqueue(&mut self, i: usize) -> bool {
        if let Device::Controller(c) = &self.nodes[i].device
            && c.pending() >= c.config().tx_queue_capacity
        {
            return false;
        }
        self.fill_in_for_enqueue(i);
        true
    }

    /// [`Self::before_enqueue`] with room in the queue.
    #[inline(never)]
    fn fill_in_for_enqueue(&mut self, i: usize) {
        let group = &mut self.whole.group;
        let (through, last) = match &self.whole.frame {
            Some(frame) => (group.frames + 1, Some(&self.whole.cache[frame.slot])),
            None => (group.frames, group.last.as_ref()),
        };
        let joined = group.joined[i];
        if joined >= through {
            return;
        }
        group.joined[i] = through;
        let frames = through - joined;
        let node = &mut self.nodes[i];
        if let (Some(last), Device::Controller(c)) = (last, &mut node.device) {
            c.bystander_frames(&last.wire);
            node.stats.received += frames;
            if matches!(group.kind[i], Bystander::Loser { .. }) {
                node.stats.arbitration_lost += frames;
            }
        }
    }

    /// Member `i` was given a frame (see [`Self::before_enqueue`]): what it does in the frames
    /// to come may have changed (a receiver now sends; a loser sends a better frame).
    pub(super) fn after_enqueue(&mut self, i: usize) {
        let Device::Controller(c) = &self.nodes[i].device else {
            return;
        };
        let group = &mut self.whole.group;
        let old = group.kind[i];
        // An error-active controller with REC 0 that was given a frame while waiting for SOF
        // is a bystander again: it sends that frame (or still its own, if better) and loses.
        let Some(new) = c.bystander() else {
            debug_assert!(false, "a member given a frame is no bystander: {c:?}");
            return self.leave_group(i, true);
        };
        if new == old {
            return;
        }
        if let Bystander::Loser { key } = old {
            group.losers.remove((key, i as u32));
        }
        if let Bystander::Loser { key } = new {
            group.losers.insert((key, i as u32));
        }
        group.kind[i] = new;
    }

    /// Who sends, who wins (the lowest arbitration key) and whether someone else acknowledges;
    /// fills `whole.senders` (the nodes taken one by one; a winner from the group leaves it).
    /// The winner, its frame's arbitration bits and the frame decoded (from the cache);
    /// `None` if the frame cannot be applied whole. The frame is looked up here, where the
    /// winner's encoding is at hand: copied out instead (some 50 bytes in pieces, read back
    /// whole) its loads stalled on the copy's stores.
    fn arbitration(&mut self) -> Option<Winner> {
        let whole = &mut self.whole;
        whole.senders.clear();
        let mut best: Option<(u32, usize)> = None;
        let mut tie = false;
        let mut ackers = whole.group.ackers;
        for &i in &whole.ind {
            let FrameStart::Ready { sends, acks } = self.nodes[i].device.frame_start() else {
                return None;
            };
            ackers += acks as usize;
            if let Some(e) = sends {
                whole.senders.push((i, ArbitrationBits::of(e)));
                consider(&mut best, &mut tie, e.frame().arbitration_key(), i);
            }
        }
        // The group's losers are in priority order: only its first two can matter.
        for &(key, i) in whole.group.losers.best_two() {
            consider(&mut best, &mut tie, key, i as usize);
        }
        let (_, w) = best?;
        if tie {
            return None;
        }
        let from_group = whole.group.is_member(w);
        if from_group {
            self.leave_group(w, true);
        }
        let FrameStart::Ready {
            sends: Some(winning),
            acks: winner_acks,
        } = self.nodes[w].device.frame_start()
        else {
            return None;
        };
        let bits = ArbitrationBits::of(winning);
        if from_group {
            self.whole.senders.push((w, bits));
        }
        if ackers <= winner_acks as usize {
            return None;
        }
        let (slot, cached) = self.whole.wire_frame(winning, w)?;
        Some(Winner {
            node: w,
            bits,
            slot,
            cached,
        })
    }

    fn whole_frame(&mut self, end: BitTime) -> bool {
        let n = self.nodes.len();
        self.whole.prepare(n);
        // Nodes with a clock of their own (timestamps, timers) learn when the frame starts.
        if self.others > 0 {
            for node in &mut self.nodes {
                if let super::Device::Other(n) = &mut node.device {
                    n.frame_starts_at(self.now);
                }
            }
        }
        let Some(Winner {
            node: w,
            bits: winner_bits,
            slot,
            cached,
        }) = self.arbitration()
        else {
            return false;
        };
        let wire = &cached.wire;
        let t0 = self.now;
        let total = wire.total();
        let done = t0 + BitTime::from(total);
        if done > end || self.next_fault_change < done {
            return false;
        }
        let Self { nodes, whole, .. } = self;
        if whole.group.members == 0 {
            whole.roles.fill(FrameRole::Receiver);
        } else {
            for &i in &whole.ind {
                whole.roles[i] = FrameRole::Receiver;
            }
        }
        // Only nodes of another kind go through ranges (none on a bus of bare controllers).
        if self.others > 0 {
            for &i in &whole.ind {
                whole.ranged[i] = matches!(nodes[i].device, Device::Other(_));
                whole.done[i] = 0;
            }
        }
        whole.roles[w] = FrameRole::Transmitter;
        whole.losers.clear();
        let mut last_lost = 0;
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
        let in_order = self
            .obs
            .record_events
            .intersects(RecordedEvents::ARBITRATION_LOST | RecordedEvents::DROPPED)
            || self.others > 0
            || self.schedule.next.min(self.next_sample) <= t0 + BitTime::from(last_lost);
        let whole = &mut self.whole;
        if in_order {
            order_losers(&mut whole.losers, &mut whole.sorted, last_lost);
        }
        whole.frame = Some(InFrame { slot });

        // With no member every node is taken one by one: no look into the index list. (No
        // node joins or leaves during the stages: a generator gives a member its frame in
        // the group, see `before_enqueue`.)
        let all = self.whole.group.members == 0;
        // Only nodes of another kind go through ranges: without them no look at `ranged`.
        let ranged = self.others > 0;
        let count = self.whole.ind.len();
        // SOF: every controller takes part in the frame. Nothing to report but what waited
        // already (counters forced between runs report their warning and state here, as the
        // bit-level path polls them after the node samples SOF).
        for k in 0..count {
            let i = if all { k } else { self.whole.ind[k] };
            let Self {
                nodes,
                obs,
                schedule,
                whole,
                ..
            } = self;
            let node = &mut nodes[i];
            if let Device::Controller(c) = &mut node.device
                && !(ranged && whole.ranged[i])
            {
                c.frame_begin(whole.roles[i]);
                if c.has_events() {
                    drain_node(obs, schedule, i, node, t0);
                }
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
            match (&mut node.device, whole.roles[i], ranged && whole.ranged[i]) {
                (Device::Controller(c), FrameRole::LostArbitration { index, .. }, false) => {
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
        for k in 0..count {
            let i = if all { k } else { self.whole.ind[k] };
            if i == w {
                continue;
            }
            let Self {
                nodes,
                obs,
                schedule,
                whole,
                ..
            } = self;
            let node = &mut nodes[i];
            if ranged && whole.ranged[i] {
                // With REC at 0 the ACK slot changes nothing a node could report (a successful
                // reception only lowers a REC above 0, rule 8): the slot goes with the next
                // stage's bits, one call fewer per receiver and frame.
                if node.device.node().rec() != 0 {
                    self.advance_other(wire, i, ack + 1, t0);
                }
            } else if let Device::Controller(c) = &mut node.device {
                c.frame_ack();
                if c.has_events() {
                    drain_node(obs, schedule, i, node, t0 + BitTime::from(ack));
                }
            }
        }
        self.handle_due_inside(wire, t0, &mut at, eof6);
        // Nothing looks at a node between EOF bit 6 and the frame's end (a generator that
        // becomes due in between acts on the winner only, whose frame ends: see
        // `handle_event`): a node that only counts the frame takes all of it now.
        let unobserved_to_end =
            ranged && self.schedule.next.min(self.next_sample) > t0 + BitTime::from(total - 1);
        for k in 0..count {
            let i = if all { k } else { self.whole.ind[k] };
            if i == w {
                continue;
            }
            let Self {
                nodes, obs, whole, ..
            } = self;
            let node = &mut nodes[i];
            if ranged && whole.ranged[i] {
                if unobserved_to_end && whole.done[i] == 0 {
                    self.count_or_advance(wire, i, t0, eof6);
                } else {
                    self.advance_other(wire, i, eof6 + 1, t0);
                }
            } else if let Device::Controller(c) = &mut node.device
                // Handed on at once rather than queued in the controller and polled.
                && let Some(event) = c.frame_received(wire)
            {
                let time = t0 + BitTime::from(eof6);
                record(obs, i, node, time, event);
            }
        }
        self.handle_due_inside(wire, t0, &mut at, eof7);
        if self.whole.ranged[w] {
            self.advance_other(wire, w, eof7 + 1, t0);
        } else {
            self.winner_eof7(w, t0 + BitTime::from(eof7));
        }
        let last = total - 1;
        self.handle_due_inside(wire, t0, &mut at, last);
        for k in 0..count {
            let i = if all { k } else { self.whole.ind[k] };
            let Self {
                nodes,
                obs,
                schedule,
                whole,
                ..
            } = self;
            let node = &mut nodes[i];
            if ranged && whole.ranged[i] {
                self.advance_other(wire, i, total, t0);
            } else if let Device::Controller(c) = &mut node.device {
                // The others' EOF bit 7 changes nothing anybody looks at before now.
                if i != w {
                    let sent = c.frame_eof7();
                    debug_assert!(sent.is_none(), "a receiver sent a frame: {sent:?}");
                }
                c.frame_end(wire);
                if c.has_events() {
                    drain_node(obs, schedule, i, node, t0 + BitTime::from(last));
                }
            }
        }
        self.obs.bus.add_frame(&cached.stats);
        self.now = done;
        self.whole.applied += 1;
        self.whole.frame = None;
        self.whole.group.frames += 1;
        self.whole.group.taken += self.whole.group.members as u64;
        if self.grouping() {
            // Bystanders join the group: until something looks at them, the frames to come
            // cost them nothing.
            let mut kept = 0;
            for k in 0..self.whole.ind.len() {
                let i = self.whole.ind[k];
                if !self.try_join(i, i == w) {
                    self.whole.ind[kept] = i;
                    kept += 1;
                }
            }
            self.whole.ind.truncate(kept);
            if self.whole.group.members > 0 {
                self.whole.group.last = Some(cached);
            }
        }
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
            // Controllers taken stage by stage are up to date at every stage, and members of
            // the group show nothing but their queue before they are filled in (as a
            // generator queues a frame, `before_enqueue`); nodes moved on through ranges are
            // moved on here.
            self.now = due;
            // With bare controllers only, no node goes through ranges: nothing to move on.
            if self.others == 0 {
                self.handle_due();
                continue;
            }
            let generators = self.schedule.next <= due;
            if generators {
                self.schedule.take_due(due);
            }
            if self.next_sample <= due {
                for k in 0..self.whole.ind.len() {
                    let i = self.whole.ind[k];
                    self.advance_other(wire, i, *at, t0);
                }
            } else {
                for k in 0..self.schedule.due.len() {
                    let i = self.schedule.generators[self.schedule.due[k]].node;
                    self.advance_other(wire, i, *at, t0);
                }
            }
            self.handle_due_taken(generators);
        }
    }

    /// EOF bit 7 (at `time`) of the winner `w`, a controller taken stage by stage: its frame
    /// is sent. The `Transmitted` event is handed on directly, not queued and polled.
    #[inline(always)]
    fn winner_eof7(&mut self, w: usize, time: BitTime) {
        let Self {
            nodes,
            obs,
            schedule,
            ..
        } = self;
        let node = &mut nodes[w];
        let Device::Controller(c) = &mut node.device else {
            return;
        };
        // Whatever waits comes first (nothing, as a rule: every stage drains the winner).
        if c.has_events() {
            drain_node(obs, schedule, w, node, time);
        }
        if let Device::Controller(c) = &mut node.device
            && let Some(event) = c.frame_eof7()
        {
            handle_event(obs, schedule, w, node, time, event);
        }
        if matches!(&node.device, Device::Controller(c) if c.has_events()) {
            drain_node(obs, schedule, w, node, time);
        }
    }

    /// Node `i`, moved on through ranges and not yet moved in this frame, takes all of it in
    /// one call if it only counts it ([`BusNode::count_frame`]), or else the frame's bits up
    /// to EOF bit 6 (wire bit `eof6`); its events are handled at EOF bit 6 either way.
    ///
    /// [`BusNode::count_frame`]: buslab_can::node::BusNode::count_frame
    fn count_or_advance(&mut self, wire: &WireFrame, i: usize, t0: BitTime, eof6: u32) {
        let role = self.whole.roles[i];
        let time = t0 + BitTime::from(eof6);
        let Self {
            nodes,
            obs,
            schedule,
            whole,
            ..
        } = self;
        let node = &mut nodes[i];
        match node.device.node_mut().count_frame(wire, role) {
            Counting::Counted(event) => {
                whole.done[i] = wire.total();
                if let Some(event) = event {
                    handle_event(obs, schedule, i, node, time, event);
                }
            }
            Counting::Declined => {
                node.device
                    .node_mut()
                    .advance_frame(wire, role, 0..eof6 + 1);
                whole.done[i] = eof6 + 1;
                drain_node(obs, schedule, i, node, time);
            }
        }
    }

    /// Moves node `i`, if it is moved on through ranges, on through the frame's bits up to
    /// `to` (exclusive) and handles its events, which happen at bit `to - 1`.
    fn advance_other(&mut self, wire: &WireFrame, i: usize, to: u32, t0: BitTime) {
        if !self.whole.ranged[i] {
            return;
        }
        let from = self.whole.done[i];
        if from >= to {
            return;
        }
        self.whole.done[i] = to;
        let role = self.whole.roles[i];
        self.nodes[i]
            .device
            .node_mut()
            .advance_frame(wire, role, from..to);
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
    if obs.record_events.records(&event) {
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

#[cfg(test)]
mod tests {
    use super::Losers;
    use proptest::prelude::*;
    use std::collections::BTreeSet;

    proptest! {
        /// The group's losers stay a set in priority order, the best last, whatever comes and
        /// goes (entries near the end, as on a saturated bus, or anywhere).
        #[test]
        fn losers_stay_sorted_best_last(
            ops in prop::collection::vec((any::<bool>(), 0u32..12, 0u32..6), 0..80)
        ) {
            let mut losers = Losers::default();
            let mut model = BTreeSet::new();
            for (add, key, node) in ops {
                if add {
                    losers.insert((key, node));
                    model.insert((key, node));
                } else {
                    losers.remove((key, node));
                    model.remove(&(key, node));
                }
                let best_last: Vec<_> = model.iter().rev().copied().collect();
                prop_assert_eq!(&losers.0, &best_last);
            }
        }
    }
}
