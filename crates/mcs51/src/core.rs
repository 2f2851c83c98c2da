//! The core: registers, internal RAM, its time, and the loop that runs instructions and wakes
//! the peripherals when something is due.
//!
//! Time is a count of oscillator clocks ([`Clocks`]); every instruction boundary falls on a
//! machine cycle boundary (a multiple of 12). The hot loop runs instructions back to back and
//! only stops to look around (`service`) when the clock reaches `next_event`: the earliest of
//! the run's limit, the next peripheral instant (a timer flag, a UART sample or edge, an
//! announced pin change) and the earliest instant an interrupt can be taken. A write to a
//! peripheral's register sets `next_event` to 0, so the next boundary looks again.
//!
//! Peripherals are brought up to date lazily: what is due is handled at each look
//! (`catch_up`), and their counts are brought up to the instant only when the program reads or
//! writes one of their registers (`catch_up_fully`). An instruction's reads and writes of special function registers
//! happen at the start of its last machine cycle.

use alloc::collections::VecDeque;
use core::ops::RangeInclusive;

use crate::event::{Event, LineFrame, Stop};
use crate::interrupts::{Flags, Interrupts, Source};
use crate::pins::InputError;
use crate::pins::{Inputs, Pin, Port, Ports, p3};
use crate::sfr::{self, ie, pcon, scon, tcon};
use crate::timers::Timers;
use crate::uart::Uart;
use crate::{Bus, Clocks};

/// Bytes of internal RAM (an 8051: 00h..7Fh).
pub const IRAM_SIZE: usize = 128;

/// What an indirect read of 80h..FFh gives: an 8051 has no RAM there (the 8052's upper 128
/// bytes are missing), so nothing drives the internal bus. Indirect writes there are lost.
pub const NO_UPPER_RAM: u8 = 0xFF;

/// The CPU registers outside internal RAM.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Registers {
    pub pc: u16,
    pub a: u8,
    pub b: u8,
    /// With P as the hardware keeps it (the parity of A).
    pub psw: u8,
    pub sp: u8,
    pub dptr: u16,
}

/// An MCS-51 core (80C51: 128 bytes of internal RAM, two timers, one UART, five interrupt
/// sources, IDLE and power-down), sans-IO: the board hands it its memory ([`Bus`]) at each
/// [`run`](Self::run), announces pin changes with their times ([`set_pin`](Self::set_pin),
/// [`send_rxd`](Self::send_rxd)) and takes what the program did from
/// [`poll_event`](Self::poll_event).
#[derive(Clone, Debug)]
pub struct Mcs51 {
    pub(crate) pc: u16,
    pub(crate) a: u8,
    pub(crate) b: u8,
    /// PSW as written; P is computed from A when read.
    pub(crate) psw: u8,
    pub(crate) sp: u8,
    pub(crate) dptr: u16,
    pub(crate) iram: [u8; IRAM_SIZE],
    /// Instructions run since the core was made.
    pub(crate) instructions: u64,
    /// The current instruction boundary (during an instruction: its end).
    pub(crate) now: Clocks,
    /// The hot loop looks around when `now` reaches this.
    pub(crate) next_event: Clocks,
    limit: Clocks,
    /// The next instant a peripheral or an announced input needs attention.
    next_internal: Clocks,
    pub(crate) ports: Ports,
    inputs: Inputs,
    pub(crate) timers: Timers,
    pub(crate) uart: Uart,
    pub(crate) irq: Interrupts,
    /// Start of the cycle IE0 / IE1 was last set in.
    since_ext: [Clocks; 2],
    pub(crate) pcon: u8,
    idle: bool,
    powered_down: bool,
    /// The instruction just run was RETI or wrote IE/IP: no interrupt at this boundary.
    pub(crate) irq_block: bool,
    events: VecDeque<Event>,
    trap_start: u16,
    trap_len: u32,
}

impl Default for Mcs51 {
    fn default() -> Self {
        Mcs51::new()
    }
}

