//! A user's terminal on a served VT100 port (the PowerPC node's MoniCAN screen): the link is
//! opened raw at 19200 8N1 and the screen is read back with an independent VT100 emulator
//! (the `vt100` crate). Waits return as soon as the screen shows what is asked.

use std::fs::{File, OpenOptions};
use std::io::{Read, Write};
use std::os::fd::AsFd;
use std::path::Path;
use std::sync::mpsc::{self, Receiver};
use std::time::{Duration, Instant};

use nix::sys::termios::{
    BaudRate, FlushArg, SetArg, cfmakeraw, cfsetspeed, tcflush, tcgetattr, tcsetattr,
};

/// The ceiling for a wait (a wait returns as soon as the screen shows what it waits for).
pub const CEILING: Duration = Duration::from_secs(60);
/// Bytes the reader asks the link for at once: a chunk this long may end inside a write.
pub const READ_SIZE: usize = 4096;

pub struct Terminal {
    keys: File,
    output: Receiver<Vec<u8>>,
    screen: vt100::Parser,
}

#[allow(dead_code)] // each test file uses its own subset
impl Terminal {
    /// Opens the link raw at 19200 baud; a thread forwards what the node sends.
    pub fn open(path: &Path) -> Self {
        Self::open_with(path, false)
    }

    /// Opens the link as `screen` and `picocom` do: raw at 19200 baud, then throws away what
    /// waited unread (`tcflush`).
    pub fn open_flushing(path: &Path) -> Self {
        Self::open_with(path, true)
    }

    fn open_with(path: &Path, flush: bool) -> Self {
        let file = OpenOptions::new()
            .read(true)
            .write(true)
            .open(path)
            .unwrap_or_else(|e| panic!("open {}: {e}", path.display()));
        let mut t = tcgetattr(file.as_fd()).unwrap();
        cfmakeraw(&mut t);
        cfsetspeed(&mut t, BaudRate::B19200).unwrap();
        tcsetattr(file.as_fd(), SetArg::TCSANOW, &t).unwrap();
        if flush {
            tcflush(file.as_fd(), FlushArg::TCIFLUSH).unwrap();
        }
        let mut reader = file.try_clone().unwrap();
        let (tx, output) = mpsc::channel();
        std::thread::spawn(move || {
            let mut buf = [0u8; READ_SIZE];
            while let Ok(n) = reader.read(&mut buf) {
                if n == 0 || tx.send(buf[..n].to_vec()).is_err() {
                    break;
                }
            }
        });
        Self {
            keys: file,
            output,
            screen: vt100::Parser::new(24, 80, 0),
        }
    }

    /// Takes in the next chunk, as one read of the link gave it (what a terminal shows
    /// between two reads); returns its length.
    pub fn read_chunk(&mut self) -> usize {
        match self.output.recv_timeout(CEILING) {
            Ok(bytes) => {
                self.screen.process(&bytes);
                bytes.len()
            }
            Err(_) => panic!(
                "nothing came within {CEILING:?}; the screen:\n{}",
                self.contents()
            ),
        }
    }

    /// Takes in what already arrived.
    pub fn drain(&mut self) {
        while let Ok(bytes) = self.output.try_recv() {
            self.screen.process(&bytes);
        }
    }

    pub fn type_keys(&mut self, keys: &[u8]) {
        self.keys.write_all(keys).unwrap();
    }

    /// The whole screen as text.
    pub fn contents(&self) -> String {
        self.screen.screen().contents()
    }

    /// The text of row `row` (1-based, as MoniCAN's layout numbers them).
    pub fn row(&self, row: u8) -> String {
        self.screen
            .screen()
            .contents_between(row as u16 - 1, 0, row as u16 - 1, 80)
    }

    /// Reads until `done` holds for the screen; panics with the screen after the ceiling.
    pub fn wait_until(&mut self, what: &str, done: impl Fn(&Self) -> bool) {
        let start = Instant::now();
        while !done(self) {
            let left = CEILING.saturating_sub(start.elapsed());
            match self.output.recv_timeout(left) {
                Ok(bytes) => self.screen.process(&bytes),
                Err(_) => panic!(
                    "{what} never showed within {CEILING:?}; the screen:\n{}",
                    self.contents()
                ),
            }
        }
    }

    /// Reads until the screen shows `text`.
    pub fn wait_for_text(&mut self, text: &str) {
        self.wait_until(&format!("{text:?}"), |t| t.contents().contains(text));
    }
}
