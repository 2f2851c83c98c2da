//! An SJA1000 with the CPU that services it through the host library's driver, as a
//! [`BusNode`] on the one bus engine: every client of `buslab bus serve` gets one, and scenario
//! files put them on the wire with `kind = "sja1000"` (`buslab-bench`'s node factory).
//!
//! The CPU keeps a software queue of frames ahead of the chip's single TX buffer, takes received
//! frames and error frames out for its host, and brings the chip back after bus-off as the
//! configuration says: the seed's way by default (reset mode cleared at once, the chip counting
//! its 128 × 11 recessive bits with TXERR falling), Linux's fast restart 100 ms later, or not at
//! all (the chip stays bus-off until it is initialised again, as a Lawicel CANUSB's).

use std::any::Any;
use std::collections::VecDeque;
use std::ops::Range;

use buslab_can::controller::{ErrorState, Event, FrameRole, FrameStart, QueueFull, WireFrame};
use buslab_can::node::{BusNode, Counting};
use buslab_can::{BitTime, Frame, Level, Nanos};
use buslab_sja1000::Sja1000;

use crate::{
    BusOffRecovery, ControllerSettings, ControllerState, DriverEvent, ErrorFrame, NodeCounters,
    Sja1000Config, Sja1000Driver, Timing, TxFailure,
};

/// Crystal of every client's SJA1000 (the seed's boards: 16 MHz, CAN clock 8 MHz).
pub const CRYSTAL_HZ: u32 = 16_000_000;
/// A node whose bit rate differs from the bus by more than this (per mille) cannot follow it.
/// CAN's oscillator tolerance is at most 1.58 %; 1 % is a round figure inside it.
pub const TOLERANCE_PERMILLE: u64 = 10;
/// With the fast restart, how long a bus-off node waits before its driver restarts it (Linux's
/// `restart-ms`).
pub const RESTART_AFTER: Nanos = Nanos::from_millis(100);
/// Per-node transmit queue length (frames waiting for the chip's single TX buffer).
pub const TX_QUEUE: usize = 64;
/// Recessive bit-times after which the bus is idle (CAN's bus-integration run: the ACK
/// delimiter, end of frame and intermission). A node at the wrong bit rate reads an idle bus
/// right: recessive is recessive at any rate.
pub const IDLE_BITS: u32 = 11;

/// A frame for a client and the bit-time at which its chip had it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Delivery {
    pub frame: Frame,
    pub time: BitTime,
}

/// An error frame for a client (SocketCAN's layout, as Linux's SJA1000 driver fills it) and
/// the bit-time.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TimedErrorFrame {
    pub frame: ErrorFrame,
    pub time: BitTime,
}

/// Something a client node's driver noticed that its operator should hear about.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum NodeNotice {
    /// A frame was given up (not by an abort).
    NotSent { frame: Frame, reason: TxFailure },
    /// The chip refused a frame handed to it (bus-off, reset mode).
    Refused { frame: Frame },
    /// The receive FIFO overflowed: frames were lost in the chip.
    Overrun,
    /// The error state changed; TXERR and RXERR as the chip shows them.
    StateChanged {
        from: ControllerState,
        to: ControllerState,
        txerr: u8,
        rxerr: u8,
    },
    /// The driver restarted the chip after bus-off (`Err`: the chip did not come back).
    Restarted(Result<(), String>),
    /// The driver cleared reset mode after bus-off: the chip counts its way back (128 × 11
    /// recessive bits, TXERR falling); `Err`: it did not leave reset mode.
    Recovering(Result<(), String>),
}

/// Messages that fill the 64-byte FIFO RAM whatever their length (the shortest takes 3 bytes):
/// an older one's bytes are all overwritten by these.
const MESSAGES_COVERING_FIFO: usize = 64 / 3 + 1;

