//! One node's CAN protocol controller (MAC/LLC) as a sans-IO state machine.
//!
//! Driving it, once per bit-time: ask [`Controller::output`] for the level this node drives,
//! combine all nodes' outputs on the wire (wired-AND), then hand the sampled bus level to
//! [`Controller::sample`]. Drain [`Controller::poll_event`] whenever convenient.
//!
//! The controller follows the facts sheet (`can-bitlevel.md`): integration (11 recessive bits),
//! arbitration, ACK, the five error kinds, active/passive error flags and delimiters, overload
//! frames, intermission, suspend transmission, and fault confinement with all counter rules and
//! their exceptions. Its receive path is the [`wire::Receiver`]; it counts EOF itself because a
//! controller and a bare decoder treat the last EOF bit differently.

mod fault;
mod queue;
mod whole_frame;

use alloc::collections::VecDeque;

use crate::wire::{self, Encoded, Field, Receiver, Step, WireErrorKind};
use crate::{Frame, Level};
use fault::Counters;
use queue::{Queued, TxQueue};

pub use whole_frame::{ArbitrationBits, Bystander, FrameRole, FrameStart, WireFrame};

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

/// Fault confinement state (ISO 11898-1): the one error-state type of the workspace, from the
/// protocol controller up to python-can's `ErrorState` view in the host tools. The warning
/// level is no state of its own here (it is error-active); the SJA1000's status shows it, see
/// `buslab_bus::ControllerState`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ErrorState {
    /// Error-active (the warning level included): takes part fully, signals errors with
    /// active error flags.
    Active,
    /// Error-passive: a counter is above 127.
    Passive,
    /// Bus-off: the controller takes no part in bus traffic.
    BusOff,
}

impl core::fmt::Display for ErrorState {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            ErrorState::Active => "error-active",
            ErrorState::Passive => "error-passive",
            ErrorState::BusOff => "bus-off",
        })
    }
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

/// Where the last error was detected, for error-code capture registers (SJA1000 ECC).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ErrorLocation {
    /// Inside a data or remote frame: the field and the de-stuffed index (SOF = 0) of the next
    /// data bit when the error was seen.
    Frame { field: Field, index: u32 },
    /// In our own active error flag (`overload`: our overload flag).
    Flag { overload: bool },
    /// In an error or overload delimiter.
    Delimiter { overload: bool },
}

/// Which flag is being sent.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Flag {
    ActiveError,
    PassiveError,
    Overload,
}

/// What the current bit-time is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Phase {
    /// After reset: waiting for 11 consecutive recessive bits.
    Integrating { recessive: u8 },
    /// Bus idle: a pending frame starts with SOF.
    Idle,
    /// SOF .. ACK delimiter; every bit goes through the receiver.
    Frame,
    /// EOF bit `n` (1..=7).
    Eof { n: u8 },
    /// Intermission bit `n` (1..=3).
    Intermission { n: u8 },
    /// Suspend transmission bit `n` (1..=8), for an error-passive node after transmitting.
    Suspend { n: u8 },
    /// Bit `n` (0-based) of a flag; `equal`/`last` follow the sampled levels for a passive flag.
    Flag {
        flag: Flag,
        n: u8,
        equal: u8,
        last: bool,
    },
    /// Error or overload delimiter: `dominant` bits seen after the flag while waiting for the
    /// first recessive bit, then `recessive` delimiter bits seen (1..=7).
    Delimiter {
        overload: bool,
        recessive: u8,
        dominant: u32,
    },
    /// Bus-off; recovery counts 128 sequences of 11 recessive bits.
    BusOff { recessive: u8, sequences: u8 },
}

/// Consecutive recessive bits that integrate a node into bus activity.
const INTEGRATION_BITS: u8 = 11;
/// Sequences of 11 recessive bits a bus-off node waits for.
const RECOVERY_SEQUENCES: u8 = 128;

