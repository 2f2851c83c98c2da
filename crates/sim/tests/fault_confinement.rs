//! Fault confinement on the simulated bus, checked against the counter rules of the facts sheet
//! (can-bitlevel.md §5): the seed's cut-wire experiment, the lone node, a bit flipped at one
//! receiver (and the known double reception at the last EOF bit), and listen-only.

mod common;

use buslab_bench::Scenario;
use buslab_can::BitTime;
use buslab_can::Level;
use buslab_can::controller::{ControllerConfig, ErrorKind, ErrorState, Event};
use buslab_sim::{Fault, FaultKind, Simulation, Traffic};
use common::*;

const SEED_SCENARIO: &str = include_str!("../../../scenarios/cut-wire-controllers.toml");

/// (a) SPEC N2, the seed's experiment with bare protocol controllers, run from the shipped
/// scenario file (the SJA1000 version, `seed-cut-wire.toml`, is tested in `buslab-canbus` and
/// through `buslab sim`).
#[test]
fn cut_wire_drives_the_sender_to_bus_off_and_it_recovers_after_reconnection() {
    let scenario = Scenario::from_toml(SEED_SCENARIO).unwrap();
    let cut = scenario.faults[0].clone();
    assert!(matches!(cut.kind, FaultKind::Cut { .. }));
    let mut sim = scenario.build().unwrap();
    sim.run_until(scenario.duration);
    let (sender, pc) = (0, 1);
    let ev = events(sim.records(), sender);

    // Before the cut: no errors at all.
    assert!(
        ev.iter()
            .all(|(t, e)| *t >= cut.start || !matches!(e, Event::Error { .. }))
    );

    // During the cut the TEC climbs by 8 per failed transmission, through the warning level
    // (96) and error-passive (128), to bus-off.
    let bus_off = entered(sim.records(), sender, ErrorState::BusOff);
    let first_bus_off = *bus_off.first().expect("the sender never went bus-off");
    assert!((cut.start..cut.end).contains(&first_bus_off));
    let warning_up = ev
        .iter()
        .find_map(|(t, e)| matches!(e, Event::Warning { above: true, .. }).then_some(*t))
        .expect("no warning-level crossing");
    let passive = entered(sim.records(), sender, ErrorState::Passive)[0];
    assert!(cut.start <= warning_up && warning_up <= passive && passive < first_bus_off);
    let tec_path: Vec<u16> = ev
        .iter()
        .filter(|(t, _)| *t <= first_bus_off)
        .filter_map(|(_, e)| match e {
            Event::Error {
                transmitter: true,
                tec,
                ..
            } => Some(*tec),
            _ => None,
        })
        .collect();
    assert!(tec_path.windows(2).all(|w| w[1] >= w[0]), "{tec_path:?}");
    assert!(*tec_path.last().unwrap() >= 248, "{tec_path:?}");

    // Every recovery from bus-off takes at least 128 × 11 recessive bits.
    let recoveries: Vec<BitTime> = ev
        .iter()
        .filter_map(|(t, e)| {
            matches!(
                e,
                Event::StateChanged {
                    from: ErrorState::BusOff,
                    ..
                }
            )
            .then_some(*t)
        })
        .collect();
    assert!(!recoveries.is_empty());
    for (off, on) in bus_off.iter().zip(&recoveries) {
        assert!(
            *on - *off >= BitTime::new(128 * 11),
            "bus-off at {off}, recovered at {on}"
        );
    }
    // The wire is repaired while the sender is bus-off; it recovers after that, and then the
    // counters have fallen.
    let last_recovery = *recoveries.last().unwrap();
    assert_eq!(bus_off.len(), recoveries.len());
    assert!(*bus_off.last().unwrap() < cut.end && cut.end < last_recovery);
    let c = sim.node(sender);
    assert_eq!(c.state(), ErrorState::Active);
    assert!(
        c.tec() < 96 && c.rec() < 96,
        "TEC {} REC {}",
        c.tec(),
        c.rec()
    );

    // The file arrives whole, in order, exactly once.
    assert!(sim.files_finished(sender)[0].is_some());
    let file: Vec<u8> = received(sim.records(), pc)
        .iter()
        .filter(|f| f.id().as_raw() == 0x100)
        .flat_map(|f| f.payload().to_vec())
        .collect();
    let expected: Vec<u8> = (0..4000).map(|i| (i % 251) as u8).collect();
    assert_eq!(file.len(), expected.len());
    assert!(file == expected);
}

