//! The bus: nodes on one wire, stepped together once per bit-time.

use buslab_can::controller::{
    Controller, ControllerConfig, ErrorState, Event, FrameStart, QueueFull,
};
use buslab_can::node::BusNode;
use buslab_can::{Frame, Level};

use crate::fault::{Fault, FaultKind, Wiring};
use crate::observe::{
    BusStats, CounterSample, Happening, LevelChange, NodeStats, Record, RecordedEvents,
};
use crate::rng::SplitMix64;
use crate::time::BitTime;
use crate::traffic::{Generator, Traffic};
use std::collections::BTreeMap;

mod whole_frame;

/// One node on the wire (any [`BusNode`]: a protocol controller, a chip, a device) with its
/// name and counters.
pub struct Node {
    name: String,
    device: Device,
    stats: NodeStats,
}

/// What is behind a node. Bare protocol controllers, the bulk of simulated nodes, are called
/// directly in the per-bit loop; anything else through the [`BusNode`] seam.
// Controllers stay inline on purpose: the per-bit loop walks them in order.
#[allow(clippy::large_enum_variant)]
enum Device {
    Controller(Controller),
    Other(Box<dyn BusNode>),
}

impl Device {
    /// Samples `bus` at `now`; returns the level driven for the next bit-time and whether
    /// events wait. One dispatch per node and bit-time.
    #[inline(always)]
    fn step(&mut self, now: BitTime, bus: Level) -> (Level, bool) {
        match self {
            Device::Controller(c) => {
                c.sample(bus);
                (c.output(), c.has_events())
            }
            Device::Other(n) => {
                n.sample(now, bus);
                (n.output(), true)
            }
        }
    }
    #[inline(always)]
    fn output(&self) -> Level {
        match self {
            Device::Controller(c) => c.output(),
            Device::Other(n) => n.output(),
        }
    }
    #[inline(always)]
    fn sample(&mut self, now: BitTime, bus: Level) {
        match self {
            Device::Controller(c) => c.sample(bus),
            Device::Other(n) => n.sample(now, bus),
        }
    }
    #[inline(always)]
    fn poll_event(&mut self) -> Option<Event> {
        match self {
            Device::Controller(c) => c.poll_event(),
            Device::Other(n) => n.poll_event(),
        }
    }
    #[inline(always)]
    fn frame_start(&self) -> FrameStart<'_> {
        match self {
            Device::Controller(c) => c.frame_start(),
            Device::Other(n) => n.frame_start(),
        }
    }
    fn node(&self) -> &dyn BusNode {
        match self {
            Device::Controller(c) => c,
            Device::Other(n) => &**n,
        }
    }
    fn node_mut(&mut self) -> &mut dyn BusNode {
        match self {
            Device::Controller(c) => c,
            Device::Other(n) => &mut **n,
        }
    }
}

impl core::fmt::Debug for Node {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("Node")
            .field("name", &self.name)
            .field("state", &self.device().state())
            .field("tec", &self.device().tec())
            .field("rec", &self.device().rec())
            .field("stats", &self.stats)
            .finish()
    }
}

impl Node {
    pub fn name(&self) -> &str {
        &self.name
    }
    pub fn set_name(&mut self, name: impl Into<String>) {
        self.name = name.into();
    }
    pub fn stats(&self) -> &NodeStats {
        &self.stats
    }
    /// The node behind the seam (drive, counters, queue).
    pub fn device(&self) -> &dyn BusNode {
        self.device.node()
    }
    pub fn device_mut(&mut self) -> &mut dyn BusNode {
        self.device.node_mut()
    }
    pub fn tec(&self) -> u16 {
        self.device().tec()
    }
    pub fn rec(&self) -> u16 {
        self.device().rec()
    }
    pub fn state(&self) -> ErrorState {
        self.device().state()
    }
    /// The node itself, to be taken back as its own type (`downcast`).
    pub fn into_any(self) -> Box<dyn core::any::Any> {
        match self.device {
            Device::Controller(c) => Box::new(c),
            Device::Other(n) => n,
        }
    }
    /// The node as its own type, if it is a `T` (e.g. a [`Controller`]).
    pub fn get<T: BusNode>(&self) -> Option<&T> {
        self.device().as_any().downcast_ref()
    }
    /// The node as its own type, mutable.
    pub fn get_mut<T: BusNode>(&mut self) -> Option<&mut T> {
        self.device_mut().as_any_mut().downcast_mut()
    }
}

/// The trace and the bus statistics; kept apart from the nodes so the per-bit loop can borrow
/// both.
#[derive(Debug, Default)]
struct Observers {
    records: Vec<Record>,
    record_events: RecordedEvents,
    bus: BusStats,
}

