//! Pacing a virtual clock to the wall clock, sans-IO: the one pacing policy of buslab's live
//! adapters (every served byte device behind a pseudo-terminal, `buslab_link::serve`; the
//! virtual bus server, `buslab_vbus::server`).
//!
//! A [`Pacer`] maps wall time (a [`Duration`] since the adapter's epoch: the adapter reads
//! its clock, the pacer never does) to a core's virtual time ([`Ticks`]: a device's
//! nanoseconds, a bus's bit-times) at a [`Rate`]. Each turn the adapter asks [`Pacer::plan`]
//! how far to run its core ([`Plan::run_to`]), runs it, and asks [`Pacer::wake_at`] when to
//! wake for what the core has due next. In the shape of quinn's pacer: time in, decisions
//! out, nothing else.
//!
//! **Credit.** A loop that wakes late (a loaded machine) runs its core up to the wall clock
//! at once: the virtual time it missed is not lost, so a served line keeps its rate. Up to a
//! bound ([`Pacer::new`]'s `max_credit`): after a longer stall (the process was stopped, the
//! machine suspended) a core with work due would otherwise do all of it in one burst (a
//! minute of a device's output, of a bus's traffic). Beyond the bound the virtual clock slips:
//! the core runs `max_credit` of its time, the rest of the stall is skipped
//! ([`Pacer::skipped`]) and the virtual clock stays that much behind the wall from then on.
//! An idle core (nothing due before the wall clock) follows the wall clock however long the
//! loop slept: catching up on nothing is no burst.
//!
//! **Punctual waits.** Timers wake a thread late (tens of µs); for a deadline that must be met
//! to the microsecond (a frame's end on a served bus), a [`Punctual`] wait sleeps until a
//! little before it and spins the rest, bounded.

use std::time::Duration;

mod punctual;
pub use punctual::{Punctual, Step};

/// A point on a paced core's clock, in its own ticks: nanoseconds of a device's time,
/// bit-times of a bus. One pacer's ticks are one unit, given by its [`Rate`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Ticks(pub u64);

impl Ticks {
    fn saturating_sub(self, other: Ticks) -> Ticks {
        Ticks(self.0.saturating_sub(other.0))
    }
}

/// Virtual ticks per wall-clock second, kept exactly as ticks per 1000 s (a speed factor is
/// honoured to a thousandth of a tick per second).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Rate {
    per_kilosecond: u128,
}

const NANOS_PER_KILOSECOND: u128 = 1_000_000_000_000;

impl Rate {
    /// `ticks` per second at real time: 1 000 000 000 for a device's nanoseconds, the bit rate
    /// for a bus's bit-times.
    pub fn per_second(ticks: u64) -> Self {
        Self {
            per_kilosecond: (ticks as u128 * 1000).max(1),
        }
    }

    /// This rate `factor` times faster (`0.5`: half real time). Factors that would stop the
    /// clock become the slowest rate there is (one tick per 1000 s).
    pub fn times(self, factor: f64) -> Self {
        let scaled = self.per_kilosecond as f64 * factor;
        Self {
            per_kilosecond: if scaled.is_finite() && scaled >= 1.0 {
                scaled.round() as u128
            } else {
                1
            },
        }
    }

    /// Whole ticks in `wall` (rounded down).
    fn ticks_in(self, wall: Duration) -> Ticks {
        let ticks = wall.as_nanos() * self.per_kilosecond / NANOS_PER_KILOSECOND;
        Ticks(u64::try_from(ticks).unwrap_or(u64::MAX))
    }

    /// The wall time `ticks` take (rounded up: the clock has reached them by then).
    fn wall_of(self, ticks: Ticks) -> Duration {
        let nanos = (ticks.0 as u128 * NANOS_PER_KILOSECOND).div_ceil(self.per_kilosecond);
        Duration::from_nanos(u64::try_from(nanos).unwrap_or(u64::MAX))
    }
}

/// How far to run the core this turn.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Plan {
    /// The virtual time the core should reach now: the wall clock's, less what was skipped.
    pub run_to: Ticks,
    /// Wall time skipped by this plan (a stall beyond the credit bound with work due);
    /// usually zero.
    pub skipped: Duration,
}

