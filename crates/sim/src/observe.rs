//! What the simulation records: a trace of node events, per-node counters, a sampled TEC/REC
//! series, bus-load statistics and level changes for waveforms.

use buslab_can::Level;
use buslab_can::controller::{ErrorState, Event};
use buslab_can::wire::Bits;

use crate::time::BitTime;

/// One entry of the trace.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Record {
    /// Bit-time during which it happened (the bit whose sample produced the event).
    pub time: BitTime,
    pub what: Happening,
}

#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Happening {
    /// A controller event of node `node`.
    Node { node: usize, event: Event },
    /// Fault `index` (in the order added) became active.
    FaultStarted { index: usize },
    /// Fault `index` ended.
    FaultEnded { index: usize },
}

bitflags::bitflags! {
    /// Which kinds of node events the trace records (all by default; see
    /// [`crate::Simulation::set_record_events`]). Fault starts and ends are always recorded.
    ///
    /// Recording only what is read is more than thrift: with neither [`Self::RECEIVED`] nor
    /// [`Self::ARBITRATION_LOST`] the engine may advance nodes that only watch frames go by as
    /// one group instead of one by one.
    #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
    pub struct RecordedEvents: u16 {
        const RECEIVED = 1 << 0;
        const TRANSMITTED = 1 << 1;
        const ARBITRATION_LOST = 1 << 2;
        const ERROR = 1 << 3;
        const STATE_CHANGED = 1 << 4;
        const WARNING = 1 << 5;
        const OVERLOAD = 1 << 6;
        const DROPPED = 1 << 7;
    }
}

/// Every kind, as a new simulation records.
impl Default for RecordedEvents {
    fn default() -> Self {
        Self::all()
    }
}

impl RecordedEvents {
    /// The kind of `event`.
    pub fn of(event: &Event) -> Self {
        match event {
            Event::Received(_) => Self::RECEIVED,
            Event::Transmitted(_) => Self::TRANSMITTED,
            Event::ArbitrationLost { .. } => Self::ARBITRATION_LOST,
            Event::Error { .. } => Self::ERROR,
            Event::StateChanged { .. } => Self::STATE_CHANGED,
            Event::Warning { .. } => Self::WARNING,
            Event::Overload => Self::OVERLOAD,
            Event::Dropped(_) => Self::DROPPED,
        }
    }

    /// Whether `event` is of a recorded kind.
    #[inline]
    pub fn records(self, event: &Event) -> bool {
        self.intersects(Self::of(event))
    }
}

/// Counters of one node.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct NodeStats {
    /// Frames this node transmitted successfully.
    pub sent: u64,
    /// Frames it received (including its own with self-reception).
    pub received: u64,
    /// Errors it detected (error frames it started).
    pub errors: u64,
    pub arbitration_lost: u64,
    pub overloads: u64,
    /// Single-shot frames dropped by the controller.
    pub dropped: u64,
    /// Frames the traffic generators queued, and those refused because the queue was full.
    pub queued: u64,
    pub queue_overflows: u64,
    /// Times it went bus-off.
    pub bus_off: u64,
    /// The highest TEC and REC the node's events reported (error, state change, warning).
    pub max_tec: u16,
    pub max_rec: u16,
}

impl NodeStats {
    #[inline]
    pub(crate) fn count(&mut self, event: &Event) {
        match event {
            Event::Received(_) => self.received += 1,
            Event::Transmitted(_) => self.sent += 1,
            Event::ArbitrationLost { .. } => self.arbitration_lost += 1,
            Event::Error { tec, rec, .. } => {
                self.errors += 1;
                self.max_tec = self.max_tec.max(*tec);
                self.max_rec = self.max_rec.max(*rec);
            }
            Event::StateChanged { to, tec, rec, .. } => {
                if *to == ErrorState::BusOff {
                    self.bus_off += 1;
                }
                self.max_tec = self.max_tec.max(*tec);
                self.max_rec = self.max_rec.max(*rec);
            }
            Event::Warning { tec, rec, .. } => {
                self.max_tec = self.max_tec.max(*tec);
                self.max_rec = self.max_rec.max(*rec);
            }
            Event::Overload => self.overloads += 1,
            Event::Dropped(_) => self.dropped += 1,
        }
    }
}

/// One point of the TEC/REC series.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CounterSample {
    pub time: BitTime,
    pub node: usize,
    pub tec: u16,
    pub rec: u16,
    pub state: ErrorState,
}