/// Traffic generators and the earliest time one of them wants to act.
#[derive(Debug, Default)]
struct Schedule {
    generators: Vec<Generator>,
    next: BitTime,
    /// Some generator sends a file: only those act when a node's frame leaves the bus.
    files: bool,
    /// For every time some generator waits for, those generators, earliest time first, so a
    /// generator acting costs no look at the others. Kept by time rather than one entry per
    /// generator: generators started together with one period (a saturated bus of periodic
    /// senders) are due at the same bit-times, and all of them cost one look at the map
    /// instead of one heap operation each. An entry whose generator has moved to another
    /// time since is stale and dropped when met.
    queue: BTreeMap<BitTime, Vec<usize>>,
    /// Emptied lists of `queue`, reused for the next times.
    spare: Vec<Vec<usize>>,
    /// The generators due now (see [`Self::take_due`]).
    due: Vec<usize>,
}

/// Up to this many generators a look at each costs less than keeping the queue in order.
const SCAN_GENERATORS: usize = 16;

impl Schedule {
    /// Few generators: scanned, no queue kept.
    #[inline]
    fn scanned(&self) -> bool {
        self.generators.len() <= SCAN_GENERATORS
    }

    fn recompute(&mut self) {
        self.queue.clear();
        self.next = BitTime::MAX;
        for at in 0..self.generators.len() {
            self.push(at);
        }
        self.settle();
    }

    /// Generator `at` waits for its (new) time, if any.
    #[inline]
    fn push(&mut self, at: usize) {
        if let Some(t) = self.generators[at].next() {
            if !self.scanned() {
                let spare = &mut self.spare;
                self.queue
                    .entry(t)
                    .or_insert_with(|| spare.pop().unwrap_or_default())
                    .push(at);
            }
            self.next = self.next.min(t);
        }
    }

    /// Drops stale entries at the head of the queue; `next` is the earliest time again.
    fn settle(&mut self) {
        if self.scanned() {
            self.next = self
                .generators
                .iter()
                .filter_map(Generator::next)
                .min()
                .unwrap_or(BitTime::MAX);
            return;
        }
        while let Some(entry) = self.queue.first_entry() {
            let t = *entry.key();
            if entry
                .get()
                .iter()
                .any(|&at| self.generators[at].next() == Some(t))
            {
                self.next = t;
                return;
            }
            let waiting = entry.remove();
            self.reuse(waiting);
        }
        self.next = BitTime::MAX;
    }

    /// Takes the generators due at or before `now` off the queue into `due`, in the order
    /// they act (as added).
    fn take_due(&mut self, now: BitTime) {
        self.due.clear();
        if self.scanned() {
            for (at, g) in self.generators.iter().enumerate() {
                if g.next().is_some_and(|t| t <= now) {
                    self.due.push(at);
                }
            }
            return;
        }
        while let Some(entry) = self.queue.first_entry() {
            if *entry.key() > now {
                break;
            }
            let (t, waiting) = entry.remove_entry();
            for &at in &waiting {
                if self.generators[at].next() == Some(t) {
                    self.due.push(at);
                }
            }
            self.reuse(waiting);
        }
        self.due.sort_unstable();
        self.due.dedup();
    }

    /// Keeps an emptied list of `queue` for a later time.
    #[inline]
    fn reuse(&mut self, mut waiting: Vec<usize>) {
        waiting.clear();
        self.spare.push(waiting);
    }
}

/// Level changes for waveforms; present only when asked for.
#[derive(Debug)]
struct LevelTrace {
    last: Vec<Level>,
    changes: Vec<LevelChange>,
}

impl LevelTrace {
    #[inline]
    fn set(&mut self, time: BitTime, signal: usize, level: Level) {
        if self.last[signal] != level {
            self.last[signal] = level;
            self.changes.push(LevelChange {
                time,
                signal,
                level,
            });
        }
    }
}

/// A CAN bus with its nodes, traffic and faults, in virtual time counted in bit-times.
///
/// Deterministic: the same set-up and seed give the same trace, bit for bit.
#[derive(Debug)]
pub struct Simulation {
    bitrate: u32,
    now: BitTime,
    nodes: Vec<Node>,
    schedule: Schedule,
    /// The faults not ended yet (ended ones are forgotten: a long-lived bus gets many), with
    /// whether each is in force and the number [`Self::add_fault`] gave it.
    faults: Vec<Fault>,
    fault_active: Vec<bool>,
    fault_numbers: Vec<usize>,
    faults_added: usize,
    next_fault_change: BitTime,
    wiring: Wiring,
    faulty: bool,
    rng: SplitMix64,
    seg_levels: Vec<Level>,
    outputs: Vec<Level>,
    obs: Observers,
    sample_every: Option<BitTime>,
    next_sample: BitTime,
    series: Vec<CounterSample>,
    levels: Option<LevelTrace>,
    fast_forward: bool,
    skipped: BitTime,
    whole: whole_frame::WholeFrames,
    /// Nodes that are not bare controllers.
    others: usize,
}

