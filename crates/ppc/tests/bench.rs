//! The seed's bench on the one bus engine: the PowerPC node running MoniCAN and three SLIO
//! demo boards. The terminal is read by an independent VT100 emulator (the `vt100` crate) at
//! the cells of the seed's Fig. 4.2.

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

use buslab_can::controller::{ControllerConfig, ErrorKind, Event};
use buslab_can::{BitTime, Frame, Id, Nanos};
use buslab_monican::app::MAIL_NOTICE;
use buslab_monican::layout::*;
use buslab_monican::{Config, MoniCan};
use buslab_ppc::PpcNode;
use buslab_sim::{Happening, Simulation};
use buslab_slio::board::volts_to_code;
use buslab_slio::{DemoBoard, SlioId};

const RATE: u32 = 125_000;
/// Virtual time a test may take at most, in bit-times (10 s of bus time): far beyond what
/// anything here needs, so a failure is a real one.
const BUDGET: u64 = 10 * RATE as u64;

/// A potentiometer the test turns while the bus runs (volts as f64 bits).
#[derive(Clone)]
struct Knob(Arc<AtomicU64>);

impl Knob {
    fn new(volts: f64) -> Self {
        Self(Arc::new(AtomicU64::new(volts.to_bits())))
    }
    fn set(&self, volts: f64) {
        self.0.store(volts.to_bits(), Ordering::Relaxed);
    }
    fn signal(&self) -> Box<dyn FnMut(Nanos) -> f64 + Send> {
        let cell = self.0.clone();
        Box::new(move |_| f64::from_bits(cell.load(Ordering::Relaxed)))
    }
}

struct Bench {
    sim: Simulation,
    term: vt100::Parser,
    knob: Knob,
    /// Node index of each board, by SLIO number.
    boards: Vec<(u8, usize)>,
    records: Vec<(u64, Happening)>,
}

const PPC: usize = 0;

impl Bench {
    /// The PowerPC node and demo boards with these IDs and input switches.
    fn new(boards: &[(u8, u8)]) -> Self {
        let mut sim = Simulation::new(RATE, 7);
        let ppc = PpcNode::new(Config::default()).unwrap();
        assert_eq!(sim.add_device("ppc", Box::new(ppc)), PPC);
        let knob = Knob::new(2.5);
        let mut indices = Vec::new();
        for &(id, switches) in boards {
            let mut board = DemoBoard::new(
                SlioId::new(id).unwrap(),
                RATE,
                Box::new(1.0),
                Box::new(knob.signal()),
            )
            .unwrap();
            board.set_switches(BitTime::ZERO, switches);
            indices.push((id, sim.add_device(format!("slio{id:X}"), Box::new(board))));
        }
        Self {
            sim,
            term: vt100::Parser::new(24, 80, 0),
            knob,
            boards: indices,
            records: Vec::new(),
        }
    }

    fn ppc(&mut self) -> &mut PpcNode {
        self.sim.node_mut(PPC).get_mut::<PpcNode>().unwrap()
    }

    fn app(&self) -> &MoniCan {
        self.sim.node(PPC).get::<PpcNode>().unwrap().app()
    }

    fn board(&self, id: u8) -> &DemoBoard {
        let (_, index) = self.boards.iter().find(|b| b.0 == id).unwrap();
        self.sim.node(*index).get::<DemoBoard>().unwrap()
    }

    fn type_keys(&mut self, text: &str) {
        for b in text.bytes() {
            self.ppc().key(b);
        }
    }

    /// Runs `bits` bit-times, then brings the terminal up to date.
    fn run(&mut self, bits: u64) {
        self.sim.run_for(BitTime::new(bits));
        for r in self.sim.take_records() {
            self.records.push((r.time.get(), r.what));
        }
        let out = self.ppc().take_screen();
        self.term.process(&out);
    }

    /// Runs in steps of `step` bit-times until `done` holds; panics after [`BUDGET`].
    fn run_until(&mut self, step: u64, what: &str, mut done: impl FnMut(&mut Self) -> bool) {
        let end = self.sim.now() + BitTime::new(BUDGET);
        while !done(self) {
            assert!(
                self.sim.now() < end,
                "{what}: not within {BUDGET} bit-times\n{}",
                self.screen()
            );
            self.run(step);
        }
    }

