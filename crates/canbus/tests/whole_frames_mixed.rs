//! The simulator's frame-level fast path changes nothing but the speed on buses that mix every
//! node kind: bare protocol controllers, SJA1000s serviced by this library's driver
//! ([`Sja1000Node`]) and SLIO demo boards. Over random buses (random and equal IDs, SLIO
//! calibration and commands, faults starting and ending mid-frame, error-passive and bus-off
//! nodes and their recovery, interrupt sources switched off, filters, listen-only chips, runs
//! cut mid-frame) the trace, the counters, every chip's registers, FIFO and driver, every
//! client's deliveries, error frames and notices, every SLIO's registers and notices are the
//! same with whole frames on and off. A busy mixed bus takes most of its frames whole.

use buslab_can::BitTime;
use buslab_can::controller::{Controller, ControllerConfig};
use buslab_can::node::BusNode;
use buslab_can::{Frame, Id};
use buslab_canbus::node::{Sja1000Node, node_config};
use buslab_canbus::{AcceptanceFilter, BusOffRecovery, CanMode, InterruptEnables};
use buslab_sim::{Fault, FaultKind, Simulation, Traffic};
use buslab_slio::{DemoBoard, Direction, SlioId, calibration_frame};
use proptest::prelude::*;

/// The SLIO's highest bit rate: every node kind can follow it.
const BITRATE: u32 = 125_000;

