//! The P82C150 as a bit-level node: calibration, the register logic, the watchdog.
//!
//! States (data sheet p.17–20, facts sheet §1.2):
//! - **asleep** after reset (bus mode 3): nothing until a dominant bit wakes it;
//! - **unsynced**: its RC clock knows no bit length yet; the first `1010` on the wire (two
//!   falling edges one bit apart) gives the rough bit length;
//! - **roughly calibrated**: it follows frames from the bus idle on, executes the commands
//!   addressed to it, but neither acknowledges nor transmits; a frame counts once its CRC
//!   delimiter arrives with a matching CRC (it does not wait for an ACK nobody may give: the
//!   seed's host aborts these unacknowledged calibration frames, and the SLIOs still
//!   calibrate on them);
//! - **calibrated** after one more valid frame and then a valid calibration frame: it sends its
//!   sign-on (DATA_INPUT, with RSTD set), acknowledges, answers every command (a 3-byte data
//!   frame or a remote frame to its identifiers; a data frame of another length is ignored),
//!   and reports input edges.
//!
//! A calibrated SLIO that sees no calibration frame for 8192 bit-times, or goes bus-off,
//! changes its bus mode: registers cleared (outputs float), RSTD = 1, EW = 0, BM + 1, and it
//! must be calibrated again; the ID latch is kept.

use std::any::Any;
use std::collections::VecDeque;
use std::ops::Range;

use buslab_can::controller::{
    Controller, ControllerConfig, ErrorState, Event, FrameRole, FrameStart, QueueFull, WireFrame,
};
use buslab_can::node::BusNode;
use buslab_can::wire::{Receiver, Step};
use buslab_can::{BitTime, Frame, Level, Nanos};

use crate::ids::{CALIBRATION_ID, Direction, SlioId};
use crate::registers::{CONVERT, MUX_MASK, MUX_SHIFT, Register, Reply, Request, Status, TEN_BITS};

/// The bit rates the RC oscillator can follow (the seed: "entre 20kbits/s et 125kbits/s").
pub const MIN_BITRATE: u32 = 20_000;
pub const MAX_BITRATE: u32 = 125_000;
/// Bit-times without a calibration frame after which a calibrated SLIO changes its bus mode.
pub const WATCHDOG: BitTime = BitTime::new(8192);
/// Recessive bits that tell a listener the bus is idle.
const IDLE_BITS: u8 = 11;
/// The most bit-times a frame applied whole takes, intermission included.
pub use buslab_can::wire::{LONGEST_FRAME, LONGEST_FRAME_BITS};

/// The bus level at wire bit `bit` of a whole frame (recessive in its intermission).
pub(crate) fn frame_level(frame: &WireFrame, bit: u32) -> Level {
    if bit < frame.len() {
        frame.bus().level(bit as usize)
    } else {
        Level::Recessive
    }
}

/// Why a SLIO cannot be put on a bus.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum SlioError {
    #[error(
        "bit rate {0} bit/s is outside the P82C150's range {MIN_BITRATE}..={MAX_BITRATE} bit/s (its RC oscillator cannot follow it): it cannot take part in this bus"
    )]
    Bitrate(u32),
}

/// Where the SLIO is in its calibration.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Calibration {
    /// Bus mode 3 (after reset): woken by a dominant bit.
    Asleep,
    /// Awake, waiting for `1010` to measure a bit.
    Unsynced,
    /// Roughly calibrated: executes commands, does not acknowledge or transmit.
    Rough,
    /// Calibrated: acknowledges, answers, reports.
    Calibrated,
}

/// Why a calibrated SLIO changed its bus mode.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ModeChangeCause {
    /// 8192 bit-times without a calibration frame.
    Watchdog,
    /// Its transmit error counter passed 255.
    BusOff,
}

/// Something a SLIO did that its board or an observer may act on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SlioNotice {
    /// Its calibration state changed.
    Calibration(Calibration),
    /// It changed its bus mode: registers cleared, outputs floating, calibration lost.
    BusModeChange(ModeChangeCause),
    /// A register took a new value (from the host, a conversion or a mode change).
    Register { register: Register, value: u16 },
}

/// What a SLIO reads on its analog inputs: the multiplexer input (0..=7) at a time, as a
/// 10-bit code (0..=1023 for 0..5 V). (`Any`: the board that connected them changes them.)
pub trait AnalogInputs: Send + Any {
    fn code(&mut self, input: u8, t: Nanos) -> u16;
}

