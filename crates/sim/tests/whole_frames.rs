//! The frame-level fast path changes nothing but the speed: over random buses (faults that
//! start and end mid-frame, error-passive nodes, identical IDs, overload, bus-off, listen-only
//! and single-shot nodes, small queues, files, counter samples) the trace, every counter, the
//! bus statistics, the TEC/REC series and every controller's final state are the same with
//! whole frames on and off.

mod common;

use buslab_can::BitTime;
use buslab_can::controller::{Controller, ControllerConfig};
use buslab_can::{Frame, Id};
use buslab_sim::{Fault, FaultKind, RecordedEvents, Simulation, Traffic};
use common::*;
use proptest::prelude::*;

#[derive(Clone, Debug)]
struct NodeSpec {
    listen_only: bool,
    single_shot: bool,
    self_reception: bool,
    auto_recover: bool,
    capacity: usize,
    /// TEC and REC set before the run (≥ 128: error-passive; > 255 TEC: bus-off).
    counters: (u16, u16),
}

#[derive(Clone, Debug)]
enum TrafficSpec {
    Periodic {
        frame: Frame,
        period: u64,
        start: u64,
    },
    Burst {
        frame: Frame,
        count: u32,
        period: u64,
        start: u64,
    },
    Once {
        frame: Frame,
        at: u64,
    },
    File {
        id: Id,
        len: usize,
        start: u64,
    },
}

#[derive(Clone, Debug)]
struct Bus {
    nodes: Vec<NodeSpec>,
    traffic: Vec<(usize, TrafficSpec)>,
    faults: Vec<(u8, usize, u64, u64)>,
    sample_every: Option<u64>,
    /// The run is cut into these pieces (a run may end in the middle of a frame).
    steps: Vec<u64>,
}

fn node_spec() -> impl Strategy<Value = NodeSpec> {
    (
        prop::bool::weighted(0.1),
        prop::bool::weighted(0.15),
        prop::bool::weighted(0.15),
        prop::bool::weighted(0.8),
        1usize..6,
        prop_oneof![
            6 => Just((0u16, 0u16)),
            2 => (0u16..140, 0u16..140),
            1 => (120u16..200, 0u16..256),
            1 => Just((256u16, 0u16)),
        ],
    )
        .prop_map(
            |(listen_only, single_shot, self_reception, auto_recover, capacity, counters)| {
                NodeSpec {
                    listen_only,
                    single_shot,
                    self_reception,
                    auto_recover,
                    capacity,
                    counters,
                }
            },
        )
}

/// A small ID space, so equal IDs on two nodes happen often.
fn any_frame() -> impl Strategy<Value = Frame> {
    (
        any::<bool>(),
        0u32..12,
        prop::bool::weighted(0.1),
        prop::collection::vec(any::<u8>(), 0..=8),
    )
        .prop_map(|(extended, n, remote, data)| {
            let id = if extended {
                Id::extended(0x0123_4567 ^ (n * 0x0101_0101)).unwrap()
            } else {
                Id::standard(0x100 + n as u16 * 0x31).unwrap()
            };
            if remote {
                Frame::remote(id, data.len() as u8).unwrap()
            } else {
                Frame::data(id, &data).unwrap()
            }
        })
}

fn traffic() -> impl Strategy<Value = TrafficSpec> {
    prop_oneof![
        (any_frame(), 60u64..600, 0u64..2_000).prop_map(|(frame, period, start)| {
            TrafficSpec::Periodic {
                frame,
                period,
                start,
            }
        }),
        (
            any_frame(),
            1u32..5,
            prop_oneof![Just(0u64), 300u64..3_000],
            0u64..3_000
        )
            .prop_map(|(frame, count, period, start)| TrafficSpec::Burst {
                frame,
                count,
                period,
                start
            }),
        (any_frame(), 0u64..6_000).prop_map(|(frame, at)| TrafficSpec::Once { frame, at }),
        (0u16..0x7FF, 0usize..40, 0u64..3_000).prop_map(|(id, len, start)| TrafficSpec::File {
            id: Id::standard(id).unwrap(),
            len,
            start
        }),
    ]
}

