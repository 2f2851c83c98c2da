//! The core: registers, time, and the loop that runs instructions and takes exceptions.
//!
//! Time is a count of CPU cycles. The hot loop (`run_until`) fetches, decodes on the primary
//! opcode and executes instructions back to back until the cycle count reaches a deadline: the
//! earliest of the run's limit and the next timer event that can interrupt. Anything that can
//! make an interrupt deliverable (`mtmsr`, `wrtee`, `rfi`, `mtspr` to a timer register,
//! `mtdcr`) ends the inner loop with [`Event::Sync`], so the outer loop (`run`) looks again:
//! timers brought up to date, interrupts taken at that instruction boundary.

use crate::dcr::Dcrs;
use crate::exceptions::msr;
use crate::interrupts::Interrupts;
use crate::spr::Sprs;
use crate::timers::Timers;
use crate::{Bus, Cycles};

/// The registers a program sees (and a debugger shows).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Registers {
    pub pc: u32,
    pub gpr: [u32; 32],
    pub cr: u32,
    pub lr: u32,
    pub ctr: u32,
    pub xer: u32,
    pub msr: u32,
    pub srr0: u32,
    pub srr1: u32,
    /// The 403's critical-interrupt save registers.
    pub srr2: u32,
    pub srr3: u32,
    pub sprg: [u32; 4],
    /// Exception vector prefix (the upper 16 bits of every vector address).
    pub evpr: u32,
    pub esr: u32,
    pub dear: u32,
}

/// An interrupt input of the 403's interrupt controller (EXISR/EXIER). Level-sensitive: the
/// board sets the line's level, the controller latches it in EXISR while it is high.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Irq {
    /// The critical interrupt pin (vector 0x0100, saved in SRR2/SRR3).
    Critical,
    /// The on-chip serial port's receiver (a byte is ready or a receive error).
    SerialReceive,
    /// The on-chip serial port's transmitter (ready for the next byte).
    SerialTransmit,
    /// External interrupt pin INT0..INT4 (a higher number is ignored).
    External(u8),
}

/// Why an exception was taken.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Exception {
    /// A load, store or fetch where nothing answered (vector 0x0200).
    MachineCheck { addr: u32 },
    /// An external or on-chip interrupt through EXISR/EXIER (vector 0x0500).
    External,
    /// A misaligned load or store (vector 0x0600).
    Alignment { addr: u32 },
    /// An illegal instruction word (vector 0x0700, ESR[PIL]).
    Illegal { word: u32 },
    /// A supervisor instruction in problem state (vector 0x0700, ESR[PPR]).
    Privileged { word: u32 },
    /// `tw`/`twi` whose condition held (vector 0x0700, ESR[PTR]).
    Trap,
    /// `sc` (vector 0x0C00).
    SystemCall,
    /// The programmable interval timer reached zero (vector 0x1000).
    Pit,
    /// The fixed interval timer (vector 0x1010).
    Fit,
    /// The watchdog's first time-out (vector 0x1020, critical).
    Watchdog,
    /// The critical interrupt pin (vector 0x0100, critical).
    Critical,
}

/// Why [`Ppc403::run`] returned.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stop {
    /// The limit was reached.
    Limit,
    /// An exception was just taken: the PC is at its vector, SRR0/SRR1 (SRR2/SRR3) saved.
    /// The board decides whether a program handles it (its vector holds code) or whether
    /// the program crashed. `at` is the address of the instruction that caused it (for an
    /// interrupt: the instruction it came before, the saved SRR0/SRR2).
    Exception { kind: Exception, at: u32 },
    /// `sc` ran while [`Ppc403::set_trap_sc`] is on: nothing was saved or vectored, the PC is
    /// past the `sc`; the board serves the call (registers as the program left them).
    SystemCall { at: u32 },
    /// MSR[WE] is set: the core waits for an interrupt; time was advanced to the limit or to
    /// the next timer event.
    Wait,
    /// The watchdog's second time-out with TCR[WRC] ≠ 0: the core has reset itself (PC
    /// 0xFFFF_FFFC, MSR 0, TCR 0; TSR[WRS] tells which reset). The board decides what the
    /// reset does to the rest of the system (for the node: back to the resident firmware).
    Reset { by: crate::WatchdogReset },
}