/// One node's protocol controller.
#[derive(Debug, Clone)]
pub struct Controller {
    config: ControllerConfig,
    phase: Phase,
    /// The level driven during the current bit-time (what [`Controller::output`] returns).
    drive: Level,
    rx: Receiver,
    /// The frame being (or next to be) attempted, already encoded.
    tx: Option<Encoded>,
    /// The number `tx` was queued with: it keeps its place among frames of its arbitration
    /// field if a more important frame displaces it ([`TxQueue`]).
    tx_seq: u64,
    /// The number the next frame queued gets.
    next_seq: u64,
    /// `tx` is at least as important as every queued frame: nothing was queued since
    /// [`Self::load_tx`] compared them (always false without `tx`). Saves the comparison for a
    /// node that keeps losing arbitration with a full queue.
    tx_is_best: bool,
    queue: TxQueue,
    /// The encoding of the last frame sent, kept because periodic traffic queues the same
    /// frame again: [`Self::load_tx`] reuses it instead of encoding anew.
    last_sent: Option<Encoded>,
    /// We are the transmitter of the current frame (from SOF to the end of its error frame or
    /// EOF; cleared when arbitration is lost).
    transmitting: bool,
    /// We transmitted the frame that just ended (suspend transmission if error-passive).
    was_transmitter: bool,
    counters: Counters,
    /// A passive transmitter's ACK error: TEC +8 only if a dominant bit shows up during its
    /// passive error flag (facts §5.2 rule 3, exception 1).
    ack_exception: bool,
    /// Bus-off recovery is counting (auto, or after [`Controller::recover`]).
    recovering: bool,
    /// Drop the in-flight frame instead of retrying it ([`Controller::abort_all`]).
    abort_in_flight: bool,
    /// Wire index of the current bit since the last SOF.
    frame_bit: u32,
    last_error: ErrorLocation,
    events: VecDeque<Event>,
}

impl Controller {
    pub fn new(config: ControllerConfig) -> Self {
        Self {
            config,
            phase: Phase::Integrating { recessive: 0 },
            drive: Level::Recessive,
            rx: Receiver::new(),
            tx: None,
            tx_seq: 0,
            next_seq: 0,
            tx_is_best: false,
            queue: TxQueue::with_capacity(config.tx_queue_capacity),
            last_sent: None,
            transmitting: false,
            was_transmitter: false,
            counters: Counters::new(),
            ack_exception: false,
            recovering: false,
            abort_in_flight: false,
            frame_bit: 0,
            last_error: ErrorLocation::Frame {
                field: Field::Sof,
                index: 0,
            },
            events: VecDeque::with_capacity(16),
        }
    }

    pub fn config(&self) -> &ControllerConfig {
        &self.config
    }

    /// Queue a frame for transmission (sent in priority order; equal frames in queue order).
    /// The frame in flight counts against the capacity. A listen-only controller accepts frames
    /// but never sends them.
    pub fn enqueue(&mut self, frame: Frame) -> Result<(), QueueFull> {
        self.enqueue_with_dlc(frame, frame.dlc())
    }

    /// [`enqueue`](Self::enqueue) with the DLC to put on the wire: for an 8-byte data frame (or
    /// a remote frame of DLC 8) it may be 9..15, which ISO 11898-1 lets a classic transmitter
    /// send (receivers take 8 bytes). Any other DLC than the frame's own is ignored.
    pub fn enqueue_with_dlc(&mut self, frame: Frame, dlc: u8) -> Result<(), QueueFull> {
        if self.pending() >= self.config.tx_queue_capacity {
            return Err(QueueFull {
                capacity: self.config.tx_queue_capacity,
            });
        }
        let dlc = if frame.dlc() == 8 && (8..=15).contains(&dlc) {
            dlc
        } else {
            frame.dlc()
        };
        if self.phase == Phase::Idle
            && self.tx.is_none()
            && self.queue.len() == 0
            && !self.config.listen_only
        {
            // Nothing waits on an idle bus: what `load_tx` would make of it at once, without
            // going through the queue (a periodic sender that keeps up does this every time).
            self.tx = Some(self.encoding(&frame, dlc));
            self.tx_seq = self.next_seq;
            self.next_seq += 1;
            self.tx_is_best = true;
            self.drive = Level::Dominant;
            return Ok(());
        }
        let seq = self.next_seq;
        self.next_seq += 1;
        self.queue.push(Queued { frame, dlc, seq });
        self.tx_is_best = false;
        if self.phase == Phase::Idle {
            self.drive = self.next_drive();
        }
        Ok(())
    }

    /// Frames waiting, including the one being attempted.
    pub fn pending(&self) -> usize {
        self.queue.len() + self.tx.is_some() as usize
    }

    /// The waiting frames, the one being attempted first, then in the order they will be tried.
    pub fn queued(&self) -> impl Iterator<Item = &Frame> {
        self.tx.iter().map(Encoded::frame).chain(self.queue.iter())
    }

