//! The PowerPC node as a [`BusNode`]: its SJA1000 on the wire, MoniCAN as the CPU's program
//! driving the chip through its registers (the host library's driver, PeliCAN as the seed's
//! `sja_init_pelican`), and a serial port that is bytes in, bytes out.
//!
//! A remote frame with ID 0 and DLC 0 hands the CPU over to the CAN loader (seed §4.3.3.3,
//! [`buslab_loader::Loader`]): it answers, takes the S-record file, and the node writes the
//! program into its memory image ([`PpcNode::memory`], kept by the host in a state file through
//! [`Persistent`]). With a host that keeps it ([`PpcNode::set_durable`]) the loader's report
//! waits until the image is saved ([`PpcNode::persisted`]): what the terminal says was loaded
//! survives a kill. Then the loader jumps to the program's entry point: the program runs on
//! the PPC403 core ([`crate::program`]), owns the SJA1000 and the terminal, until it exits,
//! crashes (a report on the terminal until a key) or the board is reset; MoniCAN then starts
//! again. A file without an entry point is loaded, not run: MoniCAN shows the report.

use std::any::Any;
use std::collections::VecDeque;

use buslab_can::controller::{ErrorState, Event, QueueFull};
use buslab_can::node::BusNode;
use buslab_can::{BitTime, Frame, Level, Nanos};
use buslab_device::{Changes, Persistent, ReplayError};
use buslab_loader::report::report;
use buslab_loader::{Loader, MemoryImage, MemoryMap, Outcome};
use buslab_monican::screen::Screen;
use buslab_monican::{Config, ConfigError, MoniCan, Transmit};
use buslab_ppc403::Registers;
use buslab_sja1000::{BitTiming, Sja1000, TimingError};
use buslab_sja1000_driver::{
    ControllerState, DriverError, DriverEvent, Sja1000Config, Sja1000Driver, Timing, TxFailure,
};
use tracing::{debug, info, warn};

use crate::program::Running;
use crate::sampling::Sampling;

mod firmware;

pub use crate::clocks::CRYSTAL_HZ;
/// Keys waiting for the CPU at most; beyond, a key is lost as on an overrun UART (counted).
pub const MAX_KEYS: usize = 256;
/// A frame that stays in the TX buffer this many bit-times (nobody acknowledges it: the
/// PowerPC alone on the bus) is aborted, so the periodic calibration never waits behind it.
pub const GIVE_UP: BitTime = buslab_slio::master::ANSWER_WITHIN;
/// While the bus is idle and the program's SJA1000 has nothing to do, the core runs this many
/// bit-times at once (the bus engine may skip them): a frame the program asks for in that time
/// starts up to this late (0.5 ms at 125 kbit/s), as with an interrupt's latency. It keeps a
/// running program from making the whole bus step bit by bit.
pub const IDLE_BATCH: BitTime = BitTime::new(64);
/// How long a bus-off SJA1000 waits before MoniCAN restarts it.
pub const RESTART_AFTER: Nanos = Nanos::from_millis(100);

/// Why the PowerPC node cannot be built.
#[derive(Debug, thiserror::Error)]
pub enum PpcError {
    #[error(transparent)]
    Config(#[from] ConfigError),
    #[error(
        "the PowerPC node's SJA1000 cannot run at {bitrate} bit/s from its {CRYSTAL_HZ} Hz crystal: {source}"
    )]
    Timing { bitrate: u32, source: TimingError },
    #[error("the PowerPC node's SJA1000 did not initialise: {0}")]
    Driver(#[from] DriverError),
}

