//! The cell's 8051 running a user program: the MCS-51 core wired to the cell's hardware
//! (`board::Board`), the OS area trapped (`rom`), its UART on the cell's line.
//!
//! **One character behind.** The cell hears a host byte when its stop bits have ended, but the
//! core must see its start bit: the core is run one character time (11 bits at 9600 baud) plus
//! its longest instruction behind the cell's time, so every byte reaches RxD (and INT0, wired
//! to it) at its exact start. What the program does becomes known to the cell that much later:
//! its bytes reach the host one character time after they left TxD, and when it stops, the
//! OS takes over from the instant it stopped (the cell replays the bytes heard since).
//!
//! **The OS routines** are traps (see [`rom`]): the core stops at an entry point and the model
//! does the routine's work on the core's registers, stack and SFRs, spending the routine's
//! machine cycles; `Sende`'s and `Empf`'s waits are real 8051 loops, so the program's own
//! interrupts are served meanwhile. Inside them INT0 is masked (the seed).
//!
//! **"Inter".** RxD is wired to INT0, edge-triggered: every start bit requests it (latched while
//! masked). The routine looks at the bytes whose start bits came since it last looked (waiting
//! for a byte still on the line, as a routine polling the UART would): one of them 0 stops
//! the program and restarts the OS; otherwise it clears IE0 and returns (RETI), the UART left
//! as the byte left it. `Empf` takes the bytes it received for itself: a 0 received there is
//! data.

use std::collections::VecDeque;

use buslab_device::Nanos;

use buslab_mcs51::sfr::{self, ie, scon, tcon};
use buslab_mcs51::{
    Clocks, Event, Instruction, LineFrame, Mcs51, Pin, Port, Registers, SerialFrame, SerialMode,
    Stop,
};

use crate::board::{Board, CRYSTAL};
use crate::converter::line;
use crate::memory::PROGRAM_AREA;
use crate::rom::{self, cycles};
use crate::sfr as os_sfr;
use crate::timing::BYTE_NS;

/// One bit at 9600 baud, in clocks of the 11.0592 MHz crystal.
pub(crate) const BIT_CLOCKS: u64 = 1152;
/// One machine cycle.
const CYCLE: u64 = 12;
/// How far the core runs behind the cell: one 8N2 character and the longest instruction (the
/// core stops at the first instruction boundary at or after its limit).
pub(crate) const LAG_CLOCKS: Clocks = Clocks(11 * BIT_CLOCKS + 4 * CYCLE);
/// When "Inter" knows a byte: the middle of its first stop bit, as the UART would.
const BYTE_KNOWN: Clocks = Clocks(19 * BIT_CLOCKS / 2);
/// Host bytes kept for "Inter" to look at; older ones count as the program's.
const MAX_FRAMES: usize = 16;
/// A frame the host (at 9600 baud) reads: its bit time within 2 % of 9600 baud's.
const BIT_TOLERANCE: u64 = BIT_CLOCKS / 50;
/// Trace lines kept for the host to take; beyond it they are counted as skipped.
const MAX_TRACE_QUEUE: usize = 10_000;

/// The SFRs the OS sets before it calls a program (in this order): timer 1 as the 9600-baud
/// generator, the UART in mode 3 (8N2: the 9th bit is the second stop bit), INT0
/// edge-triggered and of high priority, interrupts enabled for it.
pub const START_SFRS: [(u8, u8); 10] = [
    (sfr::TMOD, os_sfr::TMOD_BAUD),
    (sfr::TH1, os_sfr::BAUD_RELOAD),
    (sfr::TL1, os_sfr::BAUD_RELOAD),
    (sfr::TH0, 0x00),
    (sfr::TL0, 0x00),
    (sfr::PCON, 0x00),
    (sfr::SCON, os_sfr::SCON_8N2),
    (sfr::TCON, os_sfr::TCON_RUNNING),
    (sfr::IP, 0x01),
    (sfr::IE, 0x81),
];
/// SP when the program's first instruction runs: the OS's return address at 08h..09h, as
/// inside any command.
pub const START_SP: u8 = os_sfr::SP_IN_COMMAND;