    /// Drop every waiting frame. A frame on the wire right now finishes its attempt but is not
    /// retried (it is reported as [`Event::Dropped`] if that attempt fails); afterwards
    /// [`pending`](Self::pending) counts only that frame.
    pub fn abort_all(&mut self) {
        self.queue.clear();
        // During the error frame of a frame already dropped we are still the transmitter, but
        // nothing is in flight: arming the abort then would drop the next frame instead.
        if self.transmitting && self.tx.is_some() {
            self.abort_in_flight = true;
        } else {
            self.tx = None;
            self.tx_is_best = false;
        }
    }

    /// The level this node drives during the current bit-time.
    #[inline]
    pub fn output(&self) -> Level {
        self.drive
    }

    /// The bus is idle (integrated, no frame, flag or interframe space in progress): a frame
    /// queued now starts with the next bit.
    pub fn is_bus_idle(&self) -> bool {
        self.phase == Phase::Idle
    }

    /// We are the transmitter of the frame on the bus (not yet lost arbitration).
    pub fn is_transmitting(&self) -> bool {
        self.transmitting
    }

    /// We take part in a frame (or its error/overload frame) on the bus as a receiver.
    pub fn is_receiving(&self) -> bool {
        !self.transmitting
            && matches!(
                self.phase,
                Phase::Frame | Phase::Eof { .. } | Phase::Flag { .. } | Phase::Delimiter { .. }
            )
    }

    /// Where the last error was detected.
    pub fn last_error_location(&self) -> ErrorLocation {
        self.last_error
    }

    /// Force the error counters (a controller's "write TXERR/RXERR in reset mode"); the state
    /// follows them. REC saturates at 255 as usual.
    pub fn set_counters(&mut self, tec: u16, rec: u16) {
        self.counters.tec = tec;
        self.counters.rec = rec.min(255);
        self.update_state();
    }

    /// Switch single-shot transmission on or off for the frames not yet finished (the SJA1000
    /// chooses it per transmission request).
    pub fn set_single_shot(&mut self, on: bool) {
        self.config.single_shot = on;
    }

    /// The bus level sampled during the current bit-time; advances one bit-time.
    #[inline]
    pub fn sample(&mut self, bus: Level) {
        // Fast path for most bits of a frame: inside a field, nothing to check but stuffing
        // and CRC, and (for the transmitter) that the bus shows what we sent.
        let bit = bus.bit();
        match self.phase {
            Phase::Frame => {
                let drove = self.drive.bit();
                let quiet = if self.transmitting {
                    drove == bit
                } else {
                    drove
                };
                if quiet && self.rx.push_mid_field(bit) {
                    self.frame_bit += 1;
                    if self.transmitting
                        && let Some(tx) = &self.tx
                    {
                        self.drive = tx.stuffed().level(self.rx.position() as usize);
                    }
                    return;
                }
            }
            // Recessive EOF bits before the 6th: nothing happens, everybody drives recessive.
            Phase::Eof { n } if bit && n < 5 => {
                self.phase = Phase::Eof { n: n + 1 };
                self.frame_bit += 1;
                return;
            }
            _ => {}
        }
        self.sample_slow(bit);
    }

    #[inline(never)]
    fn sample_slow(&mut self, bit: bool) {
        match self.phase {
            Phase::Integrating { recessive } => {
                self.phase = match (bit, recessive + 1) {
                    (false, _) => Phase::Integrating { recessive: 0 },
                    (true, INTEGRATION_BITS) => Phase::Idle,
                    (true, n) => Phase::Integrating { recessive: n },
                };
            }
            Phase::Idle => {
                let sent_sof = self.drive == Level::Dominant;
                if !bit {
                    self.start_frame(sent_sof);
                } else if sent_sof {
                    // Our SOF read back recessive: a bit error at bit 0 of our frame.
                    self.start_frame(true);
                    self.error(ErrorKind::Bit, true);
                }
            }
            Phase::Frame => self.frame_bit(bit),
            Phase::Eof { n } => self.eof_bit(n, bit),
            Phase::Intermission { n } => self.intermission_bit(n, bit),
            Phase::Suspend { n } => {
                self.phase = match (bit, n) {
                    (false, _) => {
                        self.start_frame(false);
                        Phase::Frame
                    }
                    (true, 8) => Phase::Idle,
                    (true, n) => Phase::Suspend { n: n + 1 },
                };
            }
            Phase::Flag {
                flag,
                n,
                equal,
                last,
            } => self.flag_bit(flag, n, equal, last, bit),
            Phase::Delimiter {
                overload,
                recessive,
                dominant,
            } => self.delimiter_bit(overload, recessive, dominant, bit),
            Phase::BusOff {
                recessive,
                sequences,
            } => self.bus_off_bit(recessive, sequences, bit),
        }
        self.frame_bit = self.frame_bit.saturating_add(1);
        self.drive = self.next_drive();
    }