/// What ends an instruction other than completing normally.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Event {
    /// A synchronous exception: the instruction did not complete (for `sc`: it did).
    Exception(Exception),
    /// `sc` (vectored or trapped, depending on `trap_sc`).
    SystemCall,
    /// The instruction completed and changed something the outer loop must look at
    /// (interrupt enables, timers, MSR[WE]).
    Sync,
}

pub(crate) type Executed = Result<(), Event>;

/// A PowerPC 403 core.
#[derive(Clone, Debug)]
pub struct Ppc403 {
    pub(crate) regs: Registers,
    /// The current cycle (during an instruction: its end, as far as counted).
    pub(crate) now: u64,
    instructions: u64,
    trap_sc: bool,
    pub(crate) timers: Timers,
    pub(crate) irq: Interrupts,
    pub(crate) dcrs: Dcrs,
    pub(crate) sprs: Sprs,
    /// The address `lwarx` reserved, until a `stwcx.` or an exception.
    pub(crate) reservation: Option<u32>,
}

impl Default for Ppc403 {
    fn default() -> Self {
        Ppc403::new()
    }
}

impl Ppc403 {
    /// A core after reset: PC at 0xFFFF_FFFC, MSR 0 (supervisor, interrupts off).
    pub fn new() -> Ppc403 {
        Ppc403 {
            regs: Registers {
                pc: 0xFFFF_FFFC,
                ..Registers::default()
            },
            now: 0,
            instructions: 0,
            trap_sc: false,
            timers: Timers::default(),
            irq: Interrupts::default(),
            dcrs: Dcrs::default(),
            sprs: Sprs::default(),
            reservation: None,
        }
    }

    /// A reset (the chip's reset input, a power cycle): the registers, timers, interrupt
    /// controller and DCRs as [`new`](Self::new) makes them, but time goes on: `now()`,
    /// `instructions()` and the time base keep counting, the interrupt lines keep their
    /// levels (EXISR latches those that are high), `set_trap_sc` stays as it was.
    pub fn reset(&mut self) {
        let fresh = Ppc403 {
            now: self.now,
            instructions: self.instructions,
            trap_sc: self.trap_sc,
            ..Ppc403::new()
        };
        let levels = self.irq.levels;
        let tb = self.time_base();
        *self = fresh;
        self.timers.checked = self.now;
        self.timers.tb_offset = tb.wrapping_sub(self.now);
        self.irq.levels = levels;
        self.irq.status = levels;
    }

    /// Runs instructions until `limit` (the cycle count, not a duration) or an event. An
    /// instruction started before `limit` completes, so `now()` may pass `limit` by the
    /// cycles of one instruction.
    pub fn run(&mut self, bus: &mut impl Bus, limit: Cycles) -> Stop {
        let limit = limit.0;
        loop {
            self.catch_up_timers();
            if let Some(by) = self.timers.reset.take() {
                self.watchdog_reset();
                return Stop::Reset { by };
            }
            if let Some(kind) = self.deliverable_interrupt() {
                let at = self.regs.pc;
                return self.take_exception(kind, at, at);
            }
            let waiting = self.regs.msr & msr::WE != 0;
            if self.now >= limit {
                return if waiting { Stop::Wait } else { Stop::Limit };
            }
            let deadline = limit.min(self.next_timer_event());
            if waiting {
                self.now = self.now.max(deadline);
                continue;
            }
            if let Err(stop) = self.run_until(bus, deadline) {
                return stop;
            }
        }
    }