    fn screen(&self) -> String {
        self.term.screen().contents()
    }

    fn cells(&self, row: u8, col: u8, len: u8) -> String {
        let screen = self.term.screen();
        (0..len)
            .map(|k| {
                screen
                    .cell(u16::from(row) - 1, u16::from(col + k) - 1)
                    .map(|c| c.contents().to_string())
                    .filter(|s| !s.is_empty())
                    .unwrap_or_else(|| " ".to_string())
            })
            .collect()
    }

    fn row(&self, row: u8) -> String {
        self.term
            .screen()
            .rows(0, 80)
            .nth(usize::from(row) - 1)
            .unwrap_or_default()
            .trim_end()
            .to_string()
    }

    fn marked(&self, id: u8) -> bool {
        self.cells(slio_row(SlioId::new(id).unwrap()), MARK_COL, 1) == "*"
    }

    fn slio_cell(&self, id: u8, col: u8, len: u8) -> String {
        self.cells(slio_row(SlioId::new(id).unwrap()), col, len)
    }
}

/// Every board marked and its initialisation confirmed on the screen.
fn initialised(b: &Bench, ids: impl IntoIterator<Item = u8>) -> bool {
    ids.into_iter().all(|id| {
        b.marked(id)
            && b.slio_cell(id, OUTPUTS_COL, 4) == "2000"
            && b.slio_cell(id, INPUTS_COL, 1) == "2"
            && b.slio_cell(id, DPM1_COL, 2) == "00"
            && b.slio_cell(id, DPM2_COL, 2) == "00"
    })
}

fn started(boards: &[(u8, u8)]) -> Bench {
    let mut bench = Bench::new(boards);
    bench.run_until(100, "the boards are found and initialised", |b| {
        initialised(b, boards.iter().map(|b| b.0))
    });
    bench
}

#[test]
fn start_up_calibrates_with_single_shot_frames_and_finds_the_three_boards() {
    let mut bench = Bench::new(&[(0x0, 0x0), (0x3, 0x5), (0xA, 0xF)]);
    bench.run(1);
    assert_eq!(bench.row(HEADER_ROW), HEADER);
    assert_eq!(
        bench.row(TITLE_ROW),
        TITLE,
        "the screen is initialised first"
    );
    bench.run_until(100, "the boards are found and initialised", |b| {
        initialised(b, [0x0, 0x3, 0xA])
    });
    for (id, inputs) in [(0x0, "2000"), (0x3, "2005"), (0xA, "200F")] {
        assert_eq!(bench.slio_cell(id, OUTPUTS_COL, 4), "2000", "SLIO {id:X}");
        assert_eq!(bench.slio_cell(id, INPUTS_COL, 4), inputs, "SLIO {id:X}");
        assert_eq!(bench.slio_cell(id, DPM1_COL, 2), "00");
        assert_eq!(bench.slio_cell(id, DPM2_COL, 2), "00");
        assert_eq!(bench.slio_cell(id, ADC2_COL, 2), "XX");
        assert_eq!(bench.board(id).leds(), [false; 5]);
    }
    for id in [1, 2, 4, 5, 6, 7, 8, 9, 0xB, 0xC, 0xD, 0xE, 0xF] {
        assert!(!bench.marked(id), "SLIO {id:X} is not on the bus");
        assert_eq!(bench.slio_cell(id, OUTPUTS_COL, 4), "XXXX");
    }
    // The PowerPC's frames until its first register write: the 48 calibration frames, each
    // tried once. The first ones nobody acknowledged (ACK errors), and none was retried.
    let mut calibration_attempts = 0;
    let mut unacknowledged = 0;
    for (_, what) in &bench.records {
        let Happening::Node { node: PPC, event } = what else {
            continue;
        };
        match event {
            Event::Transmitted(f) if f.id() == Id::standard(0x0AA).unwrap() => {
                calibration_attempts += 1
            }
            Event::Transmitted(_) => break,
            Event::Error {
                transmitter: true,
                kind,
                ..
            } => {
                assert_eq!(*kind, ErrorKind::Ack, "only ACK errors while calibrating");
                calibration_attempts += 1;
                unacknowledged += 1;
            }
            _ => {}
        }
    }
    assert_eq!(calibration_attempts, 48);
    assert!(
        (2..48).contains(&unacknowledged),
        "{unacknowledged} calibration frames were not acknowledged"
    );
}

