//! The pacing policy in virtual time: a simulated loop with explicit wall times.

use super::*;

const MS: Duration = Duration::from_millis(1);
/// A device's clock: nanoseconds, at real time.
const NS: Rate = Rate {
    per_kilosecond: 1_000_000_000 * 1000,
};

fn ms(n: u64) -> Duration {
    Duration::from_millis(n)
}

fn device_ms(n: u64) -> Ticks {
    Ticks(n * 1_000_000)
}

/// A core that has work every `period` ticks (a UART sending back to back) and counts what it
/// did: how an adapter drives it, one turn per wake-up.
struct Periodic {
    period: u64,
    next: u64,
    reached: Ticks,
    done: u64,
}

impl Periodic {
    fn new(period: u64) -> Self {
        Self {
            period,
            next: period,
            reached: Ticks(0),
            done: 0,
        }
    }

    fn due(&self) -> Option<Ticks> {
        Some(Ticks(self.next))
    }

    /// Runs to `to`, doing every piece of work due by then.
    fn run_to(&mut self, to: Ticks) {
        while self.next <= to.0 {
            self.done += 1;
            self.next += self.period;
        }
        self.reached = self.reached.max(to);
    }

    /// One turn of an adapter's loop at `wall`: plan, run, and when to wake.
    fn turn(&mut self, pacer: &mut Pacer, wall: Duration) -> (Plan, Option<Duration>) {
        let plan = pacer.plan(wall, self.reached, self.due());
        self.run_to(plan.run_to);
        (plan, pacer.wake_at(wall, self.due()))
    }
}

#[test]
fn on_time_wake_ups_run_the_core_to_the_wall_clock_and_wake_for_its_next_work() {
    let mut pacer = Pacer::new(NS, 100 * MS);
    let mut core = Periodic::new(1_000_000); // every virtual millisecond
    let mut wall = Duration::ZERO;
    for _ in 0..1000 {
        let (plan, wake) = core.turn(&mut pacer, wall);
        assert_eq!(plan.run_to, pacer.ticks_at(wall));
        assert_eq!(plan.skipped, Duration::ZERO);
        // The next wake-up is the next piece of work, and the loop wakes exactly then.
        wall = wake.expect("work is always due");
        assert_eq!(pacer.ticks_at(wall), core.due().unwrap());
    }
    assert_eq!(
        core.done, 999,
        "one piece of work per millisecond of wall time"
    );
    assert_eq!(pacer.skipped(), Duration::ZERO);
}

#[test]
fn late_wake_ups_keep_their_credit_up_to_the_bound() {
    // A loaded machine: the loop wakes 30 ms after each planned wake-up; the credit (100 ms)
    // covers it, so the core does all the work the wall clock allows, late but not lost.
    let mut pacer = Pacer::new(NS, 100 * MS);
    let mut core = Periodic::new(1_000_000);
    let mut wall = Duration::ZERO;
    while wall < ms(10_000) {
        let (plan, wake) = core.turn(&mut pacer, wall);
        assert_eq!(plan.skipped, Duration::ZERO);
        wall = wake.unwrap() + 30 * MS;
    }
    core.turn(&mut pacer, ms(10_000));
    assert_eq!(core.done, 10_000, "every millisecond's work, none lost");
    assert_eq!(pacer.ticks_at(ms(10_000)), device_ms(10_000));
}

#[test]
fn a_late_wake_up_exactly_at_the_bound_keeps_all_its_credit() {
    let mut pacer = Pacer::new(NS, 100 * MS);
    let mut core = Periodic::new(1_000_000);
    core.turn(&mut pacer, Duration::ZERO);
    // Due at 1 ms, woken at 101 ms: 100 ms behind its work, the whole bound.
    let (plan, _) = core.turn(&mut pacer, ms(101));
    assert_eq!(plan.run_to, device_ms(101));
    assert_eq!(plan.skipped, Duration::ZERO);
    assert_eq!(core.done, 101);
}

#[test]
fn a_stall_beyond_the_bound_runs_the_bound_and_skips_the_rest_without_a_burst() {
    let mut pacer = Pacer::new(NS, 100 * MS);
    let mut core = Periodic::new(1_000_000);
    core.turn(&mut pacer, Duration::ZERO);
    core.turn(&mut pacer, ms(10)); // 10 pieces done, next due at 11 ms
    assert_eq!(core.done, 10);
    // The process was stopped for 5 s.
    let (plan, wake) = core.turn(&mut pacer, ms(5_010));
    // Only the bound's worth past the work due (11 ms + 100 ms), not 5 s of it at once.
    assert_eq!(plan.run_to, device_ms(111));
    assert_eq!(core.done, 111);
    assert_eq!(plan.skipped, ms(4_899));
    assert_eq!(pacer.skipped(), ms(4_899));
    // From then on the clock runs at its rate again, that much behind the wall.
    assert_eq!(wake, Some(ms(5_011)), "the next work a millisecond later");
    let (plan, _) = core.turn(&mut pacer, ms(5_060));
    assert_eq!(plan.run_to, device_ms(161));
    assert_eq!(plan.skipped, Duration::ZERO);
    assert_eq!(core.done, 161);
    assert_eq!(pacer.behind(ms(5_060), core.reached), Duration::ZERO);
}