/// (b) Alone on the bus, a node gets only ACK errors: TEC 0 → 8 → … → 128, then the
/// error-passive ACK-error exception keeps it at 128; it never goes bus-off.
#[test]
fn a_node_alone_stops_at_tec_128() {
    let mut sim = bus_with(&[("alone", &["123#1122"])]);
    sim.run_for(BitTime::new(200_000));
    let ev = events(sim.records(), 0);
    let errors: Vec<(ErrorKind, u16)> = ev
        .iter()
        .filter_map(|(_, e)| match e {
            Event::Error { kind, tec, .. } => Some((*kind, *tec)),
            _ => None,
        })
        .collect();
    assert!(errors.len() > 100, "{} errors", errors.len());
    assert!(errors.iter().all(|(k, _)| *k == ErrorKind::Ack));
    let c = sim.node(0);
    assert_eq!(c.tec(), 128);
    assert_eq!(c.state(), ErrorState::Passive);
    assert!(entered(sim.records(), 0, ErrorState::BusOff).is_empty());
    assert_eq!(entered(sim.records(), 0, ErrorState::Passive).len(), 1);
    assert_eq!(sim.node(0).stats().max_tec, 128);
    assert!(transmitted(sim.records(), 0).is_empty());
}

/// The bit-time of the start of the first frame on the bus (first dominant bus level).
fn first_sof(mut sim: Simulation) -> u64 {
    sim.trace_levels();
    sim.run_for(BitTime::new(1_000));
    (sim.take_level_changes()
        .iter()
        .find(|c| c.signal == 0 && c.level == Level::Dominant)
        .unwrap()
        .time)
        .get()
}

/// (c) A bit flipped at one receiver: it signals an error, the frame is retransmitted, and
/// every node receives it exactly once.
#[test]
fn a_bit_flipped_at_one_receiver_causes_one_retransmission() {
    let setup = || bus_with(&[("tx", &["123#1122334455"]), ("b", &[]), ("c", &[])]);
    let sof = first_sof(setup());
    for offset in [5, 20, 30, 40, 60] {
        let mut sim = setup();
        sim.add_fault(Fault {
            kind: FaultKind::Flip { node: Some(1) },
            start: BitTime::new(sof + offset),
            end: BitTime::new(sof + offset + 1),
        });
        sim.run_for(BitTime::new(1_000));
        let r = sim.records();
        assert!(sim.node(1).stats().errors >= 1, "offset {offset}");
        assert_eq!(transmitted(r, 0).len(), 1, "offset {offset}");
        for rx in [1, 2] {
            assert_eq!(
                received(r, rx),
                [frame("123#1122334455")],
                "offset {offset}"
            );
        }
        // One error as transmitter (+8), one success (−1).
        assert_eq!(sim.node(0).tec(), 7, "offset {offset}");
    }
}

/// The known double reception: receivers accept a frame at the next-to-last EOF bit; if only
/// the transmitter sees the last EOF bit dominant, it retransmits, and the receivers get the
/// frame twice.
#[test]
fn an_error_at_the_last_eof_bit_seen_by_the_transmitter_duplicates_the_frame() {
    let setup = || bus_with(&[("tx", &["123#AB"]), ("rx", &[])]);
    let mut clean = setup();
    clean.run_for(BitTime::new(500));
    let accepted = events(clean.records(), 1)
        .into_iter()
        .find_map(|(t, e)| matches!(e, Event::Received(_)).then_some(t))
        .unwrap();
    let last_eof_bit = accepted + BitTime::new(1);
    assert_eq!(transmitted(clean.records(), 0)[0].0, last_eof_bit);

    let mut sim = setup();
    sim.add_fault(Fault {
        kind: FaultKind::Flip { node: Some(0) },
        start: last_eof_bit,
        end: last_eof_bit + BitTime::new(1),
    });
    sim.run_for(BitTime::new(1_000));
    assert_eq!(
        received(sim.records(), 1),
        [frame("123#AB"), frame("123#AB")]
    );
    assert_eq!(transmitted(sim.records(), 0).len(), 1);
}

