//! Shared by the ZELLE end-to-end tests: `buslab zelle serve` as a child process.
#![allow(dead_code)]

use std::io::{BufRead, BufReader, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdin, ChildStdout, Command, Stdio};
use std::sync::{Mutex, MutexGuard};
use std::time::{Duration, Instant};

use buslab_link::SerialLine;
use buslab_zelle::client::Client;

/// A client on a served cell.
pub type SerialClient = Client<SerialLine>;

/// How long an answer may take beyond its time on the line: far more than any scheduling delay
/// on a loaded machine. Waiting costs nothing when the answer comes; only tests that expect
/// silence use a short time-out.
pub const ALLOWANCE: Duration = Duration::from_secs(30);

/// One served cell at a time. `serialport` opens ports with an exclusive `flock` and without
/// close-on-exec, so a child process spawned by a parallel test would inherit a port and keep
/// it locked after this test closed it.
static ONE_AT_A_TIME: Mutex<()> = Mutex::new(());

/// A served cell: the child process, its PTY, and its control lines on stdin/stdout.
pub struct Served {
    _turn: MutexGuard<'static, ()>,
    child: Child,
    stdin: ChildStdin,
    stdout: BufReader<ChildStdout>,
    pub pty: PathBuf,
    pub dir: tempfile::TempDir,
}

impl Served {
    /// `buslab zelle serve --state DIR/state.toml` plus `extra` arguments.
    pub fn start(extra: &[&str]) -> Served {
        let dir = tempfile::tempdir().unwrap();
        Served::start_in(dir, extra)
    }

    pub fn start_in(dir: tempfile::TempDir, extra: &[&str]) -> Served {
        let turn = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
        let mut child = Command::new(env!("CARGO_BIN_EXE_buslab"))
            .args(["zelle", "serve", "--state"])
            .arg(dir.path().join("state.toml"))
            .args(extra)
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let stdin = child.stdin.take().unwrap();
        let mut stdout = BufReader::new(child.stdout.take().unwrap());
        let mut line = String::new();
        stdout.read_line(&mut line).unwrap();
        let pty = PathBuf::from(line.trim());
        assert!(pty.exists(), "serve printed {line:?}");
        Served {
            _turn: turn,
            child,
            stdin,
            stdout,
            pty,
            dir,
        }
    }

    /// Sends a control line, returns the reply line.
    pub fn control(&mut self, line: &str) -> String {
        writeln!(self.stdin, "{line}").unwrap();
        self.stdin.flush().unwrap();
        let mut reply = String::new();
        self.stdout.read_line(&mut reply).unwrap();
        reply.trim().to_owned()
    }

    /// Asks for `status` until `want` holds (the cell may still be taking a byte the host
    /// just wrote), for at most [`ALLOWANCE`]; returns the last status line.
    pub fn status_until(&mut self, want: &str) -> String {
        let deadline = Instant::now() + ALLOWANCE;
        loop {
            let status = self.control("status");
            if status.contains(want) || Instant::now() > deadline {
                return status;
            }
            std::thread::sleep(Duration::from_millis(5));
        }
    }

    /// Asks for `status` until `done` holds for its line, for at most [`ALLOWANCE`]; panics
    /// naming `what` otherwise.
    pub fn status_where(&mut self, what: &str, done: impl Fn(&str) -> bool) -> String {
        let deadline = Instant::now() + ALLOWANCE;
        loop {
            let status = self.control("status");
            if done(&status) {
                return status;
            }
            assert!(Instant::now() < deadline, "never {what}: {status}");
            std::thread::sleep(Duration::from_millis(5));
        }
    }

    /// Waits until the armed series is back waiting for START with `values` stored: a block
    /// has run to its end, however late the server read the START.
    pub fn block_done(&mut self, values: u32) -> String {
        let want = format!(", {values} values,");
        self.status_where(&format!("waiting for START with {values} values"), |s| {
            s.contains("waiting for START") && s.contains(&want)
        })
    }

    /// The child's stderr, a line at a time, read by a thread (so that a trace never fills
    /// the pipe).
    pub fn stderr_lines(&mut self) -> std::sync::mpsc::Receiver<String> {
        let stderr = BufReader::new(self.child.stderr.take().expect("stderr taken once"));
        let (tx, rx) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            for line in stderr.lines() {
                let Ok(line) = line else { break };
                if tx.send(line).is_err() {
                    break;
                }
            }
        });
        rx
    }

    pub fn state_file(&self) -> PathBuf {
        self.dir.path().join("state.toml")
    }

    /// A host client on the PTY, at the cell's line settings, waiting [`ALLOWANCE`] beyond the
    /// line time for each answer.
    pub fn client(&self) -> SerialClient {
        client_on(&self.pty, ALLOWANCE)
    }

    /// Stops the child (SIGINT, so it saves its state) and gives the directory back.
    pub fn stop(mut self) -> tempfile::TempDir {
        let _ = Command::new("kill")
            .args(["-INT", &self.child.id().to_string()])
            .status();
        let _ = self.child.wait();
        let dir = tempfile::tempdir().unwrap();
        std::mem::replace(&mut self.dir, dir)
    }
}

impl Served {
    /// Kills the child with SIGKILL (`kill -9`: no saving, no clean-up) and gives the
    /// directory back.
    pub fn kill_9(mut self) -> tempfile::TempDir {
        let _ = self.child.kill();
        let _ = self.child.wait();
        let dir = tempfile::tempdir().unwrap();
        std::mem::replace(&mut self.dir, dir)
    }

    /// Sends `signal` (`TERM`, `HUP`, `INT`) and waits for the child; its exit status.
    pub fn signal(mut self, signal: &str) -> (std::process::ExitStatus, tempfile::TempDir) {
        let sent = Command::new("kill")
            .args([&format!("-{signal}"), &self.child.id().to_string()])
            .status()
            .unwrap();
        assert!(sent.success());
        let status = self.child.wait().unwrap();
        let dir = tempfile::tempdir().unwrap();
        (status, std::mem::replace(&mut self.dir, dir))
    }
}

impl Drop for Served {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

pub fn client_on(pty: &Path, timeout: Duration) -> SerialClient {
    let port = SerialLine::open(pty, buslab_zelle::timing::LINE).unwrap();
    Client::with_timeout(port, timeout)
}

/// Runs `buslab zelle` on the cell at `pty`, with a time-out far above any scheduling delay;
/// its standard output (the command must succeed).
pub fn buslab_zelle(pty: &Path, args: &[&str]) -> String {
    let out = Command::new(env!("CARGO_BIN_EXE_buslab"))
        .args(["zelle", "--timeout", "30s", "--port"])
        .arg(pty)
        .args(args)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).unwrap()
}