/// No analog input connected: every conversion reads 0.
#[derive(Clone, Copy, Debug, Default)]
pub struct Unconnected;

impl AnalogInputs for Unconnected {
    fn code(&mut self, _input: u8, _t: Nanos) -> u16 {
        0
    }
}

/// How a SLIO listens before it may take part (no ACK, no transmission).
#[derive(Clone, Debug)]
struct Listener {
    /// Recessive bits in a row (saturating at [`IDLE_BITS`]).
    recessive: u8,
    /// The frame being followed, from its SOF.
    rx: Option<Receiver>,
    /// The last four levels, oldest in bit 3 (1 = recessive), for the `1010` of unsynced.
    history: u8,
    /// The bit-time of the last level seen.
    last: BitTime,
}

impl Listener {
    fn new() -> Self {
        Self {
            recessive: 0,
            rx: None,
            history: 0xF,
            last: BitTime::ZERO,
        }
    }

    /// Whether it waits on an idle bus (nothing changes while the bus stays recessive).
    fn is_idle(&self) -> bool {
        self.rx.is_none() && self.recessive >= IDLE_BITS
    }
}

/// One P82C150.
pub struct Slio {
    id: SlioId,
    bitrate: u32,
    calibration: Calibration,
    listener: Listener,
    /// Since the last `Rough`: a valid frame was seen (the calibration frame must follow).
    seen_valid: bool,
    /// The protocol controller, present once calibrated.
    controller: Option<Controller>,
    regs: [u16; 9],
    status: Status,
    /// The levels the board puts on the pins that are inputs.
    inputs: u16,
    analog: Box<dyn AnalogInputs>,
    last_calibration: BitTime,
    now: BitTime,
    /// The bit-time of the SOF of the frame the engine applies whole.
    frame_sof: BitTime,
    /// That frame goes through [`BusNode::sample`] bit by bit: the SLIO was not calibrated at
    /// its SOF (it only listens, and may calibrate in the middle of the frame).
    frame_by_bits: bool,
    events: VecDeque<Event>,
    notices: VecDeque<(BitTime, SlioNotice)>,
}

impl core::fmt::Debug for Slio {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("Slio")
            .field("id", &self.id)
            .field("calibration", &self.calibration)
            .field("regs", &self.regs)
            .field("status", &self.status)
            .finish()
    }
}

impl Slio {
    /// A SLIO just after reset, its ID pins latched as `id`, on a bus at `bitrate`.
    pub fn new(id: SlioId, bitrate: u32) -> Result<Self, SlioError> {
        if !(MIN_BITRATE..=MAX_BITRATE).contains(&bitrate) {
            return Err(SlioError::Bitrate(bitrate));
        }
        Ok(Self {
            id,
            bitrate,
            calibration: Calibration::Asleep,
            listener: Listener::new(),
            seen_valid: false,
            controller: None,
            regs: [0; 9],
            // After reset: RSTD = 1, EW = 1, BM = 0 (data sheet table 14).
            status: Status {
                reset_detected: true,
                ew: true,
                bus_mode: 0,
            },
            inputs: 0,
            analog: Box::new(Unconnected),
            last_calibration: BitTime::ZERO,
            now: BitTime::ZERO,
            frame_sof: BitTime::ZERO,
            frame_by_bits: false,
            events: VecDeque::new(),
            notices: VecDeque::new(),
        })
    }

    /// Connects analog inputs (the board's potentiometer, a source).
    pub fn with_analog(mut self, analog: Box<dyn AnalogInputs>) -> Self {
        self.analog = analog;
        self
    }

    /// The analog inputs connected (to turn the board's potentiometer).
    pub fn analog_mut(&mut self) -> &mut dyn AnalogInputs {
        &mut *self.analog
    }

    pub fn id(&self) -> SlioId {
        self.id
    }

    pub fn bitrate(&self) -> u32 {
        self.bitrate
    }

    pub fn calibration(&self) -> Calibration {
        self.calibration
    }

    pub fn status(&self) -> Status {
        self.status
    }

    /// The protocol controller, present while calibrated (for viewers and tests).
    pub fn controller(&self) -> Option<&Controller> {
        self.controller.as_ref()
    }

    pub fn register(&self, register: Register) -> u16 {
        if register == Register::DataInput {
            return self.data_input();
        }
        self.regs[register.index()]
    }

    /// The levels of all 16 pins as the DATA_INPUT register shows them: outputs read back what
    /// they drive, inputs what the board puts on them.
    pub fn data_input(&self) -> u16 {
        let oe = self.regs[Register::OutputEnable.index()];
        (self.driven() & oe) | (self.inputs & !oe)
    }