/// (d) A listen-only node never drives the bus dominant, even with errors on the bus, and
/// still receives the frames.
#[test]
fn a_listen_only_node_never_drives_dominant() {
    let mut sim = Simulation::new(500_000, 5);
    let a = sim.add_node("a", ControllerConfig::default());
    let b = sim.add_node("b", ControllerConfig::default());
    let spy = sim.add_node(
        "spy",
        ControllerConfig {
            listen_only: true,
            ..Default::default()
        },
    );
    for (n, f) in [(a, "100#0102030405060708"), (b, "200#FF")] {
        sim.add_traffic(
            n,
            Traffic::Periodic {
                frame: frame(f),
                period: BitTime::new(300),
                start: BitTime::ZERO,
                count: None,
            },
        );
    }
    sim.add_fault(Fault {
        kind: FaultKind::Noise {
            nodes: vec![spy],
            rate: 0.002,
        },
        start: BitTime::ZERO,
        end: BitTime::new(u64::MAX),
    });
    sim.trace_levels();
    sim.run_for(BitTime::new(50_000));
    let spy_tx = 1 + 2 * spy;
    let changes = sim.take_level_changes();
    assert!(changes.iter().any(|c| c.signal == 2 + 2 * spy));
    assert!(!changes.iter().any(|c| c.signal == spy_tx));
    let s = sim.node(spy).stats();
    assert!(s.received > 150, "{s:?}");
    assert!(s.errors > 0, "{s:?}");
    assert_eq!(sim.node(spy).tec(), 0);
}

/// A disconnected node's frames get no ACK and the others never see them; once reconnected its
/// frame goes through.
#[test]
fn a_disconnected_node_is_invisible() {
    let mut sim = bus_with(&[("cutoff", &["123#01"]), ("other", &[])]);
    sim.add_fault(Fault {
        kind: FaultKind::Disconnect { node: 0 },
        start: BitTime::ZERO,
        end: BitTime::new(20_000),
    });
    sim.run_for(BitTime::new(19_000));
    assert!(received(sim.records(), 1).is_empty());
    assert_eq!(sim.node(0).tec(), 128);
    assert!(sim.node(1).stats().errors == 0);
    sim.run_for(BitTime::new(2_000));
    assert_eq!(received(sim.records(), 1), [frame("123#01")]);
    // Reconnected in the middle of an attempt: the other node flags an error during the
    // sender's passive error flag, so the ACK-error exception does not apply (TEC 128 + 8),
    // then the retransmission succeeds (− 1).
    assert_eq!(sim.node(0).tec(), 135);
}

/// A stuck-dominant bus: the transmitter's TEC climbs by 8 per 8 dominant bits after its error
/// flag, so it goes bus-off; once the bus is released it recovers.
#[test]
fn stuck_dominant_bus_sends_the_transmitter_bus_off() {
    let mut sim = bus_with(&[("tx", &["123#01"]), ("rx", &[])]);
    // Controllers integrate for 11 bits, so the frame is on the wire at bit 30.
    sim.add_fault(Fault {
        kind: FaultKind::StuckDominant,
        start: BitTime::new(30),
        end: BitTime::new(5_000),
    });
    sim.run_for(BitTime::new(20_000));
    let off = entered(sim.records(), 0, ErrorState::BusOff);
    assert_eq!(off.len(), 1);
    assert!(off[0] < BitTime::new(5_000));
    let active = entered(sim.records(), 0, ErrorState::Active);
    // Bits 5000..=t are the 128 × 11 recessive bits of the recovery.
    assert!(
        active
            .last()
            .is_some_and(|&t| t + BitTime::new(1) - BitTime::new(5_000) >= BitTime::new(128 * 11))
    );
    assert!(sim.node(1).stats().errors > 0);
    assert!(sim.node(1).stats().max_rec >= 128);
}

/// A clean cut (no reflections) splits the bus in two working halves: frames are acknowledged
/// and received on their own side only.
#[test]
fn a_clean_cut_makes_two_buses() {
    let mut sim = bus_with(&[("a", &[]), ("b", &[]), ("c", &[]), ("d", &[])]);
    sim.add_fault(Fault {
        kind: FaultKind::Cut {
            far_side: vec![0, 1],
            error_rate: 0.0,
        },
        start: BitTime::ZERO,
        end: BitTime::new(u64::MAX),
    });
    for (node, f) in [(0, "100#AA"), (2, "200#CC")] {
        sim.add_traffic(
            node,
            Traffic::Once {
                frame: frame(f),
                at: BitTime::new(100),
            },
        );
    }
    sim.run_for(BitTime::new(1_000));
    let r = sim.records();
    assert_eq!(received(r, 1), [frame("100#AA")]);
    assert_eq!(received(r, 3), [frame("200#CC")]);
    assert!(received(r, 0).is_empty() && received(r, 2).is_empty());
    // Both went out at the same time, without arbitration between them.
    let (a, c) = (transmitted(r, 0)[0].0, transmitted(r, 2)[0].0);
    assert!(a.get().abs_diff(c.get()) < 10, "{a} {c}");
    assert!(
        sim.nodes()
            .iter()
            .all(|n| n.stats().errors == 0 && n.stats().arbitration_lost == 0)
    );
}