/// An SJA1000 and the CPU running its driver, with the host's queues.
#[derive(Debug)]
pub struct Sja1000Node {
    driver: Sja1000Driver<Sja1000>,
    config: Sja1000Config,
    bus_bitrate: u32,
    /// The node's own bit rate when it differs from the bus's.
    mismatch: Option<u32>,
    rng: u64,
    /// Recessive bit-times in a row on the bus, up to [`IDLE_BITS`] (what a node at the wrong
    /// rate can still tell).
    recessive_run: u32,
    /// Frames the client sent, not yet handed to the chip.
    tx: VecDeque<Frame>,
    /// Frames for the client.
    rx: Vec<Delivery>,
    /// Error frames for the client (collected only when `error_frames` is on).
    errors: Vec<TimedErrorFrame>,
    /// Also deliver the node's own frames once sent.
    pub receive_own: bool,
    pub error_frames: bool,
    pub counters: NodeCounters,
    /// Frames the client handed over since it joined (sent + failed reach it when all are done).
    submitted: u64,
    restart_at: Option<BitTime>,
    /// Bus-off was seen: the counted recovery starts after this service.
    recovering: bool,
    /// Events for the bus engine besides the chip's own.
    engine_events: VecDeque<Event>,
    /// The driver's events while the interrupt is serviced (kept to spare an allocation).
    driver_events: Vec<DriverEvent>,
    notices: Vec<(BitTime, NodeNotice)>,
    /// The bit-time of the last sample (for what happens between samples).
    now: BitTime,
    /// The bit-time of the SOF of the frame the engine applies whole.
    frame_sof: BitTime,
    /// Frames received whole that only counted: the chip's controller has not seen them yet.
    counted: Counted,
}

/// Frames a receiving node took by counting (see [`Sja1000Node::counts`]): the client got
/// them and the counters moved on; the chip's protocol controller and FIFO RAM wait for them
/// until someone looks at the chip ([`Sja1000Node::settle`]). A good reception leaves a
/// receiver's controller as the frame's end alone says, so only the last frame is kept, and
/// the one under way with the bits it has had; of the messages for the FIFO RAM only the last
/// [`MESSAGES_COVERING_FIFO`] (older ones only move RBSA on).
///
/// Meanwhile the chip answers every question asked without settling it (its output, whether
/// it is ready for a frame, its counters and error state, its queue) as the settled chip
/// would: between frames a receiver's controller waits for SOF, driving recessive, either way.
/// Inside a frame only the queue and the counters are asked (the [`BusNode::advance_frame`]
/// contract), and whether the node is quiet, which the frame under way answers.
#[derive(Debug, Default)]
struct Counted {
    /// The last counted frame that ended.
    ended: Option<WireFrame>,
    /// The counted frame under way and the wire bits it has had.
    under_way: Option<(WireFrame, u32)>,
    /// Accepted counted frames whose messages are not in the FIFO RAM yet, oldest first.
    unwritten: VecDeque<Frame>,
    /// Frames counted since the node was made.
    frames: u64,
}

impl Sja1000Node {
    /// A fresh SJA1000 initialised by the driver: PeliCAN, accept all, the bus's bit rate.
    pub fn new(bus_bitrate: u32, error_frames: bool) -> Result<Self, String> {
        Self::with_config(node_config(bus_bitrate), bus_bitrate, error_frames)
    }

    /// A fresh SJA1000 initialised by the driver with `config`, on a bus at `bus_bitrate`.
    pub fn with_config(
        config: Sja1000Config,
        bus_bitrate: u32,
        error_frames: bool,
    ) -> Result<Self, String> {
        let mut driver = Sja1000Driver::new(Sja1000::new());
        driver.init(&config).map_err(|e| e.to_string())?;
        Ok(Self {
            driver,
            config,
            bus_bitrate,
            mismatch: None,
            rng: 0x9E37_79B9_7F4A_7C15,
            recessive_run: 0,
            tx: VecDeque::new(),
            rx: Vec::new(),
            errors: Vec::new(),
            receive_own: false,
            error_frames,
            counters: NodeCounters::default(),
            submitted: 0,
            restart_at: None,
            recovering: false,
            engine_events: VecDeque::new(),
            driver_events: Vec::new(),
            notices: Vec::new(),
            now: BitTime::ZERO,
            frame_sof: BitTime::ZERO,
            counted: Counted::default(),
        })
    }

    /// Hands a client's frame to the node; `Err` when its queue is full (the client waits).
    pub fn submit(&mut self, frame: Frame) -> Result<(), Frame> {
        if self.tx.len() >= TX_QUEUE {
            return Err(frame);
        }
        self.settle();
        self.tx.push_back(frame);
        self.submitted += 1;
        self.feed();
        Ok(())
    }

    /// Gives up the frame in the chip's buffer (CMR.AT: one on the wire finishes this attempt
    /// and is not retried) and every frame queued behind it; they count as failed.
    pub fn abort(&mut self) {
        self.settle();
        self.counters.tx_failed += self.tx.len() as u64;
        self.tx.clear();
        self.driver.abort();
    }