/// The bit timing closest to the SLIOs' own (10 time quanta, sample point at 60 %, SJW 4:
/// seed §2.1, facts §1.2). A 16 MHz crystal gives it exactly where 8 MHz / (10 × bit rate) is
/// a whole prescaler (20, 40, 50, 80, 100 kbit/s...); elsewhere (125 kbit/s) Linux's algorithm
/// picks the timing with the sample point nearest below 60 %.
pub fn slio_timing(bitrate: u32) -> Result<BitTiming, TimingError> {
    let clock = CRYSTAL_HZ / 2;
    if let Some(quanta) = bitrate.checked_mul(10).filter(|&q| q > 0)
        && clock.is_multiple_of(quanta)
    {
        let brp = clock / quanta;
        if let Ok(timing) = BitTiming::new(brp, 5, 4, 4, false) {
            return Ok(timing);
        }
    }
    BitTiming::for_bitrate(clock, bitrate, Some(600))
}

/// The SJA1000 set-up of the seed's `sja_init_pelican`: PeliCAN, every frame accepted (single
/// filter), the SLIOs' bit timing. Two differences, both without effect on the bus model: the
/// interrupt enables stay on (the CPU services the chip when its interrupt line rises rather
/// than reading SR every bit-time; the seed polls with IER = 0), and OCR is the library's
/// normal output mode (the seed's 0xDB selects OCMODE = 11, clock output).
pub fn chip_config(bitrate: u32) -> Result<Sja1000Config, PpcError> {
    let timing = slio_timing(bitrate).map_err(|source| PpcError::Timing { bitrate, source })?;
    let (btr0, btr1) = timing.registers();
    Ok(Sja1000Config {
        timing: Timing::Registers { btr0, btr1 },
        crystal_hz: CRYSTAL_HZ,
        ..Sja1000Config::default()
    })
}

/// The frame MoniCAN gave the SJA1000.
#[derive(Clone, Copy, Debug)]
struct InFlight {
    frame: Frame,
    /// Aborted once it starts (the calibration frames, as the seed's `calibration_slio`).
    single_shot: bool,
    /// CMR.AT was written.
    abort_requested: bool,
    /// The bit-time it was handed to the chip.
    since: BitTime,
}

/// The header of the memory image's S-record file.
pub const IMAGE_HEADER: &str = "buslab PowerPC node memory";
/// The title of the loader's screen and report page.
pub const LOADER_TITLE: &str = "*** CAN loader (loadcan) ***";
/// The report's last line when the loader jumps to the program.
pub const RUNS: &str =
    "The loader jumps to the entry point: the program has the terminal and the SJA1000.";
/// The report's last line when the file had no entry point.
pub const NOT_RUN: &str = "No entry point (S7/S8/S9): the program was loaded, not run.";
/// The title of the page MoniCAN shows after a program ended.
pub const PROGRAM_TITLE: &str = "*** the program ended ***";
/// The crash report's last line.
pub const PRESS_ANY_KEY: &str = "press any key to return to MoniCAN";
/// Clears the terminal (the firmware's report before the program's own output).
const CLEAR: &[u8] = b"\x1b[0m\x1b[H\x1b[2J";
/// The report's line when the image was saved before the report was shown.
pub const SAVED: &str = "Saved in the node's memory image (its state file) before this report.";

/// What the CPU runs.
#[derive(Debug)]
enum Program {
    MoniCan,
    /// The loader, with its own screen.
    Loader {
        loader: Loader,
        screen: Screen,
    },
    /// A program was loaded; its report waits until the memory image is saved.
    Saving {
        outcome: Outcome,
        generation: u64,
        screen: Screen,
    },
    /// The loaded program runs on the core; `start` is the bit-time its cycle 0 began.
    Running {
        run: Box<Running>,
        start: Option<BitTime>,
    },
    /// The firmware caught an exception: the report is on the terminal until a key.
    Stopped {
        reason: String,
        pc: u32,
        report: Vec<u8>,
    },
}

