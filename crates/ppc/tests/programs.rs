//! Programs built with the cross toolchain at test time, loaded over CAN by a supervisor node
//! into the PowerPC node's loader on the bus engine, and run on the PPC403 core: the seed's
//! routines driving the SJA1000 through the card's ports, the SLIO demo boards calibrated and
//! a LED lit, text on the terminal through the serial port and the firmware's `write`,
//! crashes reported, `reset` and `exit` back to MoniCAN.

#[path = "support/asm.rs"]
mod asm;

use buslab_can::controller::{ControllerConfig, Event};
use buslab_can::{BitTime, Frame, Id};
use buslab_monican::Config;
use buslab_ppc::{Activity, PpcNode};
use buslab_sim::{Happening, Simulation};
use buslab_slio::registers::{Register, Request};
use buslab_slio::{DemoBoard, SlioId};

const RATE: u32 = 125_000;
/// Virtual time a wait may take at most (10 s of bus time): far beyond what each needs.
const BUDGET: u64 = 10 * RATE as u64;
const PPC: usize = 0;
const HOST: usize = 1;

/// The bit timing of the test bus for the node's 16 MHz crystal.
fn btr() -> (u8, u8) {
    buslab_ppc::slio_timing(RATE).unwrap().registers()
}

struct Lab {
    sim: Simulation,
    records: Vec<Happening>,
    /// Everything the node sent its terminal.
    terminal: Vec<u8>,
    boards: Vec<(u8, usize)>,
}

impl Lab {
    /// The PowerPC node, a supervisor node, and demo boards with these IDs.
    fn new(boards: &[u8]) -> Self {
        let mut sim = Simulation::new(RATE, 3);
        let ppc = PpcNode::new(Config {
            bitrate: RATE,
            ..Config::default()
        })
        .unwrap();
        assert_eq!(sim.add_device("ppc", Box::new(ppc)), PPC);
        assert_eq!(sim.add_node("host", ControllerConfig::default()), HOST);
        let boards = boards
            .iter()
            .map(|&id| {
                let board =
                    DemoBoard::new(SlioId::new(id).unwrap(), RATE, Box::new(1.0), Box::new(2.5))
                        .unwrap();
                (id, sim.add_device(format!("slio{id:X}"), Box::new(board)))
            })
            .collect();
        Self {
            sim,
            records: Vec::new(),
            terminal: Vec::new(),
            boards,
        }
    }

    fn ppc(&mut self) -> &mut PpcNode {
        self.sim.node_mut(PPC).get_mut::<PpcNode>().unwrap()
    }

    fn board(&self, id: u8) -> &DemoBoard {
        let (_, index) = self.boards.iter().find(|b| b.0 == id).unwrap();
        self.sim.node(*index).get::<DemoBoard>().unwrap()
    }

    fn run(&mut self, bits: u64) {
        self.sim.run_for(BitTime::new(bits));
        self.records
            .extend(self.sim.take_records().into_iter().map(|r| r.what));
        let out = self.ppc().take_screen();
        self.terminal.extend(out);
    }

    /// Runs in steps of 50 bit-times until `done`; fails after [`BUDGET`].
    fn run_until(&mut self, what: &str, mut done: impl FnMut(&mut Self) -> bool) {
        let end = self.sim.now() + BitTime::new(BUDGET);
        while !done(self) {
            assert!(
                self.sim.now() < end,
                "{what}: not within {BUDGET} bit-times; the node: {:?}; its terminal ends:\n{}",
                self.ppc().activity(),
                self.tail()
            );
            self.run(50);
        }
    }

    fn text(&self) -> String {
        String::from_utf8_lossy(&self.terminal).into_owned()
    }

    /// The terminal's last 1500 bytes, for failure messages.
    fn tail(&self) -> String {
        let from = self.terminal.len().saturating_sub(1500);
        String::from_utf8_lossy(&self.terminal[from..]).into_owned()
    }