fn bus() -> impl Strategy<Value = Bus> {
    (2usize..7).prop_flat_map(|n| {
        (
            prop::collection::vec(node_spec(), n),
            prop::collection::vec((0..n, traffic()), 1..10),
            prop::collection::vec((0u8..6, 0..n, 0u64..8_000, 1u64..600), 0..4),
            prop::option::weighted(0.3, 50u64..700),
            prop::collection::vec(1u64..3_000, 1..6),
        )
            .prop_map(|(nodes, traffic, faults, sample_every, steps)| Bus {
                nodes,
                traffic,
                faults,
                sample_every,
                steps,
            })
    })
}

/// Many nodes on a busy bus, most of them error-active with counters of every size (a
/// receiver's REC going down at the ACK slot, crossing the warning limit), a few error-passive
/// or bus-off, and few faults: the frames applied whole have many receivers in different
/// states and many losers.
fn crowded_bus() -> impl Strategy<Value = Bus> {
    let crowd_node = (
        prop::bool::weighted(0.05),
        prop::bool::weighted(0.1),
        prop::bool::weighted(0.1),
        1usize..8,
        prop_oneof![
            3 => Just((0u16, 0u16)),
            4 => (0u16..128, 0u16..128),
            2 => (80u16..128, 90u16..128),
            1 => (0u16..200, 120u16..256),
            1 => Just((256u16, 0u16)),
        ],
    )
        .prop_map(
            |(listen_only, single_shot, self_reception, capacity, counters)| NodeSpec {
                listen_only,
                single_shot,
                self_reception,
                auto_recover: true,
                capacity,
                counters,
            },
        );
    (8usize..40).prop_flat_map(move |n| {
        (
            prop::collection::vec(crowd_node.clone(), n),
            prop::collection::vec(
                (
                    0..n,
                    (any_frame(), 100u64..3_000, 0u64..1_000).prop_map(|(frame, period, start)| {
                        TrafficSpec::Periodic {
                            frame,
                            period,
                            start,
                        }
                    }),
                ),
                n / 2..2 * n,
            ),
            prop::collection::vec((0u8..6, 0..n, 0u64..8_000, 1u64..300), 0..2),
            prop::option::weighted(0.3, 50u64..700),
            prop::collection::vec(1u64..3_000, 1..4),
        )
            .prop_map(|(nodes, traffic, faults, sample_every, steps)| Bus {
                nodes,
                traffic,
                faults,
                sample_every,
                steps,
            })
    })
}

fn build(bus: &Bus, whole: bool) -> Simulation {
    let mut sim = Simulation::new(1_000_000, 11);
    sim.set_whole_frames(whole);
    for (i, n) in bus.nodes.iter().enumerate() {
        let node = sim.add_node(
            format!("n{i}"),
            ControllerConfig {
                listen_only: n.listen_only,
                single_shot: n.single_shot,
                self_reception: n.self_reception,
                auto_recover: n.auto_recover,
                tx_queue_capacity: n.capacity,
                ..Default::default()
            },
        );
        let (tec, rec) = n.counters;
        sim.controller_mut(node).unwrap().set_counters(tec, rec);
    }
    for (node, t) in &bus.traffic {
        let traffic = match t {
            TrafficSpec::Periodic {
                frame,
                period,
                start,
            } => Traffic::Periodic {
                frame: *frame,
                period: BitTime::new(*period),
                start: BitTime::new(*start),
                count: None,
            },
            TrafficSpec::Burst {
                frame,
                count,
                period,
                start,
            } => Traffic::Burst {
                frame: *frame,
                count: *count,
                period: BitTime::new(*period),
                start: BitTime::new(*start),
            },
            TrafficSpec::Once { frame, at } => Traffic::Once {
                frame: *frame,
                at: BitTime::new(*at),
            },
            TrafficSpec::File { id, len, start } => Traffic::File {
                id: *id,
                data: (0..*len as u8).collect(),
                start: BitTime::new(*start),
            },
        };
        sim.add_traffic(*node, traffic);
    }
    for &(kind, node, start, len) in &bus.faults {
        let kind = match kind {
            0 => FaultKind::Disconnect { node },
            1 => FaultKind::Cut {
                far_side: vec![node],
                error_rate: 0.05,
            },
            2 => FaultKind::Flip { node: Some(node) },
            3 => FaultKind::StuckDominant,
            4 => FaultKind::Noise {
                nodes: vec![],
                rate: 0.02,
            },
            _ => FaultKind::Noise {
                nodes: vec![node],
                rate: 0.05,
            },
        };
        sim.add_fault(Fault {
            kind,
            start: BitTime::new(start),
            end: BitTime::new(start + len),
        });
    }
    if let Some(every) = bus.sample_every {
        sim.sample_counters_every(BitTime::new(every));
    }
    sim
}