/// What the node is doing, for its host (the control socket).
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Activity {
    MoniCan,
    /// The loader receives a file: bytes so far.
    Loading {
        received: usize,
    },
    /// A program was loaded and the memory image is being saved.
    Saving,
    /// The loaded program runs; the PC at the end of its last slice.
    Running {
        pc: u32,
    },
    /// The program stopped: why, and the instruction's address.
    Stopped {
        reason: String,
        pc: u32,
    },
    /// The program exited; MoniCAN shows its status until a key.
    Exited {
        status: i32,
    },
}

/// A finished transfer, for the host.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct LoadRecord {
    /// Transfers finished since the node started (1 for the first).
    pub number: u64,
    /// Whether the program was loaded (else nothing was written).
    pub loaded: bool,
    /// The report's lines as the terminal shows them.
    pub report: Vec<String>,
    /// The ranges this program wrote.
    pub ranges: Vec<(u32, u32)>,
    pub entry: Option<u32>,
}

/// The PowerPC node: MoniCAN, the loader, or a loaded program on the core.
pub struct PpcNode {
    driver: Sja1000Driver<Sja1000>,
    app: MoniCan,
    config: Config,
    program: Program,
    map: MemoryMap,
    memory: MemoryImage,
    /// Bumped at each load that wrote memory.
    generation: u64,
    /// The generation the host reported saved.
    saved: u64,
    /// The generation the last [`Persistent::take_changes`] reported.
    changes_taken: u64,
    /// A host saves the memory image: reports wait for it.
    durable: bool,
    last_load: Option<LoadRecord>,
    loads: u64,
    bitrate: u32,
    keys: VecDeque<u8>,
    keys_dropped: u64,
    in_flight: Option<InFlight>,
    /// A frame taken from MoniCAN that waits for the chip (a calibration frame waits until the
    /// previous transmission is over, SR.TS = 0, as the seed's `calibration_slio` does).
    next: Option<Transmit>,
    restart_at: Option<BitTime>,
    now: BitTime,
    chip_config: Sja1000Config,
    /// Bytes for the terminal before the current program's own (the end of a program's
    /// output, the firmware's reports).
    pending_output: Vec<u8>,
    /// The registers of the program running or of the last one.
    last_registers: Option<Registers>,
    /// The status of the program that exited, while MoniCAN shows it.
    exited: Option<i32>,
    /// What the chip reads from the wire while a program owns it (noise at a wrong bit rate).
    sampling: Sampling,
}

impl core::fmt::Debug for PpcNode {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("PpcNode")
            .field("bitrate", &self.bitrate)
            .field("state", &self.driver.state())
            .field("keys", &self.keys.len())
            .field("in_flight", &self.in_flight)
            .finish()
    }
}

impl PpcNode {
    /// A PowerPC node on a bus at `config.bitrate` whose clock starts at bit-time 0: MoniCAN
    /// starts (screen init), the SJA1000 is initialised, and the calibration frames are queued
    /// (§4.3.2.1).
    pub fn new(config: Config) -> Result<Self, PpcError> {
        let bitrate = config.bitrate;
        let app = MoniCan::new(config.clone(), Nanos::ZERO)?;
        let mut driver = Sja1000Driver::new(Sja1000::new());
        let chip = chip_config(bitrate)?;
        driver.init(&chip)?;
        Ok(Self {
            driver,
            app,
            config,
            program: Program::MoniCan,
            map: MemoryMap::ppc403(),
            memory: MemoryImage::new(),
            generation: 0,
            saved: 0,
            changes_taken: 0,
            durable: false,
            last_load: None,
            loads: 0,
            bitrate,
            keys: VecDeque::new(),
            keys_dropped: 0,
            in_flight: None,
            next: None,
            restart_at: None,
            now: BitTime::ZERO,
            chip_config: chip,
            pending_output: Vec::new(),
            last_registers: None,
            exited: None,
            sampling: Sampling::default(),
        })
    }

