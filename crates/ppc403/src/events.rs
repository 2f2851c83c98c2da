//! What interrupts the program: exceptions taken and returned from, the interrupt to deliver
//! at an instruction boundary, and the timers caught up with the clock. The registers, bits
//! and vectors are in `exceptions`, `interrupts` and `timers`.

use crate::core::{Event, Executed, Ppc403, Registers, Stop, privileged};
use crate::exceptions::{Exception, esr, msr};
use crate::interrupts::exisr;
use crate::timers::{
    WatchdogReset, crossings, fit_bits, tcr, to_next_multiple, tsr, watchdog_bits,
};

/// The MSR bits a non-critical exception keeps (it clears WE, EE, PR, PE, PX, LE).
const KEPT_NONCRITICAL: u32 = msr::APE | msr::CE | msr::ILE | msr::ME | msr::DE;
/// The MSR bits a critical exception keeps (it also clears CE and DE; a machine check clears
/// ME as well).
const KEPT_CRITICAL: u32 = msr::APE | msr::ILE | msr::ME;

impl Ppc403 {
    /// Takes `kind`: saves `srr0` (the instruction to return to) and the MSR, sets ESR for
    /// program exceptions, clears the MSR bits, jumps to the vector. `at` is what
    /// [`Stop::Exception`] reports.
    pub(crate) fn take_exception(&mut self, kind: Exception, srr0: u32, at: u32) -> Stop {
        match kind {
            Exception::Illegal { .. } => self.regs.esr = esr::PIL,
            Exception::Privileged { .. } => self.regs.esr = esr::PPR,
            Exception::Trap => self.regs.esr = esr::PTR,
            _ => {}
        }
        let old = self.regs.msr;
        if kind.is_critical() {
            self.regs.srr2 = srr0;
            self.regs.srr3 = old;
            let mut kept = KEPT_CRITICAL;
            if matches!(kind, Exception::MachineCheck { .. }) {
                kept &= !msr::ME;
            }
            self.regs.msr = old & kept;
        } else {
            self.regs.srr0 = srr0;
            self.regs.srr1 = old;
            self.regs.msr = old & KEPT_NONCRITICAL;
        }
        self.reservation = None;
        self.regs.pc = (self.regs.evpr & 0xFFFF_0000) | kind.vector();
        Stop::Exception { kind, at }
    }

    /// `rfi` (`critical`: `rfci`): PC and MSR back from SRR0/SRR1 (SRR2/SRR3).
    pub(crate) fn return_from_interrupt(&mut self, w: u32, critical: bool) -> Executed {
        if self.problem_state() {
            return privileged(w);
        }
        let (pc, msr) = if critical {
            (self.regs.srr2, self.regs.srr3)
        } else {
            (self.regs.srr0, self.regs.srr1)
        };
        self.regs.pc = pc & !3;
        self.regs.msr = msr & msr::IMPLEMENTED;
        self.reservation = None;
        self.spend(1);
        Err(Event::Sync)
    }
}

impl Ppc403 {
    /// The interrupt to take at this instruction boundary, the most urgent first: the
    /// critical pin, the watchdog, the external inputs, the PIT, the FIT.
    pub(crate) fn deliverable_interrupt(&self) -> Option<Exception> {
        let msr = self.regs.msr;
        if msr & (msr::CE | msr::EE) == 0 {
            return None;
        }
        let pending = self.irq.status & self.irq.enable;
        let (tcr, tsr) = (self.timers.tcr, self.timers.tsr);
        if msr & msr::CE != 0 {
            if pending & exisr::CIS != 0 {
                return Some(Exception::Critical);
            }
            if tsr & tsr::WIS != 0 && tcr & tcr::WIE != 0 {
                return Some(Exception::Watchdog);
            }
        }
        if msr & msr::EE != 0 {
            if pending & !exisr::CIS != 0 {
                return Some(Exception::External);
            }
            if tsr & tsr::PIS != 0 && tcr & tcr::PIE != 0 {
                return Some(Exception::Pit);
            }
            if tsr & tsr::FIS != 0 && tcr & tcr::FIE != 0 {
                return Some(Exception::Fit);
            }
        }
        None
    }
}

impl Ppc403 {
    /// The time base now.
    pub fn time_base(&self) -> u64 {
        self.now.wrapping_add(self.timers.tb_offset)
    }