/// Bus-wide statistics.
///
/// A bit-time counts as *busy* unless it is the 12th or later of a run of recessive bits: a
/// frame's ACK delimiter, EOF and intermission are 11 recessive bits, so back-to-back frames
/// keep the bus 100 % busy and anything beyond is idle bus.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct BusStats {
    pub bits: u64,
    pub busy_bits: u64,
    pub dominant_bits: u64,
    /// Frames transmitted successfully (all nodes).
    pub frames: u64,
    /// Error events (all nodes).
    pub errors: u64,
    pub(crate) recessive_run: u64,
}

impl BusStats {
    /// Fraction of bit-times the bus was busy, 0.0..=1.0.
    pub fn load(&self) -> f64 {
        if self.bits == 0 {
            0.0
        } else {
            self.busy_bits as f64 / self.bits as f64
        }
    }

    /// What happened between `earlier` (a copy taken before) and now: bit-times, busy bits,
    /// frames and errors in that window (its [`load`](Self::load) is the window's load).
    pub fn since(&self, earlier: &BusStats) -> BusStats {
        BusStats {
            bits: self.bits - earlier.bits,
            busy_bits: self.busy_bits - earlier.busy_bits,
            dominant_bits: self.dominant_bits - earlier.dominant_bits,
            frames: self.frames - earlier.frames,
            errors: self.errors - earlier.errors,
            recessive_run: self.recessive_run,
        }
    }

    /// Whether the last 11 bit-times were recessive: no frame, flag or delimiter is on the
    /// wire (the bus is idle or between frames).
    pub fn is_between_frames(&self) -> bool {
        self.recessive_run >= 11
    }

    /// `bits` recessive bit-times of idle bus.
    pub(crate) fn idle(&mut self, bits: u64) {
        self.bits += bits;
        self.busy_bits += 11u64.saturating_sub(self.recessive_run).min(bits);
        self.recessive_run += bits;
    }

    /// A frame whose bits, taken one by one from an idle bus, gave `frame`. A frame starts with
    /// a dominant SOF, so what came before it changes nothing but where its recessive run
    /// starts: the result is the same as taking its bits here.
    pub(crate) fn add_frame(&mut self, frame: &BusStats) {
        debug_assert!(frame.dominant_bits > 0);
        self.bits += frame.bits;
        self.busy_bits += frame.busy_bits;
        self.dominant_bits += frame.dominant_bits;
        self.recessive_run = frame.recessive_run;
    }

    /// A clean frame's bits `bus` (SOF..end of EOF) taken from an idle bus, then intermission
    /// up to `total` bit-times: the same as taking them one by one with [`Self::bit`] and
    /// [`Self::idle`], counted at once. Inside a frame no recessive run is longer than 8 bits
    /// (ACK delimiter and EOF), so every bit-time up to the end of intermission is busy.
    pub(crate) fn of_frame(bus: &Bits, total: u32) -> BusStats {
        let len = bus.len() as u64;
        let recessive_run = bus.trailing_ones() as u64 + u64::from(total) - len;
        let stats = BusStats {
            bits: u64::from(total),
            busy_bits: u64::from(total),
            dominant_bits: len - bus.count_ones() as u64,
            frames: 0,
            errors: 0,
            recessive_run,
        };
        debug_assert_eq!(stats, {
            let mut stepped = BusStats::default();
            for i in 0..bus.len() {
                stepped.bit(bus.level(i));
            }
            stepped.idle(u64::from(total) - len);
            stepped
        });
        stats
    }

    #[inline(always)]
    pub(crate) fn bit(&mut self, bus: Level) {
        self.bits += 1;
        if bus == Level::Dominant {
            self.dominant_bits += 1;
            self.recessive_run = 0;
            self.busy_bits += 1;
        } else {
            self.recessive_run += 1;
            self.busy_bits += (self.recessive_run <= 11) as u64;
        }
    }
}

/// A level change, for waveform writers: `signal` 0 is the bus (main wire), then each node's
/// TX (`1 + 2 * node`) and RX (`2 + 2 * node`) level.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LevelChange {
    pub time: BitTime,
    pub signal: usize,
    pub level: Level,
}

/// Names of the signals of [`LevelChange`] for `nodes`.
pub fn signal_names<'a>(nodes: impl Iterator<Item = &'a str>) -> Vec<String> {
    let mut names = vec!["bus".to_owned()];
    for n in nodes {
        names.push(format!("{n}_tx"));
        names.push(format!("{n}_rx"));
    }
    names
}