    /// Room in the transmit queue.
    pub fn tx_room(&self) -> usize {
        TX_QUEUE - self.tx.len()
    }

    /// Frames handed over since joining, and how many of them were sent or given up.
    pub fn submitted(&self) -> u64 {
        self.submitted
    }
    pub fn done(&self) -> u64 {
        self.counters.sent + self.counters.tx_failed
    }

    /// Frames for the client since the last call.
    pub fn take_deliveries(&mut self) -> std::vec::Drain<'_, Delivery> {
        self.rx.drain(..)
    }

    /// Error frames for the client since the last call.
    pub fn take_error_frames(&mut self) -> std::vec::Drain<'_, TimedErrorFrame> {
        self.errors.drain(..)
    }

    /// What the driver noticed since the last call, with the bit-time.
    pub fn take_notices(&mut self) -> Vec<(BitTime, NodeNotice)> {
        std::mem::take(&mut self.notices)
    }

    pub fn set_error_frames(&mut self, on: bool) {
        self.error_frames = on;
        if !on {
            self.errors.clear();
        }
    }

    /// The node's bit rate from its BTR0/BTR1 and crystal.
    pub fn bitrate(&self) -> u32 {
        self.chip().bit_timing().bitrate(self.config.crystal_hz / 2)
    }

    /// The configuration its driver programmed.
    pub fn config(&self) -> &Sja1000Config {
        &self.config
    }

    /// BTR0 and BTR1.
    pub fn btr(&self) -> (u8, u8) {
        self.chip().bit_timing().registers()
    }

    /// The node's bit rate when it cannot follow the bus.
    pub fn mismatch(&self) -> Option<u32> {
        self.mismatch
    }

    /// How the chip comes back from its next bus-off (one under way goes on as it began).
    pub fn set_bus_off_recovery(&mut self, recovery: BusOffRecovery) {
        self.config.bus_off_recovery = recovery;
    }

    pub fn bus_off_recovery(&self) -> BusOffRecovery {
        self.config.bus_off_recovery
    }

    pub fn state(&self) -> ControllerState {
        self.driver.state()
    }

    /// The driver and through it the chip, brought up to date with the frames the node only
    /// counted.
    pub fn driver(&mut self) -> &mut Sja1000Driver<Sja1000> {
        self.settle();
        &mut self.driver
    }

    fn chip(&self) -> &Sja1000 {
        self.driver.chip()
    }

    /// Frames the node took by only counting them (received whole while its chip and CPU had
    /// nothing else to do), for benchmarks and tests: they changed nothing else it shows.
    pub fn frames_counted(&self) -> u64 {
        self.counted.frames
    }

    /// Frames and error frames received for the client and not taken yet.
    pub fn deliveries_waiting(&self) -> usize {
        self.rx.len() + self.errors.len()
    }

    /// Frames waiting: the client's queue and the chip's buffer.
    pub fn tx_queued(&self) -> usize {
        self.tx.len() + self.driver.tx_pending() as usize
    }

    /// Reprograms the bit timing through the driver. A timing that does not give the bus's bit
    /// rate (within [`TOLERANCE_PERMILLE`]) leaves the node unable to communicate: it samples
    /// the bus at the wrong instants and reads noise (see docs/bus.md).
    pub fn set_btr(&mut self, btr0: u8, btr1: u8) -> Result<(), String> {
        let mut config = self.config.clone();
        config.timing = Timing::Registers { btr0, btr1 };
        self.reprogram(config)
    }

    /// Reprograms the chip through the driver with the parts `settings` gives, the others as
    /// they are (the host's controller configuration: mode, timing, filter, OCR, CLKOUT). A
    /// configuration the chip refuses leaves it as it was.
    pub fn configure(&mut self, settings: &ControllerSettings) -> Result<(), String> {
        let config = self.config.with_settings(settings);
        config.validate().map_err(|e| e.to_string())?;
        self.reprogram(config)
    }

    fn reprogram(&mut self, config: Sja1000Config) -> Result<(), String> {
        self.settle();
        if let Err(e) = self.driver.init(&config) {
            // Back to what worked: the node stays on the bus as it was.
            let _ = self.driver.init(&self.config);
            return Err(e.to_string());
        }
        self.config = config;
        self.restart_at = None;
        let rate = self.bitrate();
        let bus = self.bus_bitrate;
        let diff = (rate as i64 - bus as i64).unsigned_abs();
        self.mismatch = (diff * 1000 > bus as u64 * TOLERANCE_PERMILLE).then_some(rate);
        self.feed();
        Ok(())
    }

    /// The interrupt handler: the driver's poll, then the next frame into the TX buffer.
    #[inline(never)]
    fn service(&mut self, now: BitTime) {
        let mut events = std::mem::take(&mut self.driver_events);
        self.driver.poll_into(&mut events);
        for event in events.drain(..) {
            if self.error_frames {
                let registers = self.driver.error_registers();
                if let Some(frame) = crate::error_frame::from_driver_event(&event, registers) {
                    self.errors.push(TimedErrorFrame { frame, time: now });
                }
            }
            match event {
                DriverEvent::Received(frame) => {
                    self.counters.received += 1;
                    self.rx.push(Delivery { frame, time: now });
                }
                DriverEvent::TxDone(frame) => {
                    self.counters.sent += 1;
                    if self.receive_own {
                        self.rx.push(Delivery { frame, time: now });
                    }
                }
                DriverEvent::TxFailed { frame, reason } => {
                    self.counters.tx_failed += 1;
                    // The chip's controller drops what bus-off aborted without a word: the
                    // engine (and a scenario's file sender waiting for the frame) hears it here.
                    if reason == TxFailure::BusOff {
                        self.engine_events.push_back(Event::Dropped(frame));
                    }
                    if reason != TxFailure::Aborted {
                        self.notices
                            .push((now, NodeNotice::NotSent { frame, reason }));
                    }
                }
                DriverEvent::DataOverrun => {
                    self.counters.overruns += 1;
                    self.notices.push((now, NodeNotice::Overrun));
                }
                DriverEvent::StateChanged { from, to } => {
                    if to == ControllerState::BusOff {
                        self.counters.bus_off += 1;
                        match self.config.bus_off_recovery {
                            BusOffRecovery::Fast => {
                                self.restart_at =
                                    Some(now + RESTART_AFTER.bit_times_at(self.bus_bitrate));
                            }
                            BusOffRecovery::Counted => self.recovering = true,
                            // Bus-off is reset mode (the chip set MOD.RM): nothing clears it.
                            BusOffRecovery::Manual => {}
                        }
                    } else if from == ControllerState::BusOff
                        && self.config.bus_off_recovery == BusOffRecovery::Counted
                        && self.error_frames
                    {
                        // Back on the bus (SocketCAN's "restarted").
                        self.errors.push(TimedErrorFrame {
                            frame: ErrorFrame::restarted(),
                            time: now,
                        });
                    }
                    let chip = self.driver.chip();
                    let (txerr, rxerr) = (chip.peek(15), chip.peek(14));
                    self.notices.push((
                        now,
                        NodeNotice::StateChanged {
                            from,
                            to,
                            txerr,
                            rxerr,
                        },
                    ));
                }
                DriverEvent::BusError(_) => self.counters.bus_errors += 1,
                DriverEvent::ArbitrationLost(_) => self.counters.arbitration_lost += 1,
                DriverEvent::WakeUp => {}
            }
        }
        self.driver_events = events;
        // The seed's recovery starts at once: the chip itself waits for the bus to be free.
        if std::mem::take(&mut self.recovering) {
            let result = self.driver.recover().map_err(|e| e.to_string());
            self.notices.push((now, NodeNotice::Recovering(result)));
        }
        self.feed();
    }

    /// Hands the next waiting frame to a free TX buffer; frames wait while the chip is
    /// bus-off. A refused frame (reset mode) cannot be fixed by retrying now: it is counted as
    /// failed.
    fn feed(&mut self) {
        if self.driver.tx_pending()
            || self.restart_at.is_some()
            || self.driver.state() == ControllerState::BusOff
        {
            return;
        }
        if let Some(frame) = self.tx.pop_front()
            && self.driver.send(&frame).is_err()
        {
            self.counters.tx_failed += 1;
            self.notices.push((self.now, NodeNotice::Refused { frame }));
        }
    }

    /// Restarts the chip after bus-off once [`RESTART_AFTER`] have passed.
    #[cold]
    #[inline(never)]
    fn restart(&mut self, now: BitTime) {
        self.restart_at = None;
        let result = self.driver.restart().map_err(|e| e.to_string());
        if self.error_frames {
            self.errors.push(TimedErrorFrame {
                frame: ErrorFrame::restarted(),
                time: now,
            });
        }
        self.notices.push((now, NodeNotice::Restarted(result)));
        // The driver's state follows at the next poll.
        self.service(now);
    }
}

