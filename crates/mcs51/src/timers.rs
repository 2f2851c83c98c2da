//! Timers 0 and 1, counted lazily: between two looks the count follows from the machine cycles
//! elapsed, so a running timer costs nothing per instruction.
//!
//! A running timer counts once per machine cycle, at the cycle's end (in timer mode), or once
//! per falling edge of its T pin (counter mode, [`Timers::count_edge`]). It runs while its TR
//! bit is set and, with GATE set, its INT pin is high. Modes: 0 = 13 bits (TH and the low 5
//! bits of TL; TL's upper 3 bits are left as written), 1 = 16 bits, 2 = TL reloaded from TH, 3
//! = timer 0 split in two 8-bit timers (TL0 with timer 0's controls and TF0; TH0 counting
//! machine cycles under TR1, setting TF1), timer 1 stopped. While timer 0 is in mode 3, timer 1
//! has no TR1 and no flag: it runs whenever it is not in mode 3 itself (GATE and INT1 still
//! apply) and clocks the UART only.
//!
//! TF is set in the cycle in which the timer overflows: `since` is that cycle's start.

use crate::Clocks;
use crate::pins::p3;
use crate::sfr::tcon;

#[derive(Clone, Debug)]
pub(crate) struct Timers {
    pub tmod: u8,
    pub tcon: u8,
    pub tl: [u8; 2],
    pub th: [u8; 2],
    /// Counted up to here.
    synced: Clocks,
    /// Overflows of timer 1 itself (the UART's baud clock), ever.
    pub t1_overflows: u64,
    /// Start of the cycle in which TF0 / TF1 was last set.
    pub since_tf: [Clocks; 2],
}

/// What a counter does on each increment.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Shape {
    /// 13 bits: TH, and TL's low 5 bits.
    Bits13,
    Bits16,
    /// TL, reloaded from TH.
    Reload,
    /// TL alone (timer 0 in mode 3).
    LowByte,
    /// TH alone (TH0 in mode 3).
    HighByte,
}

/// Steps `shape` of a timer by `n`; returns the overflows and the step (1-based) of the first.
fn advance(shape: Shape, tl: &mut u8, th: &mut u8, n: u64) -> (u64, u64) {
    if n == 0 {
        return (0, 0);
    }
    let (value, period) = match shape {
        Shape::Bits13 => (u64::from(*th) << 5 | u64::from(*tl & 0x1F), 0x2000),
        Shape::Bits16 => (u64::from(*th) << 8 | u64::from(*tl), 0x1_0000),
        Shape::Reload | Shape::LowByte => (u64::from(*tl), 0x100),
        Shape::HighByte => (u64::from(*th), 0x100),
    };
    let to_first = period - value;
    if n < to_first {
        let v = value + n;
        store(shape, tl, th, v);
        return (0, 0);
    }
    let after = n - to_first;
    if shape == Shape::Reload {
        let reload = u64::from(*th);
        let span = 0x100 - reload;
        *tl = (reload + after % span) as u8;
        return (1 + after / span, to_first);
    }
    store(shape, tl, th, after % period);
    (1 + after / period, to_first)
}

fn store(shape: Shape, tl: &mut u8, th: &mut u8, v: u64) {
    match shape {
        Shape::Bits13 => {
            *th = (v >> 5) as u8;
            *tl = (*tl & 0xE0) | (v & 0x1F) as u8;
        }
        Shape::Bits16 => {
            *th = (v >> 8) as u8;
            *tl = v as u8;
        }
        Shape::Reload | Shape::LowByte => *tl = v as u8,
        Shape::HighByte => *th = v as u8,
    }
}

/// Steps from the current value to the `k`-th overflow (k ≥ 1) in `shape`.
fn steps_to_overflow(shape: Shape, tl: u8, th: u8, k: u64) -> u64 {
    let (value, period) = match shape {
        Shape::Bits13 => (u64::from(th) << 5 | u64::from(tl & 0x1F), 0x2000),
        Shape::Bits16 => (u64::from(th) << 8 | u64::from(tl), 0x1_0000),
        Shape::Reload => (u64::from(tl), 0x100 - u64::from(th)),
        Shape::LowByte => (u64::from(tl), 0x100),
        Shape::HighByte => (u64::from(th), 0x100),
    };
    let first = if shape == Shape::Reload {
        0x100 - value
    } else {
        period - value
    };
    first.saturating_add((k - 1).saturating_mul(period))
}