    /// Whether [`Self::poll_event`] has something.
    #[inline]
    pub fn has_events(&self) -> bool {
        !self.events.is_empty()
    }

    #[inline]
    pub fn poll_event(&mut self) -> Option<Event> {
        if self.events.is_empty() {
            return None;
        }
        self.events.pop_front()
    }

    pub fn tec(&self) -> u16 {
        self.counters.tec
    }
    pub fn rec(&self) -> u16 {
        self.counters.rec
    }
    pub fn state(&self) -> ErrorState {
        self.counters.state()
    }

    /// Start bus-off recovery (when `auto_recover` is off): after 128 sequences of 11
    /// recessive bits the node is error-active again with both counters 0.
    pub fn recover(&mut self) {
        if self.state() == ErrorState::BusOff {
            self.recovering = true;
        }
    }

    /// The level for the bit-time after the one just sampled.
    #[inline(always)]
    fn next_drive(&mut self) -> Level {
        if self.config.listen_only {
            return Level::Recessive;
        }
        match self.phase {
            Phase::Idle => {
                if self.load_tx() {
                    Level::Dominant
                } else {
                    Level::Recessive
                }
            }
            Phase::Frame => {
                if self.transmitting {
                    match &self.tx {
                        Some(tx) => tx.stuffed().level(self.rx.position() as usize),
                        None => Level::Recessive,
                    }
                } else if self.rx.field() == Field::AckSlot
                    && !self.rx.expects_stuff_bit()
                    && self.rx.crc_ok()
                {
                    Level::Dominant
                } else {
                    Level::Recessive
                }
            }
            Phase::Flag {
                flag: Flag::ActiveError | Flag::Overload,
                ..
            } => Level::Dominant,
            _ => Level::Recessive,
        }
    }

    /// Make `tx` the most important waiting frame; false if there is none.
    #[inline]
    fn load_tx(&mut self) -> bool {
        if self.tx_is_best {
            return true;
        }
        // Only a more important arbitration field displaces the frame waiting to be sent:
        // frames of one field leave in the order they were queued, whenever this is asked
        // (at once on an idle bus, or at the end of the frame on the wire).
        let better = match (&self.tx, self.queue.peek()) {
            (_, None) => false,
            (None, Some(_)) => true,
            (Some(tx), Some(next)) => next.arbitration_key() < tx.frame().arbitration_key(),
        };
        if better && let Some(next) = self.queue.pop() {
            let encoded = self.encoding(&next.frame, next.dlc);
            let displaced_seq = core::mem::replace(&mut self.tx_seq, next.seq);
            if let Some(old) = self.tx.replace(encoded) {
                self.queue.push(Queued {
                    frame: *old.frame(),
                    dlc: old.dlc(),
                    seq: displaced_seq,
                });
            }
        }
        // The best queued frame replaced a worse one, or was not better.
        self.tx_is_best = self.tx.is_some();
        self.tx_is_best
    }

    /// `frame` encoded with the raw `dlc`: the last frame sent's encoding if it is the same
    /// frame again, as periodic traffic queues it.
    #[inline]
    fn encoding(&self, frame: &Frame, dlc: u8) -> Encoded {
        // The same frame and raw DLC encode the same: an encoding made with a DLC that did
        // not fit carries the frame's own, so `dlc` matches it only if it fits.
        match self.last_sent {
            Some(sent) if sent.dlc() == dlc && sent.frame() == frame => sent,
            _ => wire::encode_with_dlc(frame, dlc).unwrap_or_else(|| wire::encode(frame)),
        }
    }