impl Mcs51 {
    /// A core just powered on at time 0: registers at their reset values, internal RAM clear.
    pub fn new() -> Mcs51 {
        let mut core = Mcs51 {
            pc: 0,
            a: 0,
            b: 0,
            psw: 0,
            sp: 0,
            dptr: 0,
            iram: [0; IRAM_SIZE],
            instructions: 0,
            now: Clocks::ZERO,
            next_event: Clocks::ZERO,
            limit: Clocks::ZERO,
            next_internal: Clocks::NEVER,
            ports: Ports::new(),
            inputs: Inputs::default(),
            timers: Timers::new(Clocks::ZERO),
            uart: Uart::new(Clocks::ZERO, 0),
            irq: Interrupts::default(),
            since_ext: [Clocks::ZERO; 2],
            pcon: 0,
            idle: false,
            powered_down: false,
            irq_block: false,
            events: VecDeque::new(),
            trap_start: 0,
            trap_len: 0,
        };
        core.reset();
        core
    }

    /// The RESET pin: registers and peripherals to their reset values, PC 0000h. Internal RAM,
    /// the time and the outside levels stay; ports that were not all high report the change.
    pub fn reset(&mut self) {
        while let Some(input) = self.inputs.pop_due(self.now) {
            self.apply_levels(input.port, input.mask, input.levels);
        }
        self.pc = 0;
        self.a = 0;
        self.b = 0;
        self.psw = 0;
        self.sp = 0x07;
        self.dptr = 0;
        for port in Port::ALL {
            self.set_latch(port, 0xFF, self.now);
        }
        self.timers = Timers::new(self.now);
        self.uart = Uart::new(self.now, 0);
        self.irq = Interrupts::default();
        self.since_ext = [Clocks::ZERO; 2];
        self.pcon = 0;
        self.idle = false;
        self.powered_down = false;
        self.irq_block = false;
        self.refresh_level_interrupts(self.now);
        self.reschedule();
        self.next_event = Clocks::ZERO;
    }

    // ----- running -------------------------------------------------------------------------

    /// Runs instructions until the first boundary at or after `until`, or until events wait,
    /// the program counter enters the trap range, or the core powers down. Interrupts are
    /// taken, and IDLE waits for them, on the way.
    pub fn run<B: Bus>(&mut self, bus: &mut B, until: Clocks) -> Stop {
        self.limit = until;
        self.next_event = Clocks::ZERO;
        loop {
            if self.now >= self.next_event {
                if let Some(stop) = self.service() {
                    return stop;
                }
                if self.in_trap() {
                    return Stop::Trap { pc: self.pc };
                }
                self.irq_block = false;
            } else if self.in_trap() {
                return Stop::Trap { pc: self.pc };
            }
            self.execute(bus);
        }
    }

    /// Runs one instruction (or enters one interrupt routine, or idles one cycle).
    pub fn step<B: Bus>(&mut self, bus: &mut B) -> Stop {
        self.run(bus, self.now + Clocks(1))
    }

    /// Lets time pass to `until` without running instructions or taking interrupts, the
    /// peripherals going on: the CPU is busy elsewhere (in a routine the board carries out for
    /// a trap). Returns early when events wait.
    pub fn stall(&mut self, until: Clocks) -> Stop {
        loop {
            if self.powered_down {
                self.power_down_until(until);
                return Stop::PowerDown;
            }
            self.catch_up(self.now);
            if !self.events.is_empty() {
                self.next_event = Clocks::ZERO;
                return Stop::Events;
            }
            if self.now >= until {
                return Stop::Limit;
            }
            self.now = next_boundary(self.now, self.next_internal.min(until));
        }
    }

    /// The next event the program caused, oldest first.
    pub fn poll_event(&mut self) -> Option<Event> {
        self.events.pop_front()
    }

    /// The time: the current instruction boundary.
    pub fn now(&self) -> Clocks {
        self.now
    }

    /// Instructions run since the core was made (resets do not clear it).
    pub fn instructions(&self) -> u64 {
        self.instructions
    }

    /// When the core next needs running: now while the CPU runs; in IDLE, the next instant a
    /// peripheral or an announced input changes something (an interrupt can only come from
    /// there); `None` in power-down or when idling with nothing ahead.
    pub fn next_deadline(&self) -> Option<Clocks> {
        if self.powered_down {
            None
        } else if self.idle {
            (self.next_internal != Clocks::NEVER).then_some(self.next_internal)
        } else {
            Some(self.now)
        }
    }

    /// Whether the CPU is in IDLE (PCON.IDL).
    pub fn is_idle(&self) -> bool {
        self.idle
    }