/// Why a program stopped running.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ProgramEnd {
    /// A byte 0 on RxD ("Inter"): start byte 0, the OS restarted with a fresh stack.
    Interrupted,
    /// It returned from its outermost level (`RET` to 0040h): the OS's command loop, the
    /// start byte unchanged.
    Returned,
    /// It jumped to 0000h: the OS started over and resumed the stored mode.
    Restarted,
    /// It jumped into the OS area at `pc`, where no entry point is: the OS restarted as after
    /// "Inter" (start byte 0).
    Fault { pc: u16 },
    /// The RESET key.
    Reset,
    /// The supply went off.
    PowerOff,
}

/// The special function registers a program sets up, as they were.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SfrSnapshot {
    pub ie: u8,
    pub ip: u8,
    pub tcon: u8,
    pub tmod: u8,
    pub th0: u8,
    pub tl0: u8,
    pub th1: u8,
    pub tl1: u8,
    pub scon: u8,
    pub pcon: u8,
    /// Port latches (what the program wrote).
    pub p1: u8,
    pub p2: u8,
    pub p3: u8,
}

/// The CPU of a program at one instant.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CpuSnapshot {
    pub at_ns: Nanos,
    pub registers: Registers,
    pub sfr: SfrSnapshot,
    /// Instructions the program ran since it started.
    pub instructions: u64,
}

/// How the last program stopped, and its CPU then (the PC where it was: for an interrupt,
/// the instruction it would have run next).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ProgramStop {
    pub why: ProgramEnd,
    pub cpu: CpuSnapshot,
}

