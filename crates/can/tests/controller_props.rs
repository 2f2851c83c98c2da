//! Randomised bus runs: whatever the frames and one disturbed bit (after integration: a node
//! that is still integrating misses frames by design), every frame gets through.

use buslab_can::controller::{Controller, ControllerConfig, Event};
use buslab_can::{Frame, Id, Level};
use proptest::prelude::*;

/// Frames for `nodes` nodes; arbitration fields are unique across nodes (two nodes sending the
/// same ID with different data collide by design).
fn traffic() -> impl Strategy<Value = Vec<Vec<Frame>>> {
    (2usize..6).prop_flat_map(|nodes| {
        prop::collection::vec(
            prop::collection::vec(
                (
                    any::<bool>(),
                    0u32..0x1FFF_FFFF,
                    prop::collection::vec(any::<u8>(), 0..=8),
                    any::<bool>(),
                ),
                1..4,
            ),
            nodes,
        )
        .prop_map(|per_node| {
            per_node
                .into_iter()
                .enumerate()
                .map(|(node, frames)| {
                    frames
                        .into_iter()
                        .enumerate()
                        .map(|(k, (ext, raw, data, remote))| {
                            // Low bits carry (node, k) so IDs never clash between nodes.
                            let tag = (node * 4 + k) as u32;
                            let id = if ext {
                                Id::extended(raw & !0x1F | tag).unwrap()
                            } else {
                                Id::standard((raw as u16 & 0x7E0) | tag as u16).unwrap()
                            };
                            if remote {
                                Frame::remote(id, data.len() as u8).unwrap()
                            } else {
                                Frame::data(id, &data).unwrap()
                            }
                        })
                        .collect()
                })
                .collect()
        })
    })
}

struct Run {
    received: Vec<Vec<Frame>>,
    transmitted: Vec<Vec<Frame>>,
}

fn run(traffic: &[Vec<Frame>], flip: Option<(usize, u64)>) -> Run {
    let n = traffic.len();
    let mut nodes: Vec<Controller> = (0..n)
        .map(|_| Controller::new(ControllerConfig::default()))
        .collect();
    for (node, frames) in nodes.iter_mut().zip(traffic) {
        for f in frames {
            node.enqueue(*f).unwrap();
        }
    }
    let mut out = Run {
        received: vec![Vec::new(); n],
        transmitted: vec![Vec::new(); n],
    };
    for t in 0..20_000u64 {
        let bus = nodes
            .iter()
            .fold(Level::Recessive, |b, c| b.and(c.output()));
        for (i, node) in nodes.iter_mut().enumerate() {
            let seen = match flip {
                Some((who, at)) if who == i && at == t => Level::from_bit(!bus.bit()),
                _ => bus,
            };
            node.sample(seen);
            while let Some(e) = node.poll_event() {
                match e {
                    Event::Received(f) => out.received[i].push(f),
                    Event::Transmitted(f) => out.transmitted[i].push(f),
                    _ => {}
                }
            }
        }
        if t > 11 && nodes.iter().all(|c| c.is_bus_idle() && c.pending() == 0) {
            break;
        }
    }
    out
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn every_frame_is_delivered_once_to_every_other_node(traffic in traffic()) {
        let run = run(&traffic, None);
        for (i, frames) in traffic.iter().enumerate() {
            let mut sent = run.transmitted[i].clone();
            sent.sort();
            let mut want = frames.clone();
            want.sort();
            prop_assert_eq!(sent, want, "node {} sent", i);
            let mut got = run.received[i].clone();
            got.sort();
            let mut others: Vec<Frame> = traffic
                .iter()
                .enumerate()
                .filter(|(j, _)| *j != i)
                .flat_map(|(_, f)| f.iter().copied())
                .collect();
            others.sort();
            prop_assert_eq!(got, others, "node {} received", i);
        }
    }

    #[test]
    fn one_flipped_bit_anywhere_loses_nothing(traffic in traffic(), who in 0usize..6, at in 11u64..600) {
        let who = who % traffic.len();
        let run = run(&traffic, Some((who, at)));
        for (i, frames) in traffic.iter().enumerate() {
            let mut sent = run.transmitted[i].clone();
            sent.sort();
            let mut want = frames.clone();
            want.sort();
            prop_assert_eq!(sent, want, "node {} sent", i);
            // At least once; twice only in the known last-EOF-bit case.
            for (j, other) in traffic.iter().enumerate().filter(|(j, _)| *j != i) {
                for f in other {
                    let copies = run.received[i].iter().filter(|g| *g == f).count();
                    prop_assert!((1..=2).contains(&copies), "node {} got {} {} times (from {})", i, f, copies, j);
                }
            }
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// Any bus input, any options: no panic, counters in range, listen-only stays recessive.
    #[test]
    fn garbage_on_the_bus_never_breaks_a_controller(
        levels in prop::collection::vec(prop_oneof![3 => Just(true), 1 => Just(false)], 0..3000),
        options in any::<[bool; 5]>(),
        frames in prop::collection::vec((0u16..0x800, prop::collection::vec(any::<u8>(), 0..=8)), 0..3),
    ) {
        let [listen_only, self_test, single_shot, self_reception, auto_recover] = options;
        let config = ControllerConfig {
            listen_only,
            self_test,
            single_shot,
            self_reception,
            auto_recover,
            tx_queue_capacity: 2,
        };
        let mut node = Controller::new(config);
        for (id, data) in &frames {
            let _ = node.enqueue(Frame::data(Id::standard(*id).unwrap(), data).unwrap());
        }
        for (t, &bit) in levels.iter().enumerate() {
            let out = node.output();
            if listen_only {
                prop_assert_eq!(out, Level::Recessive);
            }
            // The bus is never recessive while we drive dominant, unless a fault says so.
            let bus = if t % 7 == 0 { Level::from_bit(bit) } else { out.and(Level::from_bit(bit)) };
            node.sample(bus);
            while node.poll_event().is_some() {}
            prop_assert!(node.rec() <= 255);
            prop_assert!(node.tec() <= 255 + 8);
            prop_assert!(node.pending() <= 2);
        }
    }
}