    /// Whether the core is powered down (PCON.PD).
    pub fn is_powered_down(&self) -> bool {
        self.powered_down
    }

    // ----- traps ---------------------------------------------------------------------------

    /// Addresses at which [`run`](Self::run) stops with [`Stop::Trap`] instead of fetching:
    /// the entry points (and interrupt vectors) of an operating system the board models.
    pub fn set_traps(&mut self, range: RangeInclusive<u16>) {
        self.trap_start = *range.start();
        self.trap_len = if range.is_empty() {
            0
        } else {
            u32::from(*range.end() - *range.start()) + 1
        };
    }

    /// No traps.
    pub fn clear_traps(&mut self) {
        self.trap_len = 0;
    }

    #[inline(always)]
    fn in_trap(&self) -> bool {
        u32::from(self.pc.wrapping_sub(self.trap_start)) < self.trap_len
    }

    // ----- the outside ---------------------------------------------------------------------

    /// The outside drives `pin` high (`true`: or leaves it alone) or low from `at` on (from the
    /// next sample at or after `at`; an `at` already past counts as now).
    pub fn set_pin(&mut self, at: Clocks, pin: Pin, high: bool) -> Result<(), InputError> {
        let levels = if high { pin.mask() } else { 0 };
        self.inputs
            .push(at, self.now, pin.port(), pin.mask(), levels)?;
        self.after_input();
        Ok(())
    }

    /// The outside drives all of `port`'s pins from `at` on (1 = high or left alone).
    pub fn set_port(&mut self, at: Clocks, port: Port, levels: u8) -> Result<(), InputError> {
        self.set_port_bits(at, port, 0xFF, levels)
    }

    /// The outside drives the pins of `port` in `mask` from `at` on (1 = high or left alone);
    /// the other pins keep what was announced for them.
    pub fn set_port_bits(
        &mut self,
        at: Clocks,
        port: Port,
        mask: u8,
        levels: u8,
    ) -> Result<(), InputError> {
        self.inputs.push(at, self.now, port, mask, levels)?;
        self.after_input();
        Ok(())
    }

    /// The outside drives the pins of `port` in `mask` to `levels` from now on, seen by the
    /// next instruction already: for a device that answers a port write within the writing
    /// instruction's cycle (a converter's data output after its clock edge). The board takes
    /// the [`Event::Port`] that [`run`](Self::run) stopped for and answers before running on;
    /// [`set_pin`](Self::set_pin) would wait for the next sample instant after now. Changes
    /// announced for later still take effect at their time.
    pub fn drive_now(&mut self, port: Port, mask: u8, levels: u8) {
        self.catch_up_fully(self.now);
        let before = self.ports.pins(3);
        self.apply_levels(port as u8, mask, levels & mask);
        if port == Port::P3 {
            let after = self.ports.pins(3);
            self.p3_changed(self.now, before, after);
        }
        self.reschedule();
        self.next_event = Clocks::ZERO;
    }

    /// Puts `frame` on RxD starting at `at` (the start bit's leading edge): start bit, data
    /// bits least significant first, the 9th bit if any, then the line high (stop bits and
    /// idle). Returns when the first stop bit ends.
    pub fn send_rxd(&mut self, at: Clocks, frame: LineFrame) -> Result<Clocks, InputError> {
        if frame.bit_clocks == Clocks::ZERO || frame.bit_clocks > Clocks(1_000_000_000) {
            return Err(InputError::BitTime(frame.bit_clocks));
        }
        let data_bits: u64 = if frame.ninth.is_some() { 9 } else { 8 };
        let needed = 2 + data_bits as usize;
        if self.inputs.len() + needed > crate::pins::MAX_QUEUED_INPUTS {
            return Err(InputError::Full {
                queued: self.inputs.len(),
            });
        }
        let word = u16::from(frame.data) | u16::from(frame.ninth == Some(true)) << 8;
        let mut level = true;
        let mut change = |core: &mut Mcs51, bit: u64, high: bool| {
            if high != level {
                level = high;
                let t = at + frame.bit_clocks * bit;
                core.inputs
                    .push(
                        t,
                        core.now,
                        Port::P3,
                        p3::RXD,
                        if high { p3::RXD } else { 0 },
                    )
                    .expect("room checked above");
            }
        };
        change(self, 0, false);
        for i in 0..data_bits {
            change(self, 1 + i, word >> i & 1 != 0);
        }
        change(self, 1 + data_bits, true);
        self.after_input();
        Ok(at + frame.bit_clocks * (2 + data_bits))
    }