    /// The levels driven on output pins (only where OUTPUT_ENABLE is set; the others float).
    /// The DPM pins (P10 for DPM1, P4 for DPM2) read high while their duty is at least half.
    pub fn driven(&self) -> u16 {
        let oe = self.regs[Register::OutputEnable.index()];
        let mut levels = self.regs[Register::DataOutput.index()];
        for (pin, dpm) in [(10, Register::Dpm1), (4, Register::Dpm2)] {
            let high = self.regs[dpm.index()] >= 512;
            levels = (levels & !(1 << pin)) | (high as u16) << pin;
        }
        levels & oe
    }

    /// The pins that drive a level (OUTPUT_ENABLE).
    pub fn output_enable(&self) -> u16 {
        self.regs[Register::OutputEnable.index()]
    }

    /// A DPM output's mean level as a fraction of the supply (duty / 1024), `None` while its
    /// pin floats.
    pub fn dpm_fraction(&self, dpm: Register) -> Option<f64> {
        let pin = match dpm {
            Register::Dpm1 => 10,
            Register::Dpm2 => 4,
            _ => return None,
        };
        (self.output_enable() & (1 << pin) != 0)
            .then(|| f64::from(self.regs[dpm.index()] & TEN_BITS) / 1024.0)
    }

    /// What happened since the last call, with the bit-time.
    pub fn take_notices(&mut self) -> impl Iterator<Item = (BitTime, SlioNotice)> + '_ {
        self.notices.drain(..)
    }

    /// The board changes the levels on the pins at bit-time `now` (only input pins matter). A
    /// calibrated SLIO reports edges its edge registers ask for with a DATA_INPUT frame.
    pub fn set_inputs(&mut self, now: BitTime, levels: u16) {
        let before = self.data_input();
        self.inputs = levels;
        let after = self.data_input();
        let inputs = !self.output_enable();
        let rising = !before & after & inputs & self.regs[Register::PositiveEdge.index()];
        let falling = before & !after & inputs & self.regs[Register::NegativeEdge.index()];
        if (rising | falling) != 0 && self.calibration == Calibration::Calibrated {
            self.now = self.now.max(now);
            self.send(Register::DataInput);
        }
    }

    fn notice(&mut self, notice: SlioNotice) {
        self.notices.push_back((self.now, notice));
    }

    fn set_calibration(&mut self, to: Calibration) {
        if self.calibration != to {
            self.calibration = to;
            self.notice(SlioNotice::Calibration(to));
        }
    }

    fn set_register(&mut self, register: Register, value: u16) {
        self.regs[register.index()] = value;
        self.notice(SlioNotice::Register { register, value });
    }

    /// Carries out a request from the host; returns the register to answer with.
    fn execute(&mut self, request: Request) -> Register {
        match request {
            Request::Write {
                register: Register::AnalogConfig,
                value,
            } if value & CONVERT != 0 => {
                // The exception to "every write is echoed": a conversion request is answered
                // with its result, the ADC register.
                self.set_register(Register::AnalogConfig, value & !CONVERT);
                self.convert();
                Register::Adc
            }
            Request::Write { register, value } => {
                match register {
                    Register::Dpm1 | Register::Dpm2 => {
                        self.set_register(register, value & TEN_BITS)
                    }
                    // Read-only: nothing stored ([`Request::parse`] makes these reads).
                    Register::DataInput | Register::Adc => {
                        return self.execute(Request::Read { register });
                    }
                    _ => self.set_register(register, value),
                }
                register
            }
            Request::Read {
                register: Register::Adc,
            } => {
                self.convert();
                Register::Adc
            }
            Request::Read { register } => register,
        }
    }

    /// A conversion of the selected multiplexer input into the ADC register.
    fn convert(&mut self) {
        let input = (self.regs[Register::AnalogConfig.index()] >> MUX_SHIFT & MUX_MASK) as u8;
        let t = self.now.at_bitrate(self.bitrate);
        let code = self.analog.code(input, t).min(TEN_BITS);
        self.set_register(Register::Adc, code);
    }

    /// Queues a frame with a register's content (when calibrated).
    fn send(&mut self, register: Register) {
        let reply = Reply {
            status: self.status,
            register,
            value: self.register(register),
        };
        let frame = Frame::data(self.id.reply_id(), &reply.encode()).expect("3 bytes");
        if let Some(c) = &mut self.controller {
            // A full queue (a host that never lets it send) loses the oldest news only.
            let _ = c.enqueue(frame);
        }
    }

    /// A frame that reached this SLIO (valid up to its CRC while listening; fully received
    /// once calibrated): what it does with it.
    fn on_frame(&mut self, frame: &Frame) {
        let id = frame.id();
        if id.is_extended() {
            return; // CAN 2.0B passive
        }
        if id.as_raw() == u32::from(CALIBRATION_ID) {
            self.last_calibration = self.now;
            if self.calibration == Calibration::Rough {
                if self.seen_valid {
                    self.calibrate();
                    return;
                }
                self.seen_valid = true;
            }
            return;
        }
        if self.calibration == Calibration::Rough {
            self.seen_valid = true;
        }
        let ours = match SlioId::from_id(id) {
            Some((slio, dir)) if slio == self.id => dir,
            _ => return,
        };
        let request = match (ours, frame.is_remote()) {
            (Direction::ToSlio, remote) => Request::parse(remote, frame.payload()),
            // A remote frame for the SLIO's own answer identifier asks for its inputs too.
            (Direction::FromSlio, true) => Request::parse(true, &[]),
            (Direction::FromSlio, false) => return,
        };
        // A data frame of another length than 3 (or for no register) is no command: neither
        // executed nor answered (docs/decisions.md, "SLIO frames have 3 bytes"). Its
        // controller has acknowledged it all the same, as every CAN receiver does.
        let Ok(request) = request else { return };
        let answer = self.execute(request);
        if self.calibration == Calibration::Calibrated {
            self.send(answer);
        }
    }

    /// Enters the calibrated state: a controller takes part from the next bus idle on, and
    /// the sign-on goes out first.
    fn calibrate(&mut self) {
        self.controller = Some(Controller::new(ControllerConfig {
            // A bus-off SLIO changes its bus mode instead of recovering.
            auto_recover: false,
            tx_queue_capacity: 16,
            ..ControllerConfig::default()
        }));
        self.last_calibration = self.now;
        self.set_calibration(Calibration::Calibrated);
        self.send(Register::DataInput);
        // RSTD is reported once, in the sign-on.
        self.status.reset_detected = false;
    }

    /// The network watchdog or bus-off: the bus mode changes.
    fn change_bus_mode(&mut self, cause: ModeChangeCause) {
        self.controller = None;
        for register in Register::all() {
            if register != Register::DataInput {
                self.set_register(register, 0);
            }
        }
        self.status = Status {
            reset_detected: true,
            ew: false,
            bus_mode: (self.status.bus_mode + 1) & 3,
        };
        self.listener = Listener::new();
        self.listener.last = self.now;
        self.seen_valid = false;
        self.notice(SlioNotice::BusModeChange(cause));
        let next = if self.status.bus_mode == 3 {
            Calibration::Asleep
        } else {
            Calibration::Unsynced
        };
        self.set_calibration(next);
    }

    /// One bit while not calibrated: wake up, measure, follow frames.
    fn listen(&mut self, now: BitTime, bus: Level) {
        let bit = bus.bit();
        let l = &mut self.listener;
        if now > l.last + BitTime::ONE {
            // Skipped idle bus: recessive all along.
            l.history = 0xF;
            l.recessive = IDLE_BITS;
        }
        l.last = now;
        l.history = (l.history << 1 | bit as u8) & 0xF;
        match self.calibration {
            Calibration::Asleep => {
                if !bit {
                    self.set_calibration(Calibration::Unsynced);
                }
                return;
            }
            Calibration::Unsynced => {
                if l.history == 0b1010 {
                    l.recessive = 0;
                    self.set_calibration(Calibration::Rough);
                }
                return;
            }
            Calibration::Rough | Calibration::Calibrated => {}
        }
        let frame = match &mut l.rx {
            None => {
                if bit {
                    l.recessive = l.recessive.saturating_add(1).min(IDLE_BITS);
                } else if l.recessive >= IDLE_BITS {
                    let mut rx = Receiver::new();
                    rx.push(false);
                    l.rx = Some(rx);
                } else {
                    l.recessive = 0;
                }
                return;
            }
            Some(rx) => {
                let step = rx.push(bit);
                let valid = rx.decoded_before_ack().map(|d| d.frame);
                match (step, valid) {
                    (Step::Error(_), _) => {
                        l.rx = None;
                        l.recessive = 0;
                        return;
                    }
                    (_, Some(frame)) => {
                        l.rx = None;
                        l.recessive = 0;
                        frame
                    }
                    _ => return,
                }
            }
        };
        self.on_frame(&frame);
    }
}

