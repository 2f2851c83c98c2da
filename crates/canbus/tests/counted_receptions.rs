//! A receiving client's chip only counts the frames it takes whole (its controller is brought
//! up to date when someone looks at the chip), and nothing a user sees changes: deliveries
//! with their bit-times, counters, notices and every register read the same as when each bit
//! is stepped, including a chip looked at in the middle of a counted frame and a filter that
//! lets only some frames through.

use buslab_can::controller::ControllerConfig;
use buslab_can::{BitTime, Frame, Id};
use buslab_canbus::node::{Sja1000Node, node_config};
use buslab_canbus::{AcceptanceFilter, ControllerMode, ControllerSettings};
use buslab_sim::{Simulation, Traffic};

const BITRATE: u32 = 500_000;

/// A controller sending 5 bursts of 9 frames of every shape, back to back, then nothing;
/// client 1 takes all, client 2 only IDs 0x100..0x107; `extra` adds traffic (e.g. a client's
/// own frame at a chosen bit-time).
fn bus(whole: bool, extra: &[(usize, Traffic)]) -> Simulation {
    let mut sim = Simulation::new(BITRATE, 7);
    sim.set_whole_frames(whole);
    let sender = sim.add_node("sender", ControllerConfig::default());
    sim.add_device(
        "all",
        Box::new(Sja1000Node::new(BITRATE, true).expect("a valid bit rate")),
    );
    let mut config = node_config(BITRATE);
    config.filter = AcceptanceFilter::Single {
        code: [0x20, 0x00, 0, 0],
        mask: [0x00, 0xFF, 0xFF, 0xFF],
    };
    sim.add_device(
        "filtered",
        Box::new(Sja1000Node::with_config(config, BITRATE, false).expect("a valid config")),
    );
    let frames = [
        Frame::data(Id::standard(0x100).unwrap(), &[1, 2, 3]).unwrap(),
        Frame::data(Id::extended(0x1ABC_DEF0).unwrap(), &[0xFF; 8]).unwrap(),
        Frame::remote(Id::standard(0x7FF).unwrap(), 4).unwrap(),
        Frame::data(Id::standard(0x105).unwrap(), &[]).unwrap(),
        Frame::data(Id::standard(0x300).unwrap(), &[0, 0, 0, 0, 0, 0, 0, 0]).unwrap(),
    ];
    for (k, frame) in frames.into_iter().enumerate() {
        sim.add_traffic(
            sender,
            Traffic::Burst {
                frame,
                count: 9,
                period: BitTime::ZERO,
                start: BitTime::new(k as u64 * 800),
            },
        );
    }
    for (node, traffic) in extra {
        sim.add_traffic(*node, traffic.clone());
    }
    sim
}

/// What a user of a client node sees, as text (its driver and chip brought up to date).
fn seen(sim: &mut Simulation) -> String {
    let mut seen = format!("now {} {:?}", sim.now(), sim.bus_stats());
    for node in sim.nodes_mut().iter_mut().skip(1) {
        seen += &format!("\n{node:?}");
        let n = node.get_mut::<Sja1000Node>().expect("a client node");
        seen += &format!("\n{:?}", n.take_deliveries().collect::<Vec<_>>());
        seen += &format!("\n{:?}", n.take_error_frames().collect::<Vec<_>>());
        seen += &format!("\n{:?} {:?}", n.take_notices(), n.counters);
        seen += &format!("\n{:?}", n.driver());
        let chip = n.driver().chip();
        let registers: Vec<u8> = (0..128).map(|a| chip.peek(a)).collect();
        seen += &format!("\nregisters {registers:02X?}");
    }
    seen
}

fn counted(sim: &Simulation) -> u64 {
    (1..3)
        .map(|i| {
            sim.node(i)
                .get::<Sja1000Node>()
                .expect("a client")
                .frames_counted()
        })
        .sum()
}