impl Timers {
    pub fn new(now: Clocks) -> Timers {
        Timers {
            tmod: 0,
            tcon: 0,
            tl: [0; 2],
            th: [0; 2],
            synced: now,
            t1_overflows: 0,
            since_tf: [Clocks::ZERO; 2],
        }
    }

    fn mode(&self, t: usize) -> u8 {
        (self.tmod >> (4 * t)) & 3
    }

    fn counts_edges(&self, t: usize) -> bool {
        self.tmod >> (4 * t) & 0x04 != 0
    }

    fn gate_open(&self, t: usize, p3_pins: u8) -> bool {
        let gate = self.tmod >> (4 * t) & 0x08 != 0;
        let int = if t == 0 { p3::INT0 } else { p3::INT1 };
        !gate || p3_pins & int != 0
    }

    /// Whether timer 0 (or TL0 in mode 3) runs.
    fn t0_runs(&self, p3_pins: u8) -> bool {
        self.tcon & tcon::TR0 != 0 && self.gate_open(0, p3_pins)
    }

    /// Whether TH0 runs as timer 0's second half (mode 3, under TR1).
    fn th0_runs(&self) -> bool {
        self.mode(0) == 3 && self.tcon & tcon::TR1 != 0
    }

    /// Whether timer 1 runs.
    fn t1_runs(&self, p3_pins: u8) -> bool {
        if self.mode(1) == 3 {
            return false;
        }
        let enabled = self.mode(0) == 3 || self.tcon & tcon::TR1 != 0;
        enabled && self.gate_open(1, p3_pins)
    }

    fn shape(&self, t: usize) -> Shape {
        match self.mode(t) {
            0 => Shape::Bits13,
            1 => Shape::Bits16,
            2 => Shape::Reload,
            _ => Shape::LowByte,
        }
    }

    fn set_tf(&mut self, t: usize, since: Clocks) {
        let flag = if t == 0 { tcon::TF0 } else { tcon::TF1 };
        if self.tcon & flag == 0 {
            self.tcon |= flag;
            self.since_tf[t] = since;
        }
    }

    /// Counts the machine cycles that ended in (synced, to] with the pins as `p3_pins`.
    pub fn sync(&mut self, to: Clocks, p3_pins: u8) {
        if to <= self.synced {
            return;
        }
        // Machine cycles ended, a count of steps.
        let n = to.cycles() - self.synced.cycles();
        // The cycle whose end is the first step.
        let first_cycle = self.synced.cycle_start();
        self.synced = to;
        if n == 0 {
            return;
        }
        let at = |step: u64| first_cycle + Clocks::CYCLE * (step - 1);
        if !self.counts_edges(0) && self.t0_runs(p3_pins) {
            let shape = self.shape(0);
            let (ovf, first) = advance(shape, &mut self.tl[0], &mut self.th[0], n);
            if ovf > 0 {
                self.set_tf(0, at(first));
            }
        }
        if self.th0_runs() {
            let (ovf, first) = advance(Shape::HighByte, &mut self.tl[0], &mut self.th[0], n);
            if ovf > 0 {
                self.set_tf(1, at(first));
            }
        }
        if !self.counts_edges(1) && self.t1_runs(p3_pins) {
            let shape = self.shape(1);
            let (ovf, first) = advance(shape, &mut self.tl[1], &mut self.th[1], n);
            self.t1_overflows += ovf;
            if ovf > 0 && self.mode(0) != 3 {
                self.set_tf(1, at(first));
            }
        }
    }

    /// Moves on to `to` without counting (the oscillator stood still).
    pub fn skip_to(&mut self, to: Clocks) {
        self.synced = self.synced.max(to);
    }