/// Everything a user of the simulation can see, as text.
fn observed(sim: &Simulation) -> (String, String) {
    let nodes: Vec<String> = sim
        .nodes()
        .iter()
        .map(|n| format!("{:?}\n{:?}", n, n.get::<Controller>().unwrap()))
        .collect();
    let files: Vec<_> = (0..sim.nodes().len())
        .map(|i| sim.files_finished(i))
        .collect();
    let state = format!(
        "now {}\n{:#?}\n{:?}\n{:?}\n{:?}",
        sim.now(),
        nodes,
        sim.bus_stats(),
        sim.series(),
        files
    );
    (format!("{:#?}", sim.records()), state)
}

fn run(bus: &Bus, whole: bool) -> (Simulation, (String, String)) {
    let mut sim = build(bus, whole);
    for step in &bus.steps {
        sim.run_for(BitTime::new(*step));
        // A frame queued by hand in the middle of the run, as a scenario's one-shot would.
        let _ = sim.enqueue(0, frame("7FF#EE"));
    }
    let seen = observed(&sim);
    (sim, seen)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(160))]

    #[test]
    fn whole_frames_change_nothing_but_the_speed(bus in bus()) {
        let (_, fast_seen) = run(&bus, true);
        let (slow, slow_seen) = run(&bus, false);
        prop_assert_eq!(slow.whole_frames(), 0);
        prop_assert_eq!(&fast_seen.0, &slow_seen.0, "trace differs");
        prop_assert_eq!(&fast_seen.1, &slow_seen.1, "state differs");
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    #[test]
    fn whole_frames_change_nothing_with_many_nodes_in_different_states(bus in crowded_bus()) {
        let (_, fast_seen) = run(&bus, true);
        let (_, slow_seen) = run(&bus, false);
        prop_assert_eq!(&fast_seen.0, &slow_seen.0, "trace differs");
        prop_assert_eq!(&fast_seen.1, &slow_seen.1, "state differs");
    }
}

/// The fast path does engage on a busy clean bus, and the property above therefore compares
/// two different paths.
#[test]
fn a_busy_clean_bus_is_mostly_applied_whole() {
    let bus = |whole| {
        let mut sim = Simulation::new(1_000_000, 1);
        sim.set_whole_frames(whole);
        for i in 0..8u16 {
            let n = sim.add_node(format!("n{i}"), ControllerConfig::default());
            sim.add_traffic(
                n,
                Traffic::Periodic {
                    frame: Frame::data(Id::standard(0x100 + i).unwrap(), &[i as u8; 8]).unwrap(),
                    period: BitTime::new(500),
                    start: BitTime::new(i as u64 * 7),
                    count: None,
                },
            );
        }
        sim.run_for(BitTime::new(200_000));
        sim
    };
    let fast = bus(true);
    let slow = bus(false);
    assert!(
        fast.whole_frames() * 10 >= fast.bus_stats().frames * 9,
        "{} of {} frames applied whole",
        fast.whole_frames(),
        fast.bus_stats().frames
    );
    assert_eq!(fast.records(), slow.records());
    assert_eq!(observed(&fast), observed(&slow));
}

