//! The cell model: the OS's command loop, measurement series, UART, ports, START key and power,
//! and user programs on the 8051 core, all driven by virtual time.
//!
//! The OS is a sequential program. It is either waiting for a received byte (or the START key)
//! or busy until some instant (a set-up, an A/D conversion, a byte being sent, a measurement
//! block), or it has called a user program, which then runs on the core ([`chip`](crate::chip))
//! until it stops (a byte 0, a return, a jump to the OS, RESET or power). The UART receives in
//! hardware meanwhile, into the 8051's single receive buffer:
//!
//! - a byte that completes while the previous one is still unread is lost (overrun);
//! - a byte whose start bit begins during the 1 ms set-up after commands 1, 2, 3 and 5 is lost
//!   (the set-up re-arms the receiver; this is why the seed demands the pause), unless the host
//!   cannot see the line's timing and asks to keep it ([`SetupRule::Keep`]);
//! - the OS's send routine waits until the byte has left (it polls TI), so the OS is busy for
//!   a whole character time per byte it sends.

use std::collections::VecDeque;

use buslab_device::{Changes, Nanos, ReplayError};
use buslab_mcs51::{Clocks, Port};

use crate::analog::Source;
use crate::board::Board;
use crate::chip::{Chip, CpuSnapshot, LAG_CLOCKS, ProgramEnd, ProgramStop, TraceEvent};
use crate::command::Command;
use crate::converter::line;
use crate::memory::{
    BatteryRam, DATA_AREA, INTERNAL_RAM_SIZE, PARAMS_LEN, PROGRAM_AREA, START_BYTE,
};
use crate::sfr;
use crate::timing::{
    BYTE_NS, CONVERSION_NS, KEY_HOLD_MEASURE_NS, KEY_HOLD_PROGRAM_NS, KEY_HOLD_READY_NS, MS,
    PROGRAM_POLL_NS, SETUP_NS,
};

/// Start byte values (at 03FFh).
const START_READY: u8 = 0;
const START_MEASURE: u8 = 129;
const START_PROGRAM: u8 = 130;

/// Internal RAM addresses of the value count of the last series: R6 (high) and R7 (low) of
/// register bank 0. Read them with command 16 after stopping a series.
pub const COUNT_HIGH_REGISTER: u8 = 6;
/// See [`COUNT_HIGH_REGISTER`].
pub const COUNT_LOW_REGISTER: u8 = 7;

/// P2.6, the single line of port 2.
const P26: u8 = 1 << 6;

/// The mode the start byte at 03FFh selects after power-on or reset.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    /// 0 (and any value other than 129 and 130): the command loop.
    Ready,
    /// 129: a measurement series waiting for START.
    Measure,
    /// 130: the user program at 0400h runs.
    Program,
}

impl Mode {
    fn from_start_byte(b: u8) -> Mode {
        match b {
            START_MEASURE => Mode::Measure,
            START_PROGRAM => Mode::Program,
            _ => Mode::Ready,
        }
    }
}

/// What the cell is doing right now, for status displays and tests.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Activity {
    /// Switched off.
    Off,
    /// Just reset with the START key held: timing the hold.
    TimingKey,
    /// Waiting for a command byte.
    Ready,
    /// Inside a command's exchange.
    Exchange,
    /// A series is armed: waiting for START (key or byte 9).
    MeasureWaiting,
    /// A block of a series is being measured.
    Measuring,
    /// The user program runs on the 8051 core.
    ProgramRunning,
}

/// What the cell does with a byte whose start bit begins during the 1 ms set-up after commands
/// 1, 2, 3 and 5.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum SetupRule {
    /// Loses it, as the cell does (the set-up re-arms the receiver).
    #[default]
    Lose,
    /// Counts it ([`Stats::kept_in_setup`]) and takes it as if the client had paused: for a
    /// host that cannot tell when a byte was sent. A pseudo-terminal carries no line timing
    /// (the client's drain returns before its byte has crossed the emulated line) and a loaded
    /// server reads a command and the byte sent after the pause in one go.
    Keep,
}

/// Counters of bytes the cell did not take, by reason, and of what programs did that the host
/// cannot see.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Stats {
    /// Started during the set-up after commands 1, 2, 3 or 5.
    pub lost_in_setup: u64,
    /// Started during the set-up but taken, under [`SetupRule::Keep`].
    pub kept_in_setup: u64,
    /// Arrived while the previous byte was still unread.
    pub lost_overrun: u64,
    /// Arrived while the cell was switched off or timing the START key.
    pub lost_off: u64,
    /// Read, but meaning nothing in the state they arrived in (unknown commands, bytes other
    /// than 9 while a series waits).
    pub ignored: u64,
    /// Frames a program sent that a host at 9600 8N2 cannot read (another baud rate or serial
    /// mode): not passed on.
    pub unreadable_frames: u64,
    /// Times a program ran the reserved opcode A5h (a one-cycle no-op).
    pub reserved_opcodes: u64,
}

