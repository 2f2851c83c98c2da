//! The peripherals are brought up to date lazily, so where the board stops the core must not
//! matter: a run in one go, a run in random pieces and a run step by step give the same state
//! and the same events at the same times.

mod common;

use buslab_mcs51::{Clocks, Event, FlatMemory, LineFrame, Mcs51, Stop, sfr};
use proptest::prelude::*;

/// Timer 1 as a 9600-baud generator, UART mode 1 receiving, timer 0 in mode 2, every interrupt
/// enabled, then the random bytes.
const PROLOGUE: [u8; 24] = [
    0x75, 0x89, 0x22, // MOV TMOD,#22h
    0x75, 0x8D, 0xFD, // MOV TH1,#FDh
    0x75, 0x8C, 0x80, // MOV TH0,#80h
    0x75, 0x88, 0x55, // MOV TCON,#55h (TR1, TR0, IT1, IT0)
    0x75, 0x98, 0x50, // MOV SCON,#50h
    0x75, 0xA8, 0x9F, // MOV IE,#9Fh
    0x75, 0x81, 0x30, // MOV SP,#30h
    0x75, 0x99, 0x41, // MOV SBUF,#41h
];

struct Outcome {
    registers: buslab_mcs51::Registers,
    iram: Vec<u8>,
    sfrs: Vec<u8>,
    events: Vec<Event>,
    mem: Vec<u8>,
    now: u64,
}

fn setup(body: &[u8], frames: &[(u64, u8)]) -> (Mcs51, FlatMemory) {
    let mut mem = FlatMemory::new();
    mem.load(0, &PROLOGUE);
    mem.load(PROLOGUE.len() as u16, body);
    let mut cpu = Mcs51::new();
    for &(at, data) in frames {
        let frame = LineFrame {
            data,
            ninth: None,
            bit_clocks: Clocks(1152),
        };
        cpu.send_rxd(Clocks(at), frame).unwrap();
    }
    (cpu, mem)
}

fn outcome(mut cpu: Mcs51, mem: FlatMemory, events: Vec<Event>) -> Outcome {
    let sfrs = (0x80..=0xFFu8)
        .filter(|&a| a != sfr::SBUF)
        .map(|a| cpu.read_direct(a))
        .collect();
    Outcome {
        registers: cpu.registers(),
        iram: cpu.iram().to_vec(),
        sfrs,
        events,
        mem: mem.as_bytes().to_vec(),
        now: cpu.now().0,
    }
}

/// Runs to `end` stopping at each of `stops` (clocks, any order) and wherever events wait.
fn run(body: &[u8], frames: &[(u64, u8)], stops: &[u64], end: u64) -> Outcome {
    let (mut cpu, mut mem) = setup(body, frames);
    let mut limits: Vec<u64> = stops.iter().map(|s| s % end).collect();
    limits.sort_unstable();
    limits.push(end);
    let mut events = Vec::new();
    for limit in limits {
        loop {
            let stop = cpu.run(&mut mem, Clocks(limit));
            while let Some(e) = cpu.poll_event() {
                events.push(e);
            }
            match stop {
                Stop::Events => continue,
                Stop::Limit | Stop::PowerDown => break,
                Stop::Trap { .. } => unreachable!("no traps set"),
            }
        }
    }
    outcome(cpu, mem, events)
}

fn same(a: &Outcome, b: &Outcome) -> Result<(), TestCaseError> {
    prop_assert_eq!(a.now, b.now);
    prop_assert_eq!(a.registers, b.registers);
    prop_assert_eq!(&a.iram, &b.iram);
    prop_assert_eq!(&a.sfrs, &b.sfrs);
    prop_assert_eq!(&a.events, &b.events);
    prop_assert!(a.mem == b.mem, "memory differs");
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    #[test]
    fn where_the_board_stops_the_core_changes_nothing(
        body in proptest::collection::vec(any::<u8>(), 0..200),
        frames in proptest::collection::vec((0u64..150_000, any::<u8>()), 0..6),
        stops in proptest::collection::vec(any::<u64>(), 1..40),
    ) {
        let end = 200_000;
        let whole = run(&body, &frames, &[], end);
        let pieces = run(&body, &frames, &stops, end);
        same(&whole, &pieces)?;
        // Step by step over the first stretch, then on to the end.
        let steps: Vec<u64> = (1..2000).map(|i| i * 12).collect();
        let stepped = run(&body, &frames, &steps, end);
        same(&whole, &stepped)?;
    }
}
