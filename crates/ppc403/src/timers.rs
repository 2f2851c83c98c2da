//! The 403's timers, all clocked by the CPU clock: the 64-bit time base (TBHI:TBLO), the
//! programmable interval timer (PIT, a 32-bit down-counter, reloaded with TCR[ARE]), the fixed
//! interval timer (FIT, an event each time the time base crosses a multiple of 2^9, 2^13,
//! 2^17 or 2^21) and the watchdog (a time-out each 2^17, 2^21, 2^25 or 2^29 cycles: the first
//! sets TSR[ENW], the second TSR[WIS] (an interrupt with TCR[WIE]), the third resets the core
//! when TCR[WRC] asks for it).
//!
//! Nothing counts per cycle: the time base is `now` plus an offset, the PIT an expiry cycle,
//! and `catch_up_timers` works out what happened since it last looked.

use crate::core::{Ppc403, Registers};
use crate::exceptions::msr;

/// TCR's bits.
pub mod tcr {
    /// Watchdog period: 2^(17 + 4 × WP) cycles.
    pub const WP: u32 = 0xC000_0000;
    /// Watchdog reset control: 0 none, 1 core, 2 chip, 3 system.
    pub const WRC: u32 = 0x3000_0000;
    pub const WIE: u32 = 0x0800_0000;
    pub const PIE: u32 = 0x0400_0000;
    /// FIT period: 2^(9 + 4 × FP) cycles.
    pub const FP: u32 = 0x0300_0000;
    pub const FIE: u32 = 0x0080_0000;
    pub const ARE: u32 = 0x0040_0000;
}

/// TSR's bits (write 1 to clear).
pub mod tsr {
    pub const ENW: u32 = 0x8000_0000;
    pub const WIS: u32 = 0x4000_0000;
    /// The watchdog reset that happened (TCR[WRC] at the time).
    pub const WRS: u32 = 0x3000_0000;
    pub const PIS: u32 = 0x0800_0000;
    pub const FIS: u32 = 0x0400_0000;
}

/// The watchdog's reset, as TCR[WRC] asked for it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum WatchdogReset {
    Core,
    Chip,
    System,
}

#[derive(Clone, Debug, Default)]
pub(crate) struct Timers {
    pub tcr: u32,
    pub tsr: u32,
    /// The time base is `now + tb_offset` (wrapping).
    pub tb_offset: u64,
    /// The cycle the status bits are up to date for.
    pub checked: u64,
    /// The cycle the PIT reaches 0 (`None`: it is 0, stopped).
    pit_expiry: Option<u64>,
    /// The PIT's last written value (what TCR[ARE] reloads).
    pit_reload: u32,
    /// A watchdog reset due, not yet reported.
    pub reset: Option<WatchdogReset>,
}

fn fit_bits(tcr: u32) -> u32 {
    9 + 4 * ((tcr & tcr::FP) >> 24)
}

fn watchdog_bits(tcr: u32) -> u32 {
    17 + 4 * (tcr >> 30)
}

/// How many multiples of 2^`bits` the time base crossed going from `from` to `to`.
fn crossings(from: u64, to: u64, bits: u32) -> u64 {
    (to >> bits).wrapping_sub(from >> bits)
}

/// The cycles from time base `tb` to its next multiple of 2^`bits` (1..=2^bits).
fn to_next_multiple(tb: u64, bits: u32) -> u64 {
    let period = 1u64 << bits;
    period - (tb & (period - 1))
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
    /// 0, TCR 0), the time base running on, TSR[WRS] telling what happened.
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