    /// SOF sampled. `transmit`: we take part as a transmitter (sent SOF, or have a frame ready
    /// when SOF shows up in the 3rd intermission bit).
    fn start_frame(&mut self, transmit: bool) {
        self.rx.reset();
        let _ = self.rx.push(false);
        self.frame_bit = 0;
        self.transmitting = transmit && self.tx.is_some();
        self.phase = Phase::Frame;
    }

    #[inline(always)]
    fn frame_bit(&mut self, bit: bool) {
        let stuff = self.rx.expects_stuff_bit();
        let field = self.rx.field();
        let drove = self.drive.bit();
        // Receivers drive recessive except for the ACK: test the rare cases without branching
        // on the (data) bit first.
        let mismatch = if self.transmitting {
            drove != bit
        } else {
            !drove & bit
        };
        if mismatch {
            if self.transmitting {
                if self.rx.in_stuffed_region() {
                    let index = self.rx.index();
                    let extended = self.tx.as_ref().is_some_and(|tx| tx.frame().is_extended());
                    let arbitration_end = if extended { 32 } else { 12 };
                    if drove && (1..=arbitration_end).contains(&index) {
                        if stuff {
                            // A recessive stuff bit overwritten in arbitration: a stuff error
                            // that leaves TEC alone (facts §5.2 rule 3, exception 2).
                            return self.error(ErrorKind::Stuff, false);
                        }
                        self.lose_arbitration(index);
                    } else {
                        return self.error(ErrorKind::Bit, true);
                    }
                }
                // ACK slot overwritten = acknowledged; fixed-form bits: the receiver reports a
                // form error below.
            } else if !drove {
                // Our dominant ACK read back recessive.
                return self.error(ErrorKind::Bit, true);
            }
        }
        match self.rx.push(bit) {
            Step::Pending | Step::Frame(_) => {}
            Step::Error(error) => {
                let kind = match error.kind {
                    WireErrorKind::Stuff => ErrorKind::Stuff,
                    WireErrorKind::Form => ErrorKind::Form,
                    WireErrorKind::Crc { .. } => ErrorKind::Crc,
                };
                return self.error(kind, true);
            }
        }
        if stuff {
            return;
        }
        match field {
            Field::AckSlot => {
                if self.transmitting {
                    if bit && !self.config.self_test {
                        self.error(ErrorKind::Ack, true);
                    }
                } else if !drove {
                    // ACK sent successfully: a successful reception (rule 8).
                    self.counters.receive_ok();
                    self.update_state();
                }
            }
            Field::AckDelimiter => self.phase = Phase::Eof { n: 1 },
            _ => {}
        }
    }

    #[inline(never)]
    fn lose_arbitration(&mut self, bit: u32) {
        self.transmitting = false;
        if let Some(tx) = &self.tx {
            let frame = *tx.frame();
            self.events.push_back(Event::ArbitrationLost { frame, bit });
            if self.config.single_shot || self.abort_in_flight {
                self.drop_tx();
            }
        }
    }

    fn drop_tx(&mut self) {
        self.abort_in_flight = false;
        self.tx_is_best = false;
        if let Some(tx) = self.tx.take() {
            self.events.push_back(Event::Dropped(*tx.frame()));
        }
    }

    #[inline(never)]
    fn eof_bit(&mut self, n: u8, bit: bool) {
        if !bit {
            if n == 7 && !self.transmitting {
                // The frame is already valid for receivers: overload condition.
                return self.start_overload();
            }
            return self.error(ErrorKind::Form, true);
        }
        if n == 6
            && !self.transmitting
            && let Some(decoded) = self.rx.decoded()
        {
            self.events.push_back(Event::Received(decoded.frame));
        }
        if n < 7 {
            self.phase = Phase::Eof { n: n + 1 };
            return;
        }
        self.last_eof_bit_queued();
    }

    /// EOF bit 7 sampled recessive: the transmitter's frame is sent (facts §3), everybody
    /// enters intermission. Returns the transmitter's [`Event::Transmitted`] without queueing
    /// it (the whole-frame engine hands it on directly); what follows it (the frame received
    /// back with self-reception, a warning or state change) is queued.
    fn last_eof_bit(&mut self) -> Option<Event> {
        let mut sent = None;
        if self.transmitting
            && let Some(tx) = self.tx.take()
        {
            self.tx_is_best = false;
            let frame = *tx.frame();
            self.last_sent = Some(tx);
            self.abort_in_flight = false;
            // With TEC at 0 it stays 0, and the state, already derived from the counters,
            // stays the same: nothing to update (the usual case on a healthy bus).
            let counted = self.counters.tec != 0;
            self.counters.transmit_ok();
            sent = Some(Event::Transmitted(frame));
            if self.config.self_reception {
                self.events.push_back(Event::Received(frame));
            }
            if counted {
                self.update_state();
            }
        }
        self.end_of_frame();
        sent
    }

