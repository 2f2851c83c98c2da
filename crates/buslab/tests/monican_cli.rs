//! `buslab monican` in a terminal: a pseudo-terminal driven by the test, its screen read back
//! by an independent VT100 emulator (the `vt100` crate), against a virtual bus the test
//! builds with three SLIO demo boards on it.

use std::fs::File;
use std::io::{Read, Write};
use std::os::fd::{AsFd, OwnedFd};
use std::process::{Child, Command, Stdio};
use std::sync::mpsc::{self, Receiver};
use std::time::{Duration, Instant};

use assert_cmd::cargo::CommandCargoExt;
use buslab_monican::layout::*;
use buslab_sim::Simulation;
use buslab_slio::board::volts_to_code;
use buslab_slio::{DemoBoard, SlioId};
use buslab_vbus::server::{ServerConfig, ServerHandle, spawn};
use nix::pty::{Winsize, openpty};
use nix::sys::termios::{LocalFlags, tcgetattr};

const RATE: u32 = 125_000;
/// The ceiling for anything the test waits for: it waits for the screen to show something,
/// and this only bounds a failure (CI machines are loaded).
const CEILING: Duration = Duration::from_secs(60);

/// The bus: a virtual bus server whose engine carries demo boards 0, 3 and A (potentiometer
/// at 2.5 V, ADC1 at 1 V; input switches 0, 5, F), nothing else: MoniCAN alone with the SLIOs,
/// as on the seed's bench (its unacknowledged calibration frames are aborted).
fn bus() -> ServerHandle {
    let mut sim = Simulation::new(RATE, 3);
    for (id, switches) in [(0x0, 0x0), (0x3, 0x5), (0xA, 0xF)] {
        let mut board =
            DemoBoard::new(SlioId::new(id).unwrap(), RATE, Box::new(1.0), Box::new(2.5)).unwrap();
        board.set_switches(0, switches);
        sim.add_device(format!("slio{id:X}"), Box::new(board));
    }
    let mut config = ServerConfig::new("127.0.0.1:0".parse().unwrap(), RATE);
    config.scenario = Some(sim);
    // A quarter of real time: MoniCAN here runs on the wall clock (a calibration frame every
    // 5000 bit-times of real time), the SLIOs' watchdog on bus time (8192 bit-times); on a
    // loaded machine the host may stall longer than the difference at full speed, and the
    // SLIOs then rightly lose their calibration. At a quarter the margin is 262 ms.
    config.speed = 0.25;
    spawn(config).unwrap()
}

/// `buslab monican` on a pseudo-terminal of 24 × 80, and what its screen shows.
struct Session {
    child: Child,
    keys: File,
    /// The terminal's side, kept to look at its settings after the program left.
    slave: OwnedFd,
    output: Receiver<Vec<u8>>,
    term: vt100::Parser,
    raw: Vec<u8>,
    /// What the bus looks like, for a failure message.
    diagnose: Box<dyn Fn() -> String>,
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

impl Session {
    fn start(server: &ServerHandle) -> Self {
        let url = format!("socketcand://{}/vcan0", server.local_addr());
        let size = Winsize {
            ws_row: 24,
            ws_col: 80,
            ws_xpixel: 0,
            ws_ypixel: 0,
        };
        let pty = openpty(Some(&size), None).unwrap();
        let child = Command::cargo_bin("buslab")
            .unwrap()
            .args(["-q", "monican", "--bus", &url])
            .stdin(Stdio::from(pty.slave.try_clone().unwrap()))
            .stdout(Stdio::from(pty.slave.try_clone().unwrap()))
            .stderr(Stdio::inherit())
            .spawn()
            .unwrap();
        let mut reader = File::from(pty.master.try_clone().unwrap());
        let (tx, output) = mpsc::channel();
        std::thread::spawn(move || {
            let mut buf = [0u8; 4096];
            // EIO once the program and every copy of the terminal's side are gone.
            while let Ok(n) = reader.read(&mut buf) {
                if n == 0 || tx.send(buf[..n].to_vec()).is_err() {
                    break;
                }
            }
        });
        Self {
            child,
            keys: File::from(pty.master),
            slave: pty.slave,
            output,
            term: vt100::Parser::new(24, 80, 0),
            raw: Vec::new(),
            diagnose: Box::new(String::new),
        }
    }

    fn type_keys(&mut self, keys: &str) {
        self.keys.write_all(keys.as_bytes()).unwrap();
    }

