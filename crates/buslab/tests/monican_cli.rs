//! `buslab monican` in a terminal: a pseudo-terminal driven by the test, its screen read back
//! by an independent VT100 emulator (the `vt100` crate), against a virtual bus the test
//! builds with three SLIO demo boards on it.

#[path = "support/pty_program.rs"]
mod pty_program;

use std::process::Command;

use assert_cmd::cargo::CommandCargoExt;
use buslab_can::BitTime;
use buslab_can::controller::Event;
use buslab_monican::layout::*;
use buslab_sim::{Happening, RecordedEvents, Simulation};
use buslab_slio::board::volts_to_code;
use buslab_slio::{DemoBoard, Direction, SlioId};
use buslab_vbus::server::{ServerConfig, ServerHandle, spawn};
use pty_program::{PtyProgram, Stderr};

const RATE: u32 = 125_000;
/// The bus: a virtual bus server whose engine carries demo boards 0, 3 and A (potentiometer
/// at 2.5 V, ADC1 at 1 V; input switches 0, 5, F), nothing else: MoniCAN alone with the SLIOs,
/// as on the seed's bench (its unacknowledged calibration frames are aborted).
fn bus() -> ServerHandle {
    let mut sim = Simulation::new(RATE, 3);
    for (id, switches) in [(0x0, 0x0), (0x3, 0x5), (0xA, 0xF)] {
        let mut board =
            DemoBoard::new(SlioId::new(id).unwrap(), RATE, Box::new(1.0), Box::new(2.5)).unwrap();
        board.set_switches(BitTime::ZERO, switches);
        sim.add_device(format!("slio{id:X}"), Box::new(board));
    }
    let mut config = ServerConfig::new("127.0.0.1:0".parse().unwrap(), RATE);
    config.scenario = Some(sim);
    // A quarter of real time: MoniCAN here runs on the wall clock (a calibration frame every
    // 5000 bit-times of real time), the SLIOs' watchdog on bus time (8192 bit-times); on a
    // loaded machine the host may stall longer than the difference at full speed, and the
    // SLIOs then rightly lose their calibration. At a quarter the margin is 262 ms.
    config.speed = buslab_vbus::Speed::Times(0.25);
    spawn(config).unwrap()
}

/// The boards' calibration and registers, and every node's status, as the server sees them.
fn diagnose(server: &ServerHandle) -> String {
    server
        .with_bus(|bus| {
            let mut out = String::new();
            for node in bus.nodes() {
                let i = bus
                    .index(&buslab_canbus::NodeRef::Number(node.number))
                    .unwrap();
                if let Some(board) = bus.sim().node(i).get::<DemoBoard>() {
                    let slio = board.slio();
                    out += &format!("{}: {:?} {:?}\n", node.name, slio.calibration(), slio);
                } else if let Ok(st) = bus.status(&buslab_canbus::NodeRef::Number(node.number)) {
                    out += &format!("{st}\n");
                }
            }
            out
        })
        .unwrap_or_default()
}

/// `buslab monican` on a pseudo-terminal of 24 × 80.
fn monican(server: &ServerHandle) -> PtyProgram {
    let url = format!("socketcand://{}/vcan0", server.local_addr());
    let mut command = Command::cargo_bin("buslab").unwrap();
    command.args(["-q", "monican", "--bus", &url]);
    PtyProgram::spawn(command, 24, 80, Stderr::Inherit)
}

/// `len` cells of a SLIO's row, from column `col`.
fn slio_cell(s: &PtyProgram, id: u8, col: u8, len: u8) -> String {
    s.cells(slio_row(SlioId::new(id).unwrap()), col, len)
}

fn initialised(s: &PtyProgram) -> bool {
    [0x0, 0x3, 0xA].iter().all(|&id| {
        slio_cell(s, id, MARK_COL, 1) == "*"
            && slio_cell(s, id, OUTPUTS_COL, 4) == "2000"
            && slio_cell(s, id, INPUTS_COL, 1) == "2"
            && slio_cell(s, id, DPM2_COL, 2) == "00"
    })
}