    /// Frames the supervisor received, as `123#CAFE`.
    fn host_received(&self) -> Vec<String> {
        self.records
            .iter()
            .filter_map(|h| match h {
                Happening::Node {
                    node: HOST,
                    event: Event::Received(f),
                } => Some(f.to_string()),
                _ => None,
            })
            .collect()
    }

    /// The supervisor sends `frame` and waits until it is on the wire.
    fn send(&mut self, frame: Frame) {
        self.sim.enqueue(HOST, frame).unwrap();
        self.run_until("the supervisor's frame", |l| {
            l.records.iter().any(|h| {
                matches!(h, Happening::Node { node: HOST, event: Event::Transmitted(sent) } if *sent == frame)
            })
        });
    }

    /// JerryCAN's "send a program": the remote frame on ID 0, the loader's answer, the file;
    /// then waits until the loader has jumped to the program.
    fn load(&mut self, text: &[u8]) {
        let id = Id::standard(0).unwrap();
        self.records.clear();
        self.sim
            .enqueue(HOST, Frame::remote(id, 0).unwrap())
            .unwrap();
        self.run_until("the loader's answer", |l| {
            l.host_received().iter().any(|f| f == "000#")
        });
        for f in buslab_can::file::frames(id, text) {
            self.records.clear();
            self.send(f);
        }
        self.records.clear();
        self.run_until("the jump to the program", |l| l.ppc().last_load().is_some());
        let load = self.ppc().last_load().unwrap().clone();
        assert!(load.loaded, "{:?}", load.report);
    }

    fn activity(&mut self) -> Activity {
        self.ppc().activity()
    }
}

/// (a) `sja_init_pelican` as the seed writes it (reset mode, PeliCAN, accept all, the bit
/// timing, OCR 0xDB, normal mode), then `send_trame`: the supervisor receives the frame.
#[test]
fn the_seeds_sja_init_pelican_then_a_frame_the_supervisor_receives() {
    let mut lab = Lab::new(&[]);
    let frame: Frame = "123#CAFE".parse().unwrap();
    let program = asm::assemble(
        &format!(
            "_start:\n\tbl sja_init_pelican\n{}\tbl send_trame\nforever:\n\tb forever\n",
            asm::frame_registers(&frame)
        ),
        btr(),
    );
    lab.load(&program);
    lab.run_until("the program's frame", |l| {
        l.host_received().contains(&"123#CAFE".to_string())
    });
    let chip = lab.ppc().chip();
    assert_eq!(chip.mode(), buslab_sja1000::CanMode::Peli);
    assert!(!chip.in_reset_mode());
    assert_eq!(chip.peek(8), 0xDB, "OCR");
    assert_eq!(chip.bit_timing().registers(), btr());
    assert!(matches!(lab.activity(), Activity::Running { .. }));
    assert!(
        lab.text().contains("*** CAN loader (loadcan) ***"),
        "the load's report first"
    );
}

/// The seed's own bit timing (BTR0 0x07, BTR1 0x4D: 20 µs bits, its 50 kbit/s bus) is not
/// this 125 kbit/s bus: the chip samples at the wrong instants, its frame never arrives and
/// its error counter climbs (the right timing's frame came within a few thousand bit-times).
#[test]
fn a_program_with_another_buss_bit_timing_is_not_on_this_one() {
    let mut lab = Lab::new(&[]);
    let frame: Frame = "123#CAFE".parse().unwrap();
    let program = asm::assemble(
        &format!(
            "_start:\n\tbl sja_init_pelican\n{}\tbl send_trame\nforever:\n\tb forever\n",
            asm::frame_registers(&frame)
        ),
        (0x07, 0x4D),
    );
    lab.load(&program);
    lab.run(100_000);
    assert!(
        !lab.host_received().contains(&"123#CAFE".to_string()),
        "{:?}",
        lab.host_received()
    );
    let chip = lab.ppc().chip();
    assert_eq!(chip.bit_timing().registers(), (0x07, 0x4D));
    assert_ne!(
        chip.error_state(),
        buslab_can::controller::ErrorState::Active,
        "TXERR {}",
        buslab_can::node::BusNode::tec(chip)
    );
}

