//! `buslab monitor` on a pseudo-terminal, its screen read by an independent VT100 emulator
//! (the `vt100` crate): the per-ID table and the nodes of a virtual bus, pause, a filter, and
//! the terminal given back in its normal mode.

mod bus_common;
#[path = "support/pty_program.rs"]
mod pty_program;

use std::process::Command;

use bus_common::Serve;
use pty_program::{PtyProgram, Stderr};

const ROWS: u16 = 30;
const COLS: u16 = 110;

/// `buslab monitor` on a pseudo-terminal of ROWS × COLS.
fn monitor(url: &str) -> PtyProgram {
    let mut command = Command::new(env!("CARGO_BIN_EXE_buslab"));
    command
        .args(["-q", "monitor", "--bus", url])
        .env_remove("BUSLAB_BUS");
    PtyProgram::spawn(command, ROWS, COLS, Stderr::Null)
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