    /// Reads the program's output until `done` holds for the screen.
    fn wait_for(&mut self, what: &str, done: impl Fn(&Self) -> bool) {
        let start = Instant::now();
        while !done(self) {
            let left = CEILING.saturating_sub(start.elapsed());
            match self.output.recv_timeout(left) {
                Ok(bytes) => {
                    self.term.process(&bytes);
                    self.raw.extend_from_slice(&bytes);
                }
                Err(_) => panic!(
                    "{what}: not on the screen within {CEILING:?}\n{}\n{}",
                    self.term.screen().contents(),
                    (self.diagnose)()
                ),
            }
        }
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

    fn slio_cell(&self, id: u8, col: u8, len: u8) -> String {
        self.cells(slio_row(SlioId::new(id).unwrap()), col, len)
    }

    /// Waits for the program to end (the terminal's output drained first).
    fn wait_exit(&mut self) -> std::process::ExitStatus {
        let start = Instant::now();
        loop {
            if let Some(status) = self.child.try_wait().unwrap() {
                while let Ok(bytes) = self.output.recv_timeout(Duration::from_millis(200)) {
                    self.raw.extend_from_slice(&bytes);
                }
                return status;
            }
            assert!(start.elapsed() < CEILING, "buslab monican did not exit");
            if let Ok(bytes) = self.output.recv_timeout(Duration::from_millis(50)) {
                self.term.process(&bytes);
                self.raw.extend_from_slice(&bytes);
            }
        }
    }

    /// Whether the terminal is back in its normal (cooked, echoing) mode.
    fn cooked(&self) -> bool {
        let attrs = tcgetattr(self.slave.as_fd()).unwrap();
        attrs
            .local_flags
            .contains(LocalFlags::ICANON | LocalFlags::ECHO)
    }
}

fn initialised(s: &Session) -> bool {
    [0x0, 0x3, 0xA].iter().all(|&id| {
        s.slio_cell(id, MARK_COL, 1) == "*"
            && s.slio_cell(id, OUTPUTS_COL, 4) == "2000"
            && s.slio_cell(id, INPUTS_COL, 1) == "2"
            && s.slio_cell(id, DPM2_COL, 2) == "00"
    })
}

#[test]
fn monican_in_a_terminal_finds_the_boards_lights_an_led_and_reads_the_potentiometer() {
    let server = std::sync::Arc::new(bus());
    let mut s = Session::start(&server);
    let handle = server.clone();
    s.diagnose = Box::new(move || diagnose(&handle));
    s.wait_for("the three boards, initialised", initialised);
    assert!(!s.cooked(), "raw mode while MoniCAN runs");
    assert_eq!(s.row(TITLE_ROW), TITLE);
    assert_eq!(s.row(HEADER_ROW), HEADER);
    assert_eq!(s.slio_cell(0x3, INPUTS_COL, 4), "2005");
    assert_eq!(s.slio_cell(0xA, INPUTS_COL, 4), "200F");
    assert_eq!(s.slio_cell(0x5, OUTPUTS_COL, 4), "XXXX");
    assert_eq!(
        s.row(COMMAND_ROW),
        "Next command > SLIO:_ I/O:_ PIN:_ VALUE:__"
    );

    s.type_keys("3O7");
    s.wait_for("the command being typed", |s| {
        s.row(COMMAND_ROW) == "Next command > SLIO:3 I/O:O PIN:7 VALUE:__"
    });
    s.type_keys("01");
    s.wait_for("the LED confirmed by SLIO 3", |s| {
        s.slio_cell(3, OUTPUTS_COL, 4) == "2080"
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
    s.wait_for("ADC2 of SLIO 3", |s| s.slio_cell(3, ADC2_COL, 2) == want);
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

#[test]
fn sigterm_restores_the_terminal() {
    let server = bus();
    let mut s = Session::start(&server);
    s.wait_for("the screen", |s| s.row(HEADER_ROW) == HEADER);
    assert!(!s.cooked());
    let pid = nix::unistd::Pid::from_raw(s.child.id() as i32);
    nix::sys::signal::kill(pid, nix::sys::signal::Signal::SIGTERM).unwrap();
    let status = s.wait_exit();
    assert!(status.success(), "{status}");
    assert!(s.cooked(), "the terminal is back in cooked mode");
    server.shutdown();
}