    /// A byte the terminal sent; MoniCAN (or a running program's serial port) takes it at the
    /// node's next bit-time.
    pub fn key(&mut self, byte: u8) {
        if self.keys.len() >= MAX_KEYS {
            self.keys_dropped += 1;
            if self.keys_dropped == 1 {
                warn!(
                    "the PowerPC node's serial port overran: keys beyond {MAX_KEYS} waiting are lost"
                );
            }
            return;
        }
        self.keys.push_back(byte);
    }

    /// Keys lost because too many were waiting.
    pub fn keys_dropped(&self) -> u64 {
        self.keys_dropped
    }

    /// The bytes for the terminal since the last call: MoniCAN's or the loader's VT100 screen
    /// (diffed now: call it when the serial line has room, not at every bit-time), or what a
    /// running program's serial port sent.
    pub fn take_screen(&mut self) -> Vec<u8> {
        let mut out = std::mem::take(&mut self.pending_output);
        match &mut self.program {
            Program::MoniCan => out.extend(self.app.take_screen()),
            Program::Running { run, .. } => out.extend(run.board_mut().spu.take_output()),
            Program::Stopped { .. } => {}
            Program::Loader { loader, screen } => {
                draw_loader(screen, loader.received(), false);
                screen.render(&mut out);
            }
            Program::Saving {
                outcome, screen, ..
            } => {
                draw_loader(screen, outcome.text_bytes(), true);
                screen.render(&mut out);
            }
        }
        out
    }

    /// The next [`take_screen`](Self::take_screen) redraws the whole screen (a terminal that
    /// connected late).
    pub fn redraw(&mut self) {
        match &mut self.program {
            Program::MoniCan => self.app.redraw(),
            Program::Loader { screen, .. } | Program::Saving { screen, .. } => screen.redraw(),
            // The program's output is a stream, not a screen: nothing to draw again.
            Program::Running { .. } => {}
            Program::Stopped { report, .. } => {
                self.pending_output = [CLEAR, report.as_slice()].concat();
            }
        }
    }

    /// What the CPU is doing.
    pub fn activity(&self) -> Activity {
        match &self.program {
            Program::MoniCan => match self.exited {
                Some(status) if self.app.showing_page() => Activity::Exited { status },
                _ => Activity::MoniCan,
            },
            Program::Loader { loader, .. } => Activity::Loading {
                received: loader.received(),
            },
            Program::Saving { .. } => Activity::Saving,
            Program::Running { run, .. } => Activity::Running { pc: run.pc() },
            Program::Stopped { reason, pc, .. } => Activity::Stopped {
                reason: reason.clone(),
                pc: *pc,
            },
        }
    }

    /// The node's memory (what loads wrote).
    pub fn memory(&self) -> &MemoryImage {
        &self.memory
    }

    /// The memory map loads are checked against.
    pub fn memory_map(&self) -> &MemoryMap {
        &self.map
    }

    /// Replaces the memory with what the host's state file holds (at start).
    pub fn restore_memory(&mut self, image: MemoryImage) {
        self.memory = image;
    }

    /// A host keeps the memory image in a file: the loader's report waits for
    /// [`persisted`](Self::persisted).
    pub fn set_durable(&mut self, durable: bool) {
        self.durable = durable;
    }

    /// The host saved the memory image of `generation` ([`Persistent::state_generation`]).
    pub fn persisted(&mut self, generation: u64) {
        self.saved = self.saved.max(generation);
        if let Program::Saving {
            generation: waits, ..
        } = self.program
            && self.saved >= waits
        {
            let Program::Saving { outcome, .. } =
                std::mem::replace(&mut self.program, Program::MoniCan)
            else {
                return;
            };
            let ns = self.now.at_bitrate(self.bitrate);
            self.resume(ns, outcome, true);
        }
    }

    /// The last transfer the loader finished.
    pub fn last_load(&self) -> Option<&LoadRecord> {
        self.last_load.as_ref()
    }

    /// MoniCAN, to look at (what the screen shows of each SLIO, the inventory).
    pub fn app(&self) -> &MoniCan {
        &self.app
    }