/// While the bus is recessive, how often (in bit-times) the clean loop checks whether every
/// node is idle so it can fast-forward.
const IDLE_CHECK_EVERY: u64 = 16;

impl Simulation {
    /// An empty bus at `bitrate` bit/s (used only to convert bit-times to seconds); `seed`
    /// drives the random faults. Panics if `bitrate` is 0.
    pub fn new(bitrate: u32, seed: u64) -> Self {
        assert!(bitrate > 0, "bit rate must be positive");
        Self {
            bitrate,
            now: BitTime::ZERO,
            nodes: Vec::new(),
            schedule: Schedule {
                next: BitTime::MAX,
                ..Default::default()
            },
            faults: Vec::new(),
            fault_active: Vec::new(),
            fault_numbers: Vec::new(),
            faults_added: 0,
            next_fault_change: BitTime::MAX,
            wiring: Wiring::build(0, core::iter::empty()),
            faulty: false,
            rng: SplitMix64::new(seed),
            seg_levels: Vec::new(),
            outputs: Vec::new(),
            obs: Observers {
                record_events: RecordedEvents::all(),
                // The bus has been idle since forever.
                bus: BusStats {
                    recessive_run: 11,
                    ..Default::default()
                },
                ..Default::default()
            },
            sample_every: None,
            next_sample: BitTime::MAX,
            series: Vec::new(),
            levels: None,
            fast_forward: true,
            skipped: BitTime::ZERO,
            whole: whole_frame::WholeFrames::default(),
            others: 0,
        }
    }

    /// Adds a protocol controller; returns its index (0, 1, ...).
    pub fn add_node(&mut self, name: impl Into<String>, config: ControllerConfig) -> usize {
        self.push_node(name.into(), Device::Controller(Controller::new(config)))
    }

    /// Adds any bit-level node (a chip with its driver, a device); returns its index.
    pub fn add_device(&mut self, name: impl Into<String>, device: Box<dyn BusNode>) -> usize {
        self.push_node(name.into(), Device::Other(device))
    }

    fn push_node(&mut self, name: String, device: Device) -> usize {
        self.others += matches!(device, Device::Other(_)) as usize;
        self.whole.nodes_changed = true;
        self.nodes.push(Node {
            name,
            device,
            stats: NodeStats::default(),
        });
        let n = self.nodes.len();
        self.outputs.resize(n, Level::Recessive);
        self.wiring = Wiring::build(n, self.active_faults());
        self.seg_levels
            .resize(n + self.faults.len() + 1, Level::Recessive);
        if let Some(levels) = &mut self.levels {
            levels.last.resize(1 + 2 * n, Level::Recessive);
        }
        n - 1
    }

    /// Takes node `index` off the wire (its connector is pulled, even in the middle of a
    /// frame) and returns it. Nodes after it move down one index; its traffic goes with it, and
    /// faults forget it (a fault that named only this node never becomes active again).
    pub fn remove_node(&mut self, index: usize) -> Node {
        let node = self.nodes.remove(index);
        self.others -= matches!(node.device, Device::Other(_)) as usize;
        self.whole.nodes_changed = true;
        self.outputs.remove(index);
        self.schedule.generators.retain(|g| g.node != index);
        for g in &mut self.schedule.generators {
            if g.node > index {
                g.node -= 1;
            }
        }
        self.schedule.recompute();
        for at in 0..self.faults.len() {
            let fault = &mut self.faults[at];
            if !fault.kind.forget_node(index) {
                fault.end = fault.start.min(self.now);
                // Its node is gone: it ends now (it still names that node, so the wiring must
                // not see it in force).
                if std::mem::take(&mut self.fault_active[at]) {
                    let index = self.fault_numbers[at];
                    self.obs.records.push(Record {
                        time: self.now,
                        what: Happening::FaultEnded { index },
                    });
                }
            }
        }
        if let Some(levels) = &mut self.levels {
            let first = 1 + 2 * index;
            levels.last.drain(first..first + 2);
        }
        self.wiring = Wiring::build(self.nodes.len(), self.active_faults());
        self.next_fault_change = self.now;
        node
    }