/// Issue 25: the PowerPC's MoniCAN read inputs with `29C#00`, a 1-byte frame a P82C150 need
/// not answer (its frames « ont toujours 3 octets », seed §2.1.2.1). Its start-up reads and
/// `3I0` are 3-byte frames now, and the SLIOs, which ignore other lengths, answer them.
#[test]
fn the_powerpcs_input_reads_are_three_byte_frames_and_answered() {
    let mut bench = started(&[(0x0, 0x0), (0x3, 0x5), (0xA, 0xF)]);
    bench.type_keys("3I0");
    bench.run_until(100, "SLIO 3's inputs", |b| {
        b.row(INPUT_LOG_ROW) == "ID_slio:3 Data input:2005"
    });
    let to_slios: Vec<String> = bench
        .records
        .iter()
        .filter_map(|(_, what)| match what {
            Happening::Node {
                node: PPC,
                event: Event::Transmitted(f),
            } if f.id() != Id::standard(0x0AA).unwrap() => Some(f.to_string()),
            _ => None,
        })
        .collect();
    // The start-up reads of the three boards, then the command's.
    let reads: Vec<&String> = to_slios.iter().filter(|f| f.ends_with("#000000")).collect();
    assert_eq!(
        reads,
        ["284#000000", "29C#000000", "394#000000", "29C#000000"],
        "{to_slios:?}"
    );
    for f in &to_slios {
        assert_eq!(f.len(), "29C#000000".len(), "{f} in {to_slios:?}");
    }
}

#[test]
fn a_typed_command_lights_the_led_and_shows_it_only_once_the_slio_answered() {
    let mut bench = started(&[(0x0, 0), (0x3, 0), (0xA, 0)]);
    bench.type_keys("3O701");
    bench.records.clear();
    // Bit by bit: when the LED lights, when the PowerPC receives the answer, when the screen
    // shows it.
    let (mut lit_at, mut answer_at, mut shown_at) = (None, None, None);
    let answer: Frame = "29D#232080".parse().unwrap();
    bench.run_until(1, "the LED command goes round", |b| {
        let now = b.sim.now();
        if lit_at.is_none() && b.board(3).leds()[0] {
            lit_at = Some(now);
        }
        if answer_at.is_none()
            && b.records.iter().any(|(_, h)| {
                matches!(h, Happening::Node { node: PPC, event: Event::Received(f) } if *f == answer)
            })
        {
            answer_at = Some(now);
        }
        if shown_at.is_none() && b.slio_cell(3, OUTPUTS_COL, 4) == "2080" {
            shown_at = Some(now);
        }
        shown_at.is_some()
    });
    let (lit, answer, shown) = (lit_at.unwrap(), answer_at.unwrap(), shown_at.unwrap());
    assert!(
        lit < answer,
        "the SLIO drives the LED before its answer is on the bus"
    );
    assert!(
        shown >= answer,
        "the screen waits for the answer ({shown} < {answer})"
    );
    assert_eq!(
        bench.row(COMMAND_ROW),
        "Next command > SLIO:3 I/O:O PIN:7 VALUE:01"
    );
    assert_eq!(bench.row(OUTPUT_LOG_ROW), "ID_slio:3 Data_output:2080");
    assert_eq!(
        bench.row(LAST_FRAME_ROW),
        "Last frame received : ID1:53 ID2:A0 DATA1:23 DATA2:20 DATA3:80"
    );
    assert_eq!(bench.board(3).leds(), [true, false, false, false, false]);
    assert_eq!(bench.board(0).leds(), [false; 5], "only SLIO 3");
    // The DPM output follows a DPM command; the screen shows the confirmed value.
    bench.type_keys("AOA80");
    bench.run_until(50, "DPM1 of SLIO A", |b| {
        b.slio_cell(0xA, DPM1_COL, 2) == "80"
    });
    let volts = bench.board(0xA).dpm_volts()[0].unwrap();
    assert!((volts - 2.5).abs() < 0.01, "{volts} V");
}