/// (b) A program that sends every frame it receives back with the next identifier.
#[test]
fn a_program_echoes_the_frames_it_receives() {
    let mut lab = Lab::new(&[]);
    let program = asm::assemble(
        "_start:\n\tbl sja_init_pelican\nloop:\n\tbl receive_trame\n\tcmpwi r6,0\n\tbeq loop\n\
         \taddi r3,r3,0x20\n\tbl send_trame\n\tb loop\n",
        btr(),
    );
    lab.load(&program);
    // The program has taken the chip once it is out of reset mode in PeliCAN.
    lab.run_until("the chip initialised", |l| {
        let chip = l.ppc().chip();
        chip.mode() == buslab_sja1000::CanMode::Peli && !chip.in_reset_mode()
    });
    for (sent, echo) in [
        ("200#0102030405060708", "201#0102030405060708"),
        ("7F0#AB", "7F1#AB"),
        ("05A#", "05B#"),
    ] {
        lab.records.clear();
        lab.send(sent.parse().unwrap());
        lab.run_until(&format!("the echo of {sent}"), |l| {
            l.host_received().contains(&echo.to_string())
        });
    }
}

/// (b') The same echo driven by the SJA1000's interrupt: the program's own vectors at EVPR
/// 0x00030000, the external interrupt (INT0, the card's INT) enabled in EXIER and MSR[EE];
/// the handler reads the frame (which lowers INT), sends it back on the next identifier,
/// counts it at 0x37000, clears EXISR and returns; the main loop waits with MSR[WE].
#[test]
fn an_interrupt_driven_program_echoes_the_frames_it_receives() {
    let mut lab = Lab::new(&[]);
    let program = r#"
_start:
	b     main
	.org  0x500
external:
	stwu  r1,-32(r1)
	stw   r0,8(r1)
	mflr  r0
	stw   r0,12(r1)
	stw   r3,16(r1)
	stw   r4,20(r1)
	stw   r5,24(r1)
	stw   r6,28(r1)
	bl    receive_trame
	cmpwi r6,0
	beq   done
	addi  r3,r3,0x20
	bl    send_trame
	lis   r7,0x0003
	lwz   r8,0x7000(r7)
	addi  r8,r8,1
	stw   r8,0x7000(r7)
done:
	li    r0,0x10
	mtdcr 0x40,r0
	lwz   r6,28(r1)
	lwz   r5,24(r1)
	lwz   r4,20(r1)
	lwz   r3,16(r1)
	lwz   r0,12(r1)
	mtlr  r0
	lwz   r0,8(r1)
	addi  r1,r1,32
	rfi
main:
	bl    sja_init_pelican
	wrsjai 0x01,INTERRUPT_ENABLE
	lis   r9,0x0003
	mtspr 982,r9
	li    r9,0x10
	mtdcr 0x42,r9
	lis   r9,0x0004
	ori   r9,r9,0x8000
wait:
	mtmsr r9
	b     wait
"#;
    lab.load(&asm::assemble_at(program, btr(), 0x30000));
    lab.run_until("the chip's interrupt enabled", |l| {
        l.ppc().chip().peek(4) == 0x01
    });
    for (sent, echo) in [
        ("200#0102030405060708", "201#0102030405060708"),
        ("7F0#AB", "7F1#AB"),
    ] {
        lab.records.clear();
        lab.send(sent.parse().unwrap());
        lab.run_until(&format!("the echo of {sent}"), |l| {
            l.host_received().contains(&echo.to_string())
        });
    }
    lab.run(1000);
    assert!(matches!(lab.activity(), Activity::Running { .. }));
    // The handler's count of echoes, at 0x37000.
    let count = lab.ppc().ram(0x37000, 4).unwrap();
    assert_eq!(
        u32::from_be_bytes(count.try_into().unwrap()),
        2,
        "one echo a frame"
    );
}