/// Which RAM area commands 3 and 5 fill.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Area {
    Data,
    Program,
}

/// A measurement series as its 8 parameter bytes describe it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Series {
    /// Scan cycles per block.
    cycles: u16,
    /// Converter inputs (0..3) of the enabled channel slots, in slot order.
    inputs: [u8; 4],
    enabled: u8,
    /// The wait after each cycle's conversions.
    wait_ms: u16,
}

impl Series {
    fn from_params(p: [u8; 8]) -> Series {
        let mut inputs = [0; 4];
        let mut enabled = 0;
        for &ch in &p[2..6] {
            // Any nonzero channel byte enables its slot; the OS puts the low two bits of
            // (channel - 1) on the multiplexer, so 1..4 select inputs 1..4.
            if ch != 0 {
                inputs[usize::from(enabled)] = (ch.wrapping_sub(1)) & 3;
                enabled += 1;
            }
        }
        Series {
            cycles: u16::from_be_bytes([p[0], p[1]]),
            inputs,
            enabled,
            wait_ms: u16::from_be_bytes([p[6], p[7]]),
        }
    }

    /// Time from one cycle's start to the next: the conversions plus the wait.
    fn period_ns(&self) -> Nanos {
        u64::from(self.enabled) * CONVERSION_NS + u64::from(self.wait_ms) * MS
    }
}

/// The OS's program counter, so to speak.
#[derive(Clone, Debug)]
enum Os {
    Off,
    KeyHold {
        since: Nanos,
    },
    Ready,
    Args {
        cmd: Command,
        buf: [u8; 3],
        len: u8,
    },
    Params {
        buf: [u8; 8],
        len: u8,
    },
    Dump {
        ptr: u16,
    },
    UploadTiming {
        area: Area,
        ptr: u16,
    },
    UploadFlag {
        area: Area,
        ptr: u16,
    },
    UploadData {
        area: Area,
        ptr: u16,
    },
    AnalogLoop,
    MeasureWait {
        series: Series,
    },
    /// Converting slot `slot` of cycle `cycle`; the conversion ends at `busy_until`.
    Block {
        series: Series,
        cycle: u16,
        slot: u8,
        cycle_start: Nanos,
    },
    /// The user program has the CPU (the chip runs it).
    Program,
}

/// The ZELLE cell. See the [crate docs](crate) and the module docs for the timing model.
#[derive(Clone, Debug)]
pub struct Cell {
    now: Nanos,
    powered: bool,
    board: Board,
    chip: Chip,
    /// The last external RAM address the OS used (the data pointer; command 16 reads it).
    dptr: u16,
    key_release_at: Option<Nanos>,
    rx: Option<u8>,
    rx_deaf_until: Nanos,
    setup_rule: SetupRule,
    tx_free_at: Nanos,
    tx: VecDeque<(Nanos, u8)>,
    /// Host bytes heard while a program runs, kept until the core is past their start bits:
    /// if the program stops before, the OS takes them.
    program_rx: VecDeque<(Nanos, u8)>,
    os: Os,
    busy_until: Nanos,
    stats: Stats,
}

impl Default for Cell {
    fn default() -> Self {
        Cell::new(BatteryRam::default())
    }
}

impl Cell {
    /// A cell with this battery-backed RAM, switched on at time 0 (so the stored mode resumes).
    pub fn new(ram: BatteryRam) -> Cell {
        let mut cell = Cell {
            now: Nanos::ZERO,
            powered: false,
            board: Board::new(ram),
            chip: Chip::new(),
            dptr: 0,
            key_release_at: None,
            rx: None,
            rx_deaf_until: Nanos::ZERO,
            setup_rule: SetupRule::Lose,
            tx_free_at: Nanos::ZERO,
            tx: VecDeque::new(),
            program_rx: VecDeque::new(),
            os: Os::Off,
            busy_until: Nanos::ZERO,
            stats: Stats::default(),
        };
        cell.power_on(Nanos::ZERO);
        cell
    }

    // ----- the line -------------------------------------------------------------------------

    /// A byte has fully arrived on RxD at `now` (its stop bits ended).
    pub fn receive(&mut self, now: Nanos, byte: u8) {
        let now = self.advance(now);
        if self.powered {
            // On RxD and INT0 from its start bit on, for a program's UART and "Inter".
            self.chip.announce_byte(now, byte);
        }
        if let Os::Program = self.os {
            self.program_rx.push_back((now, byte));
            self.forget_program_bytes();
        } else {
            self.receive_os(now, byte);
        }
    }

    /// The OS's part of a received byte.
    fn receive_os(&mut self, now: Nanos, byte: u8) {
        match self.os {
            Os::Off | Os::KeyHold { .. } => {
                self.stats.lost_off += 1;
                return;
            }
            // RxD is wired to the external interrupt too: a 0 byte stops a series at once.
            // Inside the serial routines (every other state) it is masked.
            Os::MeasureWait { .. } | Os::Block { .. } if byte == 0 => {
                self.interrupt(now);
                return;
            }
            _ => {}
        }
        let in_setup = now.saturating_sub(BYTE_NS) < self.rx_deaf_until;
        if in_setup && self.setup_rule == SetupRule::Lose {
            self.stats.lost_in_setup += 1;
        } else if self.rx.is_some() {
            self.stats.lost_overrun += 1;
        } else {
            if in_setup {
                self.stats.kept_in_setup += 1;
            }
            self.rx = Some(byte);
            self.run_os(now);
        }
    }