impl Sja1000Node {
    /// What the CPU does after the chip saw the bus up to bit-time `now`: it services the
    /// interrupt, and restarts the chip when the time has come.
    #[inline]
    fn after_bits(&mut self, now: BitTime) {
        if self.driver.chip().interrupt() {
            self.service(now);
        }
        if self.restart_at.is_some_and(|t| now >= t) {
            self.restart(now);
        }
    }

    /// Whether the frame starting now, received whole, may only be counted: the chip would take
    /// it and its CPU service it with nothing else to do (see
    /// [`Sja1000::counts_receptions`]); the CPU has no frame to send, no restart due and no
    /// event waiting for the engine, and the node follows the bus.
    #[inline]
    fn counts(&self) -> bool {
        self.tx.is_empty()
            && !self.driver.tx_pending()
            && self.mismatch.is_none()
            && self.restart_at.is_none()
            && self.engine_events.is_empty()
            && self
                .driver
                .config()
                .is_some_and(|config| config.mode == buslab_sja1000::CanMode::Peli)
            && self.chip().counts_receptions()
    }

    /// Wire bits `bits` of a counted frame: at EOF bit 6 what the chip, its CPU and the engine
    /// would have of it (the frame reported, and if the filter takes it, the client's delivery
    /// and counter), without stepping the controller or writing the FIFO RAM.
    fn count_bits(&mut self, frame: &WireFrame, bits: Range<u32>) {
        let now = self.frame_sof + BitTime::from(bits.end) - BitTime::ONE;
        self.now = now;
        if bits.contains(&frame.eof_bit(6)) {
            let event = self.count_reception(frame);
            self.engine_events.push_back(event);
        }
        if bits.end >= frame.total() {
            self.counted.ended = self.counted.under_way.take().map(|(frame, _)| frame);
        } else if let Some((_, done)) = &mut self.counted.under_way {
            *done = bits.end;
        }
    }