    /// Attaches a traffic generator to `node`.
    pub fn add_traffic(&mut self, node: usize, traffic: Traffic) {
        assert!(node < self.nodes.len(), "no node {node}");
        let generator = Generator::new(node, traffic);
        self.schedule.files |= generator.is_file();
        self.schedule.generators.push(generator);
        self.schedule.recompute();
    }

    /// Adds a fault; returns its number: 0, 1, ... in the order added (as used in
    /// [`Happening::FaultStarted`]).
    pub fn add_fault(&mut self, fault: Fault) -> usize {
        assert!(
            fault.kind.nodes().all(|n| n < self.nodes.len()),
            "fault names a node that does not exist"
        );
        self.faults.push(fault);
        self.fault_active.push(false);
        let number = self.faults_added;
        self.fault_numbers.push(number);
        self.faults_added += 1;
        self.seg_levels
            .resize(self.nodes.len() + self.faults.len() + 1, Level::Recessive);
        self.next_fault_change = self.now;
        number
    }

    /// Ends every fault now: those active stop, those not started yet never start. Returns how
    /// many were ended.
    pub fn end_faults(&mut self) -> usize {
        let now = self.now;
        let mut ended = 0;
        for fault in &mut self.faults {
            if fault.end > now {
                fault.end = now;
                fault.start = fault.start.min(now);
                ended += 1;
            }
        }
        self.next_fault_change = now;
        ended
    }

    /// Jump over idle bus time (on by default; see [`Self::run_until`]). Turning it off
    /// changes nothing but the speed.
    pub fn set_fast_forward(&mut self, on: bool) {
        self.fast_forward = on;
    }

    /// Bit-times jumped over by fast-forwarding so far.
    pub fn fast_forwarded(&self) -> BitTime {
        self.skipped
    }

    /// Which node events to record in the trace (all by default; `RecordedEvents::empty()`
    /// for none). Counters are kept either way.
    pub fn set_record_events(&mut self, kinds: RecordedEvents) {
        self.obs.record_events = kinds;
    }

    /// Sample every node's TEC/REC every `interval` bit-times into [`Self::series`].
    pub fn sample_counters_every(&mut self, interval: BitTime) {
        assert!(interval > BitTime::ZERO);
        self.sample_every = Some(interval);
        self.next_sample = self.now;
    }

    /// Record level changes of the bus and of each node's TX and RX (see [`LevelChange`]).
    /// Call it before running: the trace starts from an idle (recessive) bus.
    pub fn trace_levels(&mut self) {
        // Every signal starts recessive (the idle bus); only changes are recorded.
        self.levels = Some(LevelTrace {
            last: vec![Level::Recessive; 1 + 2 * self.nodes.len()],
            changes: Vec::new(),
        });
    }

    pub fn bitrate(&self) -> u32 {
        self.bitrate
    }
    /// The current bit-time (bits simulated so far).
    pub fn now(&self) -> BitTime {
        self.now
    }
    pub fn nodes(&self) -> &[Node] {
        &self.nodes
    }
    pub fn node(&self, node: usize) -> &Node {
        &self.nodes[node]
    }
    /// Index of the node called `name`.
    pub fn find_node(&self, name: &str) -> Option<usize> {
        self.nodes.iter().position(|n| n.name == name)
    }
    pub fn nodes_mut(&mut self) -> &mut [Node] {
        &mut self.nodes
    }
    pub fn node_mut(&mut self, node: usize) -> &mut Node {
        &mut self.nodes[node]
    }
    /// Direct access to a node's protocol controller (e.g. to call `recover()`), if the node
    /// is a bare controller.
    pub fn controller_mut(&mut self, node: usize) -> Option<&mut Controller> {
        self.nodes[node].get_mut()
    }
    /// The faults not ended yet: in force, or to start later. An ended fault is forgotten
    /// once the simulation has run up to its end.
    pub fn faults(&self) -> &[Fault] {
        &self.faults
    }
    pub fn bus_stats(&self) -> &BusStats {
        &self.obs.bus
    }
    /// The trace so far (since the last [`Self::take_records`]).
    pub fn records(&self) -> &[Record] {
        &self.obs.records
    }
    /// Takes the trace recorded so far, leaving it empty (for streaming output).
    pub fn take_records(&mut self) -> Vec<Record> {
        // Room for as many again: a streaming caller takes about as many each time.
        let room = Vec::with_capacity(self.obs.records.len());
        core::mem::replace(&mut self.obs.records, room)
    }
    /// The TEC/REC series (see [`Self::sample_counters_every`]).
    pub fn series(&self) -> &[CounterSample] {
        &self.series
    }
    /// Takes the TEC/REC series recorded so far, leaving it empty (for streaming output).
    pub fn take_series(&mut self) -> Vec<CounterSample> {
        core::mem::take(&mut self.series)
    }
    /// Takes the level changes recorded so far (see [`Self::trace_levels`]).
    pub fn take_level_changes(&mut self) -> Vec<LevelChange> {
        self.levels
            .as_mut()
            .map(|l| core::mem::take(&mut l.changes))
            .unwrap_or_default()
    }
    /// Bit-time at which each file transfer of `node` finished (in the order added).
    pub fn files_finished(&self, node: usize) -> Vec<Option<BitTime>> {
        self.schedule
            .generators
            .iter()
            .filter(|g| g.node == node && g.is_file())
            .map(|g| g.finished_at)
            .collect()
    }

