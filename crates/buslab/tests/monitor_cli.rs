//! `buslab monitor` on a pseudo-terminal, its screen read by an independent VT100 emulator
//! (the `vt100` crate): the per-ID table and the nodes of a virtual bus, pause, a filter, and
//! the terminal given back in its normal mode; with `--dbc`, the lab's traffic as named
//! signals, a changing value highlighted and a constant one not.

mod bus_common;
#[path = "support/pty_program.rs"]
mod pty_program;

use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::Instant;

use bus_common::Serve;
use pty_program::{PtyProgram, Stderr};

const ROWS: u16 = 30;
const COLS: u16 = 110;

/// `buslab monitor` on a pseudo-terminal of ROWS × COLS.
fn monitor(url: &str) -> PtyProgram {
    monitor_with(url, &[], Stderr::Null, ROWS)
}

fn monitor_with(url: &str, extra: &[&str], stderr: Stderr, rows: u16) -> PtyProgram {
    let mut command = Command::new(env!("CARGO_BIN_EXE_buslab"));
    command
        .args(["-q", "monitor", "--bus", url])
        .args(extra)
        .env_remove("BUSLAB_BUS");
    PtyProgram::spawn(command, rows, COLS, stderr)
}

#[test]
fn the_monitor_shows_ids_nodes_and_frames_and_gives_the_terminal_back() {
    let dir = tempfile::tempdir().unwrap();
    let scenario = dir.path().join("nodes.toml");
    std::fs::write(
        &scenario,
        "bitrate = 125000\n[[nodes]]\nname = \"engine\"\n  [[nodes.traffic]]\n  kind = \"periodic\"\n  frame = \"0C0#0FA0\"\n  period = \"10ms\"\n  start = \"1ms\"\n[[nodes]]\nname = \"body\"\n  [[nodes.traffic]]\n  kind = \"periodic\"\n  frame = \"18FF0010#A5\"\n  period = \"50ms\"\n  start = \"2ms\"\n",
    )
    .unwrap();
    let serve = Serve::start_with(125_000, &["--nodes", scenario.to_str().unwrap()]);
    let mut s = monitor(&serve.url);
    s.wait_for_contents("the per-ID table and the nodes", |t| {
        t.contains("0C0")
            && t.contains("18FF0010")
            && t.contains("engine")
            && t.contains("error-active")
    });
    assert!(s.contents().contains("0F A0"), "{}", s.contents());
    // A filter keeps the log to one ID.
    s.type_keys("f18FF0010\r");
    s.wait_for_contents("the filter", |t| t.contains("frames (filtered)"));
    s.wait_for_contents("only 18FF0010 in the log", |t| {
        let log: Vec<&str> = t.lines().filter(|l| l.contains('#')).collect();
        !log.is_empty() && log.iter().all(|l| l.contains("18FF0010#A5"))
    });
    s.type_keys("p");
    s.wait_for_contents("pause", |t| t.contains("PAUSED"));
    s.type_keys("q");
    let status = s.wait_exit();
    assert!(status.success(), "{status}");
    assert!(s.cooked(), "the terminal is left in raw mode");
}

struct Kill(Child);

impl Drop for Kill {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// `buslab lab` with its folder `dir` (bus URL in DIR/bus, its DBC in DIR/lab.dbc), without
/// devices or web pages; returns it and its bus's URL once DIR/bus is written.
fn start_lab(dir: &Path) -> (Kill, String) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_buslab"))
        .args([
            "-q",
            "lab",
            "--no-devices",
            "--no-web",
            "--listen",
            "127.0.0.1:0",
        ])
        .arg("--dir")
        .arg(dir)
        .env_remove("BUSLAB_BUS")
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let stderr = BufReader::new(child.stderr.take().unwrap());
    let lab = Kill(child);
    // The banner goes on being read so the lab never blocks on a full pipe; the bus file is
    // written once everything is up, the banner before it.
    std::thread::spawn(move || stderr.lines().for_each(drop));
    let bus_file = dir.join("bus");
    let start = Instant::now();
    let url = loop {
        if let Ok(text) = std::fs::read_to_string(&bus_file)
            && text.ends_with('\n')
        {
            break text.trim().to_string();
        }
        assert!(
            start.elapsed() < pty_program::CEILING,
            "the lab never wrote {}",
            bus_file.display()
        );
        std::thread::sleep(std::time::Duration::from_millis(20));
    };
    (lab, url)
}

/// The value after the signal `name` on the screen, and how it is shown: (text, inverted
/// (highlighted), dimmed); `None` while no row shows the signal.
fn value(p: &PtyProgram, name: &str) -> Option<(String, bool, bool)> {
    let screen = p.screen.screen();
    let (rows, _) = screen.size();
    let label = format!(" {name} ");
    for row in 1..=rows {
        let text = p.row(row as u8);
        // A signal's row: its name first (the ID column is blank).
        if text.trim_start_matches('│').split_whitespace().next() != Some(name) {
            continue;
        }
        let Some(at) = text.find(&label) else {
            continue;
        };
        // The value: from the first character after the name and its padding to the next
        // run of blanks (the panel's border at the latest).
        let after = at + label.len();
        let rest = &text[after..];
        let offset = rest.find(|c: char| c != ' ')?;
        let value = rest[offset..]
            .split("  ")
            .next()?
            .trim_end_matches('│')
            .trim();
        let cell = screen.cell(row - 1, (after + offset) as u16)?;
        return Some((value.to_string(), cell.inverse(), cell.dim()));
    }
    None
}

