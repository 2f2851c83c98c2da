//! The interrupt system: five sources, two priority levels, the polling rules.
//!
//! Each flag is sampled in the machine cycle it is set in and polled in the next one; a
//! request polled in the last cycle of an instruction becomes a hardware `LCALL` (2 cycles)
//! right after it. So a source whose flag was set in the cycle starting at `since` can be
//! taken at the first instruction boundary at or after `since + 24` clocks: at least three
//! whole cycles pass between a request and the first instruction of its service routine.
//! Not at a boundary after `RETI` or after an instruction that wrote IE or IP (one more
//! instruction runs first), nor while a routine of the same or a higher level is in progress.
//! Among the requests that can be taken, a high-priority one (its IP bit set) wins, then the
//! polling order IE0, TF0, IE1, TF1, RI/TI.

use crate::Clocks;
use crate::sfr::ie;

/// From the start of the cycle a flag is set in to the earliest boundary it is taken at.
const LATENCY: Clocks = Clocks::from_cycles(2);
const LOW: u8 = 1;
const HIGH: u8 = 2;

/// The five sources, in polling order.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Source {
    /// External interrupt 0 (IE0), vector 0003h.
    External0,
    /// Timer 0 overflow (TF0), vector 000Bh.
    Timer0,
    /// External interrupt 1 (IE1), vector 0013h.
    External1,
    /// Timer 1 overflow (TF1), vector 001Bh.
    Timer1,
    /// Serial port (RI or TI), vector 0023h.
    Serial,
}

impl Source {
    /// All five, in polling order.
    pub const ALL: [Source; 5] = [
        Source::External0,
        Source::Timer0,
        Source::External1,
        Source::Timer1,
        Source::Serial,
    ];

    /// Where its service routine starts.
    pub const fn vector(self) -> u16 {
        3 + 8 * self as u16
    }

    /// Its bit in IE and IP.
    pub const fn mask(self) -> u8 {
        1 << self as u8
    }
}

#[derive(Clone, Debug, Default)]
pub(crate) struct Interrupts {
    pub ie: u8,
    pub ip: u8,
    /// Levels whose routine is in progress (LOW, HIGH).
    pub in_progress: u8,
}

/// The flags as they stand: for each source, the start of the cycle its flag was set in, if
/// set.
pub(crate) type Flags = [Option<Clocks>; 5];

impl Interrupts {
    /// Whether `source` could interrupt now if its flag were polled: enabled, and no routine
    /// of its level or above in progress. Returns its level.
    fn admissible(&self, source: Source) -> Option<bool> {
        if self.ie & ie::EA == 0 || self.ie & source.mask() == 0 {
            return None;
        }
        let high = self.ip & source.mask() != 0;
        let free = if high {
            self.in_progress & HIGH == 0
        } else {
            self.in_progress == 0
        };
        free.then_some(high)
    }

    /// The earliest boundary at which some request can be taken.
    pub fn earliest(&self, flags: &Flags) -> Clocks {
        Source::ALL
            .iter()
            .zip(flags)
            .filter_map(|(&s, since)| {
                self.admissible(s)?;
                Some(*since.as_ref()? + LATENCY)
            })
            .min()
            .unwrap_or(Clocks::NEVER)
    }

    /// The request to take at the boundary `now`, with its level (true = high).
    pub fn choose(&self, flags: &Flags, now: Clocks) -> Option<(Source, bool)> {
        let mut best: Option<(Source, bool)> = None;
        for (&s, since) in Source::ALL.iter().zip(flags) {
            let Some(high) = self.admissible(s) else {
                continue;
            };
            if !since.is_some_and(|t| t + LATENCY <= now) {
                continue;
            }
            match best {
                None => best = Some((s, high)),
                Some((_, false)) if high => best = Some((s, high)),
                _ => {}
            }
        }
        best
    }

    /// A routine of that level starts.
    pub fn enter(&mut self, high: bool) {
        self.in_progress |= if high { HIGH } else { LOW };
    }

    /// `RETI`: the routine of the highest level in progress ends.
    pub fn reti(&mut self) {
        if self.in_progress & HIGH != 0 {
            self.in_progress &= !HIGH;
        } else {
            self.in_progress &= !LOW;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn high_priority_first_then_polling_order() {
        let mut irq = Interrupts {
            ie: 0x9F,
            ip: ie::ET1,
            in_progress: 0,
        };
        let flags = [Some(0), None, Some(0), Some(12), Some(0)].map(|f| f.map(Clocks));
        assert_eq!(irq.earliest(&flags), Clocks(24));
        assert_eq!(
            irq.choose(&flags, Clocks(24)),
            Some((Source::External0, false))
        );
        assert_eq!(irq.choose(&flags, Clocks(36)), Some((Source::Timer1, true)));
        irq.enter(false);
        assert_eq!(irq.choose(&flags, Clocks(36)), Some((Source::Timer1, true)));
        irq.enter(true);
        assert_eq!(irq.choose(&flags, Clocks(36)), None);
        assert_eq!(irq.earliest(&flags), Clocks::NEVER);
        irq.reti();
        assert_eq!(irq.in_progress, LOW);
        irq.ie &= !ie::EA;
        irq.reti();
        assert_eq!(irq.choose(&flags, Clocks(36)), None);
        assert_eq!(Source::Serial.vector(), 0x23);
    }
}
