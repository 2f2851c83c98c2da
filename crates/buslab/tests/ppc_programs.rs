//! Issue 30's acceptance end to end: `buslab lab`, then `buslab load examples/ppc/demo.s37
//! --verify` → the program runs on the PowerPC node's core: its frame received by python-can
//! (socketcand), the LED it lights on demo board A seen on the board (`buslab slio board`),
//! its text on MoniCAN's terminal (the PTY, read by the `vt100` crate), frames echoed, the
//! state and registers on the control socket; `reset` brings MoniCAN back; `--no-run` loads
//! without running. The programs are built here from examples/ppc with the cross binutils
//! (examples/ppc/build.sh).

#[path = "support/vt100_terminal.rs"]
mod vt100_terminal;

#[path = "support/outside_tools.rs"]
mod outside_tools;

#[path = "../../ppc/tests/support/asm.rs"]
mod asm;

use std::io::{BufRead, BufReader, Write};
use std::os::unix::net::UnixStream;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use outside_tools::{python_can, root};
use vt100_terminal::{CEILING, Terminal};

/// A process stopped (SIGTERM) when the test ends.
struct Stopped(Child);

impl Drop for Stopped {
    fn drop(&mut self) {
        let _ = Command::new("kill")
            .args(["-TERM", &self.0.id().to_string()])
            .status();
        let _ = self.0.wait();
    }
}