/// One line of the instruction trace ([`Cell::set_trace`](crate::Cell::set_trace)).
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum TraceEvent {
    /// An instruction about to run, with A, PSW and SP before it.
    Instruction {
        at_ns: Nanos,
        instruction: Instruction,
        a: u8,
        psw: u8,
        sp: u8,
    },
    /// The core took an interrupt: its routine starts at `vector`.
    Interrupt { at_ns: Nanos, vector: u16 },
    /// The program called into the OS (`routine`: Sende, Empf, Inter, ...).
    Os { at_ns: Nanos, routine: &'static str },
    /// Instructions that ran untraced (beyond the limit per second, or while the queue was
    /// full), up to `until_ns`.
    Skipped { instructions: u64, until_ns: Nanos },
}

/// What the chip counts.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct ChipStats {
    /// Frames the program sent that a host at 9600 8N2 cannot read (another rate or mode, a
    /// 9th bit 0 where the stop bit belongs).
    pub unreadable_frames: u64,
    /// Times the program ran the reserved opcode A5h.
    pub reserved_opcodes: u64,
    /// Level changes the core had no room for.
    pub lost_inputs: u64,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Run {
    /// No program: the core lets time pass.
    Off,
    /// The OS calls the program at `at`.
    Starting {
        at: Clocks,
    },
    Running,
    /// Inside an OS routine: time passes (no instructions) until `until`, then the program
    /// runs on.
    Busy {
        until: Clocks,
    },
    /// "Inter" waits until `until` for a byte to be complete.
    Inter {
        until: Clocks,
    },
    /// Stopped for `why`; the OS takes over once the UART's frame in progress has left.
    Draining {
        why: ProgramEnd,
    },
}

/// A host byte on RxD: its start bit's time (clocks) and value.
#[derive(Clone, Copy, Debug)]
struct RxFrame {
    start: Clocks,
    byte: u8,
}

#[derive(Clone, Debug)]
struct Tracer {
    per_second: u64,
    window: u64,
    shown: u64,
    /// Instructions count when the untraced stretch of this window began.
    untraced_from: Option<u64>,
    queue: VecDeque<TraceEvent>,
}

/// The 8051 and what the model keeps of a program's run.
#[derive(Clone, Debug)]
pub(crate) struct Chip {
    core: Mcs51,
    run: Run,
    frames: VecDeque<RxFrame>,
    started_instructions: u64,
    last_stop: Option<ProgramStop>,
    trace: Option<Tracer>,
    pub stats: ChipStats,
}

impl Chip {
    pub fn new() -> Chip {
        let mut core = Mcs51::new();
        core.set_traps(rom::TRAPS);
        let mut chip = Chip {
            core,
            run: Run::Off,
            frames: VecDeque::new(),
            started_instructions: 0,
            last_stop: None,
            trace: None,
            stats: ChipStats::default(),
        };
        chip.os_serial_setup();
        chip
    }

    // ----- what the OS uses -----------------------------------------------------------------

    pub fn iram(&self) -> &[u8; 128] {
        self.core.iram()
    }

    pub fn iram_mut(&mut self) -> &mut [u8; 128] {
        self.core.iram_mut()
    }

    /// A port's latch.
    pub fn latch(&self, port: Port) -> u8 {
        self.core.port_latch(port)
    }

    /// The OS writes a port latch (commands 11 and 14, its conversions).
    pub fn write_latch(&mut self, board: &mut Board, port: Port, value: u8) {
        self.core.write_direct(port.sfr(), value);
        self.handle_events(board, &mut VecDeque::new());
    }

    /// Power on: the RESET pin, internal RAM cleared (it is not battery-backed).
    pub fn power_on(&mut self) {
        self.core.reset();
        self.core.iram_mut().fill(0);
        self.os_serial_setup();
        self.run = Run::Off;
    }

    /// The RESET pin (internal RAM kept).
    pub fn reset(&mut self) {
        self.core.reset();
        self.os_serial_setup();
        self.run = Run::Off;
    }

    /// What the OS sets up first after a reset: its UART, receiving at 9600 8N2 from then on.
    /// The core's receiver then follows every host byte from its start bit while the OS runs,
    /// so a byte on the line when a program starts reaches the program whole (RI, SBUF), as on
    /// the cell: a receiver switched on in the middle of it took a 0 data bit for a start bit.
    fn os_serial_setup(&mut self) {
        for (addr, value) in START_SFRS {
            if matches!(
                addr,
                sfr::TMOD | sfr::TH1 | sfr::TL1 | sfr::PCON | sfr::SCON
            ) {
                self.core.write_direct(addr, value);
            }
        }
        let tcon = self.core.read_direct(sfr::TCON);
        self.core.write_direct(sfr::TCON, tcon | tcon::TR1);
    }

    /// Whether the program is in the OS's `Sende` or `Empf` (or "Inter").
    pub fn in_os_routine(&self) -> Option<&'static str> {
        match self.run {
            Run::Inter { .. } => Some("Inter"),
            Run::Running | Run::Busy { .. } => match self.core.pc() {
                rom::SENDE_WAIT | rom::SENDE_DONE | rom::SENDE => Some("Sende"),
                rom::EMPF_WAIT | rom::EMPF_DONE | rom::EMPF => Some("Empf"),
                _ => None,
            },
            _ => None,
        }
    }

    /// The OS calls the program at `at_ns` (the core gets there one character later).
    pub fn start(&mut self, at_ns: Nanos) {
        self.run = Run::Starting {
            at: CRYSTAL.clocks_at_ns(at_ns),
        };
    }

    /// The cell stops a running program (RESET, power-off): its CPU is kept for a look.
    pub fn stop(&mut self, why: ProgramEnd) {
        if matches!(self.run, Run::Off | Run::Starting { .. }) {
            self.run = Run::Off;
            return;
        }
        let pc = self.core.pc();
        self.last_stop = Some(ProgramStop {
            why,
            cpu: self.snapshot(pc),
        });
        self.run = Run::Off;
    }

    /// How the last program stopped.
    pub fn last_stop(&self) -> Option<ProgramStop> {
        self.last_stop
    }

    /// The running program's CPU now (as far as the core has run).
    pub fn cpu(&mut self) -> Option<CpuSnapshot> {
        if matches!(self.run, Run::Off | Run::Starting { .. }) {
            None
        } else {
            Some(self.snapshot(self.core.pc()))
        }
    }

    /// Where the core's time is, in the cell's nanoseconds.
    pub fn now_ns(&self) -> Nanos {
        CRYSTAL.ns(self.core.now())
    }

    // ----- the outside ----------------------------------------------------------------------

    /// A host byte arrived at `arrival_ns` (its stop bits ended): it is put on RxD and INT0
    /// from its start bit on.
    pub fn announce_byte(&mut self, arrival_ns: Nanos, byte: u8) {
        let start = CRYSTAL
            .clocks_at_ns(arrival_ns.saturating_sub(BYTE_NS))
            .max(self.core.now());
        let frame = LineFrame {
            data: byte,
            ninth: None,
            bit_clocks: Clocks(BIT_CLOCKS),
        };
        if self.core.send_rxd(start, frame).is_err() {
            self.stats.lost_inputs += 1;
            return;
        }
        // INT0 is wired to RxD: the same levels.
        let mut level = true;
        for bit in 0..10u64 {
            let high = match bit {
                0 => false,
                9 => true,
                _ => byte >> (bit - 1) & 1 != 0,
            };
            if high != level {
                level = high;
                let at = Clocks(start.0 + bit * BIT_CLOCKS);
                if self.core.set_pin(at, Pin::INT0, high).is_err() {
                    self.stats.lost_inputs += 1;
                }
            }
        }
        self.frames.push_back(RxFrame { start, byte });
        while self.frames.len() > MAX_FRAMES {
            self.frames.pop_front();
        }
    }

    /// The START key (INT1, low while pressed) from `at_ns` on.
    pub fn set_key(&mut self, at_ns: Nanos, down: bool) {
        let at = CRYSTAL.clocks_at_ns(at_ns);
        if self.core.set_pin(at, Pin::INT1, !down).is_err() {
            self.stats.lost_inputs += 1;
        }
    }

    /// Port 1 pins pulled low from outside (bit set), from `at_ns` on. P1.3 is also the
    /// converter's output: low if either pulls it.
    pub fn set_p1_pulls(&mut self, at_ns: Nanos, mask: u8, converter_out: bool) {
        let at = CRYSTAL.clocks_at_ns(at_ns);
        let levels = !mask & !line::DO | u8::from(converter_out && mask & line::DO == 0) << 3;
        if self.core.set_port(at, Port::P1, levels).is_err() {
            self.stats.lost_inputs += 1;
        }
    }

    /// P2.6 pulled low from outside, from `at_ns` on.
    pub fn set_p26_pull(&mut self, at_ns: Nanos, low: bool) {
        let at = CRYSTAL.clocks_at_ns(at_ns);
        let pin = Pin::new(Port::P2, 6).expect("bit 6");
        if self.core.set_pin(at, pin, !low).is_err() {
            self.stats.lost_inputs += 1;
        }
    }

    // ----- tracing --------------------------------------------------------------------------

    /// Trace at most `per_second` instructions a second of the cell's time (`None`: off).
    pub fn set_trace(&mut self, per_second: Option<u32>) {
        self.trace = per_second.map(|n| Tracer {
            per_second: u64::from(n),
            window: 0,
            shown: 0,
            untraced_from: None,
            queue: VecDeque::new(),
        });
    }

    /// The trace lines since the last call.
    pub fn take_trace(&mut self, out: &mut Vec<TraceEvent>) {
        if let Some(t) = &mut self.trace {
            out.extend(t.queue.drain(..));
        }
    }

    fn trace(&mut self, event: TraceEvent) {
        if let Some(t) = &mut self.trace
            && t.queue.len() < MAX_TRACE_QUEUE
        {
            t.queue.push_back(event);
        }
    }

    /// Whether the next instruction is to be traced: within this second's budget, and room.
    fn tracing_now(&mut self) -> bool {
        let now = self.core.now().0;
        let instructions = self.core.instructions();
        let Some(t) = &mut self.trace else {
            return false;
        };
        let window = now / u64::from(CRYSTAL.hz());
        if window != t.window {
            if let Some(from) = t.untraced_from.take()
                && instructions > from
            {
                t.queue.push_back(TraceEvent::Skipped {
                    instructions: instructions - from,
                    until_ns: CRYSTAL.ns(Clocks(window * u64::from(CRYSTAL.hz()))),
                });
            }
            t.window = window;
            t.shown = 0;
        }
        let traced = t.shown < t.per_second && t.queue.len() < MAX_TRACE_QUEUE;
        if traced {
            t.shown += 1;
        } else if t.untraced_from.is_none() {
            t.untraced_from = Some(instructions);
        }
        traced
    }

    /// Where an untraced stretch must end: the next second's start.
    fn next_trace_window(&self) -> Clocks {
        match &self.trace {
            Some(t) => Clocks((t.window + 1) * u64::from(CRYSTAL.hz())),
            None => Clocks::NEVER,
        }
    }

    // ----- running --------------------------------------------------------------------------

    /// Runs the core up to the cell's `now_ns` less `lag` clocks: a program, or time alone.
    /// Frames the program sent go to `tx` (time their last stop bit ends, byte). Returns when
    /// and why the program stopped, if it did (the OS takes over from that instant).
    pub fn advance(
        &mut self,
        board: &mut Board,
        now_ns: Nanos,
        lag: Clocks,
        tx: &mut VecDeque<(Nanos, u8)>,
    ) -> Option<(Nanos, ProgramEnd)> {
        let target = CRYSTAL.clocks_at_ns(now_ns) - lag;
        loop {
            match self.run {
                Run::Off => {
                    self.stall_to(board, target, tx);
                    return None;
                }
                Run::Starting { at } => {
                    if !self.stall_to(board, at.min(target), tx) || self.core.now() < at {
                        return None;
                    }
                    self.begin();
                }
                Run::Busy { until } => {
                    if !self.stall_to(board, until.min(target), tx) || self.core.now() < until {
                        return None;
                    }
                    self.run = Run::Running;
                }
                Run::Inter { until } => {
                    // Reaching the target before `until` is not reaching `until`: "Inter"
                    // would find its byte still on the line and wait again, for ever.
                    if !self.stall_to(board, until.min(target), tx) || self.core.now() < until {
                        return None;
                    }
                    self.inter();
                }
                Run::Draining { why } => {
                    if !self.core.transmitting() {
                        return Some(self.finish(why));
                    }
                    if self.core.now() >= target {
                        return None;
                    }
                    if self.core.stall(target) == Stop::Events {
                        self.handle_events(board, tx);
                    }
                }
                Run::Running => {
                    if self.core.now() >= target {
                        return None;
                    }
                    let stop = if self.tracing_now() {
                        self.traced_step(board, target)
                    } else {
                        let until = target.min(self.next_trace_window());
                        self.core.run(board, until)
                    };
                    match stop {
                        Stop::Limit => {}
                        Stop::Events => self.handle_events(board, tx),
                        Stop::Trap { pc } => self.trap(pc),
                        Stop::PowerDown => return None,
                    }
                }
            }
        }
    }

    /// Stalls the core to `until`, taking its events. True when it got there.
    fn stall_to(
        &mut self,
        board: &mut Board,
        until: Clocks,
        tx: &mut VecDeque<(Nanos, u8)>,
    ) -> bool {
        loop {
            match self.core.stall(until) {
                Stop::Events => self.handle_events(board, tx),
                _ => return self.core.now() >= until,
            }
        }
    }

    /// One instruction, traced.
    fn traced_step(&mut self, board: &mut Board, target: Clocks) -> Stop {
        let pc = self.core.pc();
        let at_ns = self.now_ns();
        let before = self.core.instructions();
        let registers = self.core.registers();
        let instruction = Instruction::at(board, pc);
        let until = (self.core.now() + Clocks(1)).min(target);
        let stop = self.core.run(board, until);
        if self.core.instructions() > before {
            self.trace(TraceEvent::Instruction {
                at_ns,
                instruction,
                a: registers.a,
                psw: registers.psw,
                sp: registers.sp,
            });
        } else if self.core.pc() != pc && self.core.registers().sp == registers.sp.wrapping_add(2) {
            self.trace(TraceEvent::Interrupt {
                at_ns,
                vector: self.core.pc(),
            });
        }
        stop
    }

    fn handle_events(&mut self, board: &mut Board, tx: &mut VecDeque<(Nanos, u8)>) {
        while let Some(event) = self.core.poll_event() {
            match event {
                Event::Serial(frame) => {
                    if readable(&frame) {
                        tx.push_back((CRYSTAL.ns(frame.stop_end()), frame.data));
                    } else {
                        self.stats.unreadable_frames += 1;
                    }
                }
                Event::Port {
                    port: Port::P1,
                    latch,
                    at,
                } => {
                    let pins = latch & !board.p1_pulled_low;
                    if let Some(out) =
                        board
                            .converter
                            .pins_changed(pins, CRYSTAL.ns(at), &board.analog)
                    {
                        let high = out && board.p1_pulled_low & line::DO == 0;
                        self.core
                            .drive_now(Port::P1, line::DO, if high { line::DO } else { 0 });
                    }
                }
                Event::ReservedOpcode { .. } => self.stats.reserved_opcodes += 1,
                Event::Port { .. } => {}
            }
        }
    }

    /// The OS calls the program: SFRs as it leaves them, a fresh stack with the return
    /// address into the OS, PC 0400h.
    fn begin(&mut self) {
        // The OS ends any interrupt routine still in progress (RETI to its own code) first.
        for _ in 0..2 {
            self.core.push(0);
            self.core.push(0);
            self.core.reti();
        }
        // The baud generator already running as the OS left it is not restarted: a reload in
        // the middle of a host byte would shift the receiver's sampling.
        let baud_running = self.core.read_direct(sfr::TMOD) == 0x20
            && self.core.read_direct(sfr::TH1) == 0xFD
            && self.core.read_direct(sfr::TCON) & tcon::TR1 != 0;
        for (addr, value) in START_SFRS {
            if baud_running && addr == sfr::TL1 {
                continue;
            }
            self.core.write_direct(addr, value);
        }
        self.core.set_registers(Registers {
            pc: PROGRAM_AREA,
            a: 0,
            b: 0,
            psw: 0,
            sp: START_SP - 2,
            dptr: 0,
        });
        let [high, low] = rom::PROGRAM_RETURN.to_be_bytes();
        self.core.push(low);
        self.core.push(high);
        let now = self.core.now();
        self.frames.retain(|f| f.start >= now);
        self.started_instructions = self.core.instructions();
        self.run = Run::Running;
    }

    /// The core stopped at `pc` in the OS area: do what the OS does there.
    fn trap(&mut self, pc: u16) {
        let now = self.core.now();
        let busy = |n: u64| Run::Busy {
            until: now + Clocks::from_cycles(n),
        };
        let name = match pc {
            rom::INTER => "Inter",
            rom::SENDE => "Sende",
            rom::EMPF => "Empf",
            rom::PROGRAM_RETURN => "return to the OS",
            rom::RESET => "reset entry",
            rom::SENDE_DONE | rom::EMPF_DONE => "",
            _ if rom::vector_target(pc).is_some() => "",
            _ => "fault",
        };
        if !name.is_empty() {
            let at_ns = self.now_ns();
            self.trace(TraceEvent::Os {
                at_ns,
                routine: name,
            });
        }
        match pc {
            rom::INTER => self.inter(),
            rom::SENDE => {
                let ie = self.core.read_direct(sfr::IE);
                self.core.push(ie);
                self.core.write_direct(sfr::IE, ie & !ie::EX0);
                self.clear(sfr::SCON, scon::TI);
                let a = self.core.a();
                self.core.write_direct(sfr::SBUF, a);
                self.core.set_pc(rom::SENDE_WAIT);
                self.run = busy(cycles::SENDE_ENTRY);
            }
            rom::SENDE_DONE => {
                self.clear(sfr::SCON, scon::TI);
                self.restore_ex0();
                self.core.ret();
                self.run = busy(cycles::SENDE_END);
            }
            rom::EMPF => {
                let ie = self.core.read_direct(sfr::IE);
                self.core.push(ie);
                self.core.write_direct(sfr::IE, ie & !ie::EX0);
                self.core.set_pc(rom::EMPF_WAIT);
                self.run = busy(cycles::EMPF_ENTRY);
            }
            rom::EMPF_DONE => {
                self.clear(sfr::SCON, scon::RI);
                let byte = self.core.read_direct(sfr::SBUF);
                self.core.write_direct(sfr::ACC, byte);
                // The bytes it received are its data: their edges do not interrupt.
                self.clear(sfr::TCON, tcon::IE0);
                self.frames.retain(|f| f.start > now);
                self.restore_ex0();
                self.core.ret();
                self.run = busy(cycles::EMPF_END);
            }
            rom::PROGRAM_RETURN => self.end(ProgramEnd::Returned, pc),
            rom::RESET => self.end(ProgramEnd::Restarted, pc),
            _ => match rom::vector_target(pc) {
                Some(target) => {
                    self.core.set_pc(target);
                    self.run = busy(cycles::VECTOR);
                }
                None => self.end(ProgramEnd::Fault { pc }, pc),
            },
        }
    }

    /// "Inter", at its entry or after waiting for a byte.
    fn inter(&mut self) {
        let now = self.core.now();
        let seen = || self.frames.iter().filter(|f| f.start <= now);
        let known = seen().map(|f| f.start + BYTE_KNOWN).max();
        match known {
            Some(until) if until > now => {
                self.run = Run::Inter { until };
                return;
            }
            Some(_) if seen().any(|f| f.byte == 0) => {
                let sp = self.core.registers().sp;
                let iram = self.core.iram();
                let back = u16::from_be_bytes([
                    iram[usize::from(sp & 0x7F)],
                    iram[usize::from(sp.wrapping_sub(1) & 0x7F)],
                ]);
                self.end(ProgramEnd::Interrupted, back);
                return;
            }
            _ => {}
        }
        self.frames.retain(|f| f.start > now);
        self.clear(sfr::TCON, tcon::IE0);
        self.core.reti();
        self.run = Run::Busy {
            until: now + Clocks::from_cycles(cycles::INTER_RETURN),
        };
    }

    /// The program stopped at `pc` for `why`: the OS takes over once the UART is done.
    fn end(&mut self, why: ProgramEnd, pc: u16) {
        self.last_stop = Some(ProgramStop {
            why,
            cpu: self.snapshot(pc),
        });
        if why == ProgramEnd::Interrupted {
            self.core.reti();
        }
        // A fresh stack for the OS.
        let mut r = self.core.registers();
        r.sp = 0x07;
        self.core.set_registers(r);
        self.run = Run::Draining { why };
    }

    fn finish(&mut self, why: ProgramEnd) -> (Nanos, ProgramEnd) {
        // The OS starts over: its UART set up again, whatever the program made of it.
        self.os_serial_setup();
        self.run = Run::Off;
        (self.now_ns(), why)
    }

    fn clear(&mut self, addr: u8, bits: u8) {
        let value = self.core.read_direct(addr);
        if value & bits != 0 {
            self.core.write_direct(addr, value & !bits);
        }
    }

    /// The end of `Sende`/`Empf`: EX0 as it was at their entry (pushed there).
    fn restore_ex0(&mut self) {
        let saved = self.core.pop();
        let ie = self.core.read_direct(sfr::IE);
        self.core
            .write_direct(sfr::IE, ie & !ie::EX0 | saved & ie::EX0);
    }

    fn snapshot(&mut self, pc: u16) -> CpuSnapshot {
        let mut registers = self.core.registers();
        registers.pc = pc;
        let mut read = |addr| self.core.read_direct(addr);
        let sfr = SfrSnapshot {
            ie: read(sfr::IE),
            ip: read(sfr::IP),
            tcon: read(sfr::TCON),
            tmod: read(sfr::TMOD),
            th0: read(sfr::TH0),
            tl0: read(sfr::TL0),
            th1: read(sfr::TH1),
            tl1: read(sfr::TL1),
            scon: read(sfr::SCON),
            pcon: read(sfr::PCON),
            p1: self.core.port_latch(Port::P1),
            p2: self.core.port_latch(Port::P2),
            p3: self.core.port_latch(Port::P3),
        };
        CpuSnapshot {
            at_ns: self.now_ns(),
            registers,
            sfr,
            instructions: self.core.instructions() - self.started_instructions,
        }
    }

    /// When the cell must next run the chip, given its time `now_ns`: often while a program
    /// runs (its output is due when it has run), never while it sleeps in power-down.
    pub fn next_deadline(&self, now_ns: Nanos, quantum_ns: Nanos) -> Option<Nanos> {
        match self.run {
            Run::Off => None,
            Run::Running if self.core.is_powered_down() => None,
            _ => Some(now_ns + quantum_ns),
        }
    }
}

/// Whether a host at 9600 8N2 reads `frame`: modes 1 and 3 at 9600 baud (within 2 %), a 9th
/// bit (mode 3) of 1, read as the first stop bit.
fn readable(frame: &SerialFrame) -> bool {
    let mode = matches!(frame.mode, SerialMode::Mode1 | SerialMode::Mode3);
    mode && frame.ninth != Some(false) && frame.bit_clocks().0.abs_diff(BIT_CLOCKS) <= BIT_TOLERANCE
}
