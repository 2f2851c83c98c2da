//! SJA1000 chips on the simulator's frame-level fast path: over random buses of chips that a
//! test "CPU" programs between runs of random length (transmission requests with and without
//! single-shot and self-reception, aborts, IR/ALC/ECC reads, receive buffer releases, reset
//! mode with new counters, PeliCAN and BasicCAN, listen-only and self-test, interrupt sources
//! switched off, a FIFO left to overflow) and faults starting and ending mid-frame, every
//! chip's registers, FIFO, status, interrupts, counters and controller are the same with
//! whole frames on and off, and so is the trace.

use buslab_can::BitTime;
use buslab_can::{Frame, Id};
use buslab_sim::{Fault, FaultKind, Simulation};
use buslab_sja1000::{CanMode, Sja1000};
use proptest::prelude::*;

const MOD: u8 = 0;
const CMR: u8 = 1;

#[derive(Clone, Debug)]
struct ChipSpec {
    basic: bool,
    /// PeliCAN MOD bits (LOM, STM, AFM) when leaving reset mode.
    mode: u8,
    ier: u8,
    ewlr: u8,
}

#[derive(Clone, Debug)]
enum Op {
    /// Load the TX buffer with `frame` and write `command` to CMR (TR, TR+AT, SRR, SRR+AT).
    Transmit {
        chip: usize,
        frame: Frame,
        command: u8,
    },
    /// A CPU read with side effects (IR, ALC, ECC) or without (SR, RMC).
    Read { chip: usize, addr: u8 },
    /// CMR: RRB, CDO, AT.
    Command { chip: usize, command: u8 },
    /// Reset mode, TXERR/RXERR written, back to operating mode (PeliCAN).
    Counters { chip: usize, txerr: u8, rxerr: u8 },
}

#[derive(Clone, Debug)]
struct Bus {
    chips: Vec<ChipSpec>,
    /// Run this many bit-times, then do these operations.
    pieces: Vec<(u64, Vec<Op>)>,
    faults: Vec<(u8, usize, u64, u64)>,
}

fn chip_spec() -> impl Strategy<Value = ChipSpec> {
    (
        prop::bool::weighted(0.2),
        prop_oneof![
            6 => Just(0x08u8),
            2 => Just(0x00u8),
            1 => Just(0x0Au8),
            1 => Just(0x0Cu8),
        ],
        prop_oneof![3 => Just(0xFFu8), 1 => any::<u8>()],
        prop_oneof![3 => Just(96u8), 1 => 1u8..=255],
    )
        .prop_map(|(basic, mode, ier, ewlr)| ChipSpec {
            basic,
            mode,
            ier,
            ewlr,
        })
}

