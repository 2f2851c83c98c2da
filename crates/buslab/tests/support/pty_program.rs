//! A full-screen `buslab` command (`monican`, `monitor`, `config wizard`) run on a
//! pseudo-terminal driven by the test: keys typed into the terminal's side, the screen read
//! back by an independent VT100 emulator (the `vt100` crate). Every wait ends on what the
//! screen shows; the ceiling only bounds a failure (CI machines are loaded).

use std::fs::File;
use std::io::{Read, Write};
use std::os::fd::AsFd;
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError};
use std::time::{Duration, Instant};

use nix::pty::{Winsize, openpty};
use nix::sys::termios::{LocalFlags, tcgetattr};

pub const CEILING: Duration = Duration::from_secs(120);

/// Where the program's standard error goes.
#[allow(dead_code)] // each test file uses its own
pub enum Stderr {
    /// On the terminal, as a user sees it.
    Terminal,
    /// The test's own standard error.
    Inherit,
    Null,
}

pub struct PtyProgram {
    pub child: Child,
    /// The controlling side: keys go in here, and its settings are the terminal's (Linux
    /// answers `tcgetattr` on a master with its terminal's side).
    keys: File,
    output: Receiver<Vec<u8>>,
    pub screen: vt100::Parser,
    /// Every byte the program wrote, for checks on escape sequences.
    pub raw: Vec<u8>,
    /// More context for a failure message (the bus's state, say).
    pub diagnose: Box<dyn Fn() -> String>,
}

#[allow(dead_code)] // each test file uses its own subset
impl PtyProgram {
    /// Starts `command` on a terminal of `rows` × `cols`.
    /// The test keeps no copy of the terminal's side, so the reader meets the end of the
    /// output when the program and its children are gone.
    pub fn spawn(mut command: Command, rows: u16, cols: u16, stderr: Stderr) -> Self {
        let size = Winsize {
            ws_row: rows,
            ws_col: cols,
            ws_xpixel: 0,
            ws_ypixel: 0,
        };
        let pty = openpty(Some(&size), None).unwrap();
        let stderr = match stderr {
            Stderr::Terminal => Stdio::from(pty.slave.try_clone().unwrap()),
            Stderr::Inherit => Stdio::inherit(),
            Stderr::Null => Stdio::null(),
        };
        let child = command
            .stdin(Stdio::from(pty.slave.try_clone().unwrap()))
            .stdout(Stdio::from(pty.slave.try_clone().unwrap()))
            .stderr(stderr)
            .spawn()
            .unwrap();
        drop(command); // it holds copies of the terminal's side
        drop(pty.slave);
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
            output,
            screen: vt100::Parser::new(rows, cols, 0),
            raw: Vec::new(),
            diagnose: Box::new(String::new),
        }
    }

    pub fn type_keys(&mut self, keys: &str) {
        self.keys.write_all(keys.as_bytes()).unwrap();
    }

    /// The whole screen as text.
    pub fn contents(&self) -> String {
        self.screen.screen().contents()
    }

    /// Row `row` (1-based), without trailing blanks.
    pub fn row(&self, row: u8) -> String {
        let (_, cols) = self.screen.screen().size();
        self.screen
            .screen()
            .rows(0, cols)
            .nth(usize::from(row) - 1)
            .unwrap_or_default()
            .trim_end()
            .to_string()
    }

    /// `len` cells from row `row`, column `col` (both 1-based); an empty cell reads as a blank.
    pub fn cells(&self, row: u8, col: u8, len: u8) -> String {
        let screen = self.screen.screen();
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

    fn take(&mut self, bytes: &[u8]) {
        self.screen.process(bytes);
        self.raw.extend_from_slice(bytes);
    }

    /// Reads the program's output until `done` holds; panics with the screen after the
    /// ceiling.
    pub fn wait_until(&mut self, what: &str, done: impl Fn(&Self) -> bool) {
        let start = Instant::now();
        while !done(self) {
            let left = CEILING.saturating_sub(start.elapsed());
            match self.output.recv_timeout(left) {
                Ok(bytes) => self.take(&bytes),
                Err(_) => panic!(
                    "{what}: not on the screen within {CEILING:?}\n{}\n{}",
                    self.contents(),
                    (self.diagnose)()
                ),
            }
        }
    }

    /// Reads until `done` holds for the screen's text.
    pub fn wait_for_contents(&mut self, what: &str, done: impl Fn(&str) -> bool) {
        self.wait_until(what, |p| done(&p.contents()));
    }

    /// Reads until the screen shows `text`.
    pub fn wait_for_text(&mut self, text: &str) {
        self.wait_until(&format!("{text:?}"), |p| p.contents().contains(text));
    }

    /// Waits for the program to end, then reads its last words until no process holds the
    /// terminal any more.
    pub fn wait_exit(&mut self) -> ExitStatus {
        let start = Instant::now();
        let status = loop {
            if let Some(status) = self.child.try_wait().unwrap() {
                break status;
            }
            assert!(
                start.elapsed() < CEILING,
                "the program did not exit:\n{}",
                self.contents()
            );
            if let Ok(bytes) = self.output.recv_timeout(Duration::from_millis(50)) {
                self.take(&bytes);
            }
        };
        // Its last words may still be in the terminal: read until the reader meets the end.
        loop {
            match self
                .output
                .recv_timeout(CEILING.saturating_sub(start.elapsed()))
            {
                Ok(bytes) => self.take(&bytes),
                Err(RecvTimeoutError::Disconnected) => break,
                Err(RecvTimeoutError::Timeout) => {
                    panic!("the terminal stayed open after the program left")
                }
            }
        }
        status
    }

    /// Whether the terminal is in its normal (cooked, echoing) mode.
    pub fn cooked(&self) -> bool {
        let attrs = tcgetattr(self.keys.as_fd()).unwrap();
        attrs
            .local_flags
            .contains(LocalFlags::ICANON | LocalFlags::ECHO)
    }
}

impl Drop for PtyProgram {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}