impl Slio {
    /// What the SLIO does after its controller moved on to bit-time `now`: the frames it
    /// received, bus-off, the watchdog.
    fn after_controller(&mut self, now: BitTime) {
        let Some(controller) = &mut self.controller else {
            return;
        };
        let mut received = Vec::new();
        let mut bus_off = false;
        while let Some(event) = controller.poll_event() {
            match &event {
                Event::Received(frame) => received.push(*frame),
                Event::StateChanged {
                    to: ErrorState::BusOff,
                    ..
                } => bus_off = true,
                _ => {}
            }
            self.events.push_back(event);
        }
        for frame in received {
            self.on_frame(&frame);
        }
        if bus_off {
            self.change_bus_mode(ModeChangeCause::BusOff);
        } else if now >= self.last_calibration + WATCHDOG {
            self.change_bus_mode(ModeChangeCause::Watchdog);
        }
    }

    /// The bit-time of the SOF of the frame being applied whole.
    pub(crate) fn frame_sof(&self) -> BitTime {
        self.frame_sof
    }

    /// Whether a frame starting now goes through bit by bit (see `frame_by_bits`).
    pub(crate) fn listens(&self) -> bool {
        self.controller.is_none()
    }
}

impl BusNode for Slio {
    fn output(&self) -> Level {
        self.controller
            .as_ref()
            .map_or(Level::Recessive, Controller::output)
    }