    fn after_input(&mut self) {
        self.next_internal = self.next_internal.min(self.inputs.next_at());
        self.next_event = Clocks::ZERO;
    }

    // ----- looking inside ------------------------------------------------------------------

    /// The registers.
    pub fn registers(&self) -> Registers {
        Registers {
            pc: self.pc,
            a: self.a,
            b: self.b,
            psw: self.psw_value(),
            sp: self.sp,
            dptr: self.dptr,
        }
    }

    /// Sets the registers (P in `psw` is ignored: it follows A).
    pub fn set_registers(&mut self, r: Registers) {
        self.pc = r.pc;
        self.a = r.a;
        self.b = r.b;
        self.psw = r.psw;
        self.sp = r.sp;
        self.dptr = r.dptr;
    }

    /// The program counter.
    pub fn pc(&self) -> u16 {
        self.pc
    }

    /// Continues at `pc`.
    pub fn set_pc(&mut self, pc: u16) {
        self.pc = pc;
    }

    /// The accumulator.
    pub fn a(&self) -> u8 {
        self.a
    }

    /// Register Rn (0..=7) of the selected bank.
    pub fn r(&self, n: u8) -> u8 {
        self.iram[usize::from((self.psw & 0x18) | (n & 7))]
    }

    /// Internal RAM.
    pub fn iram(&self) -> &[u8; IRAM_SIZE] {
        &self.iram
    }

    /// Internal RAM, to change.
    pub fn iram_mut(&mut self) -> &mut [u8; IRAM_SIZE] {
        &mut self.iram
    }

    /// What a `MOV A,direct` would read at `addr` now (RAM below 80h, SFRs above; ports read
    /// their pins).
    pub fn read_direct(&mut self, addr: u8) -> u8 {
        if addr < 0x80 {
            self.iram[usize::from(addr)]
        } else {
            self.sfr_read(addr, false, self.now)
        }
    }

    /// What a `MOV direct,A` would do now.
    pub fn write_direct(&mut self, addr: u8, value: u8) {
        if addr < 0x80 {
            self.iram[usize::from(addr)] = value;
        } else {
            self.sfr_write(addr, value, self.now);
        }
    }

    /// A port's latch (what the program wrote).
    pub fn port_latch(&self, port: Port) -> u8 {
        self.ports.latch[port.index()]
    }

    /// A port's pins now (latch AND outside levels taken so far).
    pub fn port_pins(&self, port: Port) -> u8 {
        self.ports.pins(port.index())
    }

    /// Pushes `value` as `PUSH` does.
    pub fn push(&mut self, value: u8) {
        self.sp = self.sp.wrapping_add(1);
        self.set_indirect(self.sp, value);
    }

    /// Pops a byte as `POP` does.
    pub fn pop(&mut self) -> u8 {
        let v = self.indirect(self.sp);
        self.sp = self.sp.wrapping_sub(1);
        v
    }

    /// Returns from a subroutine as `RET` does (for a trap's routine), without spending time.
    /// It stands for an instruction: after a write to IE or IP in the routine, it is the one
    /// more instruction that runs before an interrupt is taken.
    pub fn ret(&mut self) {
        let hi = self.pop();
        let lo = self.pop();
        self.pc = u16::from_be_bytes([hi, lo]);
        self.irq_block = false;
    }

    /// Returns from an interrupt routine as `RETI` does (for a trapped interrupt vector),
    /// without spending time: the routine's priority level ends, and one more instruction runs
    /// before the next interrupt is taken.
    pub fn reti(&mut self) {
        self.ret();
        self.irq.reti();
        self.irq_block = true;
        self.next_event = Clocks::ZERO;
    }

    /// Whether the UART is sending: SBUF was written and the frame's TI is not set yet.
    pub fn transmitting(&self) -> bool {
        self.uart.sending()
    }

    // ----- inside: data access -------------------------------------------------------------

    #[inline(always)]
    pub(crate) fn psw_value(&self) -> u8 {
        (self.psw & !sfr::psw::P) | (self.a.count_ones() & 1) as u8
    }

