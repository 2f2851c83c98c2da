//! One node's CAN protocol controller (MAC/LLC) as a sans-IO state machine.
//!
//! Driving it, once per bit-time: ask [`Controller::output`] for the level this node drives,
//! combine all nodes' outputs on the wire (wired-AND), then hand the sampled bus level to
//! [`Controller::sample`]. Drain [`Controller::poll_event`] whenever convenient.

use crate::Frame;
use crate::Level;

/// Options that change how the controller behaves on the bus.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ControllerConfig {
    /// Never drive the bus dominant (no ACK, no error flags, no transmission).
    pub listen_only: bool,
    /// A transmission needs no ACK from another node (SJA1000 self-test).
    pub self_test: bool,
    /// Do not retransmit after a lost arbitration or an error.
    pub single_shot: bool,
    /// Deliver our own successfully sent frames as received frames too.
    pub self_reception: bool,
    /// After bus-off, start the recovery sequence by itself (otherwise wait for
    /// [`Controller::recover`]).
    pub auto_recover: bool,
    /// Maximum number of frames waiting in the transmit queue.
    pub tx_queue_capacity: usize,
}

impl Default for ControllerConfig {
    fn default() -> Self {
        Self {
            listen_only: false,
            self_test: false,
            single_shot: false,
            self_reception: false,
            auto_recover: true,
            tx_queue_capacity: 64,
        }
    }
}

/// Fault confinement state.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ErrorState {
    Active,
    Passive,
    BusOff,
}

/// The five CAN error kinds.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ErrorKind {
    Bit,
    Stuff,
    Crc,
    Form,
    Ack,
}

/// Something that happened on this node.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Event {
    /// A frame received from the bus (or our own with self-reception).
    Received(Frame),
    /// Our frame was sent successfully (no error up to the end of EOF).
    Transmitted(Frame),
    /// Our frame lost arbitration at the given bit (index in the de-stuffed frame, SOF = 0).
    ArbitrationLost { frame: Frame, bit: u32 },
    /// An error was detected. `bit` is the position in the current frame's raw (stuffed) bit
    /// stream, SOF = 0.
    Error {
        kind: ErrorKind,
        transmitter: bool,
        bit: u32,
        tec: u16,
        rec: u16,
    },
    /// The fault confinement state changed.
    StateChanged {
        from: ErrorState,
        to: ErrorState,
        tec: u16,
        rec: u16,
    },
    /// TEC or REC crossed the error warning limit (96) upwards (`true`) or downwards.
    Warning { above: bool, tec: u16, rec: u16 },
    /// We sent an overload frame.
    Overload,
    /// A single-shot frame was dropped after an error or a lost arbitration.
    Dropped(Frame),
}

/// The transmit queue is full.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[error("transmit queue is full ({capacity} frames)")]
pub struct QueueFull {
    pub capacity: usize,
}

/// One node's protocol controller.
#[derive(Debug)]
pub struct Controller {
    config: ControllerConfig,
}

impl Controller {
    pub fn new(config: ControllerConfig) -> Self {
        Self { config }
    }

    pub fn config(&self) -> &ControllerConfig {
        &self.config
    }

    /// Queue a frame for transmission (sent in priority order).
    pub fn enqueue(&mut self, frame: Frame) -> Result<(), QueueFull> {
        let _ = frame;
        Err(QueueFull {
            capacity: self.config.tx_queue_capacity,
        })
    }

    /// The level this node drives during the current bit-time.
    pub fn output(&self) -> Level {
        Level::Recessive
    }

    /// The bus level sampled during the current bit-time; advances one bit-time.
    pub fn sample(&mut self, bus: Level) {
        let _ = bus;
    }

    pub fn poll_event(&mut self) -> Option<Event> {
        None
    }

    pub fn tec(&self) -> u16 {
        0
    }
    pub fn rec(&self) -> u16 {
        0
    }
    pub fn state(&self) -> ErrorState {
        ErrorState::Active
    }

    /// Start bus-off recovery (when `auto_recover` is off).
    pub fn recover(&mut self) {}
}