    /// A falling edge on T0 (`t = 0`) or T1 sampled in the cycle starting at `cycle`: a
    /// counter counts it, visible from the next cycle on.
    pub fn count_edge(&mut self, t: usize, cycle: Clocks, p3_pins: u8) {
        if !self.counts_edges(t) {
            return;
        }
        let since = cycle + Clocks::CYCLE;
        if t == 0 && self.t0_runs(p3_pins) {
            let shape = self.shape(0);
            if advance(shape, &mut self.tl[0], &mut self.th[0], 1).0 > 0 {
                self.set_tf(0, since);
            }
        } else if t == 1 && self.t1_runs(p3_pins) {
            let shape = self.shape(1);
            let ovf = advance(shape, &mut self.tl[1], &mut self.th[1], 1).0;
            self.t1_overflows += ovf;
            if ovf > 0 && self.mode(0) != 3 {
                self.set_tf(1, since);
            }
        }
    }

    /// The clock (a cycle boundary) at which the step `k` cycles from the last sync happens.
    fn step_time(&self, k: u64) -> Clocks {
        let first_end = self.synced.cycle_start() + Clocks::CYCLE;
        first_end + Clocks::CYCLE * (k - 1)
    }

    /// When timer 1's overflow number `number` (counted in `t1_overflows`) happens, if timer 1
    /// counts machine cycles undisturbed until then (synced first).
    pub fn t1_overflow_time(&self, number: u64, p3_pins: u8) -> Option<Clocks> {
        if number <= self.t1_overflows {
            return Some(self.synced);
        }
        if self.counts_edges(1) || !self.t1_runs(p3_pins) {
            return None;
        }
        let k = number - self.t1_overflows;
        Some(self.step_time(steps_to_overflow(self.shape(1), self.tl[1], self.th[1], k)))
    }

    /// When a clear TF flag will next be set by counting machine cycles (synced first).
    pub fn next_flag_time(&self, p3_pins: u8) -> Clocks {
        let mut next = Clocks::NEVER;
        if self.tcon & tcon::TF0 == 0 && !self.counts_edges(0) && self.t0_runs(p3_pins) {
            let steps = steps_to_overflow(self.shape(0), self.tl[0], self.th[0], 1);
            next = next.min(self.step_time(steps));
        }
        if self.tcon & tcon::TF1 == 0 {
            if self.th0_runs() {
                let steps = steps_to_overflow(Shape::HighByte, self.tl[0], self.th[0], 1);
                next = next.min(self.step_time(steps));
            } else if self.mode(0) != 3 && !self.counts_edges(1) && self.t1_runs(p3_pins) {
                let steps = steps_to_overflow(self.shape(1), self.tl[1], self.th[1], 1);
                next = next.min(self.step_time(steps));
            }
        }
        next
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counting_in_each_shape_wraps_where_the_manual_says() {
        let (mut tl, mut th) = (0xFE, 0xFF);
        assert_eq!(advance(Shape::Bits16, &mut tl, &mut th, 3), (1, 2));
        assert_eq!((tl, th), (1, 0));
        // 13 bits: TL counts 0..31 only, its top 3 bits stay.
        let (mut tl, mut th) = (0xFF, 0xFF);
        assert_eq!(advance(Shape::Bits13, &mut tl, &mut th, 1), (1, 1));
        assert_eq!((tl, th), (0xE0, 0));
        // Auto-reload from FDh: an overflow every 3 steps.
        let (mut tl, mut th) = (0xFD, 0xFD);
        assert_eq!(advance(Shape::Reload, &mut tl, &mut th, 9), (3, 3));
        assert_eq!(tl, 0xFD);
        assert_eq!(advance(Shape::Reload, &mut tl, &mut th, 4), (1, 3));
        assert_eq!(tl, 0xFE);
        assert_eq!(steps_to_overflow(Shape::Reload, 0xFE, 0xFD, 1), 2);
        assert_eq!(steps_to_overflow(Shape::Reload, 0xFE, 0xFD, 3), 8);
        assert_eq!(steps_to_overflow(Shape::Bits13, 0, 0, 1), 0x2000);
    }
}