#[test]
fn an_idle_core_follows_the_wall_clock_however_long_the_loop_slept() {
    // Nothing due: catching up is no burst, so nothing is skipped (a served terminal nobody
    // typed on for an hour; a quiet bus).
    let mut pacer = Pacer::new(NS, 100 * MS);
    let plan = pacer.plan(ms(3_600_000), Ticks(0), None);
    assert_eq!(plan.run_to, device_ms(3_600_000));
    assert_eq!(plan.skipped, Duration::ZERO);
    assert_eq!(pacer.wake_at(ms(3_600_000), None), None, "wait for input");
    // Work due only after the wall clock (a timer far ahead) is no burst either.
    let plan = pacer.plan(
        ms(7_200_000),
        device_ms(3_600_000),
        Some(device_ms(7_200_500)),
    );
    assert_eq!(plan.run_to, device_ms(7_200_000));
    assert_eq!(plan.skipped, Duration::ZERO);
    assert_eq!(
        pacer.wake_at(ms(7_200_000), Some(device_ms(7_200_500))),
        Some(ms(7_200_500))
    );
}

#[test]
fn a_core_busy_now_is_the_work_due() {
    // A bus with a frame on the wire: due where it is. A turn that could not run it all the
    // way leaves it behind; the loop wakes at once to go on.
    let mut pacer = Pacer::new(Rate::per_second(500_000), Duration::from_secs(1));
    let reached = Ticks(1000);
    let plan = pacer.plan(ms(10), reached, Some(reached));
    assert_eq!(plan.run_to, Ticks(5000));
    assert_eq!(pacer.wake_at(ms(10), Some(reached)), Some(ms(10)));
    assert_eq!(pacer.behind(ms(10), reached), ms(8));
    // Three seconds behind its work: it runs one second's worth past it.
    let plan = pacer.plan(ms(3_002), reached, Some(reached));
    assert_eq!(plan.run_to, Ticks(1000 + 500_000));
    assert_eq!(plan.skipped, ms(2_000));
}

#[test]
fn speed_factors_scale_virtual_time_and_the_waits() {
    // A 500 kbit/s bus at 4 times real time: 2 000 000 bit-times per wall second.
    let mut pacer = Pacer::new(Rate::per_second(500_000).times(4.0), Duration::from_secs(1));
    assert_eq!(pacer.ticks_at(ms(1)), Ticks(2000));
    assert_eq!(pacer.wall_at(Ticks(2000)), ms(1));
    assert_eq!(pacer.plan(ms(250), Ticks(0), None).run_to, Ticks(500_000));
    // A 500 bit/s clock at a thousandth of real time: a tick lasts 2 s.
    let slow = Pacer::new(Rate::per_second(500).times(0.001), Duration::from_secs(1));
    assert_eq!(slow.ticks_at(ms(1_999)), Ticks(0));
    assert_eq!(slow.ticks_at(ms(2_000)), Ticks(1));
    assert_eq!(slow.wall_at(Ticks(3)), ms(6_000));
    // The credit bound is wall time at any speed: one wall second at 4x is 2 000 000 ticks.
    let plan = pacer.plan(ms(5_000), Ticks(0), Some(Ticks(0)));
    assert_eq!(plan.run_to, Ticks(2_000_000));
    assert_eq!(plan.skipped, ms(4_000));
}

#[test]
fn the_clock_reaches_a_tick_by_the_wall_time_given_for_it() {
    // Rates whose ticks do not divide a nanosecond evenly: a loop woken at `wall_at(t)` finds
    // `t` reached (it would spin on a wake-up a nanosecond early).
    for rate in [
        Rate::per_second(9600),
        Rate::per_second(125_000).times(3.0),
        Rate::per_second(1_000_000).times(0.7),
        NS.times(1.5),
    ] {
        let pacer = Pacer::new(rate, Duration::from_secs(1));
        for t in [1, 2, 3, 7, 1000, 123_457, 99_999_999] {
            let wall = pacer.wall_at(Ticks(t));
            assert!(pacer.ticks_at(wall) >= Ticks(t), "{rate:?} {t}");
            assert!(
                pacer.ticks_at(wall - Duration::from_nanos(1)) < Ticks(t),
                "{rate:?} {t}: not the first nanosecond"
            );
        }
    }
}

#[test]
fn factors_that_would_stop_the_clock_keep_it_running() {
    for factor in [0.0, -1.0, f64::NAN, 1e-30] {
        let pacer = Pacer::new(Rate::per_second(10).times(factor), Duration::from_secs(1));
        assert_eq!(
            pacer.ticks_at(Duration::from_secs(1000)),
            Ticks(1),
            "{factor}"
        );
    }
}