    /// Drops the bytes a running program has had from the start bit on: they are its.
    fn forget_program_bytes(&mut self) {
        let core = self.chip.now_ns();
        while let Some(&(at, _)) = self.program_rx.front() {
            if at.saturating_sub(BYTE_NS) > core {
                break;
            }
            self.program_rx.pop_front();
        }
    }

    /// Advances to `now` and appends the bytes whose transmission has ended by then.
    pub fn poll(&mut self, now: Nanos, out: &mut Vec<u8>) {
        let now = self.advance(now);
        while let Some(&(done, byte)) = self.tx.front() {
            if done > now {
                break;
            }
            out.push(byte);
            self.tx.pop_front();
        }
    }

    /// When [`poll`](Self::poll) must be called next even without input.
    pub fn next_deadline(&self) -> Option<Nanos> {
        let chip = matches!(self.os, Os::Program)
            .then(|| self.chip.next_deadline(self.now, PROGRAM_POLL_NS))
            .flatten();
        [
            self.tx.front().map(|&(done, _)| done),
            self.next_os_event(),
            chip,
        ]
        .into_iter()
        .flatten()
        .min()
    }

    // ----- the outside world ----------------------------------------------------------------

    /// Switches the cell on. The OS starts at address 0: it times the START key if held, then
    /// resumes the mode in the start byte.
    pub fn power_on(&mut self, now: Nanos) {
        let now = self.advance(now);
        if self.powered {
            return;
        }
        self.powered = true;
        // Internal RAM is not battery-backed; call it cleared.
        self.chip.power_on();
        self.restart(now);
    }

    /// Switches the cell off: bytes still being sent are cut, received bytes are lost, a
    /// running program stops, the battery-backed RAM stays.
    pub fn power_off(&mut self, now: Nanos) {
        let now = self.advance_exactly(now);
        if !self.powered {
            return;
        }
        self.powered = false;
        self.chip.stop(ProgramEnd::PowerOff);
        self.tx.retain(|&(done, _)| done <= now);
        self.rx = None;
        self.program_rx.clear();
        self.os = Os::Off;
    }

    /// The RESET key: like power-on, but internal RAM keeps its contents.
    pub fn reset(&mut self, now: Nanos) {
        let now = self.advance_exactly(now);
        if self.powered {
            self.chip.stop(ProgramEnd::Reset);
            self.chip.reset();
            self.tx.retain(|&(done, _)| done <= now);
            self.program_rx.clear();
            self.restart(now);
        }
    }

    /// Presses the START key (and keeps it down).
    pub fn key_down(&mut self, now: Nanos) {
        let now = self.advance(now);
        self.key_release_at = None;
        if self.board.key_down {
            return;
        }
        self.board.key_down = true;
        self.chip.set_key(now, true);
        if let Os::MeasureWait { series } = self.os
            && now >= self.busy_until
        {
            self.start_block(now, series);
        }
    }

    /// Releases the START key.
    pub fn key_up(&mut self, now: Nanos) {
        let now = self.advance(now);
        self.release_key(now);
    }

    /// Presses the START key now and releases it `hold_ns` later.
    pub fn press_key_for(&mut self, now: Nanos, hold_ns: Nanos) {
        self.key_down(now);
        self.key_release_at = Some(self.now + hold_ns);
    }

    /// Whether the START key is down.
    pub fn key_is_down(&self) -> bool {
        self.board.key_down
    }

    /// Feeds A/D input `channel` (1..4) from `source`.
    pub fn set_analog(&mut self, channel: u8, source: Source) -> Result<(), InputError> {
        match channel {
            1..=4 => {
                self.board.analog[usize::from(channel - 1)] = source;
                Ok(())
            }
            _ => Err(InputError::Channel(channel)),
        }
    }

    /// The source on A/D input `channel` (1..4).
    pub fn analog(&self, channel: u8) -> Option<&Source> {
        self.board.analog.get(usize::from(channel.wrapping_sub(1)))
    }

    /// Pins of port 1 that outside circuits pull low (a bit set = pulled low). A pin reads low
    /// if either the cell's latch or the outside pulls it low (quasi-bidirectional port).
    pub fn set_port1_pulled_low(&mut self, mask: u8) {
        self.board.p1_pulled_low = mask;
        let converter = self.board.converter.data_out();
        self.chip.set_p1_pulls(self.now, mask, converter);
    }

    /// Whether an outside circuit pulls P2.6 low.
    pub fn set_p26_pulled_low(&mut self, low: bool) {
        self.board.p26_pulled_low = low;
        self.chip.set_p26_pull(self.now, low);
    }