    pub fn app_mut(&mut self) -> &mut MoniCan {
        &mut self.app
    }

    /// The SJA1000 (registers, counters).
    pub fn chip(&self) -> &Sja1000 {
        self.driver.chip()
    }

    pub fn driver(&mut self) -> &mut Sja1000Driver<Sja1000> {
        &mut self.driver
    }

    pub fn bitrate(&self) -> u32 {
        self.bitrate
    }

    fn service(&mut self, now: BitTime) {
        let ns = now.at_bitrate(self.bitrate);
        for event in self.driver.poll() {
            match event {
                DriverEvent::Received(frame) => self.received(ns, &frame),
                DriverEvent::TxDone(frame) => {
                    debug!("PowerPC sent {frame}");
                    self.in_flight = None;
                }
                DriverEvent::TxFailed { frame, reason } => {
                    let expected = self.in_flight.is_some_and(|t| t.single_shot)
                        && matches!(reason, TxFailure::Aborted | TxFailure::SingleShot);
                    if expected {
                        debug!("PowerPC: {frame} not acknowledged, aborted");
                    } else {
                        warn!("the PowerPC node gave up {frame}: {reason}");
                    }
                    self.in_flight = None;
                }
                DriverEvent::DataOverrun => {
                    warn!("the PowerPC node's SJA1000 lost received frames (RX FIFO overrun)");
                }
                DriverEvent::StateChanged { to, .. } => {
                    if to == ControllerState::BusOff {
                        warn!(
                            "the PowerPC node's SJA1000 went bus-off; restarting it in {} ms",
                            RESTART_AFTER.as_duration().as_millis()
                        );
                        self.in_flight = None;
                        self.next = None;
                        self.restart_at = Some(now + RESTART_AFTER.bit_times_at(self.bitrate));
                    }
                }
                DriverEvent::BusError(_)
                | DriverEvent::ArbitrationLost(_)
                | DriverEvent::WakeUp => {}
            }
        }
    }

    /// The seed's `calibration_slio` aborts a calibration frame once it is on the wire
    /// (CMR.AT after SR.TS): one attempt, no retry while nobody acknowledges. Any other frame
    /// still unsent after [`GIVE_UP`] is aborted too.
    fn watch_transmission(&mut self, now: BitTime) {
        let Some(tx) = self.in_flight else { return };
        if tx.abort_requested {
            return;
        }
        let abort = if tx.single_shot {
            self.driver.status().transmitting()
        } else {
            now >= tx.since + GIVE_UP
        };
        if abort {
            if !tx.single_shot {
                warn!(
                    "the PowerPC node aborts {} after {GIVE_UP} bit-times unsent (nobody acknowledges it)",
                    tx.frame
                );
            }
            self.driver.abort();
            self.in_flight = Some(InFlight {
                abort_requested: true,
                ..tx
            });
        }
    }

    /// The next frame of MoniCAN's into a free TX buffer.
    fn feed(&mut self, now: BitTime) {
        if self.in_flight.is_some() || self.restart_at.is_some() || self.driver.tx_pending() {
            return;
        }
        let ns = now.at_bitrate(self.bitrate);
        let Some(t) = self.next.take().or_else(|| self.poll_program(ns)) else {
            return;
        };
        if t.single_shot && self.driver.status().transmitting() {
            // The error frame of the previous attempt is still ours on the wire: a request now
            // would be aborted before it ever started.
            self.next = Some(t);
            return;
        }
        match self.driver.send(&t.frame) {
            Ok(()) => {
                self.in_flight = Some(InFlight {
                    frame: t.frame,
                    single_shot: t.single_shot,
                    abort_requested: false,
                    since: now,
                });
            }
            Err(e) => warn!("the PowerPC node cannot send {}: {e}", t.frame),
        }
    }
}