    /// One bit-time with the wire level passed through `disturb`, as a disturber on the wire
    /// would change it (force a dominant bit, invert one): it becomes a fault lasting this one
    /// bit-time. Panics if `disturb` would force the wire recessive, which no disturber can (a
    /// dominant driver always wins).
    pub fn step_disturbed(&mut self, disturb: impl Fn(Level) -> Level) {
        let kind = match (disturb(Level::Recessive), disturb(Level::Dominant)) {
            (Level::Recessive, Level::Dominant) => None,
            (Level::Dominant, Level::Dominant) => Some(FaultKind::StuckDominant),
            (Level::Dominant, Level::Recessive) => Some(FaultKind::Flip { node: None }),
            (Level::Recessive, Level::Recessive) => {
                panic!("a disturber cannot hold the wire recessive")
            }
        };
        if let Some(kind) = kind {
            self.add_fault(Fault {
                kind,
                start: self.now,
                end: self.now + BitTime::ONE,
            });
        }
        self.run_for(BitTime::ONE);
    }

    /// Simulates `bits` more bit-times.
    pub fn run_for(&mut self, bits: BitTime) {
        self.run_until(self.now.saturating_add(bits));
    }

    /// Simulates up to (not including) bit-time `end`.
    ///
    /// When no fault is active and every controller is idle on an idle bus with nothing to
    /// send, nothing can happen before the next traffic, fault or sample time: the simulation
    /// jumps there (idle controllers that sample recessive stay idle, and every level stays
    /// recessive).
    pub fn run_until(&mut self, end: BitTime) {
        self.run_past(end, end);
    }

    /// Simulates up to `end`, or on past it to the end of the frame on the bus at `end` if
    /// that frame is applied whole and ends by `limit`; returns the bit-time reached (from
    /// `end` to `limit`). Everything then stands as after [`Self::run_until`] that time.
    ///
    /// For a long run cut into pieces (to print the trace between them): a piece that ends
    /// in the middle of a frame no longer makes every node step that frame bit by bit.
    pub fn run_past(&mut self, end: BitTime, limit: BitTime) -> BitTime {
        self.run_until_inner(end, limit.max(end));
        // Every node is filled in for whoever looks at it next.
        self.dissolve_group();
        self.now
    }

    /// Runs to `end`; a whole frame may end as late as `limit`.
    fn run_until_inner(&mut self, end: BitTime, limit: BitTime) {
        while self.now < end {
            self.handle_due();
            let horizon = end
                .min(self.schedule.next)
                .min(self.next_fault_change)
                .min(self.next_sample);
            debug_assert!(horizon > self.now);
            if self.try_whole_frame(limit) {
                continue;
            }
            let quiet = if self.fast_forward && !self.faulty {
                self.quiet_until()
            } else {
                None
            };
            if let Some(until) = quiet {
                // Idle levels are all recessive, as they already were: no level changes. A
                // node's own timer ends the jump; it is then sampled again.
                let to = horizon.min(until);
                self.obs.bus.idle((to - self.now).get());
                self.skipped += to - self.now;
                self.now = to;
                if to == until && to < horizon {
                    self.run_clean(to + BitTime::ONE);
                }
            } else if self.faulty || self.levels.is_some() {
                while self.now < horizon.min(self.schedule.next) {
                    self.step_faulty();
                    if self.fast_forward && !self.faulty && self.may_be_idle() && self.all_idle() {
                        break;
                    }
                }
            } else {
                self.run_clean(horizon);
            }
        }
    }

    /// Whether it is worth checking [`Self::all_idle`]: a frame ends with 11 recessive bits
    /// (ACK delimiter, EOF, intermission); only then can everybody be idle. Checked every few
    /// bits, not every bit, in case a node stays busy (bus-off, suspend) on an idle bus.
    #[inline]
    fn may_be_idle(&self) -> bool {
        let run = self.obs.bus.recessive_run;
        run >= 11 && (run - 11).is_multiple_of(IDLE_CHECK_EVERY)
    }