    #[inline(always)]
    pub(crate) fn indirect(&self, addr: u8) -> u8 {
        if addr < 0x80 {
            self.iram[usize::from(addr)]
        } else {
            NO_UPPER_RAM
        }
    }

    #[inline(always)]
    pub(crate) fn set_indirect(&mut self, addr: u8, value: u8) {
        if addr < 0x80 {
            self.iram[usize::from(addr)] = value;
        }
    }

    /// Reads SFR `addr` at `at`: ports give their pins, or with `latch` their latch (the
    /// read-modify-write instructions).
    pub(crate) fn sfr_read(&mut self, addr: u8, latch: bool, at: Clocks) -> u8 {
        match addr {
            sfr::ACC => self.a,
            sfr::B => self.b,
            sfr::PSW => self.psw_value(),
            sfr::SP => self.sp,
            sfr::DPL => self.dptr as u8,
            sfr::DPH => (self.dptr >> 8) as u8,
            sfr::P0 | sfr::P1 | sfr::P2 | sfr::P3 => {
                self.catch_up(at);
                let port = usize::from((addr - sfr::P0) >> 4);
                if latch {
                    self.ports.latch[port]
                } else {
                    self.ports.pins(port)
                }
            }
            sfr::TCON | sfr::TL0 | sfr::TL1 | sfr::TH0 | sfr::TH1 => {
                self.catch_up_fully(at);
                match addr {
                    sfr::TCON => self.timers.tcon,
                    sfr::TL0 => self.timers.tl[0],
                    sfr::TL1 => self.timers.tl[1],
                    sfr::TH0 => self.timers.th[0],
                    _ => self.timers.th[1],
                }
            }
            sfr::TMOD => self.timers.tmod,
            sfr::SCON => {
                self.catch_up(at);
                self.uart.scon
            }
            sfr::SBUF => self.uart.sbuf,
            sfr::IE => self.irq.ie,
            sfr::IP => self.irq.ip,
            sfr::PCON => self.pcon,
            _ => sfr::UNIMPLEMENTED_READ,
        }
    }

    /// Writes SFR `addr` at `at`.
    pub(crate) fn sfr_write(&mut self, addr: u8, value: u8, at: Clocks) {
        match addr {
            sfr::ACC => self.a = value,
            sfr::B => self.b = value,
            sfr::PSW => self.psw = value,
            sfr::SP => self.sp = value,
            sfr::DPL => self.dptr = (self.dptr & 0xFF00) | u16::from(value),
            sfr::DPH => self.dptr = (self.dptr & 0x00FF) | u16::from(value) << 8,
            _ => self.sfr_write_peripheral(addr, value, at),
        }
    }

    #[inline(never)]
    fn sfr_write_peripheral(&mut self, addr: u8, value: u8, at: Clocks) {
        self.catch_up_fully(at);
        match addr {
            sfr::P0 => self.set_latch(Port::P0, value, at),
            sfr::P1 => self.set_latch(Port::P1, value, at),
            sfr::P2 => self.set_latch(Port::P2, value, at),
            sfr::P3 => {
                let before = self.ports.pins(3);
                self.set_latch(Port::P3, value, at);
                let after = self.ports.pins(3);
                self.p3_changed(at, before, after);
            }
            sfr::TCON => self.write_tcon(value, at),
            sfr::TMOD => self.timers.tmod = value,
            sfr::TL0 => self.timers.tl[0] = value,
            sfr::TL1 => self.timers.tl[1] = value,
            sfr::TH0 => self.timers.th[0] = value,
            sfr::TH1 => self.timers.th[1] = value,
            sfr::SCON => self.uart.write_scon(value, at),
            sfr::SBUF => self.uart.write_sbuf(value, at),
            sfr::PCON => {
                self.uart.set_smod(value & pcon::SMOD != 0);
                self.pcon = value;
                if value & pcon::PD != 0 {
                    self.powered_down = true;
                } else if value & pcon::IDL != 0 {
                    self.idle = true;
                }
            }
            sfr::IE => {
                self.irq.ie = value;
                self.irq_block = true;
            }
            sfr::IP => {
                self.irq.ip = value;
                self.irq_block = true;
            }
            _ => {}
        }
        self.reschedule();
        self.next_event = Clocks::ZERO;
    }