/// A crowded bus whose receivers sit at every REC (so the ACK slot moves each one's counter
/// differently, across the warning limit) is applied whole too, and the same.
#[test]
fn receivers_in_different_states_are_applied_whole_and_the_same() {
    let bus = |whole| {
        let mut sim = Simulation::new(1_000_000, 1);
        sim.set_whole_frames(whole);
        for i in 0..32u16 {
            let n = sim.add_node(format!("n{i}"), ControllerConfig::default());
            sim.controller_mut(n)
                .unwrap()
                .set_counters(i * 3, (i * 37) % 128);
            if i % 4 == 0 {
                sim.add_traffic(
                    n,
                    Traffic::Periodic {
                        frame: Frame::data(Id::standard(0x700 - i).unwrap(), &[i as u8; 3])
                            .unwrap(),
                        period: BitTime::new(700),
                        start: BitTime::new(i as u64),
                        count: None,
                    },
                );
            }
        }
        sim.sample_counters_every(BitTime::new(333));
        sim.run_for(BitTime::new(60_000));
        sim
    };
    let fast = bus(true);
    let slow = bus(false);
    assert!(
        fast.whole_frames() * 10 >= fast.bus_stats().frames * 9,
        "{} of {} frames applied whole",
        fast.whole_frames(),
        fast.bus_stats().frames
    );
    assert!(
        fast.records().iter().any(|r| matches!(
            r.what,
            buslab_sim::Happening::Node {
                event: buslab_can::controller::Event::Warning { above: false, .. },
                ..
            }
        )),
        "some receiver's REC crossed the warning limit downwards"
    );
    assert_eq!(fast.records(), slow.records());
    assert_eq!(observed(&fast), observed(&slow));
}

/// As [`run`] on the fast path with no trace recorded (`buslab sim --quiet`): the fast path
/// then takes the losers of a frame in node order where only the trace could tell.
fn run_untraced(bus: &Bus) -> (Simulation, (String, String)) {
    let mut sim = build(bus, true);
    sim.set_record_events(RecordedEvents::empty());
    for step in &bus.steps {
        sim.run_for(BitTime::new(*step));
        let _ = sim.enqueue(0, frame("7FF#EE"));
    }
    let seen = observed(&sim);
    (sim, seen)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(96))]

    #[test]
    fn whole_frames_without_a_trace_change_no_counter_or_state(
        bus in prop_oneof![bus(), crowded_bus()]
    ) {
        let (fast, fast_seen) = run_untraced(&bus);
        let (_, slow_seen) = run(&bus, false);
        prop_assert!(
            fast.records().iter().all(|r| !matches!(r.what, buslab_sim::Happening::Node { .. })),
            "node events recorded although switched off"
        );
        prop_assert_eq!(&fast_seen.1, &slow_seen.1, "state differs");
    }
}

/// A saturated bus (every node always has a frame waiting, most lose every arbitration, some
/// single-shot, some sending files) without a trace ends in the same state as stepping every
/// bit with the trace on.
#[test]
fn a_saturated_bus_without_a_trace_ends_the_same() {
    let bus = |whole: bool| {
        let mut sim = Simulation::new(1_000_000, 1);
        sim.set_whole_frames(whole);
        sim.set_record_events(if whole {
            RecordedEvents::empty()
        } else {
            RecordedEvents::all()
        });
        for i in 0..16u16 {
            let n = sim.add_node(
                format!("n{i}"),
                ControllerConfig {
                    single_shot: i % 5 == 4,
                    tx_queue_capacity: 4 + i as usize % 3,
                    ..Default::default()
                },
            );
            let id = Id::standard(0x100 + i).unwrap();
            let traffic = if i % 7 == 6 {
                Traffic::File {
                    id,
                    data: (0..200u8).collect(),
                    start: BitTime::new(i as u64 * 3),
                }
            } else {
                Traffic::Periodic {
                    frame: Frame::data(id, &[i as u8; 8]).unwrap(),
                    period: BitTime::new(50 * 16),
                    start: BitTime::ZERO,
                    count: None,
                }
            };
            sim.add_traffic(n, traffic);
        }
        sim.run_for(BitTime::new(300_000));
        sim
    };
    let fast = bus(true);
    let slow = bus(false);
    assert!(
        fast.whole_frames() * 10 >= fast.bus_stats().frames * 9,
        "{} of {} frames applied whole",
        fast.whole_frames(),
        fast.bus_stats().frames
    );
    assert!(fast.records().is_empty());
    assert_eq!(observed(&fast).1, observed(&slow).1);
}