/// (c) The seed's `calibration_slio`, then OUTPUT_ENABLE and DATA_OUTPUT written to SLIO 3
/// (the frames of `make_slio_ffi` and `wr_reg_slio`): its P7 LED lights, and stays lit while
/// the program keeps calibrating (the SLIO's watchdog is 8192 bit-times).
#[test]
fn a_program_calibrates_the_slio_boards_and_lights_a_led() {
    let mut lab = Lab::new(&[3, 10]);
    let slio = SlioId::new(3).unwrap();
    let write = |register, value| {
        asm::frame_registers(&Request::Write { register, value }.frame(slio).unwrap())
    };
    let program = asm::assemble(
        &format!(
            "_start:\n\tbl sja_init_pelican\n\tbl calibration_slio\n{}\tbl send_trame\n{}\tbl send_trame\n\
             keep:\n\tlis r7,1\n\tmtctr r7\ndelay:\n\tbdnz delay\n\
             tbs:\n\trdsja STATUS,r3\n\tandi. r3,r3,0x04\n\tbeq tbs\n\tbl send_calibration\n\tb keep\n",
            write(Register::OutputEnable, buslab_slio::board::OUTPUT_ENABLE),
            write(Register::DataOutput, 0x2080),
        ),
        btr(),
    );
    lab.load(&program);
    lab.run_until("SLIO 3's LED on P7", |l| l.board(3).leds()[0]);
    assert_eq!(lab.board(3).leds(), [true, false, false, false, false]);
    assert_eq!(lab.board(10).leds(), [false; 5], "only SLIO 3 was written");
    // Four watchdog periods later, still lit: the program's calibrations keep it.
    for _ in 0..4 {
        lab.run(8192);
        assert!(lab.board(3).leds()[0], "the LED went out");
    }
}

const SPU_TEXT: &str = r#"
_start:
	lis   r9,0x4000
	lis   r10,spu_text@ha
	addi  r10,r10,spu_text@l
next:
	lbz   r11,0(r10)
	cmpwi r11,0
	beq   done
wait_tbr:
	lbz   r12,0(r9)
	andi. r12,r12,0x04
	beq   wait_tbr
	stb   r11,9(r9)
	addi  r10,r10,1
	b     next
done:
	li    r0,4
	li    r3,1
	lis   r4,sc_text@ha
	addi  r4,r4,sc_text@l
	li    r5,sc_end-sc_text
	sc
	mr    r31,r3
	li    r0,1
	li    r3,7
	sc
spu_text:
	.asciz "hello through the SPU\r\n"
sc_text:
	.ascii "hello through sc write\r\n"
sc_end:
"#;

/// (d) Text through the serial port's registers and through the firmware's `write`, then
/// `exit(7)`: MoniCAN comes back with the status.
#[test]
fn text_reaches_the_terminal_through_the_spu_and_sc_write_and_exit_returns_to_monican() {
    let mut lab = Lab::new(&[]);
    lab.load(&asm::assemble(SPU_TEXT, btr()));
    lab.run_until("the exit", |l| {
        l.activity() == Activity::Exited { status: 7 }
    });
    lab.run(100);
    let text = lab.text();
    let spu = text.find("hello through the SPU\r\n").expect(&text);
    let sc = text.find("hello through sc write\r\n").expect(&text);
    assert!(spu < sc, "{text}");
    assert!(text.contains("The program exited with status 7."), "{text}");
    assert_eq!(
        lab.ppc().registers().unwrap().gpr[31],
        24,
        "write returned its length"
    );
    // A key dismisses the page: MoniCAN's own screen.
    lab.ppc().key(b' ');
    lab.run_until("MoniCAN", |l| l.activity() == Activity::MoniCan);
}

/// The serial port sends at its baud rate: 24 characters at 19290 baud take 12.4 ms, so the
/// text is not all there 10 ms after the jump.
#[test]
fn the_spu_text_takes_its_line_time() {
    let mut lab = Lab::new(&[]);
    lab.load(&asm::assemble(SPU_TEXT, btr()));
    let at_jump = lab.terminal.len();
    // 10 ms at 125 kbit/s.
    lab.run(1250);
    let shown = String::from_utf8_lossy(&lab.terminal[at_jump..]).into_owned();
    assert!(
        !shown.contains("hello through the SPU\r\n"),
        "24 characters in under 10 ms: {shown:?}"
    );
    lab.run_until("the whole line", |l| {
        l.text().contains("hello through the SPU\r\n")
    });
}

