//! The example programs of examples/zelle/, built here with Debian's as31 and SDCC, loaded
//! into the served cell and shown working with the existing client (issue 27, deliverable 4),
//! and the C example driven by pyserial alone (the acceptance).

#[path = "support/zelle_served.rs"]
mod served;

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

use buslab_zelle::client::{Port, Transfer};
use buslab_zelle::program::image_from_file;
use served::{ALLOWANCE, Served, buslab_zelle as buslab};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// Whether `tool` runs; in CI (which installs it: scripts/setup-test-deps.sh) a missing tool is
/// a failure, elsewhere the test says it was skipped.
fn have(tool: &str) -> bool {
    let found = std::env::var_os("PATH")
        .is_some_and(|path| std::env::split_paths(&path).any(|dir| dir.join(tool).is_file()));
    if !found {
        assert!(std::env::var_os("CI").is_none(), "{tool} is missing in CI");
        eprintln!("SKIPPED: {tool} is missing; run scripts/setup-test-deps.sh");
    }
    found
}

/// Builds `examples/zelle/NAME` in `dir` with as31 (`.asm`) or SDCC (`.c`); the HEX file.
fn build(name: &str, dir: &Path) -> Option<PathBuf> {
    let source = root().join("examples/zelle").join(name);
    std::fs::copy(&source, dir.join(name)).unwrap();
    let (tool, args, out): (&str, Vec<&str>, String) = match name.rsplit_once('.') {
        Some((stem, "asm")) => ("as31", vec![name], format!("{stem}.hex")),
        Some((stem, "c")) => (
            "sdcc",
            vec![
                "-mmcs51",
                "--code-loc",
                "0x400",
                "--code-size",
                "0x400",
                "--iram-size",
                "128",
                name,
            ],
            format!("{stem}.ihx"),
        ),
        _ => panic!("{name}: not .asm or .c"),
    };
    if !have(tool) {
        return None;
    }
    let run = Command::new(tool)
        .args(&args)
        .current_dir(dir)
        .output()
        .unwrap();
    let hex = dir.join(out);
    assert!(
        run.status.success() && hex.exists(),
        "{tool} {name}: {}{}",
        String::from_utf8_lossy(&run.stdout),
        String::from_utf8_lossy(&run.stderr)
    );
    Some(hex)
}

/// P1's latch from the control line `cpu` while the program runs.
fn port1(s: &mut Served) -> Option<u8> {
    let cpu = s.control("cpu");
    let at = cpu.find(" P1=")?;
    u8::from_str_radix(&cpu[at + 4..at + 6], 16).ok()
}

#[test]
fn blink_toggles_the_led_on_p1_0_until_a_0_stops_it() {
    let mut s = Served::start(&[]);
    let Some(hex) = build("blink.asm", s.dir.path()) else {
        return;
    };
    let pty = s.pty.clone();
    assert!(buslab(&pty, &["load", hex.to_str().unwrap()]).starts_with("loaded 26 bytes"));
    buslab(&pty, &["run"]);
    // The LED changes every 100 ms of the cell's time: see it lit and dark, twice each.
    let mut changes = Vec::new();
    let deadline = Instant::now() + ALLOWANCE;
    while changes.len() < 4 {
        if let Some(p1) = port1(&mut s)
            && changes.last() != Some(&(p1 & 1))
        {
            changes.push(p1 & 1);
        }
        assert!(Instant::now() < deadline, "LED levels seen: {changes:?}");
        std::thread::sleep(Duration::from_millis(20));
    }
    buslab(&pty, &["stop"]);
    s.status_until(", ready,");
    assert!(
        s.control("cpu")
            .starts_with("ok program stopped (interrupted by a 0 on RxD)"),
    );
}

#[test]
fn echo_answers_each_byte_plus_one_through_empf_and_sende_and_q_returns_to_the_os() {
    let mut s = Served::start(&[]);
    let Some(hex) = build("echo.asm", s.dir.path()) else {
        return;
    };
    let mut cell = s.client();
    let program = image_from_file(&std::fs::read(&hex).unwrap()).unwrap();
    cell.load_program(&program, Transfer::Pipelined).unwrap();
    cell.run_program().unwrap();
    // One byte at a time, each answer awaited: the program is in Empf when the next comes,
    // where a 0 is data (seed 003). (Bytes sent back to back would reach it inside Sende: the
    // 8051 keeps one received byte, and a 0 held off there stops the program as Sende ends.)
    let sent = [0x41, 0x00, 0x7F, 0xFF];
    let port = cell.port();
    let mut heard = Vec::new();
    for byte in sent {
        port.send(&[byte]).unwrap();
        let mut answer = [0u8; 1];
        let n = port.recv(&mut answer, ALLOWANCE).unwrap();
        assert_eq!(n, 1, "no answer to {byte:#04x}; heard {heard:02X?}");
        heard.push(answer[0]);
    }
    assert_eq!(heard, [0x42, 0x01, 0x80, 0x00]);
    port.send(b"q").unwrap();
    s.status_until(", ready,");
    let cpu = s.control("cpu");
    assert!(
        cpu.starts_with("ok program stopped (returned to the OS)"),
        "{cpu}"
    );
}

#[test]
fn measure_takes_its_own_readings_into_the_data_area() {
    let mut s = Served::start(&["--analog", "1=2.5V"]);
    let Some(hex) = build("measure.c", s.dir.path()) else {
        return;
    };
    let mut cell = s.client();
    let expected = cell.analog(1).unwrap();
    let program = image_from_file(&std::fs::read(&hex).unwrap()).unwrap();
    cell.load_program(&program, Transfer::Pipelined).unwrap();
    cell.run_program().unwrap();
    let mut said = [0u8; 1];
    let n = cell.port().recv(&mut said, ALLOWANCE).unwrap();
    assert_eq!(&said[..n], b"D", "the program's word when done");
    cell.interrupt().unwrap();
    s.status_until(", ready,");
    assert_eq!(cell.peek(0x0800).unwrap(), 16, "the count");
    let values = cell.read_data(8 + 16, Transfer::Pipelined).unwrap();
    assert_eq!(values[8..], [expected; 16]);
}

#[test]
fn pyserial_loads_the_c_example_with_command_5_runs_it_with_6_and_reads_it_back_with_18() {
    let python = root().join(".venv/bin/python");
    if !python.exists() {
        assert!(
            std::env::var_os("CI").is_none(),
            "{} is missing in CI",
            python.display()
        );
        eprintln!("SKIPPED: {} is missing", python.display());
        return;
    }
    let mut s = Served::start(&["--analog", "1=2.5V"]);
    let Some(hex) = build("measure.c", s.dir.path()) else {
        return;
    };
    let expected = s.client().analog(1).unwrap();
    let out = Command::new(&python)
        .arg(root().join("tests/interop/zelle_program.py"))
        .arg(&s.pty)
        .arg(&hex)
        .arg(expected.to_string())
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "pyserial script failed:\n{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(stdout.trim_end().ends_with("ok"), "{stdout}");
    eprintln!("{stdout}");
    assert!(s.status_until(", ready,").contains(", ready,"));
}