    /// Brings TSR up to `now`: the PIT's expiries (with reloads), FIT events, watchdog
    /// time-outs.
    pub(crate) fn catch_up_timers(&mut self) {
        let now = self.now;
        let t = &mut self.timers;
        if now == t.checked {
            return;
        }
        let from = t.checked.wrapping_add(t.tb_offset);
        let to = now.wrapping_add(t.tb_offset);
        if let Some(expiry) = t.pit_expiry
            && expiry <= now
        {
            t.tsr |= tsr::PIS;
            t.pit_expiry = if t.tcr & tcr::ARE != 0 && t.pit_reload != 0 {
                let reload = u64::from(t.pit_reload);
                Some(expiry.saturating_add(((now - expiry) / reload + 1) * reload))
            } else {
                None
            };
        }
        if crossings(from, to, fit_bits(t.tcr)) > 0 {
            t.tsr |= tsr::FIS;
        }
        for _ in 0..crossings(from, to, watchdog_bits(t.tcr)).min(3) {
            if t.tsr & tsr::ENW == 0 {
                t.tsr |= tsr::ENW;
            } else if t.tsr & tsr::WIS == 0 {
                t.tsr |= tsr::WIS;
            } else {
                let wrc = t.tcr & tcr::WRC;
                if wrc != 0 && t.reset.is_none() {
                    t.tsr = (t.tsr & !tsr::WRS) | wrc;
                    t.reset = Some(match wrc >> 28 {
                        1 => WatchdogReset::Core,
                        2 => WatchdogReset::Chip,
                        _ => WatchdogReset::System,
                    });
                }
            }
        }
        t.checked = now;
    }

    /// The next cycle a timer can interrupt (as TCR and the MSR stand) or reset the core
    /// (`u64::MAX`: none can). Events that can do neither are left to `catch_up_timers`.
    pub(crate) fn next_timer_event(&self) -> u64 {
        let t = &self.timers;
        let msr = self.regs.msr;
        let tb = self.time_base();
        let ee = msr & msr::EE != 0;
        let mut next = u64::MAX;
        if ee
            && t.tcr & tcr::PIE != 0
            && let Some(expiry) = t.pit_expiry
        {
            next = next.min(expiry);
        }
        if ee && t.tcr & tcr::FIE != 0 {
            next = next.min(
                self.now
                    .saturating_add(to_next_multiple(tb, fit_bits(t.tcr))),
            );
        }
        let watchdog_interrupts = msr & msr::CE != 0 && t.tcr & tcr::WIE != 0;
        if watchdog_interrupts || t.tcr & tcr::WRC != 0 {
            next = next.min(
                self.now
                    .saturating_add(to_next_multiple(tb, watchdog_bits(t.tcr))),
            );
        }
        next
    }

    pub(crate) fn pit(&self) -> u32 {
        self.timers
            .pit_expiry
            .map_or(0, |expiry| expiry.saturating_sub(self.now) as u32)
    }

    pub(crate) fn write_pit(&mut self, value: u32) {
        self.catch_up_timers();
        self.timers.pit_reload = value;
        self.timers.pit_expiry = (value != 0).then(|| self.now.saturating_add(u64::from(value)));
    }

    pub(crate) fn write_tcr(&mut self, value: u32) {
        self.catch_up_timers();
        self.timers.tcr = value;
    }

    pub(crate) fn clear_tsr(&mut self, value: u32) {
        self.catch_up_timers();
        self.timers.tsr &= !value;
    }

    /// Writes the time base's high (`high`) or low word.
    pub(crate) fn write_time_base(&mut self, value: u32, high: bool) {
        self.catch_up_timers();
        let tb = self.time_base();
        let tb = if high {
            (tb & 0xFFFF_FFFF) | (u64::from(value) << 32)
        } else {
            (tb & !0xFFFF_FFFF) | u64::from(value)
        };
        self.timers.tb_offset = tb.wrapping_sub(self.now);
    }

    /// The watchdog's reset: the core's registers as after a power-on (PC 0xFFFF_FFFC, MSR
    /// 0, TCR 0), the time base running on, `TSR[WRS]` telling what happened.
    pub(crate) fn watchdog_reset(&mut self) {
        self.regs = Registers {
            pc: 0xFFFF_FFFC,
            ..Registers::default()
        };
        self.timers.tcr = 0;
        self.timers.pit_expiry = None;
        self.reservation = None;
    }
}