/// The program's side: frames, timers, the hand-over to the loader and back.
impl PpcNode {
    /// A frame for the CPU at `ns`.
    fn received(&mut self, ns: Nanos, frame: &Frame) {
        match &mut self.program {
            Program::MoniCan => {
                if buslab_loader::loader::is_request(frame) {
                    self.enter_loader(ns);
                } else {
                    self.app.handle_frame(ns, frame);
                }
            }
            Program::Loader { loader, .. } => {
                loader.handle_frame(ns, frame);
                self.check_outcome(ns);
            }
            // Nothing runs but the save: the frame is lost to the CPU. (A program reads the
            // chip itself; a stopped one reads nothing.)
            Program::Saving { .. } | Program::Running { .. } | Program::Stopped { .. } => {}
        }
    }

    /// MoniCAN branches to the loader (§4.3.3.3): what MoniCAN still had to send is dropped.
    fn enter_loader(&mut self, ns: Nanos) {
        info!("the PowerPC node hands over to the CAN loader");
        self.next = None;
        self.program = Program::Loader {
            loader: Loader::new(self.map.clone(), ns),
            screen: Screen::new(),
        };
    }

    fn check_outcome(&mut self, ns: Nanos) {
        let Program::Loader { loader, .. } = &mut self.program else {
            return;
        };
        let Some(outcome) = loader.take_outcome() else {
            return;
        };
        if let Outcome::Loaded { program, .. } = &outcome {
            self.memory.load(program);
            self.generation += 1;
            if self.durable && self.saved < self.generation {
                let screen = match std::mem::replace(&mut self.program, Program::MoniCan) {
                    Program::Loader { screen, .. } => screen,
                    _ => Screen::new(),
                };
                self.program = Program::Saving {
                    outcome,
                    generation: self.generation,
                    screen,
                };
                return;
            }
        }
        self.program = Program::MoniCan;
        self.resume(ns, outcome, false);
    }

    /// The transfer is over: MoniCAN starts again (as the loaded program would) with the
    /// report on its screen.
    fn resume(&mut self, ns: Nanos, outcome: Outcome, saved: bool) {
        let mut lines = report(&outcome);
        let entry = match &outcome {
            Outcome::Loaded { program, .. } => program.start,
            _ => None,
        };
        if outcome.is_loaded() {
            if saved {
                lines.push(SAVED.to_string());
            }
            lines.push(if entry.is_some() { RUNS } else { NOT_RUN }.to_string());
        }
        self.loads += 1;
        let (ranges, entry) = match &outcome {
            Outcome::Loaded { program, .. } => (program.ranges(), program.start),
            _ => (Vec::new(), None),
        };
        info!(
            "the CAN loader finished: {}",
            lines.first().map_or("", String::as_str)
        );
        self.last_load = Some(LoadRecord {
            number: self.loads,
            loaded: outcome.is_loaded(),
            report: lines.clone(),
            ranges,
            entry,
        });
        if let Some(entry) = entry {
            self.start_program(entry, &lines);
            return;
        }
        match MoniCan::new(self.config.clone(), ns) {
            Ok(app) => self.app = app,
            Err(e) => warn!("MoniCAN cannot start again: {e}"),
        }
        self.app.show_page(LOADER_TITLE, lines);
    }

    /// The program's next frame, handed to the chip's driver at `ns`.
    fn poll_program(&mut self, ns: Nanos) -> Option<Transmit> {
        match &mut self.program {
            Program::MoniCan => self.app.poll_transmit(ns),
            Program::Loader { loader, .. } => loader.poll_transmit().map(|frame| Transmit {
                frame,
                single_shot: false,
            }),
            Program::Saving { .. } | Program::Running { .. } | Program::Stopped { .. } => None,
        }
    }

    fn program_queued(&self) -> usize {
        match &self.program {
            Program::MoniCan => self.app.queued(),
            // The answer, when it waits: the loader keeps at most one frame.
            Program::Loader { .. }
            | Program::Saving { .. }
            | Program::Running { .. }
            | Program::Stopped { .. } => 0,
        }
    }

