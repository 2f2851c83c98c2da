//! No program makes the node panic or hang: random words as a program, run on the board with
//! the firmware's services (many cases, directly), and loaded over CAN into the node (a few,
//! the whole path: the jump, the end, the report, `reset`).

use buslab_can::controller::ControllerConfig;
use buslab_can::{BitTime, Frame, Id};
use buslab_ppc::board::Board;
use buslab_ppc::program::{Cycles, Ending, Running};
use buslab_ppc::{Activity, PpcNode};
use buslab_sim::Simulation;
use proptest::prelude::*;

const TEXT: u32 = 0x32000;

fn words_strategy() -> impl Strategy<Value = Vec<u32>> {
    // Half the words from the opcodes programs use most, half anything.
    let common = prop::sample::select(vec![
        0x3800_0000u32, // addi
        0x3C00_0000,    // addis
        0x8000_0000,    // lwz
        0x9000_0000,    // stw
        0x8800_0000,    // lbz
        0x9800_0000,    // stb
        0x4800_0000,    // b
        0x4000_0000,    // bc
        0x4C00_0000,    // bclr, rfi, ...
        0x7C00_0000,    // the X-forms, mtspr, mtmsr, mtdcr
        0x4400_0002,    // sc
    ]);
    let word = prop_oneof![
        (common, any::<u32>()).prop_map(|(op, low)| op | (low & 0x03FF_FFFF)),
        any::<u32>(),
    ];
    prop::collection::vec(word, 1..64)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    /// 2 ms of CPU time (50 000 cycles) of random words, in slices of a bit-time: the run
    /// ends or goes on, never panics, and time always moves.
    #[test]
    fn random_words_run_on_the_board_without_a_panic(words in words_strategy()) {
        let mut board = Board::new();
        for (i, w) in words.iter().enumerate() {
            board.load(TEXT + 4 * i as u32, &w.to_be_bytes());
        }
        let mut run = Running::start(board, TEXT);
        let mut chip = buslab_sja1000::Sja1000::new();
        let mut until = 0;
        while until < 50_000 {
            until += 200;
            match run.run(&mut chip, Cycles(until)) {
                None => prop_assert!(run.cycles() >= Cycles(until)),
                Some(Ending::Stopped { reason, .. }) => {
                    prop_assert!(!reason.is_empty());
                    break;
                }
                Some(_) => break,
            }
        }
    }
}

/// The loader's protocol from a supervisor node: the remote frame, the answer, the file.
fn load(sim: &mut Simulation, host: usize, text: &[u8]) {
    let id = Id::standard(0).unwrap();
    let send = |sim: &mut Simulation, frame: Frame| {
        sim.enqueue(host, frame).unwrap();
        let end = sim.now() + BitTime::new(100_000);
        while sim.node(host).device().pending() > 0 {
            assert!(sim.now() < end, "{frame} never went out");
            sim.run_for(BitTime::new(20));
        }
    };
    send(sim, Frame::remote(id, 0).unwrap());
    for f in buslab_can::file::frames(id, text) {
        send(sim, f);
    }
}

#[test]
fn random_programs_loaded_over_can_end_or_run_and_reset_takes_the_board_back() {
    let rate = 125_000;
    let mut runner = proptest::test_runner::TestRunner::deterministic();
    let mut seen = Vec::new();
    for case in 0..32 {
        let words = proptest::strategy::ValueTree::current(
            &words_strategy().new_tree(&mut runner).unwrap(),
        );
        let mut sim = Simulation::new(rate, case);
        let ppc = sim.add_device(
            "ppc",
            Box::new(
                PpcNode::new(buslab_monican::Config {
                    bitrate: rate,
                    ..Default::default()
                })
                .unwrap(),
            ),
        );
        let host = sim.add_node("host", ControllerConfig::default());
        let bytes: Vec<u8> = words.iter().flat_map(|w| w.to_be_bytes()).collect();
        let text = buslab_loader::srec::write(b"random", [(TEXT, &bytes[..])], Some(TEXT));
        load(&mut sim, host, &text);
        let end = sim.now() + BitTime::new(100_000);
        while node(&mut sim, ppc).last_load().is_none() {
            assert!(sim.now() < end, "case {case}: the load never finished");
            sim.run_for(BitTime::new(100));
        }
        // 20 000 bit-times (160 ms) of the program, the terminal read as a host would.
        for _ in 0..200 {
            sim.run_for(BitTime::new(100));
            node(&mut sim, ppc).take_screen();
        }
        let activity = node(&mut sim, ppc).activity();
        let load = node(&mut sim, ppc).last_load().cloned().unwrap();
        assert!(
            load.loaded && load.entry == Some(TEXT),
            "case {case}: {load:?}"
        );
        seen.push(activity.clone());
        assert!(
            matches!(
                activity,
                Activity::Running { .. }
                    | Activity::Stopped { .. }
                    | Activity::Exited { .. }
                    | Activity::MoniCan
            ),
            "case {case}: {activity:?}"
        );
        if let Activity::Stopped { .. } = activity {
            node(&mut sim, ppc).key(b' ');
            sim.run_for(BitTime::new(10));
            assert_eq!(
                node(&mut sim, ppc).activity(),
                Activity::MoniCan,
                "case {case}"
            );
        }
        node(&mut sim, ppc).reset();
        assert_eq!(
            node(&mut sim, ppc).activity(),
            Activity::MoniCan,
            "case {case}"
        );
        sim.run_for(BitTime::new(10_000));
    }
    eprintln!("how the random programs were after 20 000 bit-times: {seen:?}");
}

fn node(sim: &mut Simulation, ppc: usize) -> &mut PpcNode {
    sim.node_mut(ppc).get_mut::<PpcNode>().unwrap()
}