    fn sample(&mut self, now: BitTime, bus: Level) {
        self.now = now;
        let Some(controller) = &mut self.controller else {
            self.listen(now, bus);
            return;
        };
        controller.sample(bus);
        self.after_controller(now);
    }

    fn frame_starts_at(&mut self, now: BitTime) {
        self.frame_sof = now;
    }

    /// A SLIO that only listens (not calibrated) drives nothing: it takes any frame, bit by
    /// bit through its listener. A calibrated one takes a frame whole when its controller is
    /// lined up at a frame start and its watchdog cannot run out before the frame ends.
    fn frame_start(&self) -> FrameStart<'_> {
        match &self.controller {
            None => FrameStart::Ready {
                sends: None,
                acks: false,
            },
            Some(_) if self.frame_sof + LONGEST_FRAME > self.last_calibration + WATCHDOG => {
                FrameStart::NotReady
            }
            Some(c) => c.frame_start(),
        }
    }

    fn advance_frame(&mut self, frame: &WireFrame, role: FrameRole, bits: Range<u32>) {
        if bits.is_empty() {
            return;
        }
        if bits.start == 0 {
            self.frame_by_bits = self.listens();
        }
        if self.frame_by_bits {
            for bit in bits {
                self.sample(self.frame_sof + BitTime::from(bit), frame_level(frame, bit));
            }
            return;
        }
        let Some(controller) = &mut self.controller else {
            return;
        };
        let now = self.frame_sof + BitTime::from(bits.end) - BitTime::ONE;
        self.now = now;
        controller.advance_frame(frame, role, bits);
        self.after_controller(now);
    }

    fn poll_event(&mut self) -> Option<Event> {
        self.events.pop_front()
    }

    fn tec(&self) -> u16 {
        self.controller.as_ref().map_or(0, Controller::tec)
    }

    fn rec(&self) -> u16 {
        self.controller.as_ref().map_or(0, Controller::rec)
    }

    fn state(&self) -> ErrorState {
        self.controller
            .as_ref()
            .map_or(ErrorState::Active, Controller::state)
    }

    fn quiet_until(&self) -> Option<BitTime> {
        match (&self.controller, self.calibration) {
            (Some(c), _) => (c.is_bus_idle() && c.pending() == 0 && self.events.is_empty())
                .then_some(self.last_calibration + WATCHDOG),
            (None, Calibration::Rough) => self.listener.is_idle().then_some(BitTime::MAX),
            (None, _) => Some(BitTime::MAX),
        }
    }

    /// A SLIO has no CPU to queue frames: it sends only what its register logic decides.
    fn enqueue(&mut self, _frame: Frame) -> Result<(), QueueFull> {
        Err(QueueFull { capacity: 0 })
    }

    fn pending(&self) -> usize {
        self.controller.as_ref().map_or(0, Controller::pending)
    }

    fn as_any(&self) -> &dyn Any {
        self
    }
    fn as_any_mut(&mut self) -> &mut dyn Any {
        self
    }
}
