//! `buslab monitor` on a pseudo-terminal, its screen read by an independent VT100 emulator
//! (the `vt100` crate): the per-ID table and the nodes of a virtual bus, pause, a filter, and
//! the terminal given back in its normal mode.

mod bus_common;

use std::fs::File;
use std::io::{Read, Write};
use std::os::fd::{AsFd, OwnedFd};
use std::process::{Child, Command, Stdio};
use std::sync::mpsc::{self, Receiver};
use std::time::{Duration, Instant};

use bus_common::Serve;
use nix::pty::{Winsize, openpty};
use nix::sys::termios::{LocalFlags, tcgetattr};

/// Only a guard against a failure: every wait ends on what the screen shows first.
const CEILING: Duration = Duration::from_secs(120);
const ROWS: u16 = 30;
const COLS: u16 = 110;

struct Session {
    child: Child,
    keys: File,
    slave: OwnedFd,
    output: Receiver<Vec<u8>>,
    term: vt100::Parser,
}

impl Session {
    fn start(url: &str) -> Self {
        let size = Winsize {
            ws_row: ROWS,
            ws_col: COLS,
            ws_xpixel: 0,
            ws_ypixel: 0,
        };
        let pty = openpty(Some(&size), None).unwrap();
        let child = Command::new(env!("CARGO_BIN_EXE_buslab"))
            .args(["-q", "monitor", "--bus", url])
            .env_remove("BUSLAB_BUS")
            .stdin(Stdio::from(pty.slave.try_clone().unwrap()))
            .stdout(Stdio::from(pty.slave.try_clone().unwrap()))
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        let mut reader = File::from(pty.master.try_clone().unwrap());
        let (tx, output) = mpsc::channel();
        std::thread::spawn(move || {
            let mut buf = [0u8; 4096];
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
            term: vt100::Parser::new(ROWS, COLS, 0),
        }
    }

    fn screen(&self) -> String {
        self.term.screen().contents()
    }

    fn wait_for(&mut self, what: &str, done: impl Fn(&str) -> bool) {
        let start = Instant::now();
        while !done(&self.screen()) {
            let left = CEILING.saturating_sub(start.elapsed());
            match self.output.recv_timeout(left) {
                Ok(bytes) => self.term.process(&bytes),
                Err(_) => panic!("{what}: not on the screen\n{}", self.screen()),
            }
        }
    }

    fn type_keys(&mut self, keys: &str) {
        self.keys.write_all(keys.as_bytes()).unwrap();
    }
}

impl Drop for Session {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
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
    let mut s = Session::start(&serve.url);
    s.wait_for("the per-ID table and the nodes", |t| {
        t.contains("0C0")
            && t.contains("18FF0010")
            && t.contains("engine")
            && t.contains("error-active")
    });
    assert!(s.screen().contains("0F A0"), "{}", s.screen());
    // A filter keeps the log to one ID.
    s.type_keys("f18FF0010\r");
    s.wait_for("the filter", |t| t.contains("frames (filtered)"));
    s.wait_for("only 18FF0010 in the log", |t| {
        let log: Vec<&str> = t.lines().filter(|l| l.contains('#')).collect();
        !log.is_empty() && log.iter().all(|l| l.contains("18FF0010#A5"))
    });
    s.type_keys("p");
    s.wait_for("pause", |t| t.contains("PAUSED"));
    s.type_keys("q");
    let start = Instant::now();
    let status = loop {
        if let Some(status) = s.child.try_wait().unwrap() {
            break status;
        }
        assert!(start.elapsed() < CEILING, "buslab monitor did not quit");
        if let Ok(bytes) = s.output.recv_timeout(Duration::from_millis(50)) {
            s.term.process(&bytes);
        }
    };
    assert!(status.success(), "{status}");
    let attrs = tcgetattr(s.slave.as_fd()).unwrap();
    assert!(
        attrs
            .local_flags
            .contains(LocalFlags::ICANON | LocalFlags::ECHO),
        "the terminal is left in raw mode"
    );
}