/// What a user may do between two runs of a bus whose bystanders are advanced as a group:
/// every one of them looks at the nodes or changes the bus, so the members must be filled in
/// exactly as stepping every bit leaves them.
#[derive(Clone, Debug)]
enum Action {
    Run(u64),
    /// Queue a frame on a node by hand.
    Enqueue(usize, Frame),
    /// Record these kinds of events in the trace from now on.
    Trace(RecordedEvents),
    /// A fault from now on for that long.
    Fault(u8, usize, u64),
    AddNode(bool),
    RemoveNode(usize),
    /// Force a node's counters (a REC above 0 takes it out of the group).
    Counters(usize, u16, u16),
}

fn action() -> impl Strategy<Value = Action> {
    prop_oneof![
        6 => (1u64..4_000).prop_map(Action::Run),
        2 => (0usize..64, any_frame()).prop_map(|(n, f)| Action::Enqueue(n, f)),
        1 => prop_oneof![
            Just(RecordedEvents::all()),
            Just(RecordedEvents::empty()),
            // What `buslab sim` records: the group stays on.
            Just(RecordedEvents::all() - RecordedEvents::RECEIVED - RecordedEvents::ARBITRATION_LOST),
            any::<u16>().prop_map(RecordedEvents::from_bits_truncate),
        ]
        .prop_map(Action::Trace),
        1 => (0u8..6, 0usize..64, 1u64..300).prop_map(|(k, n, len)| Action::Fault(k, n, len)),
        1 => any::<bool>().prop_map(Action::AddNode),
        1 => (0usize..64).prop_map(Action::RemoveNode),
        1 => (0usize..64, 0u16..140, 0u16..4).prop_map(|(n, t, r)| Action::Counters(n, t, r)),
    ]
}

/// `bus` (untraced at first), then `actions`, with what can be seen compared after each
/// action between the fast path and the bit-level path.
fn act(bus: &Bus, actions: &[Action], whole: bool) -> Vec<(String, String)> {
    let mut sim = build(bus, whole);
    sim.set_record_events(RecordedEvents::empty());
    let mut seen = Vec::new();
    for a in actions {
        let n = sim.nodes().len();
        match a {
            Action::Run(bits) => sim.run_for(BitTime::new(*bits)),
            Action::Enqueue(node, f) => {
                let _ = sim.enqueue(node % n, *f);
            }
            Action::Trace(kinds) => sim.set_record_events(*kinds),
            Action::Fault(kind, node, len) => {
                let node = node % n;
                let kind = match kind {
                    0 => FaultKind::Disconnect { node },
                    1 => FaultKind::Flip { node: Some(node) },
                    2 => FaultKind::StuckDominant,
                    _ => FaultKind::Noise {
                        nodes: vec![node],
                        rate: 0.05,
                    },
                };
                sim.add_fault(Fault {
                    kind,
                    start: sim.now(),
                    end: sim.now() + BitTime::new(*len),
                });
            }
            Action::AddNode(sends) => {
                let i = sim.add_node(format!("new{n}"), ControllerConfig::default());
                if *sends {
                    sim.add_traffic(
                        i,
                        Traffic::Periodic {
                            frame: Frame::data(Id::standard(0x0F0 + n as u16).unwrap(), &[1; 8])
                                .unwrap(),
                            period: BitTime::new(400),
                            start: sim.now(),
                            count: None,
                        },
                    );
                }
            }
            Action::RemoveNode(node) => {
                if n > 2 {
                    sim.remove_node(node % n);
                }
            }
            Action::Counters(node, tec, rec) => {
                sim.controller_mut(node % n)
                    .unwrap()
                    .set_counters(*tec, *rec);
            }
        }
        seen.push(observed(&sim));
    }
    seen
}

