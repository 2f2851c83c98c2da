//! `buslab lab` as a new user meets it (issue 26): a status line that stays on one row of an
//! 80-column terminal, and a banner whose commands reach this lab's bus when pasted, even when
//! another server holds socketcand's port.

#[path = "support/pty_program.rs"]
mod pty_program;

use std::io::{BufRead, BufReader, Write};
use std::net::{TcpListener, TcpStream};
use std::process::{Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use assert_cmd::cargo::CommandCargoExt;
use pty_program::{CEILING, PtyProgram, Stderr};

fn buslab() -> Command {
    Command::cargo_bin("buslab").unwrap()
}

/// socketcand's port, the lab's first choice.
const SOCKETCAND_PORT: u16 = 29536;

/// What the lab writes to refresh its status line in place.
const REFRESH: &str = "\r\x1b[2K";

#[test]
fn lab_status_line_stays_on_one_row_of_an_80_column_terminal() {
    let mut command = buslab();
    command.args(["lab", "--no-devices", "--no-web", "--listen", "127.0.0.1:0"]);
    let mut lab = PtyProgram::spawn(command, 24, 80, Stderr::Terminal);
    let refreshes = |p: &PtyProgram| String::from_utf8_lossy(&p.raw).matches(REFRESH).count();
    lab.wait_until("a status line", |p| refreshes(p) >= 1);
    // A warning while the status shows (a client that leaves in the middle of a command) is
    // a line of its own, not glued to the status.
    let url = lab
        .contents()
        .split_whitespace()
        .find(|w| w.starts_with("socketcand://"))
        .map(|u| u.trim_start_matches("socketcand://").to_string())
        .unwrap();
    let addr = url.split('/').next().unwrap().to_string();
    let mut client = TcpStream::connect(&addr).unwrap();
    client.write_all(b"< open vcan0 >< send 1").unwrap();
    drop(client);
    lab.wait_for_text("closed in the middle of an element");
    // Three refreshes in place: a line wider than the terminal would have wrapped, and each
    // refresh would have left its first part on the row above.
    let seen = refreshes(&lab);
    lab.wait_until("three more status refreshes", |p| refreshes(p) >= seen + 3);
    let raw = String::from_utf8_lossy(&lab.raw).to_string();
    // Every status as drawn (the erase sequence also comes before each log line).
    for status in raw.split(REFRESH).skip(1) {
        let line = status.split(['\r', '\n']).next().unwrap();
        if !line.contains("frames/s") {
            continue;
        }
        assert!(
            line.chars().count() < 80,
            "{} columns: {line:?}",
            line.chars().count()
        );
    }
    // The screen between two updates: one status row, under the warning.
    lab.wait_for_contents("one status row", |t| {
        t.lines().filter(|r| r.contains("frames/s")).count() == 1
    });
    let rows = lab.contents();
    let status_rows: Vec<&str> = rows.lines().filter(|r| r.contains("frames/s")).collect();
    assert_eq!(status_rows.len(), 1, "the screen:\n{rows}");
    let warning = rows
        .lines()
        .find(|r| r.contains("closed in the middle of an element"))
        .unwrap();
    assert!(
        warning.contains("WARN") && !warning.contains("frames/s"),
        "{rows}"
    );
    assert_eq!(
        rows.lines().rfind(|r| !r.trim().is_empty()),
        Some(status_rows[0]),
        "the status is the last row:\n{rows}"
    );
    assert!(status_rows[0].starts_with("load "), "{}", status_rows[0]);
    assert!(status_rows[0].contains(" client"), "{}", status_rows[0]);
}

#[test]
fn lab_hints_name_its_bus_when_the_usual_port_is_taken() {
    // Another server on socketcand's port, held by this test for its whole run. A test beside
    // this one (a lab of its own) may hold it now and let it go at any moment, so wait until it
    // is ours: taking "already held" as "taken" let the lab get the port when the other one
    // stopped in between (CI saw the lab on 29536).
    let start = Instant::now();
    let other = loop {
        match TcpListener::bind(("127.0.0.1", SOCKETCAND_PORT)) {
            Ok(listener) => break listener,
            Err(e) => assert!(
                start.elapsed() < CEILING,
                "port {SOCKETCAND_PORT} stayed taken by another test: {e}"
            ),
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let dir = tempfile::tempdir().unwrap();
    let mut lab = buslab()
        .args(["lab", "--no-devices", "--no-web", "--dir"])
        .arg(dir.path())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let stderr = lab.stderr.take().unwrap();
    let (tx, lines) = mpsc::channel();
    std::thread::spawn(move || {
        for line in BufReader::new(stderr).lines().map_while(Result::ok) {
            if tx.send(line).is_err() {
                break;
            }
        }
    });
    let mut banner = Vec::new();
    while banner.last().is_none_or(|l: &String| l != "Ctrl-C to stop") {
        let line = lines
            .recv_timeout(CEILING)
            .unwrap_or_else(|_| panic!("the banner did not end: {banner:#?}"));
        banner.push(line);
    }
    let text = banner.join("\n");
    let url = text
        .split_whitespace()
        .find(|w| w.starts_with("socketcand://"))
        .unwrap()
        .to_string();
    assert!(!url.contains(":29536/"), "{text}");
    assert!(text.contains("port 29536 is taken"), "{text}");
    // The lab's bus for scripts, once the lab is up.
    let written = std::fs::read_to_string(dir.path().join("bus")).unwrap();
    assert_eq!(written.trim_end(), url);

    // The SLIO hint, run as printed, lists the lab's boards.
    let hint = banner
        .iter()
        .find_map(|l| l.split_once("try: ").filter(|_| l.contains("SLIO boards")))
        .map(|(_, hint)| hint.trim_end_matches(')').to_string())
        .unwrap_or_else(|| panic!("no SLIO hint:\n{text}"));
    assert!(hint.contains(&format!("--bus {url}")), "{hint}");
    let words: Vec<&str> = hint.split_whitespace().collect();
    let out = Command::new(words[0]).args(&words[1..]).output().unwrap();
    let listed = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success() && listed.contains("SLIO 3:") && listed.contains("SLIO A:"),
        "{hint}: {listed}{}",
        String::from_utf8_lossy(&out.stderr)
    );

    // A stopped lab takes its URL away (the next script must not reach whatever takes the port).
    let killed = Command::new("kill")
        .args(["-TERM", &lab.id().to_string()])
        .status()
        .unwrap();
    assert!(killed.success());
    assert!(lab.wait().unwrap().success());
    assert!(!dir.path().join("bus").exists());
    drop(other);
}