/// A crash: the terminal shows the report and the registers, `state` says why and where;
/// any key returns to MoniCAN.
fn crashes(source: &str, reason: &str, pc: u32) {
    let mut lab = Lab::new(&[]);
    lab.load(&asm::assemble(source, btr()));
    lab.run_until("the stop", |l| {
        matches!(l.activity(), Activity::Stopped { .. })
    });
    assert_eq!(
        lab.activity(),
        Activity::Stopped {
            reason: reason.to_string(),
            pc
        }
    );
    lab.run(100);
    let text = lab.text();
    assert!(
        text.contains(&format!(
            "*** the program stopped: {reason} at {pc:08X} ***"
        )),
        "{text}"
    );
    assert!(text.contains("r18  75000000  r19  76000000"), "{text}");
    assert!(text.contains(buslab_ppc::node::PRESS_ANY_KEY), "{text}");
    lab.ppc().key(b'x');
    lab.run_until("MoniCAN", |l| l.activity() == Activity::MoniCan);
}

#[test]
fn an_illegal_instruction_stops_the_program_with_a_report() {
    crashes(
        "_start:\n\tnop\n\t.long 0\n",
        "illegal instruction 00000000",
        asm::TEXT + 4,
    );
}

#[test]
fn a_load_where_nothing_answers_stops_the_program_with_a_report() {
    crashes(
        "_start:\n\tlis r3,0x8000\n\tlwz r4,0(r3)\n",
        "machine check: nothing answers at 80000000",
        asm::TEXT + 4,
    );
}

#[test]
fn an_unknown_system_call_stops_the_program() {
    crashes(
        "_start:\n\tli r0,99\n\tsc\n",
        "unknown system call r0=99",
        asm::TEXT + 4,
    );
}

/// A `blr` at the top level returns into the loader in flash (LR at the jump): the firmware
/// takes the board back, r3 is the status.
#[test]
fn a_top_level_blr_returns_to_the_firmware() {
    let mut lab = Lab::new(&[]);
    lab.load(&asm::assemble("_start:\n\tli r3,5\n\tblr\n", btr()));
    lab.run_until("the return", |l| {
        l.activity() == Activity::Exited { status: 5 }
    });
    lab.run(100);
    assert!(
        lab.text()
            .contains("returned to the firmware (blr to FFFE2000) with r3 = 5"),
        "{}",
        lab.text()
    );
}

/// A program that points EVPR at its own memory handles `sc` itself; with the firmware's
/// vectors back, `sc` is the firmware's service again.
#[test]
fn a_program_with_its_own_vectors_handles_its_system_calls() {
    let mut lab = Lab::new(&[]);
    let program = r#"
_start:
	lis   r9,0x0003
	ld32b r10,0x38630001
	stw   r10,0xC00(r9)
	ld32b r10,0x4C000064
	stw   r10,0xC04(r9)
	mtspr 982,r9
	li    r3,41
	sc
	li    r10,0
	mtspr 982,r10
	li    r0,1
	sc
"#;
    lab.load(&asm::assemble(program, btr()));
    lab.run_until("the exit", |l| {
        l.activity() == Activity::Exited { status: 42 }
    });
}

/// `reset` (a power cycle) takes the board from a program that never ends: MoniCAN starts
/// and finds the SLIO board again.
#[test]
fn reset_returns_from_a_running_program_to_monican() {
    let mut lab = Lab::new(&[3]);
    lab.load(&asm::assemble("_start:\n\tb _start\n", btr()));
    lab.run(5000);
    assert_eq!(lab.activity(), Activity::Running { pc: asm::TEXT });
    lab.ppc().reset();
    assert_eq!(lab.activity(), Activity::MoniCan);
    lab.run_until("MoniCAN finds SLIO 3", |l| {
        l.ppc()
            .app()
            .present()
            .any(|s| s == SlioId::new(3).unwrap())
    });
}