/// A saturated bus: every node always has a frame waiting, most lose every arbitration.
fn saturated_bus() -> impl Strategy<Value = Bus> {
    (3usize..24).prop_flat_map(|n| {
        (
            prop::collection::vec(
                prop_oneof![
                    8 => Just(NodeSpec {
                        listen_only: false,
                        single_shot: false,
                        self_reception: false,
                        auto_recover: true,
                        capacity: 4,
                        counters: (0, 0),
                    }),
                    2 => node_spec(),
                ],
                n,
            ),
            prop::option::weighted(0.3, 50u64..700),
        )
            .prop_map(move |(nodes, sample_every)| Bus {
                traffic: (0..nodes.len())
                    .map(|i| {
                        (
                            i,
                            TrafficSpec::Periodic {
                                frame: Frame::data(
                                    Id::standard(0x100 + i as u16).unwrap(),
                                    &[i as u8; 8],
                                )
                                .unwrap(),
                                period: 50 * nodes.len() as u64,
                                start: i as u64 % 7,
                            },
                        )
                    })
                    .collect(),
                nodes,
                faults: Vec::new(),
                sample_every,
                steps: Vec::new(),
            })
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// Reads, hand-queued frames, the trace switched on and off, faults starting, counters
    /// forced and nodes added and removed between runs: after every one the fast path (with
    /// its group of bystanders) shows what the bit-level path shows.
    #[test]
    fn the_group_is_filled_in_whatever_looks_between_runs(
        bus in prop_oneof![saturated_bus(), crowded_bus(), bus()],
        actions in prop::collection::vec(action(), 1..24),
    ) {
        let fast = act(&bus, &actions, true);
        let slow = act(&bus, &actions, false);
        for (k, (f, s)) in fast.iter().zip(&slow).enumerate() {
            prop_assert_eq!(&f.0, &s.0, "trace differs after action {}: {:?}", k, &actions[k]);
            prop_assert_eq!(&f.1, &s.1, "state differs after action {}: {:?}", k, &actions[k]);
        }
    }
}

/// A saturated bus of 64 nodes without a trace, with counter samples inside frames: every
/// frame is applied whole, and everything (counters, series, every controller) is the same
/// as bit by bit, though most nodes were advanced as a group.
#[test]
fn a_saturated_bus_of_64_nodes_advanced_as_a_group_ends_the_same() {
    let bus = |whole: bool| {
        let mut sim = Simulation::new(1_000_000, 1);
        sim.set_whole_frames(whole);
        sim.set_record_events(RecordedEvents::empty());
        for i in 0..64u16 {
            let n = sim.add_node(format!("n{i}"), ControllerConfig::default());
            sim.add_traffic(
                n,
                Traffic::Periodic {
                    frame: Frame::data(Id::standard(0x100 + i).unwrap(), &[i as u8; 8]).unwrap(),
                    period: BitTime::new(50 * 64),
                    start: BitTime::new(u64::from(i % 5)),
                    count: None,
                },
            );
        }
        sim.sample_counters_every(BitTime::new(977));
        for _ in 0..10 {
            sim.run_for(BitTime::new(20_000));
        }
        sim
    };
    let fast = bus(true);
    let slow = bus(false);
    assert!(
        fast.whole_frames() * 10 >= fast.bus_stats().frames * 9,
        "{} of {} frames applied whole",
        fast.whole_frames(),
        fast.bus_stats().frames
    );
    // Most nodes took most frames as members of the group.
    assert!(
        fast.frames_in_group() * 10 >= fast.whole_frames() * 64 * 9,
        "{} node-frames in the group of {} frames on 64 nodes",
        fast.frames_in_group(),
        fast.whole_frames()
    );
    assert_eq!(observed(&fast), observed(&slow));
}

/// Regression: counters forced between two runs queue a warning (and a state change) in the
/// controller; a frame applied whole next reported them with the frame's events instead of at
/// its SOF, where the bit-level path polls them after the node samples the bit.
#[test]
fn counters_forced_between_runs_report_at_the_next_frame_start() {
    let bus = |whole: bool| {
        let mut sim = bus_with(&[("a", &["100#"]), ("b", &["092B4D6F#93A542F202161800"])]);
        sim.set_whole_frames(whole);
        sim.run_for(BitTime::new(200));
        sim.controller_mut(0).unwrap().set_counters(117, 0);
        sim.controller_mut(1).unwrap().set_counters(28, 100);
        sim.enqueue(0, frame("100#")).unwrap();
        sim.enqueue(1, frame("092B4D6F#93A542F202161800")).unwrap();
        sim.run_for(BitTime::new(400));
        sim
    };
    let fast = bus(true);
    let slow = bus(false);
    assert!(fast.whole_frames() > 0);
    assert_eq!(observed(&fast), observed(&slow));
}

/// What can be seen after each piece of a run.
type Seen = Vec<(String, String)>;

/// `bus` run in pieces with [`Simulation::run_past`] (fast path; the trace recording
/// `recorded`), and the same bus run bit by bit to each time it returned: what can be seen
/// after each piece (each piece ends between its end and its limit).
fn run_in_pieces(bus: &Bus, pieces: &[(u64, u64)], recorded: RecordedEvents) -> (Seen, Seen) {
    let mut fast = build(bus, true);
    let mut slow = build(bus, false);
    fast.set_record_events(recorded);
    slow.set_record_events(recorded);
    let (mut fast_seen, mut slow_seen) = (Vec::new(), Vec::new());
    for &(len, slack) in pieces {
        let end = fast.now() + BitTime::new(len);
        let limit = end + BitTime::new(slack);
        let reached = fast.run_past(end, limit);
        assert!(
            end <= reached && reached <= limit,
            "{reached} not in {end}..={limit}"
        );
        slow.run_until(reached);
        fast_seen.push(observed(&fast));
        slow_seen.push(observed(&slow));
    }
    (fast_seen, slow_seen)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// A run in pieces that may end a little late, at the end of a frame applied whole,
    /// leaves everything as the bit-level path run to the same times.
    #[test]
    fn run_past_stands_as_the_bit_level_path_at_the_time_it_returns(
        bus in prop_oneof![saturated_bus(), crowded_bus(), bus()],
        pieces in prop::collection::vec((1u64..3_000, prop_oneof![Just(0u64), 0u64..400]), 1..12),
        recorded in any::<u16>().prop_map(RecordedEvents::from_bits_truncate),
    ) {
        let (fast, slow) = run_in_pieces(&bus, &pieces, recorded);
        for (k, (f, s)) in fast.iter().zip(&slow).enumerate() {
            prop_assert_eq!(&f.0, &s.0, "trace differs after piece {}", k);
            prop_assert_eq!(&f.1, &s.1, "state differs after piece {}", k);
        }
    }
}

/// On a saturated bus a piece that ends inside a frame goes on to the frame's end (applied
/// whole), never past the limit; with no room for the frame it ends on time.
#[test]
fn run_past_finishes_the_frame_it_would_cut_within_the_limit() {
    let mut sim = bus_with(&[("a", &["100#0102030405060708"]), ("b", &[])]);
    sim.set_record_events(RecordedEvents::empty());
    sim.run_until(BitTime::new(1_000));
    assert_eq!(sim.nodes()[0].stats().sent, 1);
    let frames = sim.whole_frames();
    // The frame queued now starts at once; 20 bits on is inside it: on to its end.
    sim.enqueue(0, frame("100#0102030405060708")).unwrap();
    let start = sim.now();
    let reached = sim.run_past(start + BitTime::new(20), start + BitTime::new(1_000));
    assert!(reached > start + BitTime::new(100), "stopped at {reached}");
    assert_eq!(sim.whole_frames(), frames + 1);
    assert_eq!(sim.nodes()[0].stats().sent, 2);
    // No room before the limit: bit by bit up to the end asked for.
    sim.enqueue(0, frame("100#0102030405060708")).unwrap();
    let end = sim.now() + BitTime::new(30);
    assert_eq!(sim.run_past(end, end + BitTime::new(10)), end);
    assert_eq!(sim.whole_frames(), frames + 1);
}