    fn program_deadline(&self) -> Option<Nanos> {
        match &self.program {
            Program::MoniCan => self.app.next_deadline(),
            Program::Loader { loader, .. } => loader.next_deadline(),
            Program::Saving { .. } | Program::Running { .. } | Program::Stopped { .. } => None,
        }
    }

    fn program_timeout(&mut self, ns: Nanos) {
        match &mut self.program {
            Program::MoniCan => self.app.handle_timeout(ns),
            Program::Loader { loader, .. } => {
                loader.handle_timeout(ns);
                self.check_outcome(ns);
            }
            Program::Saving { .. } | Program::Running { .. } | Program::Stopped { .. } => {}
        }
    }
}

/// The loader's screen: what it waits for and how much arrived.
fn draw_loader(screen: &mut Screen, received: usize, saving: bool) {
    screen.blank();
    screen.put_line(1, LOADER_TITLE);
    screen.put_line(
        3,
        "MoniCAN handed over to the loader (remote frame, ID 000).",
    );
    screen.put_line(
        4,
        "Receiving the S-record file on ID 000, 8 bytes a frame; a shorter frame ends it.",
    );
    screen.put_line(6, &format!("received: {received} bytes"));
    if saving {
        screen.put_line(8, "Program loaded; saving the memory image...");
    }
    screen.put_line(24, "(the loader does not read the keyboard)");
    screen.set_cursor(24, 1);
}

/// The memory image is what outlives the node (its state file: an S-record file).
impl Persistent for PpcNode {
    type Snapshot = MemoryImage;

    fn state_generation(&self) -> u64 {
        self.generation
    }

    fn snapshot(&self) -> MemoryImage {
        self.memory.clone()
    }

    fn file_bytes(snapshot: &MemoryImage) -> Vec<u8> {
        snapshot.to_srec(IMAGE_HEADER)
    }

    /// A load changes up to megabytes at once: the image is saved whole, never journalled.
    fn take_changes(&mut self) -> Changes {
        if self.generation == self.changes_taken {
            return Changes::Records(Vec::new());
        }
        self.changes_taken = self.generation;
        Changes::Snapshot
    }

    fn replay(_: &mut MemoryImage, record: &[u8]) -> Result<(), ReplayError> {
        Err(ReplayError::new(
            record,
            "the PowerPC node writes no journal records (its memory image is saved whole)",
        ))
    }
}

impl BusNode for PpcNode {
    fn output(&self) -> Level {
        self.driver.chip().output()
    }

    fn sample(&mut self, now: BitTime, bus: Level) {
        self.now = now;
        let chip = self.driver.registers();
        let seen = match self.program {
            Program::Running { .. } | Program::Stopped { .. } => {
                self.sampling.level(chip, self.bitrate, now, bus)
            }
            _ => bus,
        };
        chip.sample(seen);
        let interrupt = chip.interrupt();
        let ns = now.at_bitrate(self.bitrate);
        match self.program {
            Program::Running { .. } => return self.run_program(now),
            Program::Stopped { .. } if !self.keys.is_empty() => {
                // The key that returns to MoniCAN is the report's, not MoniCAN's.
                self.keys.pop_front();
                info!("the PowerPC node returns to MoniCAN after the program stopped");
                self.firmware(ns);
            }
            Program::Stopped { .. } => return,
            _ => {}
        }
        while let Some(key) = self.keys.pop_front() {
            // The loader does not read the keyboard.
            if let Program::MoniCan = self.program {
                self.app.handle_key(ns, key);
            }
        }
        if self.exited.is_some() && !self.app.showing_page() {
            self.exited = None;
        }
        if interrupt {
            self.service(now);
        }
        self.watch_transmission(now);
        if self.program_deadline().is_some_and(|t| t <= ns) {
            self.program_timeout(ns);
        }
        if self.restart_at.is_some_and(|t| now >= t) {
            self.restart_at = None;
            if let Err(e) = self.driver.restart() {
                warn!("the PowerPC node's SJA1000 did not restart: {e}");
            }
            self.service(now);
        }
        self.feed(now);
    }

