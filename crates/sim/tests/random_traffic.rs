//! Random traffic on a clean bus: every frame reaches every other node exactly once, nobody
//! sees an error, and fast-forwarding over idle time changes nothing.

mod common;

use buslab_can::BitTime;
use buslab_can::controller::ControllerConfig;
use buslab_can::{Frame, Id};
use buslab_sim::{Simulation, Traffic};
use common::*;
use proptest::prelude::*;

/// `(node, extended, data, at)` for each frame; IDs are made unique from the frame's index, as
/// two nodes sending the same ID at once is a protocol violation, not a test of the bus.
fn build(frames: &[(usize, bool, Vec<u8>, u64)], nodes: usize, fast_forward: bool) -> Simulation {
    let mut sim = Simulation::new(500_000, 7);
    sim.set_fast_forward(fast_forward);
    for n in 0..nodes {
        sim.add_node(format!("n{n}"), ControllerConfig::default());
    }
    for (i, (node, extended, data, at)) in frames.iter().enumerate() {
        let id = if *extended {
            Id::extended(0x0100_0000 + i as u32 * 0x1357).unwrap()
        } else {
            Id::standard(0x010 + i as u16 * 0x23).unwrap()
        };
        sim.add_traffic(
            node % nodes,
            Traffic::Once {
                frame: Frame::data(id, data).unwrap(),
                at: BitTime::new(*at),
            },
        );
    }
    sim
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    #[test]
    fn every_frame_reaches_every_other_node_once(
        nodes in 2usize..7,
        frames in prop::collection::vec(
            (0usize..7, any::<bool>(), prop::collection::vec(any::<u8>(), 0..=8), 0u64..3_000),
            1..24,
        ),
    ) {
        let mut sim = build(&frames, nodes, true);
        sim.run_for(BitTime::new(20_000));
        for rx in 0..nodes {
            let mut got: Vec<Frame> = received(sim.records(), rx);
            got.sort();
            let mut expected: Vec<Frame> = (0..nodes)
                .filter(|&tx| tx != rx)
                .flat_map(|tx| transmitted(sim.records(), tx))
                .map(|(_, f)| f)
                .collect();
            expected.sort();
            prop_assert_eq!(got, expected);
        }
        prop_assert_eq!(sim.bus_stats().frames, frames.len() as u64);
        prop_assert_eq!(sim.bus_stats().errors, 0);

        let mut slow = build(&frames, nodes, false);
        slow.run_for(BitTime::new(20_000));
        prop_assert_eq!(sim.records(), slow.records());
    }
}
