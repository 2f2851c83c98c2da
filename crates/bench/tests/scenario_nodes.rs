//! SJA1000 nodes operated by this library's driver in scenario files (`kind = "sja1000"`): the
//! seed's cut-wire experiment, the fast restart as an option, and fast-forward over idle bus
//! time changing nothing.

use buslab_bench::Scenario;
use buslab_can::BitTime;
use buslab_can::controller::{ErrorState, Event};
use buslab_sim::{Happening, Simulation};

const SEED: &str = include_str!("../../../scenarios/seed-cut-wire.toml");

fn run(text: &str, fast_forward: bool) -> Simulation {
    let scenario = Scenario::from_toml(text).unwrap();
    let mut sim = scenario.build().unwrap();
    sim.set_fast_forward(fast_forward);
    sim.run_until(scenario.duration);
    sim
}

/// The sender's TXERR at each sample (bit-time, value), and when it entered bus-off.
fn sender(sim: &Simulation) -> (Vec<(BitTime, u16)>, Vec<BitTime>) {
    let samples = sim
        .series()
        .iter()
        .filter(|s| s.node == 0)
        .map(|s| (s.time, s.tec))
        .collect();
    let bus_offs = sim
        .records()
        .iter()
        .filter_map(|r| match &r.what {
            Happening::Node {
                node: 0,
                event:
                    Event::StateChanged {
                        to: ErrorState::BusOff,
                        ..
                    },
            } => Some(r.time),
            _ => None,
        })
        .collect();
    (samples, bus_offs)
}

#[test]
fn the_seed_recovery_counts_txerr_down_and_the_fast_restart_jumps_to_zero() {
    let seed = run(SEED, true);
    let (samples, bus_offs) = sender(&seed);
    assert!(!bus_offs.is_empty());
    // Right after bus-off the chip shows 127 or a little less, falling.
    let after = |t: BitTime| samples.iter().find(|s| s.0 > t).unwrap().1;
    assert!(bus_offs.iter().all(|&t| (100..=127).contains(&after(t))));

    let fast = SEED.replace(
        "kind = \"sja1000\"     # recovery",
        "kind = \"sja1000\"\nrecovery = \"fast\" # ",
    );
    assert_ne!(fast, SEED);
    let fast = run(&fast, true);
    let (samples, bus_offs) = sender(&fast);
    assert!(!bus_offs.is_empty());
    // Linux's restart: bus-off for 100 ms (TXERR stays 127), then TXERR := 0 at once (the
    // wire is still cut, so the next millisecond's sample shows a couple of new failures; the
    // counted recovery would show about 127 - 125 / 11 = 116).
    let restarted = bus_offs[0] + BitTime::new(125_000 / 10);
    let before = samples.iter().rev().find(|s| s.0 < restarted).unwrap().1;
    let after = samples.iter().find(|s| s.0 > restarted).unwrap().1;
    assert_eq!(before, 127);
    assert!(after <= 32, "{after}");
}

#[test]
fn fast_forward_over_idle_time_changes_nothing_with_sja1000_nodes() {
    let fast = run(SEED, true);
    let slow = run(SEED, false);
    assert!(fast.fast_forwarded() > BitTime::ZERO);
    assert_eq!(slow.fast_forwarded(), BitTime::ZERO);
    assert_eq!(fast.records(), slow.records());
    assert_eq!(fast.series(), slow.series());
    assert_eq!(fast.bus_stats(), slow.bus_stats());
}