    /// [`Self::last_eof_bit`] with its event queued ahead of what follows it.
    fn last_eof_bit_queued(&mut self) {
        let at = self.events.len();
        if let Some(event) = self.last_eof_bit() {
            self.events.insert(at, event);
        }
    }

    /// Into intermission after EOF or a delimiter.
    #[inline]
    fn end_of_frame(&mut self) {
        self.was_transmitter = self.transmitting;
        self.transmitting = false;
        self.phase = Phase::Intermission { n: 1 };
    }

    #[inline(never)]
    fn intermission_bit(&mut self, n: u8, bit: bool) {
        if !bit {
            if n < 3 {
                return self.start_overload();
            }
            // Dominant at the 3rd intermission bit is SOF; a node with a frame ready joins
            // without sending SOF itself (facts §3).
            let transmit = !self.config.listen_only && !self.suspended() && self.load_tx();
            return self.start_frame(transmit);
        }
        self.phase = if n < 3 {
            Phase::Intermission { n: n + 1 }
        } else if self.suspended() {
            Phase::Suspend { n: 1 }
        } else {
            Phase::Idle
        };
    }

    /// An error-passive node that transmitted the last frame waits 8 more bits.
    fn suspended(&self) -> bool {
        self.was_transmitter && self.state() == ErrorState::Passive
    }

    #[inline(never)]
    fn start_overload(&mut self) {
        if !self.config.listen_only {
            self.events.push_back(Event::Overload);
        }
        self.was_transmitter |= self.transmitting;
        self.transmitting = false;
        self.phase = Phase::Flag {
            flag: Flag::Overload,
            n: 0,
            equal: 0,
            last: false,
        };
    }

    /// An error detected: count it, report it, start the error flag with the next bit.
    /// `count_tec`: false for the arbitration stuff-bit exception.
    #[inline(never)]
    fn error(&mut self, kind: ErrorKind, count_tec: bool) {
        self.last_error = match self.phase {
            Phase::Delimiter { overload, .. } => ErrorLocation::Delimiter { overload },
            Phase::Idle => ErrorLocation::Frame {
                field: Field::Sof,
                index: 0,
            },
            Phase::Eof { .. } => ErrorLocation::Frame {
                field: Field::Eof,
                index: self.rx.index(),
            },
            // The receiver has already moved past the ACK slot when the ACK error is seen.
            _ if kind == ErrorKind::Ack => ErrorLocation::Frame {
                field: Field::AckSlot,
                index: self.rx.index(),
            },
            _ => ErrorLocation::Frame {
                field: self.rx.field(),
                index: self.rx.index(),
            },
        };
        // The flag is chosen by the state before this error is counted.
        let flag = if self.config.listen_only || self.state() == ErrorState::Passive {
            Flag::PassiveError
        } else {
            Flag::ActiveError
        };
        if !self.config.listen_only {
            if self.transmitting {
                if kind == ErrorKind::Ack && flag == Flag::PassiveError {
                    self.ack_exception = true;
                } else if count_tec {
                    self.counters.add_tec(8);
                }
            } else {
                self.counters.add_rec(1);
            }
        }
        self.events.push_back(Event::Error {
            kind,
            transmitter: self.transmitting,
            bit: self.frame_bit,
            tec: self.counters.tec,
            rec: self.counters.rec,
        });
        if self.transmitting && (self.config.single_shot || self.abort_in_flight) {
            self.drop_tx();
        }
        self.phase = Phase::Flag {
            flag,
            n: 0,
            equal: 0,
            last: false,
        };
        self.update_state();
    }

    /// +8 on the counter of our role (transmitter: TEC, receiver: REC).
    fn add_eight(&mut self) {
        if self.config.listen_only {
            return;
        }
        if self.transmitting {
            self.counters.add_tec(8);
        } else {
            self.counters.add_rec(8);
        }
        self.update_state();
    }