/// `buslab lab --no-devices` with its files in `dir`, once up; its bus URL.
fn lab(dir: &Path) -> (Stopped, String) {
    let child = Command::new(env!("CARGO_BIN_EXE_buslab"))
        .args([
            "lab",
            "-q",
            "--no-web",
            "--no-devices",
            "--listen",
            "127.0.0.1:0",
            "--dir",
        ])
        .arg(dir)
        .env_remove("BUSLAB_BUS")
        .stdout(Stdio::null())
        .stderr(std::fs::File::create(dir.join("lab.log")).unwrap())
        .spawn()
        .unwrap();
    let lab = Stopped(child);
    let start = Instant::now();
    loop {
        if let Ok(text) = std::fs::read_to_string(dir.join("bus"))
            && text.ends_with('\n')
        {
            return (lab, text.trim().to_string());
        }
        assert!(
            start.elapsed() < CEILING,
            "the lab never wrote its bus file"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// examples/ppc built into `dir` by its build script (the cross binutils; a missing tool
/// fails with the script's message naming scripts/setup-test-deps.sh).
fn build_examples(dir: &Path) -> PathBuf {
    let out = dir.join("examples");
    let run = Command::new(root().join("examples/ppc/build.sh"))
        .arg(&out)
        .output()
        .unwrap();
    assert!(
        run.status.success(),
        "examples/ppc/build.sh failed (scripts/setup-test-deps.sh installs the PowerPC cross binutils):\n{}",
        String::from_utf8_lossy(&run.stderr)
    );
    out
}

/// One command on the node's control socket, its one-line answer.
fn control(socket: &Path, command: &str) -> String {
    let mut stream = UnixStream::connect(socket).unwrap();
    writeln!(stream, "{command}").unwrap();
    let mut line = String::new();
    BufReader::new(stream).read_line(&mut line).unwrap();
    line.trim_end().to_string()
}

fn buslab(args: &[&str]) -> (bool, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_buslab"))
        .args(args)
        .env_remove("BUSLAB_BUS")
        .output()
        .unwrap();
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// python-can on the lab's socketcand: says `ready`, prints the first frame on 0x123, then
/// sends 0x600#C0FFEE and prints the echo on 0x680.
const PEER: &str = r#"
import sys, can
host, port = sys.argv[1], int(sys.argv[2])
bus = can.Bus(interface="socketcand", channel="vcan0", host=host, port=port)
def wait_for(id):
    while True:
        msg = bus.recv(timeout=60)
        if msg is None:
            print("timeout waiting for %03X" % id, flush=True)
            sys.exit(1)
        if msg.arbitration_id == id:
            return msg
try:
    print("ready", flush=True)
    msg = wait_for(0x123)
    print("rx %03X#%s" % (msg.arbitration_id, msg.data.hex().upper()), flush=True)
    sys.stdin.readline()
    bus.send(can.Message(arbitration_id=0x600, data=bytes([0xC0, 0xFF, 0xEE]), is_extended_id=False))
    msg = wait_for(0x680)
    print("echo %03X#%s" % (msg.arbitration_id, msg.data.hex().upper()), flush=True)
finally:
    bus.shutdown()
"#;

#[test]
fn the_demo_program_runs_on_the_labs_powerpc_node() {
    let Some(python) = python_can() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let examples = build_examples(dir.path());
    let (_lab, url) = lab(dir.path());
    let socket = dir.path().join("ppc.sock");
    // The terminal first: the program's text is a stream, shown to a terminal that is open.
    let mut terminal = Terminal::open(&dir.path().join("monican"));
    let address = url
        .strip_prefix("socketcand://")
        .and_then(|rest| rest.split('/').next())
        .unwrap();
    let (host, port) = address.rsplit_once(':').unwrap();
    let mut peer = Command::new(&python)
        .args(["-c", PEER, host, port])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .unwrap();
    let mut peer_in = peer.stdin.take().unwrap();
    let mut lines = BufReader::new(peer.stdout.take().unwrap()).lines();
    let _peer = Stopped(peer);
    let mut next = || lines.next().expect("python-can ended early").unwrap();
    assert_eq!(next(), "ready");

    let demo = examples.join("demo.s37");
    let (ok, _, err) = buslab(&[
        "load",
        demo.to_str().unwrap(),
        "--bus",
        &url,
        "--verify",
        socket.to_str().unwrap(),
    ]);
    assert!(ok, "{err}");
    assert!(
        err.contains("verified: the node's memory holds every byte"),
        "{err}"
    );
    assert!(
        err.contains("the node runs the program: running pc="),
        "{err}"
    );

    // Its frame, received by python-can.
    assert_eq!(next(), "rx 123#505043343033");
    // Its text on MoniCAN's terminal, after the load's report.
    terminal.wait_for_text("*** buslab PowerPC 403 demo (examples/ppc/demo.s) ***");
    // demo.s says so once SLIO A confirmed it; the board shows it, and still a second later
    // (the program keeps the SLIOs calibrated).
    terminal.wait_for_text("SLIO A: LED P7 lit.");
    wait_for_led_p7(&url);
    // A frame on 0x600 comes back on 0x680.
    writeln!(peer_in, "go").unwrap();
    assert_eq!(next(), "echo 680#C0FFEE");
    // The control socket: the state, the registers the loader set.
    let state = control(&socket, "state");
    assert!(state.starts_with("running pc="), "{state}");
    let regs = control(&socket, "regs");
    assert!(regs.contains(" r18=75000000 r19=76000000 "), "{regs}");
    // A key typed on the terminal is the program's: it echoes it.
    terminal.type_keys(b"Z");
    terminal.wait_for_text("Z");
    // A load request now is the program's business: nothing answers, and the tool says why.
    let (ok, _, err) = buslab(&[
        "load",
        examples.join("hello.s37").to_str().unwrap(),
        "--bus",
        &url,
        "--verify",
        socket.to_str().unwrap(),
        "--timeout",
        "1s",
    ]);
    assert!(!ok);
    assert!(err.contains("no loader answered on ID 000"), "{err}");
    assert!(err.contains("a program owns the SJA1000"), "{err}");
    // Reset: MoniCAN again, on the terminal and in the state.
    assert_eq!(control(&socket, "reset"), "reset: MoniCAN started");
    assert_eq!(control(&socket, "state"), "monican");
    terminal.wait_for_text("*** MoniCAN (C) ESIEE 1999 ***");
}

/// `--no-run` sends the file without its entry point: loaded, not run; `hello` run after it
/// exits and MoniCAN comes back with its status.
#[test]
fn no_run_loads_without_running_and_an_exit_returns_to_monican() {
    let dir = tempfile::tempdir().unwrap();
    let examples = build_examples(dir.path());
    let (_lab, url) = lab(dir.path());
    let socket = dir.path().join("ppc.sock");
    let mut terminal = Terminal::open(&dir.path().join("monican"));
    let hello = examples.join("hello.s37");
    let load = |extra: &[&str]| {
        let mut args = vec![
            "load",
            hello.to_str().unwrap(),
            "--bus",
            &url,
            "--verify",
            socket.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        buslab(&args)
    };
    let (ok, _, err) = load(&["--no-run"]);
    assert!(ok, "{err}");
    assert!(err.contains("no entry point: loaded, not run"), "{err}");
    assert!(control(&socket, "load").ends_with("entry=none"));
    assert_eq!(control(&socket, "state"), "monican");
    terminal.wait_for_text("No entry point (S7/S8/S9): the program was loaded, not run.");

    let (ok, _, err) = load(&[]);
    assert!(ok, "{err}");
    assert!(
        err.contains("the node runs the program") || err.contains("which already exited 0"),
        "{err}"
    );
    terminal.wait_for_text("The program exited with status 0.");
    let start = Instant::now();
    while control(&socket, "state") != "exited 0" {
        assert!(
            start.elapsed() < CEILING,
            "state: {}",
            control(&socket, "state")
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    terminal.type_keys(b" ");
    terminal.wait_for_text("*** MoniCAN (C) ESIEE 1999 ***");
    assert_eq!(control(&socket, "state"), "monican");
}

/// The seed's `calibration_slio`, then, every 262144 turns of a `bdnz` loop (about 10 ms), a
/// calibration frame and the two writes to SLIO A: OUTPUT_ENABLE and DATA_OUTPUT (P13 and LED
/// P7). (Written again and again: on the loaded lab some of the 48 calibration frames lose
/// arbitration and are aborted, as the seed's routine does, so the SLIO may still be
/// calibrating when the first writes come.) `buslab slio board A` shows the LED lit, and still
/// lit a second later.
#[test]
fn a_program_lights_a_led_on_the_labs_demo_board() {
    let dir = tempfile::tempdir().unwrap();
    let (_lab, url) = lab(dir.path());
    let socket = dir.path().join("ppc.sock");
    use buslab_slio::registers::{Register, Request};
    let slio = buslab_slio::SlioId::new(0xA).unwrap();
    let write = |register, value| {
        asm::frame_registers(&Request::Write { register, value }.frame(slio).unwrap())
    };
    let source = format!(
        "_start:\n\tbl sja_init_pelican\n\tbl calibration_slio\n\
         keep:\n\tlis r7,4\n\tmtctr r7\ndelay:\n\tbdnz delay\n\
         tbs:\n\trdsja STATUS,r3\n\tandi. r3,r3,0x04\n\tbeq tbs\n\tbl send_calibration\n\
         {}\tbl send_trame\n{}\tbl send_trame\n\tb keep\n",
        write(Register::OutputEnable, 0x3F90),
        write(Register::DataOutput, 0x2080),
    );
    let program = dir.path().join("led.s37");
    let btr = buslab_ppc::slio_timing(125_000).unwrap().registers();
    std::fs::write(&program, asm::assemble(&source, btr)).unwrap();
    let (ok, _, err) = buslab(&[
        "load",
        program.to_str().unwrap(),
        "--bus",
        &url,
        "--verify",
        socket.to_str().unwrap(),
    ]);
    assert!(ok, "{err}");
    wait_for_led_p7(&url);
}

/// LED P7 of demo board A lit, as `buslab slio board A` shows it, and still lit a second
/// later (more than ten times the SLIOs' calibration watchdog at 125 kbit/s: the program keeps
/// them calibrated).
fn wait_for_led_p7(url: &str) {
    let board = || {
        let (ok, out, err) = buslab(&["slio", "board", "A", "--bus", url]);
        assert!(ok, "{err}");
        out
    };
    let start = Instant::now();
    loop {
        let out = board();
        if out.contains("LEDs P7,") {
            break;
        }
        assert!(
            start.elapsed() < CEILING,
            "LED P7 of board A never lit: {out}"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
    std::thread::sleep(Duration::from_secs(1));
    let out = board();
    assert!(out.contains("LEDs P7,"), "the LED went out: {out}");
}