    /// EOF bit 6 of a counted frame: if the filter takes it, the client's delivery (at that
    /// bit) and counter; the event to report.
    fn count_reception(&mut self, frame: &WireFrame) -> Event {
        let received = *frame.frame();
        if self.chip().accepts(&received) {
            self.counters.received += 1;
            self.rx.push(Delivery {
                frame: received,
                time: self.frame_sof + BitTime::from(frame.eof_bit(6)),
            });
            self.counted.unwritten.push_back(received);
            if self.counted.unwritten.len() > MESSAGES_COVERING_FIFO
                && let Some(old) = self.counted.unwritten.pop_front()
            {
                self.driver.registers().pass_over_released(&old);
            }
        }
        Event::Received(received)
    }

    /// Brings the chip's controller up to the frames the node only counted (see [`Counted`]).
    #[inline]
    fn settle(&mut self) {
        if self.counted.ended.is_some() || self.counted.under_way.is_some() {
            self.settle_counted();
        }
    }

    #[cold]
    #[inline(never)]
    fn settle_counted(&mut self) {
        let chip = self.driver.registers();
        for frame in self.counted.unwritten.drain(..) {
            chip.store_released(&frame);
        }
        if let Some(frame) = self.counted.ended.take() {
            chip.settle_received(&frame, 0..frame.total());
        }
        if let Some((frame, done)) = self.counted.under_way.take() {
            chip.settle_received(&frame, 0..done);
        }
    }

    /// Wire bits `bits` of a whole frame through the chip, then the CPU at the last of them.
    fn advance_chip(&mut self, frame: &WireFrame, role: FrameRole, bits: Range<u32>) {
        let now = self.frame_sof + BitTime::from(bits.end) - BitTime::ONE;
        self.now = now;
        self.driver.registers().advance_frame(frame, role, bits);
        self.after_bits(now);
    }
}

impl BusNode for Sja1000Node {
    fn output(&self) -> Level {
        self.chip().output()
    }

