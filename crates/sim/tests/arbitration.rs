//! Arbitration on a bit-level bus: the lowest arbitration field wins, losers retry, and every
//! frame reaches every other node exactly once.

mod common;

use buslab_can::BitTime;
use buslab_can::controller::{ControllerConfig, Event};
use buslab_sim::{Simulation, Traffic};
use common::*;

/// Frames transmitted by all nodes, in bus order.
fn bus_order(sim: &Simulation) -> Vec<String> {
    let mut all: Vec<_> = (0..sim.nodes().len())
        .flat_map(|n| transmitted(sim.records(), n))
        .collect();
    all.sort_by_key(|(t, _)| *t);
    all.into_iter().map(|(_, f)| f.to_string()).collect()
}

fn assert_everyone_got_everything_once(sim: &Simulation) {
    let n = sim.nodes().len();
    for rx in 0..n {
        let mut got: Vec<String> = received(sim.records(), rx)
            .iter()
            .map(|f| f.to_string())
            .collect();
        got.sort();
        let mut expected: Vec<String> = (0..n)
            .filter(|&tx| tx != rx)
            .flat_map(|tx| transmitted(sim.records(), tx))
            .map(|(_, f)| f.to_string())
            .collect();
        expected.sort();
        assert_eq!(got, expected, "node {} received", sim.node(rx).name());
    }
}

#[test]
fn lowest_id_wins_and_losers_retry() {
    let mut sim = bus_with(&[
        ("a", &["200#AA"]),
        ("b", &["100#BB"]),
        ("c", &["150#CC"]),
        ("d", &["7FF#"]),
    ]);
    sim.run_for(BitTime::new(2_000));
    assert_eq!(bus_order(&sim), ["100#BB", "150#CC", "200#AA", "7FF#"]);
    // The first round: everyone but b lost; then c's rivals lost again, and so on.
    let lost = |n| sim.node(n).stats().arbitration_lost;
    assert_eq!([lost(0), lost(1), lost(2), lost(3)], [2, 0, 1, 3]);
    assert_everyone_got_everything_once(&sim);
    assert!(
        sim.nodes()
            .iter()
            .all(|n| n.stats().errors == 0 && n.tec() == 0)
    );
}

#[test]
fn standard_beats_extended_with_the_same_base_and_data_beats_remote() {
    // 048C0000 is the extended ID whose 11 base bits are 0x123.
    let mut sim = bus_with(&[
        ("ext", &["048C0000#01"]),
        ("remote", &["123#R2"]),
        ("data", &["123#0102"]),
        ("ext_remote", &["048C0000#R"]),
    ]);
    sim.run_for(BitTime::new(2_000));
    assert_eq!(
        bus_order(&sim),
        ["123#0102", "123#R2", "048C0000#01", "048C0000#R"]
    );
    assert_everyone_got_everything_once(&sim);
}

#[test]
fn arbitration_loss_is_reported_at_the_deciding_bit() {
    // 0x100 vs 0x101 differ in the last ID bit: SOF + 11 ID bits → bit 11 (SOF = 0).
    let mut sim = bus_with(&[("low", &["100#"]), ("high", &["101#"])]);
    sim.run_for(BitTime::new(500));
    let lost: Vec<_> = events(sim.records(), 1)
        .into_iter()
        .filter_map(|(_, e)| match e {
            Event::ArbitrationLost { frame, bit } => Some((frame.to_string(), bit)),
            _ => None,
        })
        .collect();
    assert_eq!(lost, [("101#".to_owned(), 11)]);
}

#[test]
fn saturated_bus_delivers_every_frame_once() {
    let mut sim = Simulation::new(1_000_000, 9);
    for i in 0..8u16 {
        let n = sim.add_node(format!("n{i}"), ControllerConfig::default());
        sim.add_traffic(
            n,
            Traffic::Periodic {
                frame: frame(&format!("{:03X}#{:02X}", 0x700 - i * 0x10, i)),
                period: BitTime::new(100 + 37 * i as u64),
                start: BitTime::ZERO,
                count: Some(25),
            },
        );
    }
    sim.run_for(BitTime::new(60_000));
    for n in sim.nodes() {
        assert_eq!(n.stats().sent, 25, "{} sent", n.name());
        assert_eq!(n.stats().received, 7 * 25, "{} received", n.name());
        assert_eq!(n.stats().errors, 0);
        assert_eq!(n.stats().queue_overflows, 0);
    }
    assert!(
        sim.nodes()
            .iter()
            .map(|n| n.stats().arbitration_lost)
            .sum::<u64>()
            > 0
    );
    assert_everyone_got_everything_once(&sim);
    assert_eq!(sim.bus_stats().frames, 8 * 25);
}
