//! Helpers shared by the simulator's integration tests.
#![allow(dead_code)]

use buslab_can::Frame;
use buslab_can::controller::{ControllerConfig, ErrorState, Event};
use buslab_sim::{BitTime, Happening, Record, Simulation, Traffic};

pub fn frame(text: &str) -> Frame {
    text.parse().unwrap()
}

/// A bus with one node per `(name, frames queued at t = 0)`.
pub fn bus_with(nodes: &[(&str, &[&str])]) -> Simulation {
    let mut sim = Simulation::new(1_000_000, 1);
    for (name, frames) in nodes {
        let n = sim.add_node(*name, ControllerConfig::default());
        for f in *frames {
            sim.add_traffic(
                n,
                Traffic::Once {
                    frame: frame(f),
                    at: BitTime::ZERO,
                },
            );
        }
    }
    sim
}

/// `(time, event)` of node `node`, in order.
pub fn events(records: &[Record], node: usize) -> Vec<(BitTime, Event)> {
    records
        .iter()
        .filter_map(|r| match &r.what {
            Happening::Node { node: n, event } if *n == node => Some((r.time, event.clone())),
            _ => None,
        })
        .collect()
}

pub fn received(records: &[Record], node: usize) -> Vec<Frame> {
    events(records, node)
        .into_iter()
        .filter_map(|(_, e)| match e {
            Event::Received(f) => Some(f),
            _ => None,
        })
        .collect()
}

pub fn transmitted(records: &[Record], node: usize) -> Vec<(BitTime, Frame)> {
    events(records, node)
        .into_iter()
        .filter_map(|(t, e)| match e {
            Event::Transmitted(f) => Some((t, f)),
            _ => None,
        })
        .collect()
}

/// Times at which node `node` entered state `to`.
pub fn entered(records: &[Record], node: usize, to: ErrorState) -> Vec<BitTime> {
    events(records, node)
        .into_iter()
        .filter_map(|(t, e)| match e {
            Event::StateChanged { to: s, .. } if s == to => Some(t),
            _ => None,
        })
        .collect()
}