    /// The hot loop: instructions until `deadline` or an [`Event`]. `Err` is a stop for the
    /// caller of `run`.
    fn run_until(&mut self, bus: &mut impl Bus, deadline: u64) -> Result<(), Stop> {
        while self.now < deadline {
            let pc = self.regs.pc & !3;
            let word = match bus.fetch(pc) {
                Ok(word) => word,
                Err(e) => {
                    self.regs.esr = crate::exceptions::esr::MCI;
                    let kind = Exception::MachineCheck { addr: e.addr };
                    return Err(self.take_exception(kind, pc, pc));
                }
            };
            self.regs.pc = pc.wrapping_add(4);
            self.now = self.now.saturating_add(1);
            match self.execute(bus, word, pc) {
                Ok(()) => self.instructions += 1,
                Err(Event::Sync) => {
                    self.instructions += 1;
                    return Ok(());
                }
                Err(Event::SystemCall) => {
                    self.instructions += 1;
                    if self.trap_sc {
                        return Err(Stop::SystemCall { at: pc });
                    }
                    let next = self.regs.pc;
                    return Err(self.take_exception(Exception::SystemCall, next, pc));
                }
                Err(Event::Exception(kind)) => {
                    return Err(self.take_exception(kind, pc, pc));
                }
            }
        }
        Ok(())
    }

    /// Sets an interrupt line's level.
    pub fn set_irq(&mut self, irq: Irq, level: bool) {
        self.irq.set_line(irq, level);
    }

    /// `sc` stops [`run`](Self::run) with [`Stop::SystemCall`] instead of vectoring.
    pub fn set_trap_sc(&mut self, on: bool) {
        self.trap_sc = on;
    }

    pub fn registers(&self) -> &Registers {
        &self.regs
    }

    pub fn registers_mut(&mut self) -> &mut Registers {
        &mut self.regs
    }

    pub fn pc(&self) -> u32 {
        self.regs.pc
    }

    pub fn set_pc(&mut self, pc: u32) {
        self.regs.pc = pc;
    }

    pub fn gpr(&self, n: usize) -> u32 {
        self.regs.gpr[n]
    }

    pub fn set_gpr(&mut self, n: usize, value: u32) {
        self.regs.gpr[n] = value;
    }

    /// The current cycle.
    pub fn now(&self) -> Cycles {
        Cycles(self.now)
    }

    /// Instructions completed since the core was made.
    pub fn instructions(&self) -> u64 {
        self.instructions
    }

    /// CR0 from a signed result, with XER[SO].
    #[inline(always)]
    pub(crate) fn set_cr0(&mut self, value: u32) {
        let field = compare_field(value as i32, 0) | self.xer_so();
        self.regs.cr = (self.regs.cr & 0x0FFF_FFFF) | (field << 28);
    }

    /// Sets CR field `n` (0..7) to the low 4 bits of `field`.
    #[inline(always)]
    pub(crate) fn set_cr_field(&mut self, n: usize, field: u32) {
        let shift = 28 - 4 * n as u32;
        self.regs.cr = (self.regs.cr & !(0xF << shift)) | ((field & 0xF) << shift);
    }

    /// XER[SO] as the low bit of a CR field (1 or 0).
    #[inline(always)]
    pub(crate) fn xer_so(&self) -> u32 {
        self.regs.xer >> 31
    }

    #[inline(always)]
    pub(crate) fn problem_state(&self) -> bool {
        self.regs.msr & msr::PR != 0
    }

    /// Adds cycles beyond the one every instruction takes.
    #[inline(always)]
    pub(crate) fn spend(&mut self, cycles: u64) {
        self.now = self.now.saturating_add(cycles);
    }
}

/// LT, GT or EQ (as bits 3, 2, 1 of a CR field) of comparing `a` with `b`.
#[inline(always)]
pub(crate) fn compare_field<T: Ord>(a: T, b: T) -> u32 {
    match a.cmp(&b) {
        core::cmp::Ordering::Less => 0b1000,
        core::cmp::Ordering::Greater => 0b0100,
        core::cmp::Ordering::Equal => 0b0010,
    }
}