    /// Every node is quiet: a recessive bus changes nothing but the time until the returned
    /// bit-time (the earliest of the nodes' own timers), which is later than now.
    fn quiet_until(&self) -> Option<BitTime> {
        let mut until = BitTime::MAX;
        for n in &self.nodes {
            until = until.min(n.device().quiet_until()?);
        }
        (until > self.now).then_some(until)
    }

    fn all_idle(&self) -> bool {
        self.quiet_until().is_some()
    }

    /// Everything scheduled at or before `now`: fault changes, traffic, counter samples.
    #[inline(always)]
    fn handle_due(&mut self) {
        // Nothing due, as after most frames of a busy bus: not even a call.
        let due = self
            .schedule
            .next
            .min(self.next_fault_change)
            .min(self.next_sample);
        if due <= self.now {
            self.handle_due_taken(false);
        }
    }

    /// [`Self::handle_due`]; `taken`: the due generators are already in `schedule.due`.
    fn handle_due_taken(&mut self, taken: bool) {
        let now = self.now;
        if self.next_fault_change <= now {
            self.update_faults();
        }
        let scan = !taken && self.schedule.next <= now && self.schedule.scanned();
        if scan && self.whole.no_members() {
            // Few generators and nobody in the group (always so with the trace): the loop
            // below without looking for members, measurably cheaper.
            let mut next = BitTime::MAX;
            for g in &mut self.schedule.generators {
                if g.next().is_some_and(|t| t <= now) {
                    let node = &mut self.nodes[g.node];
                    let q = g.fire(now, node.device.node_mut());
                    node.stats.queued += q.queued;
                    node.stats.queue_overflows += q.overflows;
                }
                if let Some(t) = g.next() {
                    next = next.min(t);
                }
            }
            self.schedule.next = next;
        } else if scan {
            // Few generators: one look at each fires the due ones and finds the next time
            // (firing one changes no other's time), in the order they were added.
            let mut next = BitTime::MAX;
            for at in 0..self.schedule.generators.len() {
                if self.schedule.generators[at]
                    .next()
                    .is_some_and(|t| t <= now)
                {
                    self.fire(at, now);
                }
                if let Some(t) = self.schedule.generators[at].next() {
                    next = next.min(t);
                }
            }
            self.schedule.next = next;
        } else if taken || self.schedule.next <= now {
            if !taken {
                self.schedule.take_due(now);
            }
            for k in 0..self.schedule.due.len() {
                let at = self.schedule.due[k];
                self.fire(at, now);
                self.schedule.push(at);
            }
            self.schedule.settle();
        }
        if self.next_sample <= now {
            for (i, n) in self.nodes.iter().enumerate() {
                self.series.push(CounterSample {
                    time: now,
                    node: i,
                    tec: n.device().tec(),
                    rec: n.device().rec(),
                    state: n.device().state(),
                });
            }
            self.next_sample = self
                .sample_every
                .map_or(BitTime::MAX, |every| now.saturating_add(every));
        }
    }

    /// Generator `at` acts at `now`. A node advanced with the group is filled in before it
    /// is given a frame.
    #[inline(always)]
    fn fire(&mut self, at: usize, now: BitTime) {
        let i = self.schedule.generators[at].node;
        let member = self.whole.is_member(i);
        if member && !self.before_enqueue(i) {
            // Its queue is full (usual on a saturated bus): the frames are refused without a
            // call into the node.
            let q = self.schedule.generators[at].refuse(now);
            self.nodes[i].stats.queue_overflows += q.overflows;
            return;
        }
        let node = &mut self.nodes[i];
        let q = self.schedule.generators[at].fire(now, node.device.node_mut());
        node.stats.queued += q.queued;
        node.stats.queue_overflows += q.overflows;
        if member && q.queued > 0 {
            self.after_enqueue(i);
        }
    }

    fn update_faults(&mut self) {
        let now = self.now;
        let mut next = BitTime::MAX;
        for (at, fault) in self.faults.iter().enumerate() {
            let active = fault.start <= now && now < fault.end;
            if active != self.fault_active[at] {
                self.fault_active[at] = active;
                let index = self.fault_numbers[at];
                let what = if active {
                    Happening::FaultStarted { index }
                } else {
                    Happening::FaultEnded { index }
                };
                self.obs.records.push(Record { time: now, what });
            }
            for t in [fault.start, fault.end] {
                if t > now {
                    next = next.min(t);
                }
            }
        }
        crate::fault::forget_ended(
            now,
            &mut self.faults,
            &mut self.fault_active,
            &mut self.fault_numbers,
        );
        self.next_fault_change = next;
        self.faulty = self.fault_active.iter().any(|&a| a);
        self.wiring = Wiring::build(self.nodes.len(), self.active_faults());
    }