    /// A `MOVX`: port 0 carries the address and data, which leaves 1s in its latch.
    #[inline]
    pub(crate) fn external_access(&mut self, at: Clocks) {
        if self.ports.latch[0] != 0xFF {
            self.set_latch(Port::P0, 0xFF, at);
        }
    }

    fn set_latch(&mut self, port: Port, value: u8, at: Clocks) {
        let latch = &mut self.ports.latch[port.index()];
        if *latch != value {
            *latch = value;
            self.push_event(Event::Port {
                port,
                latch: value,
                at,
            });
        }
    }

    pub(crate) fn push_event(&mut self, event: Event) {
        self.events.push_back(event);
        self.next_event = Clocks::ZERO;
    }

    fn write_tcon(&mut self, value: u8, at: Clocks) {
        let old = self.timers.tcon;
        self.timers.tcon = value;
        for (t, flag) in [tcon::TF0, tcon::TF1].into_iter().enumerate() {
            if value & flag != 0 && old & flag == 0 {
                self.timers.since_tf[t] = at;
            }
        }
        for (x, flag) in [tcon::IE0, tcon::IE1].into_iter().enumerate() {
            if value & flag != 0 && old & flag == 0 {
                self.since_ext[x] = at;
            }
        }
        self.refresh_level_interrupts(at);
    }

    /// In level mode (ITx clear) IEx is the inverse of the INTx pin, whatever was written.
    fn refresh_level_interrupts(&mut self, at: Clocks) {
        let pins = self.ports.pins(3);
        let cycle = at.cycle_start();
        for (it, flag, pin, x) in [
            (tcon::IT0, tcon::IE0, p3::INT0, 0),
            (tcon::IT1, tcon::IE1, p3::INT1, 1),
        ] {
            let tcon = self.timers.tcon;
            if tcon & it != 0 {
                continue;
            }
            if pins & pin == 0 {
                if tcon & flag == 0 {
                    self.timers.tcon |= flag;
                    self.since_ext[x] = cycle;
                }
            } else {
                self.timers.tcon &= !flag;
            }
        }
    }

    /// P3's pins went from `before` to `after`, sampled at `at` (peripherals synced to `at`).
    fn p3_changed(&mut self, at: Clocks, before: u8, after: u8) {
        if before == after {
            return;
        }
        let cycle = at.cycle_start();
        let fell = before & !after;
        for (it, flag, pin, x) in [
            (tcon::IT0, tcon::IE0, p3::INT0, 0),
            (tcon::IT1, tcon::IE1, p3::INT1, 1),
        ] {
            let tcon = self.timers.tcon;
            if tcon & it != 0 && fell & pin != 0 && tcon & flag == 0 {
                self.timers.tcon |= flag;
                self.since_ext[x] = cycle;
            }
        }
        self.refresh_level_interrupts(at);
        if fell & p3::T0 != 0 {
            self.timers.count_edge(0, cycle, after);
        }
        if fell & p3::T1 != 0 {
            self.timers.count_edge(1, cycle, after);
            self.uart.sync(at, self.timers.t1_overflows);
        }
        if fell & p3::RXD != 0 {
            self.uart.rxd_fell();
        }
    }

    fn apply_levels(&mut self, port: u8, mask: u8, levels: u8) {
        let outside = &mut self.ports.outside[usize::from(port & 3)];
        *outside = (*outside & !mask) | levels;
    }

    // ----- inside: peripherals -------------------------------------------------------------

    fn sync(&mut self, t: Clocks) {
        let pins = self.ports.pins(3);
        self.timers.sync(t, pins);
        self.uart.sync(t, self.timers.t1_overflows);
    }

    /// Handles everything due by `to`, in time order. Flags and events are then as they are at
    /// `to`; counts (timer registers, baud ticks) only where something was due.
    pub(crate) fn catch_up(&mut self, to: Clocks) {
        while self.next_internal <= to {
            let t = self.next_internal;
            self.sync(t);
            let before = self.ports.pins(3);
            while let Some(input) = self.inputs.pop_due(t) {
                self.apply_levels(input.port, input.mask, input.levels);
            }
            let after = self.ports.pins(3);
            self.p3_changed(t, before, after);
            if let Some(frame) = self.uart.process(t, after) {
                self.push_event(Event::Serial(frame));
            }
            self.reschedule();
        }
    }

