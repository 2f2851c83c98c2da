//! The seam between the one bus engine and every kind of node on its wire.
//!
//! A node is anything that drives a level and samples the bus once per bit-time: the bare
//! protocol [`Controller`], an SJA1000 chip with the CPU that services it, a P82C150 SLIO. The
//! engine (`buslab-sim`) combines every node's [`output`](BusNode::output) on a wired-AND wire
//! and hands each one the level it sees; what happened comes back as protocol [`Event`]s,
//! which the engine counts and records for every node alike.

use core::any::Any;
use core::ops::Range;

use crate::BitTime;
use crate::Frame;
use crate::Level;
use crate::controller::{
    Controller, ErrorState, Event, FrameRole, FrameStart, QueueFull, WireFrame,
};

/// What [`BusNode::count_frame`] did with a frame.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Counting {
    /// Not counted, nothing changed: the node goes through the frame's bits in ranges.
    Declined,
    /// Counted whole, with the frame's one event if it has one (at EOF bit 6); nothing else
    /// waits in [`BusNode::poll_event`].
    Counted(Option<Event>),
}

/// A bit-level node on a CAN wire, driven once per bit-time: read [`output`](Self::output),
/// then [`sample`](Self::sample) the bus, then drain [`poll_event`](Self::poll_event).
pub trait BusNode: Any + Send {
    /// The level this node drives during the current bit-time.
    fn output(&self) -> Level;

    /// The bus level this node sees during bit-time `now` (bit-times since the bus started;
    /// it may jump forward over idle bus while the node is [quiet](Self::quiet_until)).
    fn sample(&mut self, now: BitTime, bus: Level);

    /// The next protocol event of this node's controller (what the engine counts and traces).
    fn poll_event(&mut self) -> Option<Event>;

    /// Transmit error counter (0..=256; above 255 means bus-off).
    fn tec(&self) -> u16;
    /// Receive error counter.
    fn rec(&self) -> u16;
    /// Fault confinement state.
    fn state(&self) -> ErrorState;

    /// Until when a recessive bus changes nothing in this node but the time: `None` while it
    /// is busy (it must see every bit), `Some(BitTime::MAX)` when it is idle with nothing to send,
    /// `Some(t)` when it is idle but has a timer of its own that runs out at bit-time `t`. The
    /// engine may skip bit-times without sampling up to that time; the next
    /// [`sample`](Self::sample) then comes with a later `now`.
    fn quiet_until(&self) -> Option<BitTime>;

    /// Queues a frame for transmission (traffic generators, scenario one-shots).
    fn enqueue(&mut self, frame: Frame) -> Result<(), QueueFull>;

    /// Frames waiting to be sent, including the one being attempted.
    fn pending(&self) -> usize;

    /// Whether the node is lined up at a frame start (waiting for SOF on an idle bus,
    /// error-active) so the engine may apply the next frame whole, and what it sends with
    /// that SOF. The default, [`FrameStart::NotReady`], keeps the engine on the bit-by-bit
    /// path whenever such a node is on the bus.
    fn frame_start(&self) -> FrameStart<'_> {
        FrameStart::NotReady
    }

    /// The engine considers applying a whole frame whose SOF is at bit-time `now`: called
    /// before it asks [`Self::frame_start`] for that frame and before the
    /// [`Self::advance_frame`] calls that apply it. Since the node's last
    /// [`sample`](Self::sample) the bus was recessive (the engine may have skipped those
    /// bit-times, as [`Self::quiet_until`] allowed). A node that keeps time of its own
    /// (timestamps, timers) takes the time here; the default ignores it.
    fn frame_starts_at(&mut self, now: BitTime) {
        let _ = now;
    }

    /// Wire bits `bits` of `frame` (SOF = 0) have passed with this node as `role`: advance as
    /// stepping those bits would, with the same events. Called with consecutive ranges up to
    /// [`WireFrame::total`], only after [`Self::frame_start`] said `Ready`; see
    /// [`Controller::advance_frame`].
    fn advance_frame(&mut self, frame: &WireFrame, role: FrameRole, bits: Range<u32>) {
        let _ = (frame, role, bits);
    }

    /// Takes all of `frame` as `role` in one go if the node only counts it, and says whether
    /// it did (the default: [`Counting::Declined`], nothing changed). Only counting means: it
    /// ends with the same state and events as [`Self::advance_frame`] over all the frame's
    /// bits, with at most one event, due at EOF bit 6 (when it has received the frame), which
    /// it hands over in [`Counting::Counted`] instead of keeping it for
    /// [`Self::poll_event`]; and what the engine may ask of it inside a frame (its counters,
    /// its queue) stays as it was at SOF. Called instead of the node's first range of the
    /// frame, at EOF bit 6, when nothing looks at the node before the frame's end: one call
    /// instead of a range per stage and a look at its events after each.
    fn count_frame(&mut self, frame: &WireFrame, role: FrameRole) -> Counting {
        let _ = (frame, role);
        Counting::Declined
    }

    /// The node as [`Any`], so its owner can reach its own type.
    fn as_any(&self) -> &dyn Any;
    /// The node as mutable [`Any`].
    fn as_any_mut(&mut self) -> &mut dyn Any;
}

impl BusNode for Controller {
    #[inline]
    fn output(&self) -> Level {
        Controller::output(self)
    }
    #[inline]
    fn sample(&mut self, _now: BitTime, bus: Level) {
        Controller::sample(self, bus)
    }
    #[inline]
    fn poll_event(&mut self) -> Option<Event> {
        Controller::poll_event(self)
    }
    fn tec(&self) -> u16 {
        Controller::tec(self)
    }
    fn rec(&self) -> u16 {
        Controller::rec(self)
    }
    fn state(&self) -> ErrorState {
        Controller::state(self)
    }
    fn quiet_until(&self) -> Option<BitTime> {
        (self.is_bus_idle() && Controller::pending(self) == 0).then_some(BitTime::MAX)
    }
    fn enqueue(&mut self, frame: Frame) -> Result<(), QueueFull> {
        Controller::enqueue(self, frame)
    }
    fn pending(&self) -> usize {
        Controller::pending(self)
    }
    fn frame_start(&self) -> FrameStart<'_> {
        Controller::frame_start(self)
    }
    fn advance_frame(&mut self, frame: &WireFrame, role: FrameRole, bits: Range<u32>) {
        Controller::advance_frame(self, frame, role, bits)
    }
    fn as_any(&self) -> &dyn Any {
        self
    }
    fn as_any_mut(&mut self) -> &mut dyn Any {
        self
    }
}