    fn active_faults(&self) -> impl Iterator<Item = &Fault> {
        self.faults
            .iter()
            .zip(&self.fault_active)
            .filter(|(_, a)| **a)
            .map(|(f, _)| f)
    }

    /// The hot loop: no faults, no level tracing, so every node samples the same level, the
    /// wired-AND of all outputs. Returns early when the bus may have gone idle, so
    /// [`Self::run_until`] can fast-forward.
    fn run_clean(&mut self, horizon: BitTime) {
        let fast_forward = self.fast_forward;
        let whole_from = self.whole.check_from();
        let Self {
            nodes,
            obs,
            schedule,
            now,
            ..
        } = self;
        // The wired-AND of what every node drives for the next bit is gathered while the nodes
        // sample the current one (after their events, which may queue a frame).
        let mut bus = wired_and(nodes);
        while *now < horizon.min(schedule.next) {
            // As `may_be_idle` (inlined here because of the split borrow).
            let run = obs.bus.recessive_run;
            if fast_forward
                && run >= 11
                && (run - 11).is_multiple_of(IDLE_CHECK_EVERY)
                && nodes
                    .iter()
                    .all(|n| n.device().quiet_until().is_some_and(|t| t > *now))
            {
                return;
            }
            // After a frame's 11 recessive bits: lined up for the next one to be applied whole?
            if run == 11 && *now >= whole_from && whole_frame::lined_up(nodes) {
                return;
            }
            let mut next_recessive = true;
            for (i, node) in nodes.iter_mut().enumerate() {
                let (mut out, events) = node.device.step(*now, bus);
                if events {
                    while let Some(event) = node.device.poll_event() {
                        handle_event(obs, schedule, i, node, *now, event);
                    }
                    // An event (a generator's next frame) may change what the node drives.
                    out = node.device.output();
                }
                next_recessive &= out.bit();
            }
            obs.bus.bit(bus);
            *now += BitTime::ONE;
            bus = Level::from_bit(next_recessive);
        }
    }

    /// One bit-time with faults (or level tracing) in force.
    fn step_faulty(&mut self) {
        self.step_wired();
    }

    /// Whether nothing can happen before [`Self::next_activity`] while the wire stays idle:
    /// no fault is active and every node is quiet at least until then.
    pub fn is_idle(&self) -> bool {
        !self.faulty && self.all_idle()
    }

    /// The next bit-time at which traffic, a fault change, a counter sample or a node's own
    /// timer is due.
    pub fn next_activity(&self) -> BitTime {
        self.schedule
            .next
            .min(self.next_fault_change)
            .min(self.next_sample)
            .min(self.quiet_until().unwrap_or(BitTime::MAX))
    }

    /// One bit-time through the wiring.
    fn step_wired(&mut self) {
        let now = self.now;
        let w = &self.wiring;
        let segments = w.is_bus.len();
        if self.seg_levels.len() < segments {
            self.seg_levels.resize(segments, Level::Recessive);
        }
        let seg_levels = &mut self.seg_levels[..segments];
        seg_levels.fill(Level::Recessive);
        for (i, node) in self.nodes.iter().enumerate() {
            let out = node.device.output();
            self.outputs[i] = out;
            if out == Level::Dominant {
                seg_levels[w.segment[i]] = Level::Dominant;
            }
        }
        for (level, &is_bus) in seg_levels.iter_mut().zip(&w.is_bus) {
            if !is_bus {
                continue;
            }
            if w.stuck_dominant {
                *level = Level::Dominant;
            }
            if self.rng.hit(w.bus_noise) {
                *level = invert(*level);
            }
        }
        let bus = seg_levels[0];
        for (i, node) in self.nodes.iter_mut().enumerate() {
            let mut seen = seg_levels[w.segment[i]];
            if self.rng.hit(w.node_noise[i]) {
                seen = invert(seen);
            }
            if w.flip_all || w.flip_node[i] {
                seen = invert(seen);
            }
            if let Some(levels) = &mut self.levels {
                levels.set(now, 1 + 2 * i, self.outputs[i]);
                levels.set(now, 2 + 2 * i, seen);
            }
            node.device.sample(now, seen);
            while let Some(event) = node.device.poll_event() {
                handle_event(&mut self.obs, &mut self.schedule, i, node, now, event);
            }
        }
        if let Some(levels) = &mut self.levels {
            levels.set(now, 0, bus);
        }
        self.obs.bus.bit(bus);
        self.now += BitTime::ONE;
    }

