//! A bench's simulated node on the virtual bus ([`Device`]): the bus reaches it through what it
//! reports ([`DeviceNotice`]) and what it offers (a SLIO demo board's inputs and outputs,
//! [`Board`]), never by its type. The bench (`buslab-bench`) implements [`Device`] for its
//! models and puts them on the wire as [`DeviceNode`]s.

use std::any::Any;
use std::ops::Range;

use buslab_can::controller::{ErrorState, Event, FrameRole, FrameStart, QueueFull, WireFrame};
use buslab_can::node::BusNode;
use buslab_can::{BitTime, Frame, Level};
use buslab_canbus::NodeInfo;
use buslab_canbus::admin::{BoardInput, BoardState};
use buslab_slio::{SlioId, SlioNotice};

/// What a bench's device reports to the bus (the bus says it as [`crate::BusEvent::Device`],
/// with the node's number and name).
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum DeviceNotice {
    /// A SLIO's calibration changed, or it changed its bus mode.
    Slio(SlioNotice),
}

impl DeviceNotice {
    /// Whether the operator should be warned (rather than informed).
    pub fn is_warning(&self) -> bool {
        matches!(self, DeviceNotice::Slio(SlioNotice::BusModeChange(_)))
    }
}

/// A simulated node of a bench, as the virtual bus sees it.
pub trait Device: Send {
    /// The node on the wire.
    fn node(&self) -> &dyn BusNode;
    /// The node on the wire, to step.
    fn node_mut(&mut self) -> &mut dyn BusNode;
    /// What it noticed since the last call, with the bit-time (none by default).
    fn take_notices(&mut self) -> Vec<(BitTime, DeviceNotice)> {
        Vec::new()
    }
    /// Its SLIO demo board, if it is one.
    fn board(&mut self) -> Option<&mut dyn Board> {
        None
    }
}

/// A SLIO demo board's face: its inputs a person changes and what it shows.
pub trait Board {
    /// The SLIO's number (its ID switches).
    fn slio(&self) -> SlioId;
    /// Changes an input at bit-time `now` (the bus has checked it: four switches,
    /// `Switches(0x0..=0xF)`).
    fn change(&mut self, now: BitTime, input: BoardInput);
    /// What it shows at bit-time `now`, as bus node `node`.
    fn state(&mut self, now: BitTime, node: NodeInfo) -> BoardState;
}

/// A [`Device`] on the wire: the engine steps its node, the bus asks it for notices and its
/// board.
pub struct DeviceNode(Box<dyn Device>);

impl DeviceNode {
    pub fn new(device: impl Device + 'static) -> Self {
        Self(Box::new(device))
    }

    pub fn device(&self) -> &dyn Device {
        &*self.0
    }

    pub fn device_mut(&mut self) -> &mut dyn Device {
        &mut *self.0
    }

    /// The node on the wire as its own type, for whoever put it there.
    pub fn get<T: BusNode>(&self) -> Option<&T> {
        self.0.node().as_any().downcast_ref()
    }

    /// The node on the wire as its own type, to change.
    pub fn get_mut<T: BusNode>(&mut self) -> Option<&mut T> {
        self.0.node_mut().as_any_mut().downcast_mut()
    }
}

impl std::fmt::Debug for DeviceNode {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("DeviceNode")
            .field("state", &self.0.node().state())
            .field("pending", &self.0.node().pending())
            .finish_non_exhaustive()
    }
}

impl BusNode for DeviceNode {
    #[inline]
    fn output(&self) -> Level {
        self.0.node().output()
    }
    #[inline]
    fn sample(&mut self, now: BitTime, bus: Level) {
        self.0.node_mut().sample(now, bus)
    }
    #[inline]
    fn poll_event(&mut self) -> Option<Event> {
        self.0.node_mut().poll_event()
    }
    fn tec(&self) -> u16 {
        self.0.node().tec()
    }
    fn rec(&self) -> u16 {
        self.0.node().rec()
    }
    fn state(&self) -> ErrorState {
        self.0.node().state()
    }
    fn quiet_until(&self) -> Option<BitTime> {
        self.0.node().quiet_until()
    }
    fn enqueue(&mut self, frame: Frame) -> Result<(), QueueFull> {
        self.0.node_mut().enqueue(frame)
    }
    fn pending(&self) -> usize {
        self.0.node().pending()
    }
    fn frame_start(&self) -> FrameStart<'_> {
        self.0.node().frame_start()
    }
    fn frame_starts_at(&mut self, now: BitTime) {
        self.0.node_mut().frame_starts_at(now)
    }
    fn advance_frame(&mut self, frame: &WireFrame, role: FrameRole, bits: Range<u32>) {
        self.0.node_mut().advance_frame(frame, role, bits)
    }
    fn as_any(&self) -> &dyn Any {
        self
    }
    fn as_any_mut(&mut self) -> &mut dyn Any {
        self
    }
}