    #[inline(never)]
    fn flag_bit(&mut self, flag: Flag, n: u8, equal: u8, last: bool, bit: bool) {
        if flag == Flag::PassiveError {
            if !bit && self.ack_exception {
                self.ack_exception = false;
                self.counters.add_tec(8);
                self.update_state();
                if self.phase
                    != (Phase::Flag {
                        flag,
                        n,
                        equal,
                        last,
                    })
                {
                    return; // went bus-off
                }
            }
            // Complete after 6 equal consecutive bits, whatever their level.
            let equal = if n > 0 && bit == last { equal + 1 } else { 1 };
            if equal == 6 {
                self.ack_exception = false;
                self.start_delimiter(false);
            } else {
                self.phase = Phase::Flag {
                    flag,
                    n: n.saturating_add(1),
                    equal,
                    last: bit,
                };
            }
            return;
        }
        if bit && !self.config.listen_only {
            // Our dominant flag bit read back recessive: bit error, +8 (rules 4 and 5), and a
            // new error flag.
            self.last_error = ErrorLocation::Flag {
                overload: flag == Flag::Overload,
            };
            self.add_eight();
            self.events.push_back(Event::Error {
                kind: ErrorKind::Bit,
                transmitter: self.transmitting,
                bit: self.frame_bit,
                tec: self.counters.tec,
                rec: self.counters.rec,
            });
            if matches!(self.phase, Phase::BusOff { .. }) {
                return;
            }
            let flag = if self.state() == ErrorState::Passive {
                Flag::PassiveError
            } else {
                Flag::ActiveError
            };
            self.phase = Phase::Flag {
                flag,
                n: 0,
                equal: 0,
                last: false,
            };
            return;
        }
        if n + 1 == 6 {
            self.start_delimiter(flag == Flag::Overload);
        } else {
            self.phase = Phase::Flag {
                flag,
                n: n + 1,
                equal,
                last,
            };
        }
    }

    fn start_delimiter(&mut self, overload: bool) {
        self.phase = Phase::Delimiter {
            overload,
            recessive: 0,
            dominant: 0,
        };
    }

    #[inline(never)]
    fn delimiter_bit(&mut self, overload: bool, recessive: u8, dominant: u32, bit: bool) {
        if recessive == 0 {
            if bit {
                self.phase = Phase::Delimiter {
                    overload,
                    recessive: 1,
                    dominant,
                };
                return;
            }
            let dominant = dominant.saturating_add(1);
            self.phase = Phase::Delimiter {
                overload,
                recessive,
                dominant,
            };
            // Rule 2: a receiver sampling dominant right after its error flag, +8.
            if dominant == 1 && !overload && !self.transmitting && !self.config.listen_only {
                self.counters.add_rec(8);
                self.update_state();
            }
            // Rule 6: 7 dominant bits after a flag are tolerated; the 8th and every 8 more
            // cost 8.
            if dominant.is_multiple_of(8) {
                self.add_eight();
            }
            return;
        }
        let k = recessive + 1;
        if !bit {
            if k == 8 {
                self.start_overload();
            } else {
                self.error(ErrorKind::Form, true);
            }
        } else if k == 8 {
            self.end_of_frame();
        } else {
            self.phase = Phase::Delimiter {
                overload,
                recessive: k,
                dominant,
            };
        }
    }

    #[inline(never)]
    fn bus_off_bit(&mut self, recessive: u8, sequences: u8, bit: bool) {
        if !self.recovering {
            return;
        }
        if !bit {
            self.phase = Phase::BusOff {
                recessive: 0,
                sequences,
            };
            return;
        }
        if recessive + 1 < INTEGRATION_BITS {
            self.phase = Phase::BusOff {
                recessive: recessive + 1,
                sequences,
            };
            return;
        }
        let sequences = sequences + 1;
        if sequences < RECOVERY_SEQUENCES {
            self.phase = Phase::BusOff {
                recessive: 0,
                sequences,
            };
            return;
        }
        self.recovering = false;
        self.counters.reset();
        self.update_state();
        self.phase = Phase::Idle;
    }

    fn update_state(&mut self) {
        let before = self.counters.state();
        let events = &mut self.events;
        self.counters.update(|event| events.push_back(event));
        if before != ErrorState::BusOff && self.counters.state() == ErrorState::BusOff {
            self.transmitting = false;
            self.ack_exception = false;
            self.recovering = self.config.auto_recover;
            self.phase = Phase::BusOff {
                recessive: 0,
                sequences: 0,
            };
        }
    }
}