#[test]
fn the_adc_column_follows_the_potentiometer() {
    let mut bench = started(&[(0x0, 0), (0x3, 0), (0xA, 0)]);
    for volts in [2.5, 5.0, 0.0, 1.25] {
        bench.knob.set(volts);
        bench.type_keys("3I6");
        let want = format!("{:02X}", volts_to_code(volts) >> 2);
        bench.run_until(50, "ADC2 of SLIO 3", |b| {
            b.slio_cell(3, ADC2_COL, 2) == want
        });
        assert_eq!(
            bench.row(INPUT_LOG_ROW),
            format!("ID_slio:3 ADC2:{:04X}", volts_to_code(volts))
        );
    }
    // ADC1 (P5) is a constant 1 V on these boards.
    bench.type_keys("0I5");
    let want = format!("{:02X}", volts_to_code(1.0) >> 2);
    bench.run_until(50, "ADC1 of SLIO 0", |b| {
        b.slio_cell(0, ADC1_COL, 2) == want
    });
}

#[test]
fn the_idle_node_sleeps_until_its_calibration_timer_and_keeps_the_slios() {
    let mut bench = started(&[(0x3, 0)]);
    let skipped = bench.sim.fast_forwarded();
    let start = bench.sim.now();
    // 40 watchdog periods of the SLIO.
    bench.run(40 * 8192);
    let idle = bench.sim.now() - start;
    let jumped = bench.sim.fast_forwarded() - skipped;
    assert!(
        jumped * 10 > idle * 9,
        "the bus engine jumped over {jumped} of {idle} idle bit-times"
    );
    // Still calibrated: it answers.
    bench.type_keys("3OC01");
    bench.run_until(50, "the LED on P12", |b| {
        b.slio_cell(3, OUTPUTS_COL, 4) == "3000"
    });
    assert!(bench.board(3).leds()[4]);
}

#[test]
fn a_supervisor_sends_mail_and_asks_for_the_loader() {
    let mut bench = started(&[(0x3, 0)]);
    let supervisor = bench
        .sim
        .add_node("supervisor", ControllerConfig::default());
    bench
        .sim
        .enqueue(supervisor, "700#R".parse().unwrap())
        .unwrap();
    bench.run_until(50, "the mail notice", |b| b.row(NOTICE_ROW) == MAIL_NOTICE);
    bench.type_keys("\x12");
    bench.records.clear();
    // The PowerPC answers the notifier with a remote frame on the mail identifier.
    let request: Frame = "700#R".parse().unwrap();
    bench.run_until(10, "the remote frame", |b| {
        b.records.iter().any(|(_, h)| {
            matches!(h, Happening::Node { node, event: Event::Received(f) } if *node == supervisor && *f == request)
        })
    });
    // The supervisor keeps one frame in flight (a CAN controller's queue sends frames with one
    // identifier in priority order, which for equal identifiers is not the order queued).
    let text = b"Bench closes at 18:00.\nSwitch the boards off.";
    for f in buslab_can::file::frames(Id::standard(0x700).unwrap(), text) {
        bench.sim.enqueue(supervisor, f).unwrap();
        bench.run_until(10, "a mail frame", |b| {
            b.records.iter().any(|(_, h)| {
                matches!(h, Happening::Node { node, event: Event::Transmitted(sent) } if *node == supervisor && *sent == f)
            })
        });
    }
    bench.run_until(50, "the message", |b| b.row(4) == "Switch the boards off.");
    assert_eq!(bench.row(3), "Bench closes at 18:00.");
    bench.type_keys(" ");
    bench.run_until(50, "back to the SLIO screen", |b| {
        b.row(HEADER_ROW) == HEADER
    });
    assert!(bench.marked(3));
    assert_eq!(bench.slio_cell(3, OUTPUTS_COL, 4), "2000");
}