#[test]
fn counted_receptions_leave_every_client_as_stepped_bits() {
    let mut fast = bus(true, &[]);
    let mut slow = bus(false, &[]);
    fast.run_for(BitTime::new(20_000));
    slow.run_for(BitTime::new(20_000));
    assert_eq!(counted(&slow), 0);
    assert_eq!(fast.bus_stats().frames, 45);
    // The first frame starts before the chips have seen 11 recessive bits: stepped.
    assert_eq!(fast.whole_frames(), 44);
    assert_eq!(
        counted(&fast),
        2 * fast.whole_frames(),
        "every frame received whole only counted"
    );
    let fast_seen = seen(&mut fast);
    assert_eq!(fast_seen, seen(&mut slow));
    for frame in ["100#010203", "1ABCDEF0#FFFF", "7FF#R4", "105#", "300#0000"] {
        assert!(fast_seen.contains(frame), "{frame} delivered: {fast_seen}");
    }
}

/// A client handed a frame in the middle of one it counts (before and after it takes it at
/// EOF bit 6): its chip is brought up to that bit, and the rest goes as stepped.
#[test]
fn a_client_handed_a_frame_inside_a_counted_one_goes_on_as_stepped() {
    // The first frame (0x100, 3 bytes) starts at bit-time 0; its EOF bit 6 is near 60.
    for at in [3u64, 20, 58, 59, 60, 61, 62, 64, 66, 69] {
        let own = Traffic::Once {
            // The highest priority: sent right after the frame under way.
            frame: Frame::data(Id::standard(0x001).unwrap(), &[at as u8]).unwrap(),
            at: BitTime::new(at),
        };
        let extra = [(1, own.clone()), (2, own)];
        let mut fast = bus(true, &extra);
        let mut slow = bus(false, &extra);
        fast.run_for(BitTime::new(20_000));
        slow.run_for(BitTime::new(20_000));
        assert!(
            counted(&fast) > 2 * (fast.whole_frames() - 5),
            "at {at}: counting again once sent"
        );
        assert_eq!(
            seen(&mut fast),
            seen(&mut slow),
            "handed over at bit-time {at}"
        );
    }
}

/// A client reprogrammed between runs cut in the middle of frames (its filter, listen-only,
/// back to accept-all), with counter samples inside some frames, read after every run: each
/// frame it only counts is taken in one call at EOF bit 6 when nothing looks at it before
/// the frame's end, and in ranges otherwise, and it reads the same as stepped bits.
#[test]
fn a_client_reprogrammed_between_runs_reads_as_stepped_bits() {
    let only_0x300 = ControllerSettings {
        filter: Some(AcceptanceFilter::Single {
            code: [0x60, 0x00, 0, 0],
            mask: [0x00, 0x1F, 0xFF, 0xFF],
        }),
        ..ControllerSettings::default()
    };
    let listen_only = ControllerSettings {
        mode: Some(ControllerMode::ListenOnly),
        ..ControllerSettings::default()
    };
    let accept_all = ControllerSettings {
        mode: Some(ControllerMode::PeliCan),
        filter: Some(AcceptanceFilter::Single {
            code: [0; 4],
            mask: [0xFF; 4],
        }),
        ..ControllerSettings::default()
    };
    let steps = [only_0x300, listen_only, accept_all];
    let mut fast = bus(true, &[]);
    let mut slow = bus(false, &[]);
    // Samples inside some frames: those go in ranges.
    fast.sample_counters_every(BitTime::new(1_501));
    slow.sample_counters_every(BitTime::new(1_501));
    for piece in 0..12u64 {
        // Pieces of odd lengths end inside frames.
        let length = BitTime::new(337 + 91 * piece);
        fast.run_for(length);
        slow.run_for(length);
        assert_eq!(seen(&mut fast), seen(&mut slow), "after piece {piece}");
        let settings = &steps[piece as usize % steps.len()];
        for sim in [&mut fast, &mut slow] {
            let client = sim.node_mut(1).get_mut::<Sja1000Node>().expect("a client");
            client.configure(settings).expect("a valid configuration");
        }
    }
    assert!(fast.whole_frames() > 30, "frames applied whole");
    assert!(counted(&fast) > fast.whole_frames(), "frames only counted");
    assert!(!fast.series().is_empty(), "counters sampled");
    assert_eq!(
        format!("{:?}", fast.series()),
        format!("{:?}", slow.series())
    );
    assert_eq!(
        format!("{:?}", fast.records()),
        format!("{:?}", slow.records())
    );
}