    /// Queue a frame on `node` right now.
    pub fn enqueue(&mut self, node: usize, frame: Frame) -> Result<(), QueueFull> {
        let n = &mut self.nodes[node];
        let r = n.device_mut().enqueue(frame);
        match r {
            Ok(()) => n.stats.queued += 1,
            Err(_) => n.stats.queue_overflows += 1,
        }
        r
    }
}

/// The bus level when every node drives its output.
fn wired_and(nodes: &[Node]) -> Level {
    Level::from_bit(nodes.iter().all(|n| n.device.output().bit()))
}

fn invert(level: Level) -> Level {
    match level {
        Level::Dominant => Level::Recessive,
        Level::Recessive => Level::Dominant,
    }
}

/// Counts and records one event, and lets the file senders move on. Kept out of line: events
/// are rare next to bits.
#[inline(never)]
fn handle_event(
    obs: &mut Observers,
    schedule: &mut Schedule,
    i: usize,
    node: &mut Node,
    now: BitTime,
    event: Event,
) {
    node.stats.count(&event);
    match &event {
        Event::Transmitted(frame) | Event::Dropped(frame) => {
            obs.bus.frames += matches!(event, Event::Transmitted(_)) as u64;
            let files = if schedule.files {
                schedule.generators.len()
            } else {
                0
            };
            for at in 0..files {
                let g = &mut schedule.generators[at];
                if g.node != i {
                    continue;
                }
                let q = g.on_done(frame, now, node.device.node_mut());
                node.stats.queued += q.queued;
                node.stats.queue_overflows += q.overflows;
                schedule.push(at);
            }
        }
        Event::Error { .. } => obs.bus.errors += 1,
        _ => {}
    }
    if obs.record_events.records(&event) {
        obs.records.push(Record {
            time: now,
            what: Happening::Node { node: i, event },
        });
    }
}

#[cfg(test)]
mod tests {
    use super::{BitTime, Generator, SCAN_GENERATORS, Schedule};
    use crate::traffic::Traffic;
    use buslab_can::{Frame, Id};
    use proptest::prelude::*;

    fn traffic(kind: u8, start: u64, period: u64, count: u8) -> Traffic {
        let frame = Frame::data(Id::standard(0x123).unwrap(), &[1, 2]).unwrap();
        let (start, period) = (BitTime::new(start), BitTime::new(period));
        match kind % 3 {
            0 => Traffic::Periodic {
                frame,
                period,
                start,
                count: (count > 0).then_some(u64::from(count)),
            },
            1 => Traffic::Burst {
                frame,
                count: u32::from(count % 4 + 1),
                period,
                start,
            },
            _ => Traffic::Once { frame, at: start },
        }
    }

    proptest! {
        /// With more generators than are scanned, the queue by time fires exactly the
        /// generators a look at each would, at the same bit-times, in the order added; many
        /// of them due at the same bit-time (one period, one start) as on a saturated bus.
        #[test]
        fn queued_generators_fire_as_scanned_ones(
            specs in prop::collection::vec(
                (any::<u8>(), 0u64..4, 1u64..4, 0u8..6),
                SCAN_GENERATORS + 1..SCAN_GENERATORS + 40,
            )
        ) {
            let mut schedule = Schedule::default();
            for (node, &(kind, start, period, count)) in specs.iter().enumerate() {
                // Few distinct starts and periods: many generators share their bit-times.
                let traffic = traffic(kind, start * 100, period * 100, count);
                schedule.generators.push(Generator::new(node, traffic));
            }
            prop_assert!(!schedule.scanned());
            schedule.recompute();
            // Periodic generators go on for ever: up to a horizon.
            let horizon = BitTime::new(2_000);
            while schedule.next < horizon {
                let now = schedule.next;
                let expected: Vec<usize> = (0..schedule.generators.len())
                    .filter(|&at| schedule.generators[at].next().is_some_and(|t| t <= now))
                    .collect();
                prop_assert!(!expected.is_empty(), "nothing due at the next time {now:?}");
                schedule.take_due(now);
                prop_assert_eq!(&schedule.due, &expected);
                for k in 0..schedule.due.len() {
                    let at = schedule.due[k];
                    schedule.generators[at].refuse(now);
                    schedule.push(at);
                }
                schedule.settle();
                let earliest = schedule.generators.iter().filter_map(Generator::next).min();
                prop_assert_eq!(schedule.next, earliest.unwrap_or(BitTime::MAX));
            }
        }
    }
}
