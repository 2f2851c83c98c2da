//! Waiting for a deadline that must be met to the microsecond, sans-IO: the end of a frame on
//! a served bus, whose receivers get it the moment the bus reaches it.
//!
//! A thread that sleeps on a timer wakes late: here (a 2-core VM) 20–35 µs at the median,
//! hundreds of µs now and then. A frame of 90 µs on the wire then reached its receivers 30 µs
//! late, a third of its own time. A [`Punctual`] wait sleeps until a little before the
//! deadline (its *lead*: how late the timers have woken lately, at most `max_spin`) and spins
//! the rest. So the thread takes one timer wake-up per deadline and is awake at it, and the spin
//! is bounded: never longer than `max_spin`, and only for a deadline within it (an idle bus has
//! none).
//!
//! The adapter reads its clock and sleeps; the wait decides ([`Punctual::plan`]) and learns
//! how late a timer woke ([`Punctual::woke`]).

use std::time::Duration;

/// What to do now to be awake at a deadline.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Step {
    /// Sleep (on a timer) until this wall time, then plan again.
    Sleep { until: Duration },
    /// Stay awake (polling for input without blocking) until the deadline.
    Spin { until: Duration },
    /// The deadline has come.
    Due,
}

/// Waits for deadlines with one timer wake-up each and a bounded spin before them, learning
/// how late the timers wake.
#[derive(Clone, Debug)]
pub struct Punctual {
    max_spin: Duration,
    /// How late timers woke lately: jumps up with a late wake-up, creeps down with earlier
    /// ones (a sixteenth of the difference each), so it stays near the recent worst.
    lateness: Duration,
}

/// How fast [`Punctual`]'s estimate of the timers' lateness creeps down: by 1/`DECAY` of the
/// difference per wake-up.
const DECAY: u32 = 16;

impl Punctual {
    /// A wait that spins at most `max_spin` before a deadline. Until it has seen a timer, it
    /// assumes the worst (timers `max_spin` late).
    pub fn new(max_spin: Duration) -> Self {
        Self {
            max_spin,
            lateness: max_spin,
        }
    }

    /// How long before a deadline the timer is set: how late timers woke lately, at most
    /// `max_spin`.
    pub fn lead(&self) -> Duration {
        self.lateness.min(self.max_spin)
    }

    /// What to do at `now` to be awake at `deadline`.
    pub fn plan(&self, now: Duration, deadline: Duration) -> Step {
        if now >= deadline {
            Step::Due
        } else if deadline - now <= self.lead() {
            Step::Spin { until: deadline }
        } else {
            Step::Sleep {
                until: deadline - self.lead(),
            }
        }
    }

    /// A timer set for `asked` woke the thread at `now`: how late timers wake.
    pub fn woke(&mut self, asked: Duration, now: Duration) {
        let late = now.saturating_sub(asked).min(self.max_spin);
        self.lateness = if late >= self.lateness {
            late
        } else {
            // Rounded up, so it reaches `late` rather than stopping a few nanoseconds above.
            let step = (self.lateness - late)
                .as_nanos()
                .div_ceil(u128::from(DECAY));
            self.lateness - Duration::from_nanos(step as u64)
        };
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn us(n: u64) -> Duration {
        Duration::from_micros(n)
    }

    /// A deadline far off: one sleep until the lead before it, then a spin to it, then due.
    #[test]
    fn sleeps_until_the_lead_then_spins_to_the_deadline() {
        let wait = Punctual::new(us(50));
        assert_eq!(wait.plan(us(0), us(90)), Step::Sleep { until: us(40) });
        // The timer woke on time or late, but before the deadline: no second sleep.
        assert_eq!(wait.plan(us(40), us(90)), Step::Spin { until: us(90) });
        assert_eq!(wait.plan(us(89), us(90)), Step::Spin { until: us(90) });
        assert_eq!(wait.plan(us(90), us(90)), Step::Due);
        // Woken past the deadline (a loaded host): due at once.
        assert_eq!(wait.plan(us(300), us(90)), Step::Due);
    }

    /// A deadline within the lead is spun to at once: no timer for it.
    #[test]
    fn a_deadline_within_the_lead_is_spun_to() {
        let wait = Punctual::new(us(50));
        assert_eq!(wait.plan(us(0), us(45)), Step::Spin { until: us(45) });
        assert_eq!(wait.plan(us(0), us(50)), Step::Spin { until: us(50) });
        assert_eq!(wait.plan(us(0), us(51)), Step::Sleep { until: us(1) });
    }

    /// Timers that wake 10 µs late bring the lead down towards 10 µs (less spinning); one
    /// that wakes later raises it at once; however late one wakes, the spin stays bounded.
    #[test]
    fn the_lead_follows_how_late_timers_wake_within_the_bound() {
        let mut wait = Punctual::new(us(50));
        assert_eq!(wait.lead(), us(50));
        for _ in 0..200 {
            let Step::Sleep { until } = wait.plan(us(0), us(1000)) else {
                panic!("a deadline 1 ms off is slept towards");
            };
            wait.woke(until, until + us(10));
        }
        assert!(wait.lead() < us(11), "lead {:?}", wait.lead());
        assert!(wait.lead() >= us(10), "lead {:?}", wait.lead());
        // One late wake-up: the next deadlines are slept towards with that lead.
        wait.woke(us(100), us(130));
        assert_eq!(wait.lead(), us(30));
        assert_eq!(wait.plan(us(0), us(1000)), Step::Sleep { until: us(970) });
        // A stall of the host is not spun against: the lead stays at the bound.
        wait.woke(us(100), us(5100));
        assert_eq!(wait.lead(), us(50));
        assert_eq!(wait.plan(us(0), us(1000)), Step::Sleep { until: us(950) });
    }

    /// A timer woken early or exactly on time (no lateness) lets the lead fall to zero, where
    /// the wait is a plain sleep to the deadline.
    #[test]
    fn exact_timers_need_no_spin() {
        let mut wait = Punctual::new(us(50));
        for _ in 0..400 {
            wait.woke(us(100), us(100));
        }
        assert_eq!(wait.lead(), Duration::ZERO);
        assert_eq!(wait.plan(us(0), us(90)), Step::Sleep { until: us(90) });
        assert_eq!(wait.plan(us(90), us(90)), Step::Due);
    }
}
