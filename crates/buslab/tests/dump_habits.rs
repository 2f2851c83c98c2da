//! candump's habits in `buslab dump`: `-T` (end after a quiet spell; candump's bare
//! milliseconds taken with a warning), `-f FILE`/`-f -`, `-s 0|1|2`, `-d` (DROPCOUNT lines
//! from the bus's count of frames lost for this client), `-D` (keep going when the bus goes
//! away), `any` (every bus this machine names), and `-H`, `-u`, `-r` refused with the reason.

mod bus_common;

use std::io::{BufRead, BufReader, Read};
use std::net::TcpListener;
use std::process::{Child, ChildStdout, Command, Output, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use bus_common::Serve;

/// A deadline for an event that normally comes within a second (CI machines are loaded).
const EVENT: Duration = Duration::from_secs(60);

fn buslab() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_buslab"));
    c.env_remove("BUSLAB_BUS").env_remove("RUST_LOG");
    c
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

/// `buslab send --bus URL FRAMES…` (waits until the bus took them).
fn send(url: &str, frames: &[&str]) {
    let out = buslab()
        .args(["send", "--bus", url])
        .args(frames)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", text(&out.stderr));
}

/// A process whose stderr lines arrive on a channel.
struct Running {
    child: Child,
    stdout: BufReader<ChildStdout>,
    stderr: mpsc::Receiver<String>,
    seen: Vec<String>,
}

impl Running {
    fn start(cmd: &mut Command) -> Self {
        let mut child = cmd
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let stdout = BufReader::new(child.stdout.take().unwrap());
        let (tx, stderr) = mpsc::channel();
        let lines = BufReader::new(child.stderr.take().unwrap()).lines();
        std::thread::spawn(move || {
            for line in lines.map_while(Result::ok) {
                if tx.send(line).is_err() {
                    break;
                }
            }
        });
        Self {
            child,
            stdout,
            stderr,
            seen: Vec::new(),
        }
    }

    fn wait_stderr(&mut self, want: &str) {
        let deadline = Instant::now() + EVENT;
        while !self.seen.iter().any(|l| l.contains(want)) {
            match self
                .stderr
                .recv_timeout(deadline.saturating_duration_since(Instant::now()))
            {
                Ok(line) => self.seen.push(line),
                Err(_) => panic!("never saw {want:?} on stderr: {:#?}", self.seen),
            }
        }
    }

    fn line(&mut self) -> String {
        let mut line = String::new();
        self.stdout.read_line(&mut line).unwrap();
        line.trim_end().to_string()
    }

    /// Waits (up to the event allowance) for the process to end by itself.
    fn wait_end(&mut self) -> std::process::ExitStatus {
        let deadline = Instant::now() + EVENT;
        loop {
            if let Some(status) = self.child.try_wait().unwrap() {
                return status;
            }
            assert!(Instant::now() < deadline, "it did not end by itself");
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    fn stderr_text(&mut self) -> String {
        while let Ok(line) = self.stderr.recv_timeout(Duration::from_millis(200)) {
            self.seen.push(line);
        }
        self.seen.join("\n")
    }
}

impl Drop for Running {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

#[test]
fn dump_t_ends_after_a_quiet_spell_and_takes_bare_milliseconds_with_a_warning() {
    let serve = Serve::start(500_000);
    // candump's bare number: milliseconds, with a warning saying how to write it.
    let out = buslab()
        .args(["dump", "--bus", &serve.url, "-T", "300"])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert!(
        text(&out.stderr).contains("-T 300 taken as milliseconds, as candump does: write -T 300ms"),
        "{}",
        text(&out.stderr)
    );
    let out = buslab()
        .args(["dump", "--bus", &serve.url, "-T", "300ms"])
        .output()
        .unwrap();
    assert!(
        out.status.success() && out.stderr.is_empty(),
        "{}",
        text(&out.stderr)
    );
    // Frames keep it going; it ends once they stop, with what it printed.
    let mut dump =
        Running::start(buslab().args(["-v", "dump", "--bus", &serve.url, "-L", "-T", "1s"]));
    dump.wait_stderr("dump: listening");
    send(&serve.url, &["123#01", "124#02"]);
    assert!(dump.wait_end().success(), "{}", dump.stderr_text());
    let mut printed = String::new();
    dump.stdout.read_to_string(&mut printed).unwrap();
    let frames: Vec<&str> = printed
        .lines()
        .map(|l| l.rsplit(' ').next().unwrap())
        .collect();
    assert_eq!(frames, ["123#01", "124#02"], "{printed}");
}

#[test]
fn dump_f_logs_as_l_does_and_f_dash_prints_log_lines() {
    let serve = Serve::start(500_000);
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("f.log");
    let mut dump = Running::start(
        buslab()
            .args(["-v", "dump", "--bus", &serve.url, "-n", "2", "-f"])
            .arg(&file),
    );
    dump.wait_stderr("dump: listening");
    send(&serve.url, &["123#01", "124#02"]);
    assert!(dump.wait_end().success(), "{}", dump.stderr_text());
    let log = std::fs::read_to_string(&file).unwrap();
    let frames: Vec<&str> = log.lines().map(|l| l.rsplit(' ').next().unwrap()).collect();
    assert_eq!(frames, ["123#01", "124#02"], "{log}");

    let mut dump =
        Running::start(buslab().args(["-v", "dump", "--bus", &serve.url, "-n", "1", "-f", "-"]));
    dump.wait_stderr("dump: listening");
    send(&serve.url, &["125#03"]);
    let line = dump.line();
    assert!(
        line.starts_with('(') && line.ends_with(") vcan0 125#03"),
        "a candump log line: {line:?}"
    );
}

#[test]
fn dump_s_quiets_the_terminal_but_not_the_log() {
    let serve = Serve::start(500_000);
    let dir = tempfile::tempdir().unwrap();
    for (level, want) in [("2", ""), ("1", "|\u{8}/\u{8}-\u{8}")] {
        let file = dir.path().join(format!("s{level}.log"));
        let mut dump = Running::start(
            buslab()
                .args([
                    "-v", "dump", "--bus", &serve.url, "-n", "3", "-s", level, "-l",
                ])
                .arg(&file),
        );
        dump.wait_stderr("dump: listening");
        send(&serve.url, &["123#01", "124#02", "125#03"]);
        assert!(dump.wait_end().success(), "{}", dump.stderr_text());
        let mut printed = String::new();
        dump.stdout.read_to_string(&mut printed).unwrap();
        assert_eq!(printed, want, "-s {level}");
        let log = std::fs::read_to_string(&file).unwrap();
        assert_eq!(log.lines().count(), 3, "-s {level}: {log}");
    }
    let out = buslab()
        .args(["dump", "--bus", &serve.url, "-s", "3"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(text(&out.stderr).contains("0..=2"), "{}", text(&out.stderr));
}

#[test]
fn dump_refuses_h_u_and_r_saying_why() {
    for (args, why) in [
        (&["-H"][..], "hardware timestamps"),
        (&["-u", "100"], "buslab bridge"),
        (&["-r", "65536"], "receive buffer"),
    ] {
        let out: Output = buslab()
            .arg("dump")
            .args(args)
            .args(["--bus", "socketcand://127.0.0.1:1/vcan0"])
            .output()
            .unwrap();
        let err = text(&out.stderr);
        assert!(!out.status.success(), "{args:?}");
        assert!(
            err.contains(why) && err.contains("candump"),
            "{args:?}: {err}"
        );
    }
}

/// A dump whose printer is stuck (its stdout not read) falls behind; the server drops frames
/// for it and counts them; `-d` reports them once it reads again, as candump's DROPCOUNT.
#[test]
fn dump_d_reports_the_frames_the_bus_dropped_for_it() {
    let serve = Serve::start(1_000_000);
    let mut dump = Running::start(buslab().args(["-v", "dump", "--bus", &serve.url, "-d"]));
    dump.wait_stderr("dump: listening");
    // Far more than the pipe, dump's queue and the sockets hold.
    let out = buslab()
        .args(["gen", "-q", "--bus", &serve.url, "-g", "0s", "-n", "60000"])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", text(&out.stderr));
    let line = loop {
        let line = dump.line();
        assert!(!line.is_empty(), "dump ended: {}", dump.stderr_text());
        if line.starts_with("DROPCOUNT") {
            break line;
        }
    };
    // `DROPCOUNT: dropped N CAN frames on 'vcan0' (total drops N)`
    let words: Vec<&str> = line.split_whitespace().collect();
    let dropped: u64 = words[2].parse().unwrap();
    assert!(dropped > 0, "{line}");
    assert_eq!(words[4..7], ["frames", "on", "'vcan0'"], "{line}");
    assert_eq!(
        words[9].trim_end_matches(')'),
        dropped.to_string(),
        "{line}"
    );
}

#[test]
fn dump_d_is_refused_on_a_bus_that_keeps_no_drop_count() {
    let serve = Serve::start(500_000);
    let dir = tempfile::tempdir().unwrap();
    let link = dir.path().join("ttySL0");
    let mut adapter = Running::start(
        buslab()
            .args(["slcan", "serve", "--bus", &serve.url, "--link"])
            .arg(&link),
    );
    assert_eq!(adapter.line(), link.to_str().unwrap());
    let out = buslab()
        .arg("dump")
        .arg(format!("slcan:{}", link.display()))
        .arg("-d")
        .output()
        .unwrap();
    let err = text(&out.stderr);
    assert!(!out.status.success());
    assert!(
        err.contains("-d needs a bus that counts") && err.contains("SLCAN"),
        "{err}"
    );
}

/// `buslab bus serve` on a fixed port (to come back where it was).
fn serve_at(port: u16) -> Running {
    let mut serve = Running::start(buslab().args([
        "bus",
        "serve",
        "--bitrate",
        "500000",
        "--listen",
        &format!("127.0.0.1:{port}"),
    ]));
    assert!(serve.line().starts_with("socketcand://"));
    serve
}

#[test]
fn dump_capital_d_keeps_going_when_the_bus_goes_away_and_comes_back() {
    let port = TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let url = format!("socketcand://127.0.0.1:{port}/vcan0");
    let serve = serve_at(port);
    let mut dump =
        Running::start(buslab().args(["-v", "dump", "--bus", &url, "-L", "-D", "-n", "2"]));
    dump.wait_stderr("dump: listening");
    send(&url, &["123#01"]);
    assert!(dump.line().ends_with("123#01"));
    drop(serve);
    dump.wait_stderr("-D: trying it again");
    let serve = serve_at(port);
    dump.wait_stderr(": back");
    send(&url, &["123#02"]);
    assert!(dump.line().ends_with("123#02"));
    assert!(dump.wait_end().success(), "{}", dump.stderr_text());

    // Without -D the dump ends with an error naming the bus.
    drop(serve);
    let serve = serve_at(port);
    let mut dump = Running::start(buslab().args(["-v", "dump", "--bus", &url]));
    dump.wait_stderr("dump: listening");
    drop(serve);
    let status = dump.wait_end();
    assert!(!status.success());
    assert!(dump.stderr_text().contains(&url), "{:?}", dump.seen);
}

#[test]
fn dump_any_reads_every_bus_this_machine_names() {
    let serve = Serve::start(500_000);
    // `any`: the configuration's bus (here from BUSLAB_BUS) and the kernel's CAN interfaces
    // (none on a kernel without SocketCAN); the filters apply to each.
    let mut dump = Running::start(buslab().env("BUSLAB_BUS", &serve.url).args([
        "-v",
        "dump",
        "any,123:7FF",
        "-L",
        "-n",
        "1",
    ]));
    dump.wait_stderr("dump: listening");
    send(&serve.url, &["124#01", "123#02"]);
    let line = dump.line();
    assert!(line.ends_with(" vcan0 123#02"), "{line}");
    assert!(dump.wait_end().success());

    let out = buslab()
        .env("BUSLAB_BUS", "socketcand://127.0.0.1:1/vcan0")
        .args(["dump", "any"])
        .output()
        .unwrap();
    let err = text(&out.stderr);
    assert!(!out.status.success());
    assert!(err.contains("any: no bus to dump on this machine"), "{err}");
}
