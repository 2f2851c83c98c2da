//! The cell model: the OS's command loop, measurement series, UART, ports, START key and power,
//! all driven by virtual time.
//!
//! The OS is a sequential program. It is either waiting for a received byte (or the START key)
//! or busy until some instant (a set-up, an A/D conversion, a byte being sent, a measurement
//! block). The UART receives in hardware meanwhile, into the 8051's single receive buffer:
//!
//! - a byte that completes while the previous one is still unread is lost (overrun);
//! - a byte whose start bit begins during the 1 ms set-up after commands 1, 2, 3 and 5 is lost
//!   (the set-up re-arms the receiver; this is why the seed demands the pause), unless the host
//!   cannot see the line's timing and asks to keep it ([`SetupRule::Keep`]);
//! - the OS's send routine waits until the byte has left (it polls TI), so the OS is busy for
//!   a whole character time per byte it sends.

use std::collections::VecDeque;

use buslab_device::{ChangeLog, Changes, ReplayError};

use crate::analog::Source;
use crate::command::Command;
use crate::memory::{
    BatteryRam, DATA_AREA, INTERNAL_RAM_SIZE, OPEN_BUS, PARAMS_LEN, PROGRAM_AREA, START_BYTE,
};
use crate::sfr;
use crate::timing::{
    BYTE_NS, CONVERSION_NS, KEY_HOLD_MEASURE_NS, KEY_HOLD_PROGRAM_NS, KEY_HOLD_READY_NS, MS,
    SETUP_NS,
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
    /// The user program runs (the model treats it as opaque: it only waits to be interrupted).
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

/// Counters of bytes the cell did not take, by reason.
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
    /// than 9 while a series waits, bytes to a running program).
    pub ignored: u64,
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
    fn period_ns(&self) -> u64 {
        u64::from(self.enabled) * CONVERSION_NS + u64::from(self.wait_ms) * MS
    }
}

/// The OS's program counter, so to speak.
#[derive(Clone, Debug)]
enum Os {
    Off,
    KeyHold {
        since: u64,
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
        cycle_start: u64,
    },
    Program,
}

