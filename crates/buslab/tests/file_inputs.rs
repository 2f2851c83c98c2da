//! Files that never end (`/dev/zero`) or never open (a FIFO nobody writes) as any input a
//! command reads: a clear error naming the path, at once, instead of gigabytes read or a hang.

#[path = "support/zelle_served.rs"]
mod served;

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// Far above any start-up delay on a loaded machine; a command that blocks on a FIFO would
/// run past it (and be killed), one that reads `/dev/zero` would take far longer.
const ALLOWANCE: Duration = Duration::from_secs(30);

fn mkfifo(path: &Path) {
    assert!(Command::new("mkfifo").arg(path).status().unwrap().success());
}

/// Runs `buslab args`; it must fail with `want` in its stderr within [`ALLOWANCE`]. Returns
/// how long it took.
fn refused(args: &[&str], want: &str) -> Duration {
    let started = Instant::now();
    let mut child = Command::new(env!("CARGO_BIN_EXE_buslab"))
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    while child.try_wait().unwrap().is_none() {
        if started.elapsed() > ALLOWANCE {
            let _ = child.kill();
            panic!("{args:?} still runs after {ALLOWANCE:?}");
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    let out = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{args:?} succeeded");
    assert!(err.contains(want), "{args:?}: {err}");
    started.elapsed()
}

/// `buslab cpu196 serve` on a fresh image, and its PTY.
fn board(dir: &Path) -> (Child, PathBuf) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_buslab"))
        .args(["cpu196", "serve", "--baud", "250000", "--image"])
        .arg(dir.join("image.toml"))
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let mut line = String::new();
    BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut line)
        .unwrap();
    (child, PathBuf::from(line.trim()))
}

#[test]
fn dev_zero_and_fifos_are_refused_at_once_as_any_input() {
    let dir = tempfile::tempdir().unwrap();
    let fifo = dir.path().join("fifo");
    mkfifo(&fifo);
    let fifo = fifo.to_string_lossy().into_owned();
    let inputs = [
        (fifo.as_str(), "is a FIFO, not a regular file"),
        ("/dev/zero", "is a device, not a regular file"),
    ];
    let mut slowest = Duration::ZERO;
    let mut checked = 0;
    let mut check = |args: &[&str], want: &str| {
        slowest = slowest.max(refused(args, want));
        checked += 1;
    };
    for (path, why) in inputs {
        let want = format!("{path} {why}");
        check(&["zelle", "serve", "--state", path], &want);
        check(
            &["zelle", "serve", "--analog", &format!("1=csv:{path}")],
            &want,
        );
        check(&["cpu196", "serve", "--image", path], &want);
        check(&["sim", path], &want);
        check(
            &["bus", "serve", "--listen", "127.0.0.1:0", "--nodes", path],
            &want,
        );
    }
    // Client commands with a file to send.
    let cell = served::Served::start(&[]);
    let pty = cell.pty.to_string_lossy().into_owned();
    let (mut server, board_pty) = board(dir.path());
    let board_pty = board_pty.to_string_lossy().into_owned();
    for (path, why) in inputs {
        let want = format!("{path} {why}");
        check(&["zelle", "--port", &pty, "upload", path], &want);
        check(&["zelle", "--port", &pty, "load", path], &want);
        let board = ["cpu196", "--baud", "250000", "--port", &board_pty];
        for cmd in [
            &["flash", "write", "--bank", "3", "--in", path, "--yes"][..],
            &["pic", "write", "--block", "2", "--in", path, "--yes"],
            &["eeprom", "write", "--in", path, "--yes"],
        ] {
            check(&[&board[..], cmd].concat(), &want);
        }
    }
    let _ = server.kill();
    let _ = server.wait();
    eprintln!("{checked} inputs refused, the slowest in {slowest:?} (process start included)");
}