    fn sample(&mut self, now: BitTime, bus: Level) {
        self.settle();
        self.now = now;
        let idle = self.recessive_run >= IDLE_BITS;
        self.recessive_run = match bus {
            Level::Recessive => (self.recessive_run + 1).min(IDLE_BITS),
            Level::Dominant => 0,
        };
        let seen = if self.mismatch.is_some() && !(idle && bus == Level::Recessive) {
            // Sampling a frame at the wrong instants: what it reads has nothing to do with
            // the bits. An idle bus reads recessive at any rate.
            self.rng ^= self.rng << 13;
            self.rng ^= self.rng >> 7;
            self.rng ^= self.rng << 17;
            Level::from_bit(self.rng & 1 == 1)
        } else {
            bus
        };
        self.driver.registers().sample(seen);
        self.after_bits(now);
    }

    fn frame_starts_at(&mut self, now: BitTime) {
        self.frame_sof = now;
    }

    /// Ready when the chip is (see [`Sja1000::frame_start`]) and the CPU has nothing of its
    /// own to do during the frame: the node follows the bus (no bit-rate mismatch), no restart
    /// is due, and the interrupt line is quiet.
    fn frame_start(&self) -> FrameStart<'_> {
        if self.mismatch.is_some() || self.restart_at.is_some() || self.chip().interrupt() {
            return FrameStart::NotReady;
        }
        self.chip().frame_start()
    }

    fn advance_frame(&mut self, frame: &WireFrame, role: FrameRole, mut bits: Range<u32>) {
        if bits.start == 0 && role == FrameRole::Receiver && self.counts() {
            // A new counted frame: the one before it (if counted) needs no settling.
            self.counted.under_way = Some((frame.clone(), 0));
            self.counted.frames += 1;
        }
        if self.counted.under_way.is_some() {
            return self.count_bits(frame, bits);
        }
        self.settle();
        // Events (and so interrupts) come at the last bit of a range. An interrupt the CPU left
        // asserted (a FIFO with more messages than one service reads) is serviced again at
        // every bit, as sampling would: those bits go one at a time.
        while !bits.is_empty() {
            let end = if self.chip().interrupt() {
                bits.start + 1
            } else {
                bits.end
            };
            self.advance_chip(frame, role, bits.start..end);
            bits.start = end;
        }
    }

    /// A counted reception (see `Counted`) reports the frame and delivers it at EOF bit 6,
    /// and changes neither the counters nor the queue: all of it at once, as
    /// [`Self::advance_frame`] over `0..total` would count it (nothing else waits: see
    /// `counts`).
    fn count_frame(&mut self, frame: &WireFrame, role: FrameRole) -> Counting {
        if role != FrameRole::Receiver || !self.counts() {
            return Counting::Declined;
        }
        // The frame counted before this one (if any) needs no settling.
        self.counted.frames += 1;
        self.now = self.frame_sof + BitTime::from(frame.total()) - BitTime::ONE;
        let event = self.count_reception(frame);
        self.counted.under_way = None;
        self.counted.ended = Some(frame.clone());
        Counting::Counted(Some(event))
    }

    fn poll_event(&mut self) -> Option<Event> {
        self.driver
            .registers()
            .poll_bus_event()
            .or_else(|| self.engine_events.pop_front())
    }

    fn tec(&self) -> u16 {
        BusNode::tec(self.chip())
    }
    fn rec(&self) -> u16 {
        BusNode::rec(self.chip())
    }
    fn state(&self) -> ErrorState {
        self.chip().error_state()
    }

    fn quiet_until(&self) -> Option<BitTime> {
        let quiet = self.counted.under_way.is_none()
            && self.mismatch.is_none()
            && self.tx.is_empty()
            && !self.driver.tx_pending()
            && self.chip().is_quiescent();
        // A restart after bus-off is the driver's timer.
        quiet.then_some(self.restart_at.unwrap_or(BitTime::MAX))
    }

    fn enqueue(&mut self, frame: Frame) -> Result<(), QueueFull> {
        self.submit(frame)
            .map_err(|_| QueueFull { capacity: TX_QUEUE })
    }

    fn pending(&self) -> usize {
        self.tx_queued()
    }

    fn as_any(&self) -> &dyn Any {
        self
    }
    fn as_any_mut(&mut self) -> &mut dyn Any {
        self
    }
}

/// The configuration every client's chip gets: PeliCAN, accept all, the bus's bit rate, all
/// interrupts (the CPU services the chip on its interrupt line), the seed's bus-off recovery.
pub fn node_config(bitrate: u32) -> Sja1000Config {
    Sja1000Config {
        timing: Timing::Bitrate {
            bitrate,
            sample_point_permille: None,
        },
        crystal_hz: CRYSTAL_HZ,
        ..Sja1000Config::default()
    }
}