/// The supervisor's side of the loader: a remote frame with ID 0, the answer, then the file
/// one frame at a time (each sent before the next is queued: the file protocol has no sequence
/// numbers). Returns the answer frame seen.
fn load(bench: &mut Bench, supervisor: usize, text: &[u8]) -> Frame {
    bench.records.clear();
    let request = Frame::remote(Id::standard(0).unwrap(), 0).unwrap();
    bench.sim.enqueue(supervisor, request).unwrap();
    let mut answer = None;
    bench.run_until(10, "the loader's answer", |b| {
        answer = b.records.iter().find_map(|(_, h)| match h {
            Happening::Node {
                node,
                event: Event::Received(f),
            } if *node == supervisor && f.id() == Id::standard(0).unwrap() => Some(*f),
            _ => None,
        });
        answer.is_some()
    });
    for f in buslab_can::file::frames(Id::standard(0).unwrap(), text) {
        bench.records.clear();
        bench.sim.enqueue(supervisor, f).unwrap();
        bench.run_until(10, "a file frame", |b| {
            b.records.iter().any(|(_, h)| {
                matches!(h, Happening::Node { node, event: Event::Transmitted(sent) } if *node == supervisor && *sent == f)
            })
        });
    }
    answer.unwrap()
}

/// A file without an entry point is loaded, not run: MoniCAN starts again with the report.
#[test]
fn the_loader_takes_a_program_without_an_entry_point_reports_it_and_monican_starts_again() {
    let mut bench = started(&[(0x3, 0)]);
    let supervisor = bench
        .sim
        .add_node("supervisor", ControllerConfig::default());
    let program = buslab_loader::srec::write(
        b"monican2",
        [(0x30000, &[0x11u8; 64][..]), (0x32000, &[0x22u8; 300][..])],
        None,
    );
    let answer = load(&mut bench, supervisor, &program);
    // §4.4.1.1: a data frame with ID 0 and no data.
    assert_eq!(answer.to_string(), "000#");
    bench.run_until(50, "the report", |b| {
        b.row(1) == buslab_ppc::node::LOADER_TITLE
    });
    let screen = bench.screen();
    assert!(screen.contains("Program loaded: 364 bytes"), "{screen}");
    assert!(
        screen.contains("00030000-0003003F        64 bytes"),
        "{screen}"
    );
    assert!(
        screen.contains("00032000-0003212B       300 bytes"),
        "{screen}"
    );
    assert!(screen.contains(buslab_ppc::node::NOT_RUN), "{screen}");
    let ppc = bench.ppc();
    assert_eq!(ppc.memory().read(0x3212B, 2), [0x22, 0]);
    assert_eq!(ppc.activity(), buslab_ppc::Activity::MoniCan);
    assert!(ppc.last_load().unwrap().loaded);
    // MoniCAN started again underneath: it calibrates and finds the board anew.
    bench.type_keys(" ");
    bench.run_until(100, "the board again", |b| initialised(b, [3]));
    bench.type_keys("3O901");
    bench.run_until(50, "the LED on P9", |b| {
        b.slio_cell(3, OUTPUTS_COL, 4) == "2200"
    });

    // A corrupted record: refused with its line number, nothing written.
    let mut bad = buslab_loader::srec::write(b"x", [(0x40000, &[0x33u8; 8][..])], None);
    let second = bad.iter().position(|&b| b == b'\n').unwrap() + 1;
    bad[second + 10] = if bad[second + 10] == b'0' { b'1' } else { b'0' };
    load(&mut bench, supervisor, &bad);
    bench.run_until(50, "the refusal", |b| b.screen().contains("File refused"));
    assert!(
        bench.screen().contains("line 2: checksum"),
        "{}",
        bench.screen()
    );
    assert_eq!(bench.ppc().memory().read(0x40000, 1), [0]);
    assert!(!bench.ppc().last_load().unwrap().loaded);
}