    /// Brings the peripherals up to `to` entirely, counts included: before the program reads
    /// or writes one of their registers.
    fn catch_up_fully(&mut self, to: Clocks) {
        self.catch_up(to);
        self.sync(to);
    }

    fn reschedule(&mut self) {
        let pins = self.ports.pins(3);
        self.next_internal = self
            .inputs
            .next_at()
            .min(self.timers.next_flag_time(pins))
            .min(self.uart.next_time(&self.timers, pins));
    }

    fn flags(&self) -> Flags {
        let t = self.timers.tcon;
        let s = self.uart.scon;
        let serial = match (s & scon::RI != 0, s & scon::TI != 0) {
            (true, true) => Some(self.uart.since_ri.min(self.uart.since_ti)),
            (true, false) => Some(self.uart.since_ri),
            (false, true) => Some(self.uart.since_ti),
            (false, false) => None,
        };
        [
            (t & tcon::IE0 != 0).then_some(self.since_ext[0]),
            (t & tcon::TF0 != 0).then_some(self.timers.since_tf[0]),
            (t & tcon::IE1 != 0).then_some(self.since_ext[1]),
            (t & tcon::TF1 != 0).then_some(self.timers.since_tf[1]),
            serial,
        ]
    }

    fn irq_at(&self) -> Clocks {
        if self.irq.ie & ie::EA == 0 {
            Clocks::NEVER
        } else {
            self.irq.earliest(&self.flags())
        }
    }

    /// The hardware `LCALL` into `source`'s routine.
    fn vector(&mut self, source: Source, high: bool) {
        let [hi, lo] = self.pc.to_be_bytes();
        self.push(lo);
        self.push(hi);
        self.pc = source.vector();
        self.now += Clocks::from_cycles(2);
        self.irq.enter(high);
        let tcon = &mut self.timers.tcon;
        match source {
            Source::Timer0 => *tcon &= !tcon::TF0,
            Source::Timer1 => *tcon &= !tcon::TF1,
            Source::External0 if *tcon & tcon::IT0 != 0 => *tcon &= !tcon::IE0,
            Source::External1 if *tcon & tcon::IT1 != 0 => *tcon &= !tcon::IE1,
            _ => {}
        }
        if self.idle {
            self.idle = false;
            self.pcon &= !pcon::IDL;
        }
        self.reschedule();
    }

    /// Time passes to `until` with the oscillator stopped: pins still change, nothing counts
    /// or samples them.
    fn power_down_until(&mut self, until: Clocks) {
        self.catch_up_fully(self.now);
        let to = self.now.max(until.round_up_to_cycle());
        while let Some(input) = self.inputs.pop_due(to) {
            self.apply_levels(input.port, input.mask, input.levels);
        }
        self.timers.skip_to(to);
        self.uart.skip_to(to);
        self.now = to;
        self.reschedule();
    }

    /// At an instruction boundary: peripherals, events, the limit, interrupts, IDLE. `None`
    /// when the next instruction may run, with `next_event` set for the next look.
    #[inline(never)]
    fn service(&mut self) -> Option<Stop> {
        loop {
            if self.powered_down {
                self.power_down_until(self.limit);
                return Some(Stop::PowerDown);
            }
            self.catch_up(self.now);
            if !self.events.is_empty() {
                self.next_event = Clocks::ZERO;
                return Some(Stop::Events);
            }
            if self.now >= self.limit {
                self.next_event = Clocks::ZERO;
                return Some(Stop::Limit);
            }
            let irq_at = if self.irq_block {
                Clocks::NEVER
            } else {
                self.irq_at()
            };
            if irq_at <= self.now {
                let flags = self.flags();
                if let Some((source, high)) = self.irq.choose(&flags, self.now) {
                    self.vector(source, high);
                    continue;
                }
            }
            if self.idle {
                self.irq_block = false;
                let wake = self.next_internal.min(irq_at).min(self.limit);
                self.now = next_boundary(self.now, wake);
                continue;
            }
            self.next_event = if self.irq_block {
                self.now + Clocks(1)
            } else {
                self.next_internal.min(irq_at).min(self.limit)
            };
            return None;
        }
    }
}

/// The boundary to jump to from `now` when nothing happens before `t`: at least one cycle on.
fn next_boundary(now: Clocks, t: Clocks) -> Clocks {
    t.round_up_to_cycle().max(now + Clocks::CYCLE)
}