/// Maps wall time to a core's virtual time, keeping the credit of late wake-ups up to a bound
/// (see the crate's documentation).
#[derive(Clone, Debug)]
pub struct Pacer {
    rate: Rate,
    max_credit: Duration,
    /// The wall time at which the virtual clock read `origin`; moves only when the clock
    /// slips.
    origin_wall: Duration,
    origin: Ticks,
    skipped: Duration,
}

impl Pacer {
    /// A virtual clock at tick 0 at wall time zero, running at `rate`; a core with work due
    /// catches up at most `max_credit` of wall time at once.
    pub fn new(rate: Rate, max_credit: Duration) -> Self {
        Self {
            rate,
            max_credit,
            origin_wall: Duration::ZERO,
            origin: Ticks(0),
            skipped: Duration::ZERO,
        }
    }

    /// The virtual time the clock reads at `wall` (earlier than the origin: the origin).
    pub fn ticks_at(&self, wall: Duration) -> Ticks {
        let since = wall.saturating_sub(self.origin_wall);
        Ticks(self.origin.0.saturating_add(self.rate.ticks_in(since).0))
    }

    /// The wall time at which the clock reaches `ticks` (the origin's for earlier ones).
    pub fn wall_at(&self, ticks: Ticks) -> Duration {
        self.origin_wall
            .saturating_add(self.rate.wall_of(ticks.saturating_sub(self.origin)))
    }

    /// How long `ticks` last on the wall clock.
    pub fn wall_of(&self, ticks: Ticks) -> Duration {
        self.rate.wall_of(ticks)
    }

    /// How many ticks pass in `wall`.
    pub fn ticks_in(&self, wall: Duration) -> Ticks {
        self.rate.ticks_in(wall)
    }

    /// How far the core should run at `wall`. `reached` is where it is; `due` the earliest
    /// virtual time at which it has work (`reached` or earlier when it is busy now, its next
    /// deadline when it waits, `None` when nothing is scheduled). The core runs up to the wall
    /// clock, the time a late wake-up missed included; when its work due lies further behind
    /// the wall than the credit bound, the clock slips so that it runs `max_credit` past that
    /// work, no more.
    pub fn plan(&mut self, wall: Duration, reached: Ticks, due: Option<Ticks>) -> Plan {
        let target = self.ticks_at(wall);
        let credit = self.rate.ticks_in(self.max_credit).0;
        let skipped = match due {
            Some(due) => {
                let work_from = due.max(reached);
                let limit = work_from.0.saturating_add(credit);
                if target.0 > limit {
                    // The clock slips: from now on `wall` reads `limit`.
                    self.origin_wall = wall;
                    self.origin = Ticks(limit);
                    let skipped = self.rate.wall_of(Ticks(target.0 - limit));
                    self.skipped += skipped;
                    skipped
                } else {
                    Duration::ZERO
                }
            }
            None => Duration::ZERO,
        };
        Plan {
            run_to: self.ticks_at(wall),
            skipped,
        }
    }

    /// When the loop should wake at the latest for what the core has due next (`next_due`,
    /// after this turn's run): at the wall time of that work, at once (`wall`) when it is due
    /// already (a core behind the clock, a turn that could not run it all the way); `None` when
    /// nothing is due (the adapter waits for input, or its own limit).
    pub fn wake_at(&self, wall: Duration, next_due: Option<Ticks>) -> Option<Duration> {
        next_due.map(|due| self.wall_at(due).max(wall))
    }

    /// How far `reached` is behind the clock at `wall`, in wall time (the lag a core that
    /// cannot keep up shows).
    pub fn behind(&self, wall: Duration, reached: Ticks) -> Duration {
        self.rate
            .wall_of(self.ticks_at(wall).saturating_sub(reached))
    }

    /// Wall time skipped so far by stalls beyond the credit bound.
    pub fn skipped(&self) -> Duration {
        self.skipped
    }

    /// The credit bound.
    pub fn max_credit(&self) -> Duration {
        self.max_credit
    }
}

#[cfg(test)]
mod tests;