/// A small ID space, so equal IDs on two chips happen often.
fn any_frame() -> impl Strategy<Value = Frame> {
    (
        prop::bool::weighted(0.3),
        0u32..8,
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

fn op(n: usize) -> impl Strategy<Value = Op> {
    prop_oneof![
        6 => (
            0..n,
            any_frame(),
            prop_oneof![6 => Just(0x01u8), 1 => Just(0x03u8), 1 => Just(0x10u8), 1 => Just(0x12u8)]
        )
            .prop_map(|(chip, frame, command)| Op::Transmit {
                chip,
                frame,
                command
            }),
        3 => (0..n, prop::sample::select(vec![2u8, 3, 11, 12, 29]))
            .prop_map(|(chip, addr)| Op::Read { chip, addr }),
        3 => (0..n, prop::sample::select(vec![0x04u8, 0x0C, 0x02]))
            .prop_map(|(chip, command)| Op::Command { chip, command }),
        1 => (
            0..n,
            prop_oneof![Just(0u8), 90u8..140, Just(255u8)],
            prop_oneof![Just(0u8), 90u8..140]
        )
            .prop_map(|(chip, txerr, rxerr)| Op::Counters { chip, txerr, rxerr }),
    ]
}

fn bus() -> impl Strategy<Value = Bus> {
    (2usize..6).prop_flat_map(|n| {
        (
            prop::collection::vec(chip_spec(), n),
            prop::collection::vec(
                (
                    prop_oneof![1u64..40, 40u64..600],
                    prop::collection::vec(op(n), 0..6),
                ),
                1..24,
            ),
            prop::collection::vec((0u8..5, 0..n, 0u64..6_000, 1u64..400), 0..3),
        )
            .prop_map(|(chips, pieces, faults)| Bus {
                chips,
                pieces,
                faults,
            })
    })
}

/// The seed's initialisation sequence, in PeliCAN or BasicCAN.
fn init(spec: &ChipSpec) -> Sja1000 {
    let mut chip = Sja1000::new();
    chip.write(MOD, 0x01);
    if spec.basic {
        chip.write(31, 0x00);
        chip.write(4, 0x00); // ACR
        chip.write(5, 0xFF); // AMR
        chip.write(6, 0x07);
        chip.write(7, 0x4D);
        // CR: RIE, TIE, EIE, OIE from the IER bits 0..3.
        chip.write(0, (spec.ier & 0x0F) << 1);
    } else {
        chip.write(31, 0x80);
        for amr in 20..24 {
            chip.write(amr, 0xFF);
        }
        chip.write(6, 0x07);
        chip.write(7, 0x4D);
        chip.write(4, spec.ier);
        chip.write(13, spec.ewlr);
        chip.write(MOD, spec.mode);
    }
    chip
}

fn load_tx(chip: &mut Sja1000, frame: &Frame) {
    let mut buf = [0u8; 13];
    let len = buslab_sja1000::layout::encode(chip.mode(), frame, &mut buf);
    let base = match chip.mode() {
        CanMode::Peli => 16,
        CanMode::Basic => 10,
    };
    for (k, &byte) in buf[..len].iter().enumerate() {
        chip.write(base + k as u8, byte);
    }
}

fn apply(chip: &mut Sja1000, op: &Op) {
    match op {
        Op::Transmit { frame, command, .. } => {
            load_tx(chip, frame);
            chip.write(CMR, *command);
        }
        Op::Read { addr, .. } => {
            chip.read(*addr);
        }
        Op::Command { command, .. } => chip.write(CMR, *command),
        Op::Counters { txerr, rxerr, .. } => {
            if chip.mode() == CanMode::Peli {
                let mode = chip.read(MOD);
                chip.write(MOD, mode | 0x01);
                chip.write(14, *rxerr);
                chip.write(15, *txerr);
                chip.write(MOD, mode & !0x01);
            }
        }
    }
}

fn chip_of(op: &Op) -> usize {
    match op {
        Op::Transmit { chip, .. }
        | Op::Read { chip, .. }
        | Op::Command { chip, .. }
        | Op::Counters { chip, .. } => *chip,
    }
}

fn run(bus: &Bus, whole: bool) -> (u64, String, String) {
    let mut sim = Simulation::new(500_000, 3);
    sim.set_whole_frames(whole);
    for (i, spec) in bus.chips.iter().enumerate() {
        sim.add_device(format!("chip{i}"), Box::new(init(spec)));
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
    for (bits, ops) in &bus.pieces {
        sim.run_for(BitTime::new(*bits));
        for op in ops {
            let chip = sim.node_mut(chip_of(op)).get_mut::<Sja1000>().unwrap();
            apply(chip, op);
        }
    }
    let chips: Vec<String> = sim
        .nodes()
        .iter()
        .map(|n| {
            let chip = n.get::<Sja1000>().unwrap();
            let registers: Vec<u8> = (0..128).map(|a| chip.peek(a)).collect();
            format!(
                "{n:?}\n{chip:?}\nregisters {registers:02X?}\nint {} out {:?}",
                chip.interrupt(),
                chip.output()
            )
        })
        .collect();
    let state = format!("now {}\n{:#?}\n{:?}", sim.now(), chips, sim.bus_stats());
    (sim.whole_frames(), format!("{:#?}", sim.records()), state)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn whole_frames_leave_every_register_as_bit_by_bit(bus in bus()) {
        let (_, fast_trace, fast_state) = run(&bus, true);
        let (whole, slow_trace, slow_state) = run(&bus, false);
        prop_assert_eq!(whole, 0);
        prop_assert_eq!(&fast_trace, &slow_trace, "trace differs");
        prop_assert_eq!(&fast_state, &slow_state, "state differs");
    }
}

/// Chips that keep sending take most of their frames whole: the property above compares two
/// different paths.
#[test]
fn busy_chips_take_their_frames_whole() {
    let spec = ChipSpec {
        basic: false,
        mode: 0x08,
        ier: 0xFF,
        ewlr: 96,
    };
    let mut sim = Simulation::new(500_000, 3);
    for i in 0..4 {
        sim.add_device(format!("chip{i}"), Box::new(init(&spec)));
    }
    for round in 0..200u32 {
        for i in 0..4 {
            let chip = sim.node_mut(i).get_mut::<Sja1000>().unwrap();
            // The receive path of a CPU: IR read, every message released.
            chip.read(3);
            while chip.read(29) > 0 {
                chip.write(CMR, 0x04);
            }
            let id = Id::standard(0x100 + i as u16 + (round % 3) as u16 * 8).unwrap();
            load_tx(chip, &Frame::data(id, &[round as u8; 8]).unwrap());
            chip.write(CMR, 0x01);
        }
        sim.run_for(BitTime::new(1_000));
    }
    let (whole, frames) = (sim.whole_frames(), sim.bus_stats().frames);
    assert!(frames >= 700, "{frames} frames");
    assert!(
        whole * 10 >= frames * 9,
        "only {whole} of {frames} frames whole"
    );
}