/// Whether the log shows a frame from SLIO A (395) about register `register` (the low
/// digit of its first byte).
fn reply_in_log(screen: &str, register: char) -> bool {
    screen.lines().any(|l| {
        l.split("395#")
            .nth(1)
            .is_some_and(|data| data.chars().nth(1) == Some(register))
    })
}

/// Waits until MoniCAN has initialised SLIO A (P13 high: its input switches selected), as
/// `buslab slio read` tells: its later writes would undo the test's.
fn wait_for_slio_a(url: &str) {
    let start = Instant::now();
    loop {
        let out = Command::new(env!("CARGO_BIN_EXE_buslab"))
            .args(["-q", "slio", "--bus", url, "read", "A", "DATA_INPUT"])
            .env_remove("BUSLAB_BUS")
            .output()
            .unwrap();
        let text = String::from_utf8_lossy(&out.stdout).to_string();
        let inputs = text
            .trim()
            .rsplit("0x")
            .next()
            .and_then(|hex| u16::from_str_radix(hex, 16).ok());
        if inputs.is_some_and(|v| v & 1 << 13 != 0) {
            return;
        }
        assert!(
            start.elapsed() < pty_program::CEILING,
            "SLIO A was never initialised: {text}"
        );
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
}

#[test]
fn the_lab_then_the_monitor_with_its_dbc_shows_named_signals_and_highlights_what_changes() {
    let dir = tempfile::tempdir().unwrap();
    let lab_dir = dir.path().join("lab");
    let (_lab, url) = start_lab(&lab_dir);
    wait_for_slio_a(&url);
    let dbc = lab_dir.join("lab.dbc");
    // Rows enough for a SLIO's register file: 16 pins and the ADC under its status.
    let mut s = monitor_with(&url, &["--dbc", dbc.to_str().unwrap()], Stderr::Null, 50);
    s.wait_for_contents("the lab's traffic as signals", |t| {
        [
            "Brakes",
            "BrakePressure",
            "32.0 bar",
            "SlioCalibration",
            "Engine",
            "EngineSpeed",
            "4000 rpm",
            "60 km/h",
            "Counter",
            "Dash",
            "TripDistance",
            "5422.8 km",
        ]
        .iter()
        .all(|w| t.contains(w))
    });
    // The counter counts in every frame: its value is highlighted whenever it is drawn; the
    // engine's is the same in every frame and never is.
    s.wait_until("the counter highlighted", |p| {
        value(p, "Count").is_some_and(|(_, inverse, _)| inverse)
    });
    let engine = value(&s, "EngineSpeed").unwrap();
    assert_eq!(
        engine,
        ("4000 rpm".to_string(), false, false),
        "{}",
        s.contents()
    );
    let count = |p: &PtyProgram| value(p, "Count").and_then(|(v, _, _)| v.parse::<u64>().ok());
    s.wait_until("a count", |p| count(p).is_some());
    let first = count(&s).unwrap();
    s.wait_until("the count rising", |p| count(p).is_some_and(|c| c > first));

    // SLIO A's LED P9 from the monitor (DATA_OUTPUT 0x2200: P13 keeps the input switches),
    // then a conversion of ADC1: its replies read as the register file, the outputs dimmed
    // once the last reply is the ADC's. The log shows SLIO A's replies only.
    s.type_keys("f395\r");
    s.wait_for_text("frames (filtered)");
    s.type_keys("s394#032200\r");
    s.wait_for_contents("SLIO A's DATA_OUTPUT", |t| reply_in_log(t, '3'));
    s.type_keys("s394#0500E0\r");
    s.wait_for_contents("SLIO A's ADC", |t| reply_in_log(t, '8'));
    // The reply at the top of the signals (they are sorted by ID).
    while !s.row(4).contains("SLIOA_Reply") {
        let title = s.row(2);
        s.type_keys("j");
        s.wait_until("the next message at the top", |p| p.row(2) != title);
    }
    s.wait_until("SLIO A's register file", |p| {
        value(p, "ADC").is_some_and(|(v, _, dim)| v == "1.251 V" && !dim)
    });
    assert_eq!(
        value(&s, "Out_P9_LED").map(|(v, _, dim)| (v, dim)),
        Some(("on".to_string(), true)),
        "{}",
        s.contents()
    );
    assert_eq!(
        value(&s, "Out_P13_Select").map(|(v, _, dim)| (v, dim)),
        Some(("input switches".to_string(), true)),
    );
    assert_eq!(
        value(&s, "Register").map(|(v, _, _)| v),
        Some("ADC".to_string())
    );
    // The bytes again.
    s.type_keys("d");
    s.wait_for_contents("the per-ID table", |t| {
        t.contains("per ID (d: signals)") && t.contains("0F A0")
    });
    s.type_keys("q");
    let status = s.wait_exit();
    assert!(status.success(), "{status}");
    assert!(s.cooked(), "the terminal is left in raw mode");
}

#[test]
fn a_dbc_file_that_is_no_database_is_named_with_its_line() {
    let dir = tempfile::tempdir().unwrap();
    let dbc = dir.path().join("garbage.dbc");
    std::fs::write(
        &dbc,
        "VERSION \"\"\n\nBO_ 123 Engine: 8 ECU\n SG_ Speed : x|16@1+\n",
    )
    .unwrap();
    let serve = Serve::start(125_000);
    let mut s = monitor_with(
        &serve.url,
        &["--dbc", dbc.to_str().unwrap()],
        Stderr::Terminal,
        ROWS,
    );
    let status = s.wait_exit();
    assert!(!status.success());
    let text = s.contents();
    assert!(
        text.contains("garbage.dbc") && text.contains("line 4"),
        "{text}"
    );
    assert!(s.cooked(), "the terminal is left in raw mode");
}