#[test]
fn a_durable_node_reports_only_once_the_image_is_saved() {
    use buslab_device::Persistent;
    let mut bench = started(&[]);
    bench.ppc().set_durable(true);
    let supervisor = bench
        .sim
        .add_node("supervisor", ControllerConfig::default());
    let program = buslab_loader::srec::write(b"p", [(0x30000, &[1u8; 16][..])], None);
    load(&mut bench, supervisor, &program);
    bench.run(2_000);
    assert_eq!(bench.ppc().activity(), buslab_ppc::Activity::Saving);
    assert!(
        bench.screen().contains("saving the memory image"),
        "{}",
        bench.screen()
    );
    assert_eq!(bench.ppc().state_generation(), 1);
    let image = PpcNode::file_bytes(&bench.ppc().snapshot());
    let saved = buslab_loader::srec::parse(&image).unwrap();
    assert_eq!(saved.ranges(), [(0x30000, 0x3000F)]);
    bench.ppc().persisted(1);
    bench.run_until(50, "the report", |b| b.screen().contains("Loaded ranges"));
    assert!(
        bench.screen().contains(buslab_ppc::node::SAVED),
        "{}",
        bench.screen()
    );
    assert_eq!(bench.ppc().activity(), buslab_ppc::Activity::MoniCan);
}

#[test]
fn a_lone_powerpc_gives_up_unacknowledged_frames_and_keeps_calibrating() {
    let mut bench = Bench::new(&[]);
    bench.run(20_000);
    assert!(bench.app().present().next().is_none());
    bench.type_keys("3I0");
    bench.run_until(100, "the notice", |b| {
        b.row(NOTICE_ROW) == "SLIO 3 did not answer (inputs)"
    });
    // The periodic calibration still goes out (it is not stuck behind the command): each
    // 5000 bit-times a frame is tried, retried by the SJA1000 as any unacknowledged frame, and
    // given up after GIVE_UP so the next period's goes out.
    bench.records.clear();
    bench.run(50_000);
    let periods: std::collections::BTreeSet<u64> = bench
        .records
        .iter()
        .filter(|(_, h)| {
            matches!(
                h,
                Happening::Node {
                    node: PPC,
                    event: Event::Error {
                        transmitter: true,
                        ..
                    }
                }
            )
        })
        .map(|(t, _)| t / 5000)
        .collect();
    assert!(
        periods.len() >= 9,
        "calibration attempts in only {} of 10 periods",
        periods.len()
    );
    assert!(
        bench.sim.node(PPC).tec() <= 128,
        "error passive at most, never bus-off"
    );
}

/// The screen as text: 24 rows, trailing blanks removed.
fn capture(bench: &Bench) -> String {
    (1..=24)
        .map(|r| bench.row(r))
        .collect::<Vec<_>>()
        .join("\n")
}

/// docs/monican.md shows the bench's screen after start-up and two commands: this keeps the
/// capture true (on a mismatch the message has the screen to paste there).
#[test]
fn the_capture_in_docs_monican_md_is_the_bench_screen() {
    let mut bench = started(&[(0x0, 0x0), (0x3, 0x5), (0xA, 0xF)]);
    bench.type_keys("3O701");
    bench.run_until(50, "the LED", |b| b.slio_cell(3, OUTPUTS_COL, 4) == "2080");
    bench.type_keys("3I6");
    bench.run_until(50, "ADC2", |b| b.slio_cell(3, ADC2_COL, 2) == "80");
    let screen = capture(&bench);
    let doc_path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../docs/monican.md");
    let doc = std::fs::read_to_string(doc_path).unwrap();
    let start = "<!-- capture: crates/ppc/tests/bench.rs -->\n```text\n";
    let block = doc
        .split_once(start)
        .and_then(|(_, rest)| rest.split_once("\n```"))
        .map(|(block, _)| block);
    assert_eq!(
        block,
        Some(screen.as_str()),
        "docs/monican.md's capture differs from the bench's screen:\n{screen}"
    );
}