/// A bit flipped at every node at once (a glitch on the wire itself): everybody detects it,
/// the frame is retransmitted and received once.
#[test]
fn a_bit_flipped_at_every_node_is_one_error_frame() {
    let setup = || bus_with(&[("tx", &["123#1122334455"]), ("b", &[]), ("c", &[])]);
    let sof = first_sof(setup());
    let mut sim = setup();
    sim.add_fault(Fault {
        kind: FaultKind::Flip { node: None },
        start: BitTime::new(sof + 25),
        end: BitTime::new(sof + 26),
    });
    sim.run_for(BitTime::new(1_000));
    let r = sim.records();
    assert_eq!(transmitted(r, 0).len(), 1);
    for rx in [1, 2] {
        assert_eq!(received(r, rx), [frame("123#1122334455")]);
    }
    assert!(sim.nodes().iter().all(|n| n.stats().errors >= 1));
    assert_eq!(sim.node(0).tec(), 7);
}

/// A bus that lives long gets many faults: the ended ones are forgotten (a bus server counted
/// every fault it ever had against its limit), and the trace still names each by the number
/// `add_fault` gave it.
#[test]
fn ended_faults_are_forgotten_and_the_trace_keeps_their_numbers() {
    use buslab_sim::Happening;
    let mut sim = bus_with(&[("a", &[]), ("b", &[])]);
    let flip = |start, end| Fault {
        kind: FaultKind::Flip { node: Some(1) },
        start: BitTime::new(start),
        end: BitTime::new(end),
    };
    assert_eq!(sim.add_fault(flip(100, 200)), 0);
    assert_eq!(sim.add_fault(flip(150, 10_000)), 1);
    sim.run_for(BitTime::new(300));
    // The first ended and is forgotten; the second is in force.
    assert_eq!(sim.faults(), [flip(150, 10_000)]);
    assert_eq!(sim.add_fault(flip(400, 500)), 2);
    sim.run_for(BitTime::new(10_000));
    assert!(sim.faults().is_empty());
    let faults: Vec<_> = sim
        .records()
        .iter()
        .filter_map(|r| match r.what {
            Happening::FaultStarted { index } => Some((r.time.get(), "started", index)),
            Happening::FaultEnded { index } => Some((r.time.get(), "ended", index)),
            Happening::Node { .. } => None,
        })
        .collect();
    assert_eq!(
        faults,
        [
            (100, "started", 0),
            (150, "started", 1),
            (200, "ended", 0),
            (400, "started", 2),
            (500, "ended", 2),
            (10_000, "ended", 1),
        ]
    );
}

/// A node taken off the bus while a fault in force names it alone (a bus server's client with
/// its connector pulled leaves): the fault ends with it. The wiring was rebuilt with the fault
/// still in force and the removed node's index, out of bounds: the server's thread panicked.
#[test]
fn removing_the_only_node_a_fault_in_force_names_ends_the_fault() {
    use buslab_sim::Happening;
    for kind in [
        FaultKind::Disconnect { node: 1 },
        FaultKind::Cut {
            far_side: vec![1],
            error_rate: 0.0,
        },
        FaultKind::Noise {
            nodes: vec![1],
            rate: 0.5,
        },
        FaultKind::Flip { node: Some(1) },
    ] {
        let mut sim = bus_with(&[("a", &["123#01"]), ("gone", &["124#02"])]);
        sim.add_fault(Fault {
            kind: kind.clone(),
            start: BitTime::ZERO,
            end: BitTime::new(u64::MAX),
        });
        sim.run_for(BitTime::new(100));
        sim.remove_node(1);
        sim.run_for(BitTime::new(20_000));
        assert!(sim.faults().is_empty(), "{kind:?}");
        assert!(
            sim.records()
                .iter()
                .any(|r| r.what == Happening::FaultEnded { index: 0 }),
            "{kind:?}"
        );
    }
}