    /// Sets what the peripheral at parallel-bus address `addr` (0..127) answers to reads.
    pub fn set_bus(&mut self, addr: u8, value: u8) -> Result<(), InputError> {
        let slot = self
            .board
            .bus
            .get_mut(usize::from(addr))
            .ok_or(InputError::BusAddress(addr))?;
        *slot = value;
        Ok(())
    }

    // ----- programs -------------------------------------------------------------------------

    /// Shows at most `per_second` instructions a second (of the cell's time) that programs run
    /// ([`take_trace`](Self::take_trace)); `None` turns tracing off.
    pub fn set_trace(&mut self, per_second: Option<u32>) {
        self.chip.set_trace(per_second);
    }

    /// The trace since the last call.
    pub fn take_trace(&mut self, out: &mut Vec<TraceEvent>) {
        self.chip.take_trace(out);
    }

    /// How the last program stopped, with its CPU at that instant.
    pub fn last_program_stop(&self) -> Option<ProgramStop> {
        self.chip.last_stop()
    }

    /// The running program's CPU (as far as the core has run: one character time behind the
    /// line); `None` when no program runs.
    pub fn program_cpu(&mut self) -> Option<CpuSnapshot> {
        if let Os::Program = self.os {
            self.chip.cpu()
        } else {
            None
        }
    }

