//! Determinism, the shipped scenarios, and the VCD output.

mod common;

use std::collections::HashMap;

use buslab_bench::Scenario;
use buslab_can::BitTime;
use buslab_can::Level;
use buslab_sim::observe::signal_names;
use buslab_sim::{Simulation, VcdWriter};

const NOISE: &str = include_str!("../../../scenarios/noise.toml");
const SCENARIOS: [(&str, &str); 4] = [
    (
        "cut-wire-controllers",
        include_str!("../../../scenarios/cut-wire-controllers.toml"),
    ),
    (
        "arbitration",
        include_str!("../../../scenarios/arbitration.toml"),
    ),
    ("noise", NOISE),
    (
        "listen-only",
        include_str!("../../../scenarios/listen-only.toml"),
    ),
];

fn run(text: &str, seed: Option<u64>, bits: u64) -> Simulation {
    let mut scenario = Scenario::from_toml(text).unwrap();
    if let Some(seed) = seed {
        scenario.seed = seed;
    }
    let mut sim = scenario.build().unwrap();
    sim.trace_levels();
    sim.run_for(BitTime::new(bits));
    sim
}

#[test]
fn same_seed_same_trace_other_seed_other_trace() {
    let mut a = run(NOISE, None, 60_000);
    let mut b = run(NOISE, None, 60_000);
    assert!(
        a.bus_stats().errors > 0,
        "the noise scenario must produce errors"
    );
    assert_eq!(a.records(), b.records());
    assert_eq!(a.take_level_changes(), b.take_level_changes());
    let c = run(NOISE, Some(43), 60_000);
    assert_ne!(a.records(), c.records());
}

#[test]
fn shipped_scenarios_parse_and_run() {
    for (name, text) in SCENARIOS {
        let scenario = Scenario::from_toml(text).unwrap_or_else(|e| panic!("{name}: {e}"));
        let mut sim = scenario.build().unwrap();
        sim.run_until(BitTime::new(
            (scenario.duration.min(BitTime::new(50_000))).get(),
        ));
        assert!(sim.bus_stats().frames > 0, "{name}: no frames");
    }
}

/// Parses the VCD text and checks it is well formed; returns the value changes per signal
/// name as `(time, value)`.
fn parse_vcd(text: &str) -> HashMap<String, Vec<(u64, char)>> {
    let mut lines = text.lines();
    let mut codes = HashMap::new();
    let mut saw_timescale = false;
    for line in lines.by_ref() {
        let words: Vec<&str> = line.split_whitespace().collect();
        match words.as_slice() {
            ["$timescale", "1ns", "$end"] => saw_timescale = true,
            ["$var", "wire", "1", code, name, "$end"] => {
                assert!(codes.insert(code.to_string(), name.to_string()).is_none());
            }
            ["$enddefinitions", "$end"] => break,
            ["$scope", "module", _, "$end"] | ["$upscope", "$end"] => {}
            [first, .., "$end"] if first.starts_with('$') => {}
            other => panic!("unexpected header line {other:?}"),
        }
    }
    assert!(saw_timescale && !codes.is_empty());
    let mut changes: HashMap<String, Vec<(u64, char)>> = HashMap::new();
    let mut time = None::<u64>;
    for line in lines {
        if let Some(t) = line.strip_prefix('#') {
            let t: u64 = t.parse().unwrap();
            assert!(time.is_none_or(|prev| t > prev), "time goes back at {line}");
            time = Some(t);
        } else if line == "$dumpvars" || line == "$end" {
        } else {
            let (value, code) = line.split_at(1);
            let value = value.chars().next().unwrap();
            assert!(value == '0' || value == '1', "{line}");
            let name = codes
                .get(code)
                .unwrap_or_else(|| panic!("undeclared {code}"));
            let list = changes.entry(name.clone()).or_default();
            assert!(
                list.last().is_none_or(|&(_, v)| v != value),
                "not a change: {line}"
            );
            list.push((time.expect("value before any #time"), value));
        }
    }
    changes
}

#[test]
fn vcd_is_well_formed_and_matches_the_bus() {
    let text = include_str!("../../../scenarios/arbitration.toml");
    let scenario = Scenario::from_toml(text).unwrap();
    let mut sim = scenario.build().unwrap();
    sim.trace_levels();
    let names = signal_names(sim.nodes().iter().map(|n| n.name()));
    let mut vcd = VcdWriter::new(Vec::new(), sim.bitrate(), &names).unwrap();
    let mut all = Vec::new();
    for _ in 0..4 {
        sim.run_for(BitTime::new(1_000));
        let changes = sim.take_level_changes();
        vcd.write_changes(&changes).unwrap();
        all.extend(changes);
    }
    let out = String::from_utf8(vcd.finish(sim.now()).unwrap()).unwrap();
    let parsed = parse_vcd(&out);
    assert_eq!(parsed.len(), names.len());
    // 500 kbit/s: 2000 ns per bit. The bus signal is the wired-AND of the TX signals here
    // (no faults): every bus change must match.
    let bus = &parsed["bus"];
    assert!(bus.len() > 20);
    let expected: Vec<(u64, char)> = std::iter::once((0, '1'))
        .chain(all.iter().filter(|c| c.signal == 0).map(|c| {
            let v = if c.level == Level::Recessive {
                '1'
            } else {
                '0'
            };
            (c.time.get() * 2_000, v)
        }))
        .collect();
    assert_eq!(bus, &expected);
    // The bus is dominant whenever some node drives dominant.
    let level_at =
        |list: &[(u64, char)], t: u64| list.iter().take_while(|(ct, _)| *ct <= t).last().unwrap().1;
    for t in (0..4_000u64).step_by(7).map(|b| b * 2_000) {
        let any_dominant = sim
            .nodes()
            .iter()
            .any(|n| level_at(&parsed[&format!("{}_tx", n.name())], t) == '0');
        assert_eq!(level_at(bus, t) == '0', any_dominant, "at {t} ns");
    }
}

/// Jumping over idle bus time is exact: the same trace, counters and bus statistics as
/// stepping every bit.
#[test]
fn fast_forward_changes_nothing() {
    for (name, text) in SCENARIOS {
        for traced in [false, true] {
            let scenario = Scenario::from_toml(text).unwrap();
            let bits = scenario.duration.min(BitTime::new(120_000));
            let mut fast = scenario.build().unwrap();
            let mut slow = scenario.build().unwrap();
            slow.set_fast_forward(false);
            if traced {
                fast.trace_levels();
                slow.trace_levels();
            }
            fast.run_until(bits);
            slow.run_until(bits);
            // These have idle stretches without faults (the arbitration demo keeps the bus
            // saturated, the noise demo has noise all the time).
            if ["cut-wire-controllers", "listen-only"].contains(&name) {
                assert!(fast.fast_forwarded() > bits / 10, "{name}: no fast-forward");
            }
            assert_eq!(slow.fast_forwarded(), BitTime::ZERO);
            assert_eq!(
                fast.take_level_changes(),
                slow.take_level_changes(),
                "{name}"
            );
            assert!(!fast.records().is_empty(), "{name}");
            assert_eq!(fast.records(), slow.records(), "{name}");
            assert_eq!(fast.bus_stats(), slow.bus_stats(), "{name}");
            assert_eq!(fast.series(), slow.series(), "{name}");
            for (a, b) in fast.nodes().iter().zip(slow.nodes()) {
                assert_eq!(a.stats(), b.stats(), "{name}");
                assert_eq!((a.tec(), a.rec()), (b.tec(), b.rec()));
            }
        }
    }
}