    fn poll_event(&mut self) -> Option<Event> {
        self.driver.registers().poll_bus_event()
    }

    fn tec(&self) -> u16 {
        BusNode::tec(self.driver.chip())
    }

    fn rec(&self) -> u16 {
        BusNode::rec(self.driver.chip())
    }

    fn state(&self) -> ErrorState {
        self.driver.chip().error_state()
    }

    fn quiet_until(&self) -> Option<BitTime> {
        match &self.program {
            // The core runs in batches while nothing happens on the bus or at the chip.
            Program::Running { .. } => {
                let chip = self.driver.chip();
                let idle = self.keys.is_empty()
                    && chip.is_quiescent()
                    && !chip.interrupt()
                    && !self.sampling.mistimed();
                return idle.then_some(self.now + IDLE_BATCH);
            }
            // The firmware waits for a key; the chip goes on as the program left it.
            Program::Stopped { .. } => {
                let idle = self.keys.is_empty()
                    && self.driver.chip().is_quiescent()
                    && !self.sampling.mistimed();
                return idle.then_some(BitTime::MAX);
            }
            _ => {}
        }
        if !self.keys.is_empty()
            || self.in_flight.is_some()
            || self.next.is_some()
            || self.driver.tx_pending()
        {
            return None;
        }
        if let Some(t) = self.restart_at {
            return Some(t);
        }
        if self.program_queued() > 0 || !self.driver.chip().is_quiescent() {
            return None;
        }
        // The program's own timers (MoniCAN's periodic calibration and the answers it waits
        // for, the loader's patience) wake it.
        Some(
            self.program_deadline()
                .map_or(BitTime::MAX, |t| t.first_bit_time_at(self.bitrate)),
        )
    }

    /// MoniCAN alone decides what the PowerPC sends: traffic generators and scenario
    /// one-shots are refused.
    fn enqueue(&mut self, _frame: Frame) -> Result<(), QueueFull> {
        Err(QueueFull { capacity: 0 })
    }

    fn pending(&self) -> usize {
        if let Program::Running { .. } | Program::Stopped { .. } = self.program {
            return usize::from(self.driver.chip().transmission_pending());
        }
        self.program_queued()
            + usize::from(self.next.is_some())
            + usize::from(self.driver.tx_pending())
    }

    fn as_any(&self) -> &dyn Any {
        self
    }

    fn as_any_mut(&mut self) -> &mut dyn Any {
        self
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_slio_timing_where_the_crystal_allows_it() {
        for rate in [20_000, 50_000, 100_000] {
            let t = slio_timing(rate).unwrap();
            assert_eq!((t.quanta_per_bit(), t.sample_point_permille()), (10, 600));
            assert_eq!(t.bitrate(CRYSTAL_HZ / 2), rate);
        }
        // 125 kbit/s: 64 CAN clocks a bit, no whole prescaler for 10 quanta.
        let t = slio_timing(125_000).unwrap();
        assert_eq!(t.bitrate(CRYSTAL_HZ / 2), 125_000);
        assert_eq!((t.quanta_per_bit(), t.sample_point_permille()), (16, 562));
        assert!(slio_timing(0).is_err());
    }

    #[test]
    fn keys_beyond_the_port_buffer_are_counted() {
        let mut node = PpcNode::new(Config::default()).unwrap();
        for _ in 0..MAX_KEYS + 3 {
            node.key(b'x');
        }
        assert_eq!(node.keys_dropped(), 3);
        assert_eq!(node.quiet_until(), None, "keys wake the node");
    }
}