#[test]
fn monican_in_a_terminal_finds_the_boards_lights_an_led_and_reads_the_potentiometer() {
    let server = std::sync::Arc::new(bus());
    let mut s = monican(&server);
    let handle = server.clone();
    s.diagnose = Box::new(move || diagnose(&handle));
    s.wait_until("the three boards, initialised", initialised);
    assert!(!s.cooked(), "raw mode while MoniCAN runs");
    assert_eq!(s.row(TITLE_ROW), TITLE);
    assert_eq!(s.row(HEADER_ROW), HEADER);
    assert_eq!(slio_cell(&s, 0x3, INPUTS_COL, 4), "2005");
    assert_eq!(slio_cell(&s, 0xA, INPUTS_COL, 4), "200F");
    assert_eq!(slio_cell(&s, 0x5, OUTPUTS_COL, 4), "XXXX");
    assert_eq!(
        s.row(COMMAND_ROW),
        "Next command > SLIO:_ I/O:_ PIN:_ VALUE:__"
    );

    s.type_keys("3O7");
    s.wait_until("the command being typed", |s| {
        s.row(COMMAND_ROW) == "Next command > SLIO:3 I/O:O PIN:7 VALUE:__"
    });
    s.type_keys("01");
    s.wait_until("the LED confirmed by SLIO 3", |s| {
        slio_cell(s, 3, OUTPUTS_COL, 4) == "2080"
    });
    assert_eq!(s.row(OUTPUT_LOG_ROW), "ID_slio:3 Data_output:2080");
    let leds = server
        .with_bus(|bus| {
            let sim = bus.sim();
            let i = sim.find_node("slio3").unwrap();
            sim.node(i).get::<DemoBoard>().unwrap().leds()
        })
        .unwrap();
    assert_eq!(leds, [true, false, false, false, false]);

    s.type_keys("3i6");
    let want = format!("{:02X}", volts_to_code(2.5) >> 2);
    s.wait_until("ADC2 of SLIO 3", |s| slio_cell(s, 3, ADC2_COL, 2) == want);
    assert_eq!(
        s.row(INPUT_LOG_ROW),
        format!("ID_slio:3 ADC2:{:04X}", volts_to_code(2.5))
    );

    // Ctrl-Q leaves; the terminal is restored.
    s.type_keys("\x11");
    let status = s.wait_exit();
    assert!(status.success(), "{status}");
    assert!(s.cooked(), "the terminal is back in cooked mode");
    let raw = String::from_utf8_lossy(&s.raw);
    assert!(raw.contains("\x1b[?1049h"), "the alternate screen was used");
    assert!(
        raw.rfind("\x1b[?1049l") > raw.rfind("\x1b[?1049h"),
        "and left at the end"
    );
    drop(s);
    if let Ok(server) = std::sync::Arc::try_unwrap(server) {
        server.shutdown();
    }
}

/// Every frame the engine saw a node send to a SLIO identifier (transmitted or given up).
fn frames_to_slios(server: &ServerHandle) -> Vec<String> {
    server
        .with_bus(|bus| {
            bus.sim_mut()
                .take_records()
                .into_iter()
                .filter_map(|r| match r.what {
                    Happening::Node {
                        event: Event::Transmitted(f) | Event::Dropped(f),
                        ..
                    } if matches!(SlioId::from_id(f.id()), Some((_, Direction::ToSlio))) => {
                        Some(f.to_string())
                    }
                    _ => None,
                })
                .collect()
        })
        .unwrap()
}

/// Issue 25: MoniCAN's input command `3I0` and its start-up read of DATA_INPUT sent `29C#00`,
/// which the model answered and a P82C150 need not: every frame MoniCAN sends a SLIO has 3
/// bytes (seed §2.1.2.1: « toujours 3 octets »; `make_slio_ffi`: DLC = 3), and the SLIOs,
/// which now ignore any other length, answer them.
#[test]
fn monicans_reads_are_three_byte_frames_and_answered() {
    let server = std::sync::Arc::new(bus());
    server
        .with_bus(|bus| bus.sim_mut().set_record_events(RecordedEvents::all()))
        .unwrap();
    let mut s = monican(&server);
    let handle = server.clone();
    s.diagnose = Box::new(move || diagnose(&handle));
    // The start-up read of DATA_INPUT after each sign-on answered: the inputs column.
    s.wait_until("the three boards, initialised", initialised);
    let start_up = frames_to_slios(&server);
    for id in ["284", "29C", "394"] {
        assert!(
            start_up.contains(&format!("{id}#000000")),
            "{id}: {start_up:?}"
        );
    }
    s.type_keys("3I0");
    s.wait_until("SLIO 3's inputs", |s| {
        s.row(INPUT_LOG_ROW) == "ID_slio:3 Data input:2005"
    });
    let command = frames_to_slios(&server);
    assert!(command.contains(&"29C#000000".to_string()), "{command:?}");
    for f in start_up.iter().chain(&command) {
        assert_eq!(f.len(), "29C#000000".len(), "{f} is not a 3-byte frame");
    }
    s.type_keys("\x11");
    assert!(s.wait_exit().success());
    drop(s);
    if let Ok(server) = std::sync::Arc::try_unwrap(server) {
        server.shutdown();
    }
}

#[test]
fn sigterm_restores_the_terminal() {
    let server = bus();
    let mut s = monican(&server);
    s.wait_until("the screen", |s| s.row(HEADER_ROW) == HEADER);
    assert!(!s.cooked());
    let pid = nix::unistd::Pid::from_raw(s.child.id() as i32);
    nix::sys::signal::kill(pid, nix::sys::signal::Signal::SIGTERM).unwrap();
    let status = s.wait_exit();
    assert!(status.success(), "{status}");
    assert!(s.cooked(), "the terminal is back in cooked mode");
    server.shutdown();
}