/// The ZELLE cell. See the [crate docs](crate) and the module docs for the timing model.
#[derive(Clone, Debug)]
pub struct Cell {
    now: u64,
    powered: bool,
    ram: BatteryRam,
    ram_generation: u64,
    /// Writes to the battery-backed RAM not yet taken by the host (for its journal).
    changes: ChangeLog,
    /// The last external RAM address the OS used (the data pointer; command 16 reads it).
    dptr: u16,
    iram: [u8; INTERNAL_RAM_SIZE],
    p1_latch: u8,
    p1_pulled_low: u8,
    p26_latch: bool,
    p26_pulled_low: bool,
    bus: [u8; 128],
    key_down: bool,
    key_release_at: Option<u64>,
    analog: [Source; 4],
    rx: Option<u8>,
    rx_deaf_until: u64,
    setup_rule: SetupRule,
    tx_free_at: u64,
    tx: VecDeque<(u64, u8)>,
    os: Os,
    busy_until: u64,
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
            now: 0,
            powered: false,
            ram,
            ram_generation: 0,
            changes: ChangeLog::default(),
            dptr: 0,
            iram: [0; INTERNAL_RAM_SIZE],
            p1_latch: 0xFF,
            p1_pulled_low: 0,
            p26_latch: true,
            p26_pulled_low: false,
            bus: [OPEN_BUS; 128],
            key_down: false,
            key_release_at: None,
            analog: Default::default(),
            rx: None,
            rx_deaf_until: 0,
            setup_rule: SetupRule::Lose,
            tx_free_at: 0,
            tx: VecDeque::new(),
            os: Os::Off,
            busy_until: 0,
            stats: Stats::default(),
        };
        cell.power_on(0);
        cell
    }

    // ----- the line -------------------------------------------------------------------------

    /// A byte has fully arrived on RxD at `now` (its stop bits ended).
    pub fn receive(&mut self, now: u64, byte: u8) {
        let now = self.advance(now);
        match self.os {
            Os::Off | Os::KeyHold { .. } => {
                self.stats.lost_off += 1;
                return;
            }
            // RxD is wired to the external interrupt too: a 0 byte stops a series or a program
            // at once. Inside the serial routines (every other state) it is masked.
            Os::MeasureWait { .. } | Os::Block { .. } | Os::Program if byte == 0 => {
                self.interrupt(now);
                return;
            }
            // The opaque program never reads the UART.
            Os::Program => {
                self.stats.ignored += 1;
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

    /// Advances to `now` and appends the bytes whose transmission has ended by then.
    pub fn poll(&mut self, now: u64, out: &mut Vec<u8>) {
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
    pub fn next_deadline(&self) -> Option<u64> {
        let busy = (self.powered && self.busy_until > self.now).then_some(self.busy_until);
        let key_hold = match self.os {
            Os::KeyHold { since } => Some(since + KEY_HOLD_READY_NS),
            _ => None,
        };
        [
            self.tx.front().map(|&(done, _)| done),
            busy,
            self.key_release_at,
            key_hold,
        ]
        .into_iter()
        .flatten()
        .min()
    }

    // ----- the outside world ----------------------------------------------------------------

    /// Switches the cell on. The OS starts at address 0: it times the START key if held, then
    /// resumes the mode in the start byte.
    pub fn power_on(&mut self, now: u64) {
        let now = self.advance(now);
        if self.powered {
            return;
        }
        self.powered = true;
        // Internal RAM is not battery-backed; call it cleared.
        self.iram = [0; INTERNAL_RAM_SIZE];
        self.restart(now);
    }

    /// Switches the cell off: bytes still being sent are cut, received bytes are lost, the
    /// battery-backed RAM stays.
    pub fn power_off(&mut self, now: u64) {
        let now = self.advance(now);
        if !self.powered {
            return;
        }
        self.powered = false;
        self.tx.retain(|&(done, _)| done <= now);
        self.rx = None;
        self.os = Os::Off;
    }

    /// The RESET key: like power-on, but internal RAM keeps its contents.
    pub fn reset(&mut self, now: u64) {
        let now = self.advance(now);
        if self.powered {
            self.tx.retain(|&(done, _)| done <= now);
            self.restart(now);
        }
    }

    /// Presses the START key (and keeps it down).
    pub fn key_down(&mut self, now: u64) {
        let now = self.advance(now);
        self.key_release_at = None;
        if self.key_down {
            return;
        }
        self.key_down = true;
        if let Os::MeasureWait { series } = self.os
            && now >= self.busy_until
        {
            self.start_block(now, series);
        }
    }

    /// Releases the START key.
    pub fn key_up(&mut self, now: u64) {
        let now = self.advance(now);
        self.release_key(now);
    }

    /// Presses the START key now and releases it `hold_ns` later.
    pub fn press_key_for(&mut self, now: u64, hold_ns: u64) {
        self.key_down(now);
        self.key_release_at = Some(self.now + hold_ns);
    }

    /// Whether the START key is down.
    pub fn key_is_down(&self) -> bool {
        self.key_down
    }

    /// Feeds A/D input `channel` (1..4) from `source`.
    pub fn set_analog(&mut self, channel: u8, source: Source) -> Result<(), InputError> {
        match channel {
            1..=4 => {
                self.analog[usize::from(channel - 1)] = source;
                Ok(())
            }
            _ => Err(InputError::Channel(channel)),
        }
    }

    /// The source on A/D input `channel` (1..4).
    pub fn analog(&self, channel: u8) -> Option<&Source> {
        self.analog.get(usize::from(channel.wrapping_sub(1)))
    }

    /// Pins of port 1 that outside circuits pull low (a bit set = pulled low). A pin reads low
    /// if either the cell's latch or the outside pulls it low (quasi-bidirectional port).
    pub fn set_port1_pulled_low(&mut self, mask: u8) {
        self.p1_pulled_low = mask;
    }

    /// Whether an outside circuit pulls P2.6 low.
    pub fn set_p26_pulled_low(&mut self, low: bool) {
        self.p26_pulled_low = low;
    }

    /// Sets what the peripheral at parallel-bus address `addr` (0..127) answers to reads.
    pub fn set_bus(&mut self, addr: u8, value: u8) -> Result<(), InputError> {
        let slot = self
            .bus
            .get_mut(usize::from(addr))
            .ok_or(InputError::BusAddress(addr))?;
        *slot = value;
        Ok(())
    }

    // ----- looking inside -------------------------------------------------------------------

    /// The time the model has advanced to.
    pub fn now(&self) -> u64 {
        self.now
    }

    /// Whether the cell is switched on.
    pub fn is_powered(&self) -> bool {
        self.powered
    }

    /// The mode the start byte selects.
    pub fn mode(&self) -> Mode {
        Mode::from_start_byte(self.ram.read(START_BYTE))
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
        &self.ram
    }

    /// Bumped whenever the battery-backed RAM changes, so a state file is rewritten only then.
    pub fn ram_generation(&self) -> u64 {
        self.ram_generation
    }

    /// Writes the battery-backed RAM directly (a test fixture or a control command, not the
    /// serial line).
    pub fn write_ram(&mut self, addr: u16, bytes: &[u8]) {
        for (i, &b) in bytes.iter().enumerate() {
            self.ram_changed(addr.wrapping_add(i as u16), b);
        }
    }

    /// The RAM writes since the last call, as journal records: `[address high, address low,
    /// bytes…]`, contiguous writes in one record.
    pub fn take_ram_changes(&mut self) -> Changes {
        self.changes.take()
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

    /// Writes one byte of battery-backed RAM and notes it for the state file and its journal.
    fn ram_changed(&mut self, addr: u16, value: u8) {
        self.ram.write(addr, value);
        self.ram_generation += 1;
        if let Some(last) = self.changes.last_mut()
            && let [high, low, data @ ..] = &last[..]
            && u32::from(u16::from_be_bytes([*high, *low])) + data.len() as u32 == u32::from(addr)
        {
            last.push(value);
            self.changes.extended(1);
            return;
        }
        let [high, low] = addr.to_be_bytes();
        self.changes.record(vec![high, low, value]);
    }

    /// Internal RAM 0..127.
    pub fn internal_ram(&self) -> &[u8; INTERNAL_RAM_SIZE] {
        &self.iram
    }

    /// Values stored by the current or last series (registers R6:R7).
    pub fn value_count(&self) -> u16 {
        u16::from_be_bytes([
            self.iram[usize::from(COUNT_HIGH_REGISTER)],
            self.iram[usize::from(COUNT_LOW_REGISTER)],
        ])
    }

    /// Port 1 as the cell drives it (its latch).
    pub fn port1_latch(&self) -> u8 {
        self.p1_latch
    }

    /// Port 1 pins: the latch ANDed with outside pull-downs.
    pub fn port1_pins(&self) -> u8 {
        self.p1_latch & !self.p1_pulled_low
    }

    /// P2.6 pin level.
    pub fn p26_pin(&self) -> bool {
        self.p26_latch && !self.p26_pulled_low
    }

    /// The LED on P1.0 lights when the pin is low.
    pub fn led_on(&self) -> bool {
        self.port1_pins() & 1 == 0
    }

    /// What the peripheral at bus address `addr` holds.
    pub fn bus(&self, addr: u8) -> Option<u8> {
        self.bus.get(usize::from(addr)).copied()
    }

    /// Bytes the cell did not take.
    pub fn stats(&self) -> Stats {
        self.stats
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

    /// Runs every event due up to `to` (OS wake-ups, key release, key-hold timeout) in order,
    /// then returns the time the model is at.
    fn advance(&mut self, to: u64) -> u64 {
        let to = to.max(self.now);
        loop {
            let busy = (self.powered && self.busy_until > self.now).then_some(self.busy_until);
            let key_hold = match self.os {
                Os::KeyHold { since } => Some(since + KEY_HOLD_READY_NS),
                _ => None,
            };
            let next = [busy, self.key_release_at, key_hold]
                .into_iter()
                .flatten()
                .filter(|&t| t <= to)
                .min();
            let Some(t) = next else { break };
            self.now = t;
            if self.key_release_at == Some(t) {
                self.release_key(t);
            }
            if let Os::KeyHold { since } = self.os
                && t >= since + KEY_HOLD_READY_NS
            {
                self.end_key_hold(t - since);
            }
            self.run_os(t);
        }
        self.now = to;
        to
    }

    fn release_key(&mut self, now: u64) {
        self.key_release_at = None;
        if !self.key_down {
            return;
        }
        self.key_down = false;
        if let Os::KeyHold { since } = self.os {
            self.end_key_hold(now - since);
        }
    }

    /// Start of the OS after power-on or reset: port latches high, then either time the START
    /// key or resume the stored mode.
    fn restart(&mut self, now: u64) {
        self.p1_latch = 0xFF;
        self.p26_latch = true;
        self.rx = None;
        self.rx_deaf_until = 0;
        self.busy_until = now;
        self.tx_free_at = self.tx_free_at.min(now);
        if self.key_down {
            self.os = Os::KeyHold { since: now };
        } else {
            self.resume();
        }
    }

    fn end_key_hold(&mut self, held: u64) {
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
        self.resume();
    }

    /// Branches on the start byte.
    fn resume(&mut self) {
        self.dptr = START_BYTE;
        match self.mode() {
            Mode::Ready => self.os = Os::Ready,
            Mode::Measure => self.start_series(),
            Mode::Program => self.os = Os::Program,
        }
    }

    /// The interrupt service routine: start byte 0, OS restarted with a fresh stack.
    fn interrupt(&mut self, now: u64) {
        self.set_start_byte(START_READY);
        self.rx = None;
        self.busy_until = now;
        self.os = Os::Ready;
    }

    fn set_start_byte(&mut self, value: u8) {
        self.dptr = START_BYTE;
        if self.ram.read(START_BYTE) != value {
            self.ram_changed(START_BYTE, value);
        }
    }

    fn store(&mut self, addr: u16, value: u8) {
        self.dptr = addr;
        self.ram_changed(addr, value);
    }

    /// The OS reads external RAM (through the data pointer).
    fn load(&mut self, addr: u16) -> u8 {
        self.dptr = addr;
        self.ram.read(addr)
    }

    /// What the special function registers reflect now.
    fn sfr_pins(&self) -> sfr::Pins {
        sfr::Pins {
            p1: self.port1_pins(),
            p26: self.p26_pin(),
            key_down: self.key_down,
            dptr: self.dptr,
        }
    }

    /// Lets the OS run at `now` until it waits for input or is busy past `now`.
    fn run_os(&mut self, now: u64) {
        while self.powered && now >= self.busy_until && self.step(now) {}
    }

    /// One OS action at `now`; false when it is waiting for input.
    fn step(&mut self, now: u64) -> bool {
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
    fn dispatch(&mut self, now: u64, byte: u8) {
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
                self.os = Os::Program;
            }
            // START means nothing outside a series.
            Command::Start => {}
            Command::RepeatSeries => self.start_series(),
            Command::ReadPort1 => self.send(now, self.port1_pins()),
            Command::ReadKey => self.send(now, u8::from(!self.key_down)),
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
    fn execute(&mut self, now: u64, cmd: Command, args: [u8; 3]) {
        match cmd {
            // Channel 0 ends the command without a reading, as it ends command 4's loop.
            Command::Analog if args[0] == 0 => {}
            Command::Analog => self.convert_and_reply(now, args[0]),
            Command::Bus if args[0] & 0x80 != 0 => {
                self.send(now, self.bus[usize::from(args[0] & 0x7F)]);
            }
            Command::Bus => self.bus[usize::from(args[0])] = args[1],
            Command::WritePort1 => self.p1_latch = args[0],
            // The OS moves bit 0 of the byte to the pin.
            Command::WriteP26 => self.p26_latch = args[0] & 1 != 0,
            Command::ReadRegister => {
                let value = match self.iram.get(usize::from(args[0])) {
                    Some(&value) => value,
                    None => sfr::read(args[0], self.sfr_pins()),
                };
                self.send(now, value);
            }
            Command::WriteRegister => {
                if let Some(r) = self.iram.get_mut(usize::from(args[0])) {
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
    fn send(&mut self, now: u64, byte: u8) {
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
    fn convert_and_reply(&mut self, now: u64, channel: u8) {
        let byte = self.sample(channel.wrapping_sub(1) & 3, now);
        self.send(now, byte);
    }

    /// Reads converter input `input` (0..3) sampled at `at`. The converter's lines are P1.0..3;
    /// after a conversion they are all high again.
    fn sample(&mut self, input: u8, at: u64) -> u8 {
        self.p1_latch |= 0x0F;
        self.analog[usize::from(input)].code(at)
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
        self.p1_latch |= 0x0F;
        self.os = Os::MeasureWait {
            series: Series::from_params(params),
        };
    }

    fn set_value_count(&mut self, count: u16) {
        let [high, low] = count.to_be_bytes();
        self.iram[usize::from(COUNT_HIGH_REGISTER)] = high;
        self.iram[usize::from(COUNT_LOW_REGISTER)] = low;
    }

    fn start_block(&mut self, now: u64, series: Series) {
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
        now: u64,
        series: Series,
        cycle: u16,
        slot: u8,
        cycle_start: u64,
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