    /// The OS routine the running program is in (`Sende`, `Empf`, `Inter`), if any.
    pub fn program_routine(&self) -> Option<&'static str> {
        self.chip.in_os_routine()
    }

    // ----- looking inside -------------------------------------------------------------------

    /// The time the model has advanced to.
    pub fn now(&self) -> Nanos {
        self.now
    }

    /// Whether the cell is switched on.
    pub fn is_powered(&self) -> bool {
        self.powered
    }

    /// The mode the start byte selects.
    pub fn mode(&self) -> Mode {
        Mode::from_start_byte(self.board.ram.read(START_BYTE))
    }

    /// What the OS is doing.
    pub fn activity(&self) -> Activity {
        match self.os {
            Os::Off => Activity::Off,
            Os::KeyHold { .. } => Activity::TimingKey,
            Os::Ready => Activity::Ready,
            Os::MeasureWait { .. } if self.busy_until > self.now => Activity::Measuring,
            Os::MeasureWait { .. } => Activity::MeasureWaiting,
            Os::Block { .. } => Activity::Measuring,
            Os::Program => Activity::ProgramRunning,
            _ => Activity::Exchange,
        }
    }

    /// The battery-backed RAM.
    pub fn ram(&self) -> &BatteryRam {
        &self.board.ram
    }

    /// Bumped whenever the battery-backed RAM changes, so a state file is rewritten only then.
    pub fn ram_generation(&self) -> u64 {
        self.board.ram_generation
    }

    /// Writes the battery-backed RAM directly (a test fixture or a control command, not the
    /// serial line).
    pub fn write_ram(&mut self, addr: u16, bytes: &[u8]) {
        for (i, &b) in bytes.iter().enumerate() {
            self.board.write_ram(addr.wrapping_add(i as u16), b);
        }
    }

    /// The RAM writes since the last call, as journal records: `[address high, address low,
    /// bytes…]`, contiguous writes in one record.
    pub fn take_ram_changes(&mut self) -> Changes {
        self.board.changes.take()
    }

    /// Applies a record from [`take_ram_changes`](Self::take_ram_changes) to a RAM image.
    pub fn replay_ram_change(ram: &mut BatteryRam, record: &[u8]) -> Result<(), ReplayError> {
        let [high, low, data @ ..] = record else {
            return Err(ReplayError::new(record, "shorter than an address"));
        };
        let addr = u16::from_be_bytes([*high, *low]);
        if data.is_empty() || usize::from(addr) + data.len() > 0x1_0000 {
            return Err(ReplayError::new(record, "no bytes, or beyond FFFFh"));
        }
        for (i, &b) in data.iter().enumerate() {
            ram.write(addr + i as u16, b);
        }
        Ok(())
    }

    /// Internal RAM 0..127 (shared by the OS and programs).
    pub fn internal_ram(&self) -> &[u8; INTERNAL_RAM_SIZE] {
        self.chip.iram()
    }

    /// Values stored by the current or last series (registers R6:R7).
    pub fn value_count(&self) -> u16 {
        let iram = self.chip.iram();
        u16::from_be_bytes([
            iram[usize::from(COUNT_HIGH_REGISTER)],
            iram[usize::from(COUNT_LOW_REGISTER)],
        ])
    }

    /// Port 1 as the cell drives it (its latch).
    pub fn port1_latch(&self) -> u8 {
        self.chip.latch(Port::P1)
    }

    /// Port 1 pins: the latch ANDed with outside pull-downs (and the converter's output on
    /// P1.3).
    pub fn port1_pins(&self) -> u8 {
        let converter = if self.board.converter.data_out() {
            0xFF
        } else {
            !line::DO
        };
        self.port1_latch() & !self.board.p1_pulled_low & converter
    }

    /// P2.6 pin level.
    pub fn p26_pin(&self) -> bool {
        self.chip.latch(Port::P2) & P26 != 0 && !self.board.p26_pulled_low
    }

    /// The LED on P1.0 lights when the pin is low.
    pub fn led_on(&self) -> bool {
        self.port1_pins() & 1 == 0
    }

    /// What the peripheral at bus address `addr` holds.
    pub fn bus(&self, addr: u8) -> Option<u8> {
        self.board.bus.get(usize::from(addr)).copied()
    }

    /// Bytes the cell did not take, and what programs sent that a host cannot read.
    pub fn stats(&self) -> Stats {
        Stats {
            unreadable_frames: self.chip.stats.unreadable_frames,
            reserved_opcodes: self.chip.stats.reserved_opcodes,
            ..self.stats
        }
    }

    /// What happens to a byte sent within the set-up after commands 1, 2, 3 and 5 (a new cell
    /// loses it, as the real one does).
    pub fn set_setup_rule(&mut self, rule: SetupRule) {
        self.setup_rule = rule;
    }

    /// See [`set_setup_rule`](Self::set_setup_rule).
    pub fn setup_rule(&self) -> SetupRule {
        self.setup_rule
    }

    // ----- the OS ---------------------------------------------------------------------------

    /// Runs every event due up to `to` (OS wake-ups, key release, key-hold timeout, a program
    /// on the core, one character time behind) in order, then returns the time the model is at.
    fn advance(&mut self, to: Nanos) -> Nanos {
        self.advance_lagging(to, LAG_CLOCKS)
    }

    /// [`advance`](Self::advance) with the core brought all the way to `to` (before RESET or
    /// power-off: the program runs up to that instant).
    fn advance_exactly(&mut self, to: Nanos) -> Nanos {
        self.advance_lagging(to, Clocks::ZERO)
    }

    fn advance_lagging(&mut self, to: Nanos, lag: Clocks) -> Nanos {
        let to = to.max(self.now);
        loop {
            let next = self.next_os_event().filter(|&t| t <= to);
            // The core first, up to the OS's next event (it may stop the program earlier).
            let horizon = next.unwrap_or(to);
            if let Some((at, why)) = self
                .chip
                .advance(&mut self.board, horizon, lag, &mut self.tx)
            {
                self.program_ended(at, why);
                continue;
            }
            if let Some(&(done, _)) = self.tx.back() {
                self.tx_free_at = self.tx_free_at.max(done);
            }
            self.forget_program_bytes();
            let Some(t) = next else { break };
            self.now = t;
            if self.key_release_at == Some(t) {
                self.release_key(t);
            }
            if let Os::KeyHold { since } = self.os
                && t >= since + KEY_HOLD_READY_NS
            {
                self.end_key_hold(t, t - since);
            }
            self.run_os(t);
        }
        self.now = to;
        to
    }

    /// The OS's own next wake-up (a set-up, conversion or reply ending, the key).
    fn next_os_event(&self) -> Option<Nanos> {
        let program = matches!(self.os, Os::Program);
        let busy =
            (self.powered && !program && self.busy_until > self.now).then_some(self.busy_until);
        let key_hold = match self.os {
            Os::KeyHold { since } => Some(since + KEY_HOLD_READY_NS),
            _ => None,
        };
        [busy, self.key_release_at, key_hold]
            .into_iter()
            .flatten()
            .min()
    }

    /// The program stopped at `at` (up to a character time ago): the OS takes over from that
    /// instant, and takes the host bytes whose start bits came after it.
    fn program_ended(&mut self, at: Nanos, why: ProgramEnd) {
        self.now = at;
        self.busy_until = at;
        self.tx_free_at = self.tx_free_at.max(at);
        self.rx = None;
        match why {
            ProgramEnd::Returned => self.os = Os::Ready,
            ProgramEnd::Restarted => self.restart(at),
            ProgramEnd::Interrupted
            | ProgramEnd::Fault { .. }
            | ProgramEnd::Reset
            | ProgramEnd::PowerOff => self.interrupt(at),
        }
        for (t, byte) in std::mem::take(&mut self.program_rx) {
            if t.saturating_sub(BYTE_NS) < at {
                continue;
            }
            let t = self.advance(t);
            if let Os::Program = self.os {
                self.program_rx.push_back((t, byte));
            } else {
                self.receive_os(t, byte);
            }
        }
    }

    fn release_key(&mut self, now: Nanos) {
        self.key_release_at = None;
        if !self.board.key_down {
            return;
        }
        self.board.key_down = false;
        self.chip.set_key(now, false);
        if let Os::KeyHold { since } = self.os {
            self.end_key_hold(now, now - since);
        }
    }

    /// Start of the OS after power-on, reset or a jump to 0000h: either time the START key
    /// or resume the stored mode.
    fn restart(&mut self, now: Nanos) {
        self.rx = None;
        self.rx_deaf_until = Nanos::ZERO;
        self.busy_until = now;
        self.tx_free_at = self.tx_free_at.min(now);
        if self.board.key_down {
            self.os = Os::KeyHold { since: now };
        } else {
            self.resume(now);
        }
    }

    fn end_key_hold(&mut self, now: Nanos, held: Nanos) {
        let start = if held >= KEY_HOLD_READY_NS {
            Some(START_READY)
        } else if held >= KEY_HOLD_PROGRAM_NS {
            Some(START_PROGRAM)
        } else if held >= KEY_HOLD_MEASURE_NS {
            Some(START_MEASURE)
        } else {
            None
        };
        if let Some(start) = start {
            self.set_start_byte(start);
        }
        self.resume(now);
    }

    /// Branches on the start byte.
    fn resume(&mut self, now: Nanos) {
        self.dptr = START_BYTE;
        match self.mode() {
            Mode::Ready => self.os = Os::Ready,
            Mode::Measure => self.start_series(),
            Mode::Program => self.start_program(now),
        }
    }

    /// The OS calls the program at 0400h.
    fn start_program(&mut self, now: Nanos) {
        self.os = Os::Program;
        self.program_rx.clear();
        self.chip.start(now);
    }

    /// The interrupt service routine: start byte 0, OS restarted with a fresh stack.
    fn interrupt(&mut self, now: Nanos) {
        self.set_start_byte(START_READY);
        self.rx = None;
        self.busy_until = now;
        self.os = Os::Ready;
    }

    fn set_start_byte(&mut self, value: u8) {
        self.dptr = START_BYTE;
        if self.board.ram.read(START_BYTE) != value {
            self.board.write_ram(START_BYTE, value);
        }
    }

    /// The OS writes external memory (`MOVX`, through the data pointer).
    fn store(&mut self, addr: u16, value: u8) {
        self.dptr = addr;
        self.board.write_data(addr, value);
    }

    /// The OS reads external memory (through the data pointer).
    fn load(&mut self, addr: u16) -> u8 {
        self.dptr = addr;
        self.board.read_data(addr)
    }

    /// What the special function registers reflect now.
    fn sfr_pins(&self) -> sfr::Pins {
        sfr::Pins {
            p1: self.port1_pins(),
            p26: self.p26_pin(),
            key_down: self.board.key_down,
            dptr: self.dptr,
        }
    }

    /// Lets the OS run at `now` until it waits for input or is busy past `now`.
    fn run_os(&mut self, now: Nanos) {
        while self.powered && now >= self.busy_until && self.step(now) {}
    }

    /// One OS action at `now`; false when it is waiting for input.
    fn step(&mut self, now: Nanos) -> bool {
        match std::mem::replace(&mut self.os, Os::Off) {
            Os::Off => false,
            os @ Os::KeyHold { .. } => {
                self.os = os;
                false
            }
            Os::Ready => match self.rx.take() {
                Some(byte) => {
                    self.os = Os::Ready;
                    self.dispatch(now, byte);
                    true
                }
                None => {
                    self.os = Os::Ready;
                    false
                }
            },
            Os::Args { cmd, mut buf, len } => {
                let Some(byte) = self.rx.take() else {
                    self.os = Os::Args { cmd, buf, len };
                    return false;
                };
                buf[usize::from(len)] = byte;
                let len = len + 1;
                let wanted = match cmd {
                    // Bit 7 of the bus address says read; a write takes a data byte too.
                    Command::Bus if buf[0] & 0x80 == 0 => 2,
                    _ => cmd.fixed_args(),
                };
                if usize::from(len) < wanted {
                    self.os = Os::Args { cmd, buf, len };
                } else {
                    self.os = Os::Ready;
                    self.execute(now, cmd, buf);
                }
                true
            }
            Os::Params { mut buf, len } => {
                let Some(byte) = self.rx.take() else {
                    self.os = Os::Params { buf, len };
                    return false;
                };
                buf[usize::from(len)] = byte;
                if len + 1 < 8 {
                    self.os = Os::Params { buf, len: len + 1 };
                } else {
                    for (i, &b) in buf.iter().enumerate() {
                        self.store(DATA_AREA + i as u16, b);
                    }
                    self.start_series();
                }
                true
            }
            Os::Dump { ptr } => match self.rx.take() {
                None => {
                    self.os = Os::Dump { ptr };
                    false
                }
                Some(0) => {
                    self.os = Os::Ready;
                    true
                }
                // The OS only tests for zero: any other byte asks for the next one.
                Some(_) => {
                    let byte = self.load(ptr);
                    self.os = Os::Dump {
                        ptr: ptr.wrapping_add(1),
                    };
                    self.send(now, byte);
                    true
                }
            },
            Os::UploadTiming { area, ptr } => {
                self.os = Os::UploadFlag { area, ptr };
                // "A random byte without meaning": whatever is in the accumulator, here the
                // low byte of the address about to be written.
                self.send(now, ptr as u8);
                true
            }
            Os::UploadFlag { area, ptr } => match self.rx.take() {
                None => {
                    self.os = Os::UploadFlag { area, ptr };
                    false
                }
                Some(0) => {
                    if area == Area::Program {
                        // A loaded program runs after the next reset or power-on.
                        self.set_start_byte(START_PROGRAM);
                    }
                    self.os = Os::Ready;
                    true
                }
                Some(_) => {
                    self.os = Os::UploadData { area, ptr };
                    true
                }
            },
            Os::UploadData { area, ptr } => match self.rx.take() {
                None => {
                    self.os = Os::UploadData { area, ptr };
                    false
                }
                Some(byte) => {
                    self.store(ptr, byte);
                    self.os = Os::UploadTiming {
                        area,
                        ptr: ptr.wrapping_add(1),
                    };
                    true
                }
            },
            Os::AnalogLoop => match self.rx.take() {
                None => {
                    self.os = Os::AnalogLoop;
                    false
                }
                Some(0) => {
                    self.os = Os::Ready;
                    true
                }
                Some(channel) => {
                    self.os = Os::AnalogLoop;
                    self.convert_and_reply(now, channel);
                    true
                }
            },
            Os::MeasureWait { series } => match self.rx.take() {
                None => {
                    self.os = Os::MeasureWait { series };
                    false
                }
                Some(9) => {
                    self.start_block(now, series);
                    true
                }
                Some(_) => {
                    self.stats.ignored += 1;
                    self.os = Os::MeasureWait { series };
                    true
                }
            },
            Os::Block {
                series,
                cycle,
                slot,
                cycle_start,
            } => {
                self.finish_conversion(now, series, cycle, slot, cycle_start);
                true
            }
            Os::Program => {
                self.os = Os::Program;
                false
            }
        }
    }

    /// A command byte arrived in the ready state.
    fn dispatch(&mut self, now: Nanos, byte: u8) {
        let Some(cmd) = Command::from_byte(byte) else {
            self.stats.ignored += 1;
            return;
        };
        if cmd.needs_setup_pause() {
            self.busy_until = now + SETUP_NS;
            self.rx_deaf_until = now + SETUP_NS;
        }
        match cmd {
            Command::Measure => {
                self.os = Os::Params {
                    buf: [0; 8],
                    len: 0,
                }
            }
            Command::ReadData => self.os = Os::Dump { ptr: DATA_AREA },
            Command::WriteData => {
                self.os = Os::UploadTiming {
                    area: Area::Data,
                    ptr: DATA_AREA,
                }
            }
            Command::LoadProgram => {
                self.os = Os::UploadTiming {
                    area: Area::Program,
                    ptr: PROGRAM_AREA,
                }
            }
            Command::AnalogRepeat => self.os = Os::AnalogLoop,
            Command::RunProgram => {
                self.set_start_byte(START_PROGRAM);
                self.start_program(now);
            }
            // START means nothing outside a series.
            Command::Start => {}
            Command::RepeatSeries => self.start_series(),
            Command::ReadPort1 => self.send(now, self.port1_pins()),
            Command::ReadKey => self.send(now, u8::from(!self.board.key_down)),
            Command::ReadP26 => self.send(now, u8::from(self.p26_pin())),
            Command::Analog
            | Command::Bus
            | Command::WritePort1
            | Command::WriteP26
            | Command::ReadRegister
            | Command::WriteRegister
            | Command::Peek
            | Command::Poke => {
                self.os = Os::Args {
                    cmd,
                    buf: [0; 3],
                    len: 0,
                }
            }
        }
    }

    /// A command's argument bytes are complete.
    fn execute(&mut self, now: Nanos, cmd: Command, args: [u8; 3]) {
        match cmd {
            // Channel 0 ends the command without a reading, as it ends command 4's loop.
            Command::Analog if args[0] == 0 => {}
            Command::Analog => self.convert_and_reply(now, args[0]),
            Command::Bus if args[0] & 0x80 != 0 => {
                self.send(now, self.board.bus[usize::from(args[0] & 0x7F)]);
            }
            Command::Bus => self.board.bus[usize::from(args[0])] = args[1],
            Command::WritePort1 => self.chip.write_latch(&mut self.board, Port::P1, args[0]),
            // The OS moves bit 0 of the byte to the pin.
            Command::WriteP26 => {
                let p2 = self.chip.latch(Port::P2) & !P26 | if args[0] & 1 != 0 { P26 } else { 0 };
                self.chip.write_latch(&mut self.board, Port::P2, p2);
            }
            Command::ReadRegister => {
                let value = match self.chip.iram().get(usize::from(args[0])) {
                    Some(&value) => value,
                    None => sfr::read(args[0], self.sfr_pins()),
                };
                self.send(now, value);
            }
            Command::WriteRegister => {
                if let Some(r) = self.chip.iram_mut().get_mut(usize::from(args[0])) {
                    *r = args[1];
                }
            }
            Command::Peek => {
                let value = self.load(u16::from_be_bytes([args[0], args[1]]));
                self.send(now, value);
            }
            Command::Poke => self.store(u16::from_be_bytes([args[0], args[1]]), args[2]),
            _ => unreachable!("{cmd:?} takes no arguments"),
        }
    }

    /// Sends one byte the way the OS's send routine does: start at once (the line is free,
    /// since the routine always waits for the previous byte), then wait until it has left.
    fn send(&mut self, now: Nanos, byte: u8) {
        let start = now.max(self.tx_free_at);
        let done = start + BYTE_NS;
        self.tx.push_back((done, byte));
        self.tx_free_at = done;
        self.busy_until = done;
    }

    /// A direct reading (commands 4 and 7) for channel byte `channel`, which arrived at `now`.
    /// The seed lets every command but 1, 2, 3 and 5 run at full line speed because "its
    /// function ends within the time of two stop bits": the conversion happens while the
    /// channel byte's stop bits pass, so the reply starts as soon as the byte is in, and a host
    /// may send command 4's channel bytes back to back.
    fn convert_and_reply(&mut self, now: Nanos, channel: u8) {
        let byte = self.sample(channel.wrapping_sub(1) & 3, now);
        self.send(now, byte);
    }

    /// Reads converter input `input` (0..3) sampled at `at`. The converter's lines are P1.0..3;
    /// after a conversion they are all high again.
    fn sample(&mut self, input: u8, at: Nanos) -> u8 {
        self.release_converter_lines();
        crate::analog::reading(&self.board.analog[usize::from(input)], at)
    }

    /// After a conversion the converter's lines P1.0..3 are high (the seed).
    fn release_converter_lines(&mut self) {
        let p1 = self.chip.latch(Port::P1);
        if p1 & 0x0F != 0x0F {
            self.chip.write_latch(&mut self.board, Port::P1, p1 | 0x0F);
        }
    }

    /// Arms a series with the parameters at 0800h: start byte 129, value count 0, waiting for
    /// the first START.
    fn start_series(&mut self) {
        let mut params = [0; 8];
        for (i, p) in params.iter_mut().enumerate() {
            *p = self.load(DATA_AREA + i as u16);
        }
        self.set_start_byte(START_MEASURE);
        self.set_value_count(0);
        self.release_converter_lines();
        self.os = Os::MeasureWait {
            series: Series::from_params(params),
        };
    }

    fn set_value_count(&mut self, count: u16) {
        let [high, low] = count.to_be_bytes();
        let iram = self.chip.iram_mut();
        iram[usize::from(COUNT_HIGH_REGISTER)] = high;
        iram[usize::from(COUNT_LOW_REGISTER)] = low;
    }

    fn start_block(&mut self, now: Nanos, series: Series) {
        if series.cycles == 0 {
            self.os = Os::MeasureWait { series };
        } else if series.enabled == 0 {
            // Nothing to convert: the block is just its waits.
            self.busy_until = now + u64::from(series.cycles) * series.period_ns();
            self.os = Os::MeasureWait { series };
        } else {
            self.busy_until = now + CONVERSION_NS;
            self.os = Os::Block {
                series,
                cycle: 0,
                slot: 0,
                cycle_start: now,
            };
        }
    }

    /// The conversion of `slot` in `cycle` has ended at `now`: store it and go on.
    fn finish_conversion(
        &mut self,
        now: Nanos,
        series: Series,
        cycle: u16,
        slot: u8,
        cycle_start: Nanos,
    ) {
        let count = self.value_count();
        let addr = u32::from(DATA_AREA) + u32::from(PARAMS_LEN) + u32::from(count);
        if addr >= crate::memory::EXT_RAM_SIZE as u32 {
            // The data area is full: the series ends and the cell returns to the ready state,
            // so a power cycle cannot start overwriting the values.
            self.set_start_byte(START_READY);
            self.os = Os::Ready;
            return;
        }
        let sampled_at = now - CONVERSION_NS;
        let value = self.sample(series.inputs[usize::from(slot)], sampled_at);
        self.store(addr as u16, value);
        self.set_value_count(count + 1);

        if slot + 1 < series.enabled {
            let slot = slot + 1;
            self.busy_until = cycle_start + u64::from(slot + 1) * CONVERSION_NS;
            self.os = Os::Block {
                series,
                cycle,
                slot,
                cycle_start,
            };
        } else if cycle + 1 < series.cycles {
            let cycle_start = cycle_start + series.period_ns();
            self.busy_until = cycle_start + CONVERSION_NS;
            self.os = Os::Block {
                series,
                cycle: cycle + 1,
                slot: 0,
                cycle_start,
            };
        } else {
            // The block ends with its last conversion; a START that came meanwhile waits in
            // the receive buffer and starts the next block at once.
            self.os = Os::MeasureWait { series };
        }
    }
}

/// A control input out of range.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
pub enum InputError {
    #[error("analog channel {0} is out of range 1..4")]
    Channel(u8),
    #[error("bus address {0} is out of range 0..127")]
    BusAddress(u8),
}