#[derive(Clone, Debug)]
enum NodeSpec {
    Controller {
        listen_only: bool,
        single_shot: bool,
        capacity: usize,
        counters: (u16, u16),
    },
    Sja1000 {
        basic: bool,
        listen_only: bool,
        fast_restart: bool,
        ier: u8,
        ewlr: u8,
        filter: Option<u16>,
        receive_own: bool,
        error_frames: bool,
        /// TXERR and RXERR written in reset mode before the run (TXERR 255: bus-off).
        counters: (u8, u8),
    },
    Slio {
        id: u8,
        potentiometer: f64,
    },
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

fn counters() -> impl Strategy<Value = (u16, u16)> {
    prop_oneof![
        6 => Just((0u16, 0u16)),
        2 => (0u16..140, 0u16..140),
        1 => (120u16..200, 0u16..256),
        1 => Just((256u16, 0u16)),
    ]
}

fn node_spec() -> impl Strategy<Value = NodeSpec> {
    prop_oneof![
        3 => (prop::bool::weighted(0.1), prop::bool::weighted(0.15), 1usize..6, counters())
            .prop_map(|(listen_only, single_shot, capacity, counters)| NodeSpec::Controller {
                listen_only,
                single_shot,
                capacity,
                counters,
            }),
        4 => (
            (
                prop::bool::weighted(0.15),
                prop::bool::weighted(0.1),
                any::<bool>(),
                prop_oneof![4 => Just(0xFFu8), 1 => any::<u8>()],
                prop_oneof![4 => Just(96u8), 1 => 1u8..=255],
            ),
            (
                prop::option::weighted(0.2, 0u16..12),
                prop::bool::weighted(0.2),
                any::<bool>(),
                prop_oneof![
                    6 => Just((0u8, 0u8)),
                    2 => (0u8..140, 0u8..140),
                    1 => (120u8..200, 0u8..=255),
                    1 => Just((255u8, 0u8)),
                ],
            ),
        )
            .prop_map(
                |(
                    (basic, listen_only, fast_restart, ier, ewlr),
                    (filter, receive_own, error_frames, counters),
                )| NodeSpec::Sja1000 {
                    basic,
                    listen_only,
                    fast_restart,
                    ier,
                    ewlr,
                    filter,
                    receive_own,
                    error_frames,
                    counters,
                }
            ),
        3 => (0u8..16, 0.0f64..5.0).prop_map(|(id, potentiometer)| NodeSpec::Slio {
            id,
            potentiometer
        }),
    ]
}

fn standard(n: u32) -> Id {
    Id::standard(0x100 + n as u16 * 0x31).unwrap()
}

/// A small ID space, so equal IDs on two nodes happen often; SLIO calibration frames and
/// requests to SLIOs (valid or not) among them.
fn any_frame() -> impl Strategy<Value = Frame> {
    prop_oneof![
        5 => (
            any::<bool>(),
            0u32..12,
            prop::bool::weighted(0.1),
            prop::collection::vec(any::<u8>(), 0..=8),
        )
            .prop_map(|(extended, n, remote, data)| {
                let id = if extended {
                    Id::extended(0x0123_4567 ^ (n * 0x0101_0101)).unwrap()
                } else {
                    standard(n)
                };
                if remote {
                    Frame::remote(id, data.len() as u8).unwrap()
                } else {
                    Frame::data(id, &data).unwrap()
                }
            }),
        2 => Just(calibration_frame()),
        3 => (
            0u8..16,
            any::<bool>(),
            prop::bool::weighted(0.3),
            0u8..12,
            any::<u8>(),
            any::<u8>(),
        )
            .prop_map(|(slio, to_slio, remote, register, a, b)| {
                let dir = if to_slio {
                    Direction::ToSlio
                } else {
                    Direction::FromSlio
                };
                let id = Id::standard(SlioId::new(slio).unwrap().raw_id(dir)).unwrap();
                if remote {
                    Frame::remote(id, 3).unwrap()
                } else {
                    Frame::data(id, &[register, a, b]).unwrap()
                }
            }),
    ]
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
            prop::collection::vec((0u8..6, 0..n, 0u64..12_000, 1u64..600), 0..4),
            prop::option::weighted(0.3, 50u64..700),
            prop::collection::vec(1u64..4_000, 1..6),
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

fn sja1000(spec: &NodeSpec) -> Box<dyn BusNode> {
    let NodeSpec::Sja1000 {
        basic,
        listen_only,
        fast_restart,
        ier,
        ewlr,
        filter,
        receive_own,
        error_frames,
        counters: (txerr, rxerr),
    } = *spec
    else {
        unreachable!()
    };
    let mut config = node_config(BITRATE);
    config.interrupts = InterruptEnables::from_ier(ier);
    if basic {
        config.mode = CanMode::Basic;
        // BasicCAN has only RI, TI, EI, DOI and WUI.
        config.interrupts = InterruptEnables::from_ier(ier & 0x1F);
        if let Some(n) = filter {
            let id = 0x100 + n * 0x31;
            config.filter = AcceptanceFilter::Basic {
                code: (id >> 3) as u8,
                mask: 0x03,
            };
        }
    } else {
        config.listen_only = listen_only;
        config.error_warning_limit = ewlr;
        if let Some(n) = filter {
            config.filter = AcceptanceFilter::standard_id(0x100 + n * 0x31);
        }
    }
    if fast_restart {
        config.bus_off_recovery = BusOffRecovery::Fast;
    }
    let mut node = Sja1000Node::with_config(config, BITRATE, error_frames).unwrap();
    node.receive_own = receive_own;
    if !basic && (txerr, rxerr) != (0, 0) {
        // The counters as a CPU writes them in reset mode (TXERR 255: bus-off on leaving it).
        let chip = node.driver().registers();
        let mode = chip.read(0);
        chip.write(0, mode | 1);
        chip.write(14, rxerr);
        chip.write(15, txerr);
        chip.write(0, mode & !1);
    }
    Box::new(node)
}

fn build(bus: &Bus, whole: bool) -> Simulation {
    let mut sim = Simulation::new(BITRATE, 11);
    sim.set_whole_frames(whole);
    for (i, spec) in bus.nodes.iter().enumerate() {
        match spec {
            NodeSpec::Controller {
                listen_only,
                single_shot,
                capacity,
                counters: (tec, rec),
            } => {
                let node = sim.add_node(
                    format!("c{i}"),
                    ControllerConfig {
                        listen_only: *listen_only,
                        single_shot: *single_shot,
                        tx_queue_capacity: *capacity,
                        ..Default::default()
                    },
                );
                sim.controller_mut(node).unwrap().set_counters(*tec, *rec);
            }
            NodeSpec::Sja1000 { .. } => {
                sim.add_device(format!("sja{i}"), sja1000(spec));
            }
            NodeSpec::Slio { id, potentiometer } => {
                let board = DemoBoard::new(
                    SlioId::new(*id).unwrap(),
                    BITRATE,
                    Box::new(1.25),
                    Box::new(*potentiometer),
                )
                .unwrap();
                sim.add_device(format!("slio{i}"), Box::new(board));
            }
        }
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

/// Everything a user of the simulation can see of one node, as text: what the engine shows,
/// and what the node's own kind shows (a chip's registers, FIFO and driver; a client's
/// deliveries, error frames and notices; a SLIO's registers, controller and notices).
fn node_seen(node: &mut buslab_sim::Node) -> String {
    let mut seen = format!("{node:?}");
    let device = node.device();
    seen += &format!(
        "\nout {:?} quiet {:?} pending {}",
        device.output(),
        device.quiet_until(),
        device.pending()
    );
    if let Some(c) = node.get::<Controller>() {
        seen += &format!("\n{c:?}");
    } else if let Some(n) = node.get_mut::<Sja1000Node>() {
        seen += &format!("\n{:?}", n.driver());
        seen += &format!("\n{:?}", n.take_deliveries().collect::<Vec<_>>());
        seen += &format!("\n{:?}", n.take_error_frames().collect::<Vec<_>>());
        seen += &format!("\n{:?}", n.take_notices());
        seen += &format!(
            "\n{:?} {} {} {} {:?} {:?}",
            n.counters,
            n.submitted(),
            n.done(),
            n.tx_queued(),
            n.state(),
            n.mismatch(),
        );
        let chip = n.driver().chip();
        let registers: Vec<u8> = (0..128).map(|a| chip.peek(a)).collect();
        seen += &format!("\nregisters {registers:02X?} int {}", chip.interrupt());
    } else if let Some(b) = buslab_bench::board::of(node) {
        let slio = b.slio();
        seen += &format!(
            "\n{b:?}\n{:?} {:04X} {:?} {:?}\n{:?}",
            slio.calibration(),
            slio.data_input(),
            b.leds(),
            b.dpm_volts(),
            slio.controller(),
        );
        seen += &format!("\n{:?}", b.take_notices());
    } else {
        unreachable!("only controllers, SJA1000 nodes and SLIO boards here");
    }
    seen
}

/// Everything a user of the simulation can see, as text: the trace, and the state.
fn observed(sim: &mut Simulation) -> (String, String) {
    let nodes: Vec<String> = sim.nodes_mut().iter_mut().map(node_seen).collect();
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
        // A frame queued by hand in the middle of the run, as a scenario's one-shot would
        // (a SLIO refuses it).
        let _ = sim.enqueue(0, "7FF#EE".parse().unwrap());
    }
    let seen = observed(&mut sim);
    (sim, seen)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn whole_frames_change_nothing_but_the_speed_on_mixed_buses(bus in bus()) {
        let (_, fast_seen) = run(&bus, true);
        let (slow, slow_seen) = run(&bus, false);
        prop_assert_eq!(slow.whole_frames(), 0);
        prop_assert_eq!(&fast_seen.0, &slow_seen.0, "trace differs");
        prop_assert_eq!(&fast_seen.1, &slow_seen.1, "state differs");
    }
}

/// A busy clean bus of controllers, SJA1000 clients and calibrated SLIO boards: a host
/// calibrates the SLIOs and asks for their inputs, the others send periodic frames. Most
/// frames are applied whole, and the outcome is the same as bit by bit.
#[test]
fn a_busy_mixed_bus_is_mostly_applied_whole() {
    let bus = |whole| {
        let mut sim = Simulation::new(BITRATE, 1);
        sim.set_whole_frames(whole);
        let host = sim.add_node("host", ControllerConfig::default());
        sim.add_traffic(
            host,
            Traffic::Periodic {
                frame: calibration_frame(),
                period: BitTime::new(2_000),
                start: BitTime::ZERO,
                count: None,
            },
        );
        for slio in 0..3u8 {
            let id = SlioId::new(slio).unwrap();
            let board = DemoBoard::new(id, BITRATE, Box::new(1.0), Box::new(2.5)).unwrap();
            sim.add_device(format!("slio{slio}"), Box::new(board));
            let read = Id::standard(id.raw_id(Direction::FromSlio)).unwrap();
            sim.add_traffic(
                host,
                Traffic::Periodic {
                    frame: Frame::remote(read, 0).unwrap(),
                    period: BitTime::new(1_500),
                    start: BitTime::new(300 + slio as u64 * 100),
                    count: None,
                },
            );
        }
        for i in 0..3u32 {
            let n = sim.add_node(format!("c{i}"), ControllerConfig::default());
            sim.add_traffic(n, periodic(i, 900, i as u64 * 7));
        }
        for i in 3..6u32 {
            let node = Sja1000Node::new(BITRATE, true).unwrap();
            let n = sim.add_device(format!("sja{i}"), Box::new(node));
            sim.add_traffic(n, periodic(i, 700, i as u64 * 11));
        }
        sim.run_for(BitTime::new(400_000));
        sim
    };
    let mut fast = bus(true);
    let mut slow = bus(false);
    let (whole, frames) = (fast.whole_frames(), fast.bus_stats().frames);
    println!("{whole} of {frames} frames applied whole");
    assert!(frames > 1_000, "{frames} frames");
    assert!(
        whole * 10 >= frames * 8,
        "only {whole} of {frames} frames applied whole"
    );
    for slio in 1..=3 {
        let board = fast.node(slio).get::<DemoBoard>().unwrap();
        assert_eq!(
            board.slio().calibration(),
            buslab_slio::Calibration::Calibrated
        );
    }
    assert_eq!(observed(&mut fast), observed(&mut slow));
}

fn periodic(n: u32, period: u64, start: u64) -> Traffic {
    Traffic::Periodic {
        frame: Frame::data(standard(n), &[n as u8; 8]).unwrap(),
        period: BitTime::new(period),
        start: BitTime::new(start),
        count: None,
    }
}

/// The shipped scenarios (SJA1000 clients, SLIO boards, controllers, faults) run to their end
/// the same with whole frames on and off, and those with SJA1000 or SLIO nodes take a good
/// share of their frames whole.
#[test]
fn shipped_scenarios_take_their_frames_whole_and_end_the_same() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenarios");
    let mut files: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    files.sort();
    assert!(files.len() >= 6, "{files:?}");
    for file in files {
        let text = std::fs::read_to_string(&file).unwrap();
        let scenario = buslab_bench::Scenario::from_toml(&text).unwrap();
        let run = |whole| {
            let mut sim = scenario.build().unwrap();
            sim.set_whole_frames(whole);
            sim.run_until(scenario.duration);
            sim
        };
        let mut fast = run(true);
        let mut slow = run(false);
        let (whole, frames) = (fast.whole_frames(), fast.bus_stats().frames);
        let name = file.file_name().unwrap().to_string_lossy().into_owned();
        println!("{name}: {whole} of {frames} frames applied whole");
        assert_eq!(observed(&mut fast), observed(&mut slow), "{name}");
        if text.contains("kind = \"sja1000\"") || text.contains("kind = \"slio\"") {
            assert!(
                whole * 10 >= frames * 8,
                "{name}: only {whole} of {frames} frames applied whole"
            );
        }
    }
}
