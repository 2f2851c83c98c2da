//! Transports end to end: `buslab slcan serve` (an SLCAN adapter model on a PTY) with the
//! `slcan:` backend, python-can's `slcan` interface and raw bytes; `buslab bridge` between two
//! virtual buses; can-utils habits of `dump` and `send`.

#[path = "support/outside_tools.rs"]
mod outside_tools;

mod bus_common;

use outside_tools::{python_can, root};
use std::fs::OpenOptions;
use std::io::{BufRead, BufReader, Read, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdout, Command, Stdio};
use std::sync::mpsc;
use std::thread::{self, JoinHandle};
use std::time::{Duration, Instant};

use bus_common::{Serve, frame};
use buslab_canbus::CanBus;

/// How long a test waits for something that normally comes within milliseconds: a deadline
/// for an event, not a measure of speed (CI machines are loaded).
const EVENT: Duration = Duration::from_secs(60);
const WAIT: Option<Duration> = Some(EVENT);

fn buslab() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_buslab"));
    c.env_remove("RUST_LOG");
    c
}

/// A child process killed when the test ends.
struct Running {
    child: Child,
    stdout: Option<BufReader<ChildStdout>>,
    stderr: Option<JoinHandle<String>>,
}

impl Running {
    /// Starts `buslab ARGS` and waits until a line of its stderr contains `ready` (its log at
    /// -v), or, with `ready` empty, until its first stdout line, which is returned.
    fn start(args: &[&str], ready: &str) -> (Self, String) {
        Self::launch(args, ready, true)
    }

    /// Runs `buslab ARGS` to its end (bounded as [`Running::finish`]): stdout and stderr.
    fn run(args: &[&str]) -> (String, String) {
        Self::launch(args, "", false).0.finish()
    }

    fn launch(args: &[&str], ready: &str, wait: bool) -> (Self, String) {
        let mut child = buslab()
            .args(args)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let mut stdout = BufReader::new(child.stdout.take().unwrap());
        let (tx, rx) = mpsc::channel();
        let lines = BufReader::new(child.stderr.take().unwrap()).lines();
        let want = ready.to_string();
        let stderr = thread::spawn(move || {
            let mut all = String::new();
            for line in lines.map_while(Result::ok) {
                if !want.is_empty() && line.contains(&want) {
                    let _ = tx.send(());
                }
                all.push_str(&line);
                all.push('\n');
            }
            all
        });
        let mut first = String::new();
        let ok = if !wait {
            true
        } else if ready.is_empty() {
            stdout.read_line(&mut first).is_ok_and(|n| n > 0)
        } else {
            rx.recv_timeout(EVENT).is_ok()
        };
        let mut running = Self {
            child,
            stdout: Some(stdout),
            stderr: Some(stderr),
        };
        if !ok {
            let err = running.stop();
            panic!("buslab {args:?} did not get ready: {err}");
        }
        (running, first.trim().to_string())
    }

    /// Waits for the process to end by itself; its stdout and stderr.
    /// A process that has not ended EVENT after its last output is killed and the test fails
    /// with what it printed (a hang is a failure to read, not a CI timeout).
    fn finish(mut self) -> (String, String) {
        let mut stdout = self.stdout.take().unwrap();
        let reader = thread::spawn(move || {
            let mut out = String::new();
            let _ = stdout.read_to_string(&mut out);
            out
        });
        let deadline = Instant::now() + EVENT;
        let status = loop {
            if let Some(status) = self.child.try_wait().unwrap() {
                break Some(status);
            }
            if Instant::now() >= deadline {
                break None;
            }
            thread::sleep(Duration::from_millis(20));
        };
        let Some(status) = status else {
            let err = self.stop();
            let out = reader.join().unwrap();
            panic!("still running after {EVENT:?}; stdout: {out:?}\nstderr:\n{err}");
        };
        let out = reader.join().unwrap();
        let err = self.stderr.take().unwrap().join().unwrap();
        assert!(status.success(), "{err}");
        (out, err)
    }

    /// Stops the process as Ctrl-C does and waits (bounded by EVENT) for it to end by
    /// itself; its stderr, with what it said on the way out.
    fn interrupt(mut self) -> String {
        let pid = nix::unistd::Pid::from_raw(self.child.id() as i32);
        nix::sys::signal::kill(pid, nix::sys::signal::Signal::SIGINT).unwrap();
        let deadline = Instant::now() + EVENT;
        while self.child.try_wait().unwrap().is_none() {
            if Instant::now() >= deadline {
                let err = self.stop();
                panic!("still running {EVENT:?} after SIGINT; stderr:\n{err}");
            }
            thread::sleep(Duration::from_millis(20));
        }
        self.stderr.take().unwrap().join().unwrap()
    }

    /// Kills the process; its stderr so far.
    fn stop(&mut self) -> String {
        let _ = self.child.kill();
        let _ = self.child.wait();
        self.stderr
            .take()
            .map(|t| t.join().unwrap())
            .unwrap_or_default()
    }
}

impl Drop for Running {
    fn drop(&mut self) {
        self.stop();
    }
}

/// `buslab slcan serve` plugged into `bus`, its PTY linked at DIR/ttySL0.
fn slcan_serve(bus: &str, dir: &Path) -> (Running, PathBuf) {
    slcan_serve_with(&[], bus, dir)
}

/// [`slcan_serve`] with options before the subcommand (`-v`).
fn slcan_serve_with(options: &[&str], bus: &str, dir: &Path) -> (Running, PathBuf) {
    let link = dir.join("ttySL0");
    let mut args = options.to_vec();
    args.extend([
        "slcan",
        "serve",
        "--bus",
        bus,
        "--link",
        link.to_str().unwrap(),
    ]);
    let (serve, first) = Running::start(&args, "");
    assert_eq!(first, link.to_str().unwrap());
    (serve, link)
}

#[test]
fn python_can_slcan_exchanges_frames_with_buslab_dump() {
    let Some(python) = python_can() else {
        return;
    };
    let serve = Serve::start(500_000);
    let dir = tempfile::tempdir().unwrap();
    let (_adapter, pty) = slcan_serve(&serve.url, dir.path());
    let (dump, _) = Running::start(
        &["-v", "dump", "--bus", &serve.url, "-n", "3"],
        "dump: listening",
    );
    let mut peer = Command::new(&python)
        .arg(root().join("tests/interop/can_slcan_peer.py"))
        .arg(&pty)
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .unwrap();
    let mut lines = BufReader::new(peer.stdout.take().unwrap()).lines();
    let mut next = || {
        lines
            .next()
            .expect("python-can script ended early")
            .unwrap()
    };
    // python-can reads the version as two decimal numbers, and the serial number.
    assert_eq!(next(), "ready 10.13 BL01");
    assert_eq!(next(), "sent");
    // What python-can sent through the adapter is on the bus, as buslab dump shows it.
    let (out, _) = dump.finish();
    assert_eq!(
        out,
        "  vcan0  123   [3]  01 02 03\n\
         \x20 vcan0  1ABCDEF0   [2]  DE AD\n\
         \x20 vcan0       7FF   [2]  remote request\n"
    );
    // And what a node sends on the bus reaches python-can through the adapter.
    let mut me = serve.client();
    for f in ["321#AABBCC", "12345678#01", "0F0#R3"] {
        me.send(&frame(f)).unwrap();
    }
    assert_eq!(next(), "rx 321 0 0 3 AABBCC");
    assert_eq!(next(), "rx 12345678 1 0 1 01");
    assert_eq!(next(), "rx F0 0 1 3 -");
    assert!(peer.wait().unwrap().success(), "python-can script failed");
}

/// A CAN FD bus for `buslab slcan serve` to plug into: an FD SLCAN adapter (buslab's model,
/// CANable 2.0's kind) served on a PTY in this process; what the adapter's host sends comes out
/// of `events`, and `feed` gives it frames from "the bus".
struct FdBus {
    path: PathBuf,
    feed: mpsc::SyncSender<buslab_slcan::Input>,
    events: mpsc::Receiver<buslab_slcan::AdapterEvent>,
    stop: std::sync::Arc<std::sync::atomic::AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl FdBus {
    fn start() -> Self {
        let pty = buslab_link::Pty::open().unwrap();
        let path = pty.path().to_path_buf();
        let (feed, inputs) = mpsc::sync_channel(buslab_slcan::INPUT_QUEUE);
        let (events_tx, events) = mpsc::channel();
        let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
        let thread = thread::spawn({
            let (feed, stop) = (feed.clone(), stop.clone());
            move || {
                let mut adapter = buslab_slcan::Adapter::default().with_fd(true);
                buslab_slcan::serve(
                    std::os::fd::AsFd::as_fd(&pty),
                    &mut adapter,
                    feed,
                    inputs,
                    |event| {
                        let _ = events_tx.send(event);
                    },
                    &stop,
                )
                .unwrap();
            }
        });
        Self {
            path,
            feed,
            events,
            stop,
            thread: Some(thread),
        }
    }

    /// The next event that is not `Opened`/`Closed` (sessions come and go).
    fn next_frame_event(&self) -> buslab_slcan::AdapterEvent {
        loop {
            match self
                .events
                .recv_timeout(EVENT)
                .expect("an event from the FD bus")
            {
                buslab_slcan::AdapterEvent::Opened { .. } | buslab_slcan::AdapterEvent::Closed => {}
                event => return event,
            }
        }
    }
}

impl Drop for FdBus {
    fn drop(&mut self) {
        self.stop.store(true, std::sync::atomic::Ordering::SeqCst);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

fn fd(text: &str) -> buslab_can::FdFrame {
    text.parse().unwrap()
}

fn hex(bytes: impl IntoIterator<Item = u8>) -> String {
    bytes.into_iter().map(|b| format!("{b:02X}")).collect()
}

/// python-can's `slcan` interface with CAN FD (BitTimingFd 500 kbit/s / 2 Mbit/s: S6, Y2)
/// through `buslab slcan serve`, whose bus is an FD SLCAN adapter opened with
/// `?data_bitrate=2000000`: FD frames with and without BRS, extended IDs, 0 and 64 bytes, both
/// ways, in order with classic frames.
#[test]
fn python_can_fd_frames_cross_slcan_serve_to_an_fd_bus_and_back() {
    let Some(python) = python_can() else {
        return;
    };
    let bus = FdBus::start();
    let dir = tempfile::tempdir().unwrap();
    let url = format!(
        "slcan:{}?bitrate=500000&data_bitrate=2000000",
        bus.path.display()
    );
    let (_adapter, pty) = slcan_serve(&url, dir.path());
    // The serve's client opened the FD bus with the data bit rate.
    match bus.events.recv_timeout(EVENT).expect("the FD bus opened") {
        buslab_slcan::AdapterEvent::Opened {
            data_bitrate,
            timing,
            ..
        } => {
            assert_eq!(data_bitrate, Some(2_000_000));
            assert_eq!(timing, Some(buslab_slcan::Timing::Bitrate(500_000)));
        }
        other => panic!("{other:?}"),
    }
    let mut peer = Command::new(&python)
        .arg(root().join("tests/interop/can_slcan_fd_peer.py"))
        .arg(&pty)
        .arg("3")
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .unwrap();
    let mut lines = BufReader::new(peer.stdout.take().unwrap()).lines();
    let mut next = || {
        lines
            .next()
            .expect("python-can script ended early")
            .unwrap()
    };
    assert_eq!(next(), "sent");
    use buslab_slcan::AdapterEvent::{Transmit, TransmitFd};
    let long = format!("1ABCDEF0##1{}", hex(0..64));
    assert_eq!(
        (0..4).map(|_| bus.next_frame_event()).collect::<Vec<_>>(),
        [
            TransmitFd(fd(&format!("123##0{}", hex(0..12)))),
            TransmitFd(fd(&long)),
            TransmitFd(fd("7FF##0")),
            Transmit(frame("100#AA")),
        ],
        "what python-can sent reached the FD bus as it was"
    );
    use buslab_slcan::Input;
    for input in [
        Input::Fd(fd(&format!("321##1{}", hex(0xA0..0xAC)))),
        Input::Fd(fd(&format!("12345678##0{}", hex(0..64)))),
        Input::Frame(frame("0F0#0102")),
    ] {
        bus.feed.send(input).unwrap();
    }
    assert_eq!(next(), format!("rx 321 0 1 1 12 {}", hex(0xA0..0xAC)));
    assert_eq!(next(), format!("rx 12345678 1 1 0 64 {}", hex(0..64)));
    assert_eq!(next(), "rx F0 0 0 0 2 0102");
    assert!(peer.wait().unwrap().success(), "python-can script failed");
}

/// The same python-can session on buslab's bit-level bus, which is classic: the FD frames get
/// BEL (python-can does not wait for answers), the classic frame goes through, and the
/// refusal is said once with the bus's reason and counted at the end.
#[test]
fn python_can_fd_frames_on_a_classic_bus_get_bel_said_once_and_counted() {
    let Some(python) = python_can() else {
        return;
    };
    let serve = Serve::start(500_000);
    let dir = tempfile::tempdir().unwrap();
    let (adapter, pty) = slcan_serve_with(&["-v"], &serve.url, dir.path());
    let mut me = serve.client();
    let peer = Command::new(&python)
        .arg(root().join("tests/interop/can_slcan_fd_peer.py"))
        .arg(&pty)
        .arg("0")
        .output()
        .unwrap();
    assert!(peer.status.success(), "python-can script failed");
    assert_eq!(String::from_utf8_lossy(&peer.stdout), "sent\n");
    let m = me.recv(WAIT).unwrap().expect("the classic frame");
    assert_eq!(m.record.to_string(), "100#AA");
    let err = adapter.interrupt();
    let said: Vec<&str> = err
        .lines()
        .filter(|l| l.contains("the host sends CAN FD frames"))
        .collect();
    assert_eq!(said.len(), 1, "{err}");
    assert!(
        said[0].contains(&format!(
            "(first 123##0{}): answered BEL, as a classic adapter does: {} is classic CAN: buslab's bit-level bus carries no FD frames",
            hex(0..12),
            serve.url
        )),
        "{err}"
    );
    assert!(err.contains("3 CAN FD frames refused"), "{err}");
}

#[test]
fn the_slcan_backend_sends_and_receives_through_the_served_adapter() {
    let serve = Serve::start(500_000);
    let dir = tempfile::tempdir().unwrap();
    let (_adapter, pty) = slcan_serve(&serve.url, dir.path());
    let url = format!("slcan:{}?bitrate=500000", pty.display());
    let mut me = serve.client();
    Running::run(&["send", &url, "123#1122", "1ABCDEF0#", "7FF#R8"]);
    let got: Vec<String> = (0..3)
        .map(|_| me.recv(WAIT).unwrap().unwrap().record.to_string())
        .collect();
    assert_eq!(got, ["123#1122", "1ABCDEF0#", "7FF#R8"]);

    // The other way, with a candump filter on the adapter's interface name: 0x100..0x1FF only.
    let spec = format!("{},100:700", pty.display());
    let (dump, _) = Running::start(&["-v", "dump", &spec, "-n", "2"], "dump: listening");
    for f in ["100#01", "200#02", "1FF#03"] {
        me.send(&frame(f)).unwrap();
    }
    let (out, _) = dump.finish();
    assert_eq!(
        out, "  ttySL0  100   [1]  01\n  ttySL0  1FF   [1]  03\n",
        "the frame outside the filter is not shown"
    );
}

/// The PTY's bytes as they come, read by a thread (a read cannot time out).
fn reader(port: &std::fs::File) -> mpsc::Receiver<Vec<u8>> {
    let mut port = port.try_clone().unwrap();
    let (tx, rx) = mpsc::channel();
    thread::spawn(move || {
        let mut buf = [0u8; 256];
        while let Ok(n) = port.read(&mut buf) {
            if n == 0 || tx.send(buf[..n].to_vec()).is_err() {
                break;
            }
        }
    });
    rx
}

/// Reads until `want` was seen; everything read.
fn read_until(bytes: &mpsc::Receiver<Vec<u8>>, want: &[u8]) -> Vec<u8> {
    let deadline = Instant::now() + EVENT;
    let mut got = Vec::new();
    while !got.windows(want.len()).any(|w| w == want) {
        let left = deadline.saturating_duration_since(Instant::now());
        match bytes.recv_timeout(left) {
            Ok(chunk) => got.extend_from_slice(&chunk),
            Err(_) => panic!("no {want:?} in {got:?}"),
        }
    }
    got
}

#[test]
fn garbage_gets_bel_and_the_adapter_keeps_serving() {
    let serve = Serve::start(500_000);
    let dir = tempfile::tempdir().unwrap();
    let (mut adapter, pty) = slcan_serve(&serve.url, dir.path());
    let mut port = OpenOptions::new()
        .read(true)
        .write(true)
        .open(&pty)
        .unwrap();
    // Unknown commands, a bad frame, a frame while closed, binary noise and an overlong line;
    // then a version request.
    let mut noise: Vec<u8> = b"hello\rt12\rt1230\r".to_vec();
    noise.extend(
        (0u8..=255)
            .filter(|&b| b != b'\r' && b != 0x07)
            .cycle()
            .take(3000),
    );
    noise.extend_from_slice(b"\rV\r");
    let bytes = reader(&port);
    port.write_all(&noise).unwrap();
    let got = read_until(&bytes, b"V1013\r");
    assert_eq!(got, b"\x07\x07\x07\x07V1013\r", "one BEL per bad line");
    // Still serving: open, send a frame, and it reaches the bus.
    let mut me = serve.client();
    port.write_all(b"O\rt1232CAFE\r").unwrap();
    assert_eq!(read_until(&bytes, b"z\r"), b"\rz\r");
    assert_eq!(me.recv(WAIT).unwrap().unwrap().record, frame("123#CAFE"));
    let err = adapter.stop();
    assert!(err.contains("answered BEL to a bad line"), "{err}");
}

/// Issue 26 (4): python-can at 500 kbit/s on the lab's 125 kbit/s bus. The host is told
/// (a warning naming both rates, `F` flags, BEL once bus-off), the adapter's node goes bus-off
/// and stays off instead of breaking the others' frames again and again, and reopening at the
/// bus's rate works.
#[test]
fn slcan_host_at_the_wrong_bit_rate_is_told_and_goes_bus_off_until_reopened() {
    let serve = Serve::start(125_000);
    let dir = tempfile::tempdir().unwrap();
    let (mut adapter, pty) = slcan_serve(&serve.url, dir.path());
    let mut me = serve.client();
    let mut port = OpenOptions::new()
        .read(true)
        .write(true)
        .open(&pty)
        .unwrap();
    let bytes = reader(&port);
    port.write_all(b"C\rS6\rO\rt1230\r").unwrap();
    assert_eq!(read_until(&bytes, b"z\r"), b"\r\r\rz\r");
    // The frame cannot get through: the node tries until it is bus-off, and `F` says so
    // (error warning, error passive and bus error, Lawicel's flags have no bus-off bit).
    let deadline = Instant::now() + EVENT;
    loop {
        port.write_all(b"F\r").unwrap();
        let got = read_until(&bytes, b"\r");
        if got == b"FA4\r" {
            port.write_all(b"t1230\r").unwrap();
            match read_reply(&bytes).as_slice() {
                b"\x07" => break,
                // Still error-passive (a bus error since the last F): queued, try again.
                b"z\r" => {}
                other => panic!("{other:?}"),
            }
        }
        assert!(Instant::now() < deadline, "never bus-off: {got:?}");
        thread::sleep(Duration::from_millis(20));
    }
    let status = me.admin().unwrap().node_status(None).unwrap();
    // Each of its attempts breaks one frame on the wire, 32 at most (TEC += 8 up to 256);
    // measured: 14.
    let broken = status.counters.bus_errors;
    assert!((1..=32).contains(&broken), "{status}");
    // Reopened at the bus's rate, frames go through (nothing left from before).
    port.write_all(b"C\rS4\rO\rF\rt4561AA\r").unwrap();
    assert_eq!(read_until(&bytes, b"z\r"), b"\r\r\rF00\rz\r");
    assert_eq!(me.recv(WAIT).unwrap().unwrap().record, frame("456#AA"));
    let err = adapter.stop();
    let warning = "the host opened the adapter at 500000 bit/s but the bus runs at 125000 bit/s";
    assert_eq!(err.matches(warning).count(), 1, "{err}");
    assert!(err.contains("WARN"), "{err}");
    assert!(
        err.contains("123# refused (BEL): the adapter is bus-off"),
        "{err}"
    );
    eprintln!("errors the other node saw: {broken}\n{err}");
}

/// Issue 26 (4) as the user met it: python-can's `slcan` interface at 500 kbit/s on a
/// 125 kbit/s bus, then again at 125 kbit/s.
#[test]
fn python_can_at_the_wrong_bit_rate_is_refused_until_it_reopens_at_the_right_one() {
    let Some(python) = python_can() else {
        return;
    };
    let serve = Serve::start(125_000);
    let dir = tempfile::tempdir().unwrap();
    let (mut adapter, pty) = slcan_serve(&serve.url, dir.path());
    let mut me = serve.client();
    let peer = Command::new(&python)
        .arg(root().join("tests/interop/can_slcan_wrong_rate.py"))
        .args([pty.to_str().unwrap(), "500000", "125000"])
        .output()
        .unwrap();
    let out = String::from_utf8_lossy(&peer.stdout);
    assert!(
        peer.status.success(),
        "{out}{}",
        String::from_utf8_lossy(&peer.stderr)
    );
    assert_eq!(out, "sent\nflags A4\nrefused\nreopened\n");
    // Nothing of the frames at the wrong rate reached the bus; the one at the right rate did.
    assert_eq!(me.recv(WAIT).unwrap().unwrap().record, frame("456#AA"));
    let broken = me
        .admin()
        .unwrap()
        .node_status(None)
        .unwrap()
        .counters
        .bus_errors;
    // One bus-off: at most 32 attempts broke a frame (the others' view of it).
    assert!((1..=32).contains(&broken), "{broken} errors");
    let err = adapter.stop();
    let warning = "the host opened the adapter at 500000 bit/s but the bus runs at 125000 bit/s";
    assert_eq!(err.matches(warning).count(), 1, "{err}");
    eprintln!("errors the other node saw: {broken}");
}

/// One answer of the adapter: up to a CR or a BEL.
fn read_reply(bytes: &mpsc::Receiver<Vec<u8>>) -> Vec<u8> {
    let mut got = Vec::new();
    while !got.ends_with(b"\r") && !got.ends_with(b"\x07") {
        match bytes.recv_timeout(EVENT) {
            Ok(chunk) => got.extend_from_slice(&chunk),
            Err(_) => panic!("no answer after {got:?}"),
        }
    }
    got
}

#[test]
fn bridge_copies_both_ways_without_duplicates_or_echoes() {
    let one = Serve::start(500_000);
    let two = Serve::start(500_000);
    let (_bridge, _) = Running::start(&["-v", "bridge", &one.url, &two.url], "bridge: socketcand");
    let (mut a, mut a_listener) = (one.client(), one.client());
    let mut b = two.client();
    a.send(&frame("123#01")).unwrap();
    assert_eq!(b.recv(WAIT).unwrap().unwrap().record, frame("123#01"));
    assert_eq!(
        a_listener.recv(WAIT).unwrap().unwrap().record,
        frame("123#01")
    );
    b.send(&frame("00000456#02")).unwrap();
    // The next frame on bus one is B's: the first frame did not come back from bus two.
    assert_eq!(
        a_listener.recv(WAIT).unwrap().unwrap().record,
        frame("00000456#02")
    );
    assert_eq!(a.recv(WAIT).unwrap().unwrap().record, frame("00000456#02"));
    // And B's frame did not come back to bus two: B's next frame is a fresh one from A.
    a.send(&frame("7FF#R1")).unwrap();
    assert_eq!(b.recv(WAIT).unwrap().unwrap().record, frame("7FF#R1"));
}

/// Two FD buses (FD SLCAN adapters opened with `fd=1`): FD frames cross both ways as they
/// are (BRS, extended IDs, 64 bytes), in order with classic frames, and a filter applies to
/// FD IDs too.
#[test]
fn bridge_copies_fd_frames_between_fd_buses() {
    let (one, two) = (FdBus::start(), FdBus::start());
    let url = |bus: &FdBus| format!("slcan:{}?fd=1", bus.path.display());
    let (_bridge, _) = Running::start(
        &[
            "-v",
            "bridge",
            &url(&one),
            &url(&two),
            "--filter",
            "~7FF:7FF",
        ],
        "CAN FD both ways",
    );
    use buslab_slcan::AdapterEvent::{Transmit, TransmitFd};
    use buslab_slcan::Input;
    let long = fd(&format!("1ABCDEF0##1{}", hex(0..64)));
    for input in [
        Input::Fd(fd("123##0112233")),
        Input::Fd(fd("7FF##0AA")),
        Input::Frame(frame("124#01")),
        Input::Fd(long),
    ] {
        one.feed.send(input).unwrap();
    }
    assert_eq!(
        (0..3).map(|_| two.next_frame_event()).collect::<Vec<_>>(),
        [
            TransmitFd(fd("123##0112233")),
            Transmit(frame("124#01")),
            TransmitFd(long),
        ],
        "7FF is held back by the filter"
    );
    two.feed.send(Input::Fd(fd("00000321##1CAFE"))).unwrap();
    assert_eq!(one.next_frame_event(), TransmitFd(fd("00000321##1CAFE")));
}

/// An FD bus bridged to buslab's bit-level bus (classic): classic frames cross, FD frames are
/// counted, the reason is said once, and the count is shown when the bridge stops.
#[test]
fn bridge_to_a_classic_bus_counts_fd_frames_and_says_why_once() {
    let fd_bus = FdBus::start();
    let classic = Serve::start(500_000);
    let fd_url = format!("slcan:{}?fd=1", fd_bus.path.display());
    let (bridge, _) = Running::start(&["-v", "bridge", &fd_url, &classic.url], "CAN FD one way");
    let mut me = classic.client();
    use buslab_slcan::Input;
    for input in [
        Input::Fd(fd("123##0112233")),
        Input::Fd(fd("123##1112233")),
        Input::Frame(frame("124#01")),
        Input::Fd(fd("00000125##0")),
        Input::Frame(frame("126#02")),
    ] {
        fd_bus.feed.send(input).unwrap();
    }
    assert_eq!(me.recv(WAIT).unwrap().unwrap().record, frame("124#01"));
    assert_eq!(me.recv(WAIT).unwrap().unwrap().record, frame("126#02"));
    let err = bridge.interrupt();
    let said: Vec<&str> = err
        .lines()
        .filter(|l| l.contains("are not bridged"))
        .collect();
    assert_eq!(said.len(), 1, "{err}");
    assert!(
        said[0].contains(&format!(
            "CAN FD frames from {fd_url} are not bridged: {} is classic CAN: buslab's bit-level bus carries no FD frames",
            classic.url
        )),
        "{err}"
    );
    assert!(
        err.contains("2 frames A -> B, 0 B -> A")
            && err.contains("3 CAN FD frames not bridged (classic destination)")
            && err.contains(
                "bridge: 3 CAN FD frames were not bridged: their destination is classic CAN"
            ),
        "{err}"
    );
}

#[test]
fn bridge_one_way_with_a_filter() {
    let one = Serve::start(500_000);
    let two = Serve::start(500_000);
    let (_bridge, _) = Running::start(
        &[
            "-v",
            "bridge",
            &one.url,
            &two.url,
            "--one-way",
            "--filter",
            "~100:700",
        ],
        "bridge: socketcand",
    );
    let (mut a, mut a_listener) = (one.client(), one.client());
    let mut b = two.client();
    b.send(&frame("222#02")).unwrap();
    a.send(&frame("123#01")).unwrap();
    a.send(&frame("321#03")).unwrap();
    // 0x123 is held back by the inverted filter.
    assert_eq!(b.recv(WAIT).unwrap().unwrap().record, frame("321#03"));
    // B's frame, sent first, did not cross the other way: bus one carries only A's frames.
    a.send(&frame("555#")).unwrap();
    let on_one: Vec<String> = (0..3)
        .map(|_| a_listener.recv(WAIT).unwrap().unwrap().record.to_string())
        .collect();
    assert_eq!(on_one, ["123#01", "321#03", "555#"]);
}

#[test]
fn bridging_a_bus_to_itself_is_refused() {
    let out = buslab()
        .args(["bridge", "vcan0", "vcan0"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("is bridged to itself"),
        "{err}"
    );
}

#[test]
fn cansend_and_candump_habits() {
    let serve = Serve::start(500_000);
    let url = serve.url.as_str();
    // The interface first, as cansend takes it; a URL works in its place.
    let mut me = serve.client();
    let out = buslab().args(["send", url, "123#1122"]).output().unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(me.recv(WAIT).unwrap().unwrap().record, frame("123#1122"));
    let out = buslab()
        .args(["send", url, "123#11", "--bus", url])
        .output()
        .unwrap();
    assert!(String::from_utf8_lossy(&out.stderr).contains("the bus is given twice"));
    let out = buslab().args(["send", url]).output().unwrap();
    assert!(String::from_utf8_lossy(&out.stderr).contains("no frame to send"));

    // candump -L: log lines on stdout, with -t z from zero; two filters OR-ed, one inverted.
    let spec = format!("{url},100:700,~7F0:7F0");
    let (dump, _) = Running::start(
        &["-v", "dump", &spec, "-L", "-t", "z", "-n", "2"],
        "dump: listening",
    );
    for f in ["1AA#01", "7F5#02", "300#03"] {
        me.send(&frame(f)).unwrap();
    }
    let (out, _) = dump.finish();
    let lines: Vec<&str> = out.lines().collect();
    assert_eq!(lines.len(), 2, "{out}");
    assert_eq!(lines[0], "(0000000000.000000) vcan0 1AA#01");
    assert!(lines[1].ends_with(") vcan0 300#03"), "{out}");

    // -t A: the date; -c: colour.
    let (dump, _) = Running::start(
        &["-v", "dump", url, "-t", "A", "-c", "-n", "1"],
        "dump: listening",
    );
    me.send(&frame("042#")).unwrap();
    let (out, _) = dump.finish();
    assert!(out.starts_with("\x1b[31m (20"), "{out:?}");
    assert!(out.ends_with(")  vcan0  042   [0] \x1b[0m\n"), "{out:?}");
}

/// Traffic both ways at full bus load: the bridge keeps copying afterwards. (Its hand-over
/// never blocks, so two pumps cannot wait on each other's full queues; with socketcand on both
/// sides TCP buffers absorb the backlog first, so this is a liveness check, and
/// `pump::tests::a_full_queue_refuses_instead_of_blocking` pins the non-blocking hand-over.)
#[test]
fn a_bridge_flooded_both_ways_keeps_copying() {
    let one = Serve::start(1_000_000);
    let two = Serve::start(1_000_000);
    let (_bridge, _) = Running::start(&["-v", "bridge", &one.url, &two.url], "bridge: socketcand");
    let (mut a_watch, mut b_watch) = (one.client(), two.client());
    let flood = |serve: &Serve, f: &'static str| {
        let mut c = serve.client();
        thread::spawn(move || {
            for _ in 0..3000 {
                c.send(&frame(f)).unwrap();
            }
            c.admin().unwrap().flush(EVENT).unwrap();
        })
    };
    let floods = [
        flood(&one, "100#0102030405060708"),
        flood(&two, "200#0102030405060708"),
    ];
    floods.into_iter().for_each(|t| t.join().unwrap());
    // After the floods, a frame each way still crosses (sent again until seen: one sent while
    // a queue was full may be dropped).
    for (from, to, f) in [
        (&one, &mut b_watch, "7FF#A5"),
        (&two, &mut a_watch, "7FE#5A"),
    ] {
        let mut sender = from.client();
        let deadline = Instant::now() + EVENT;
        'seen: loop {
            assert!(Instant::now() < deadline, "{f} never crossed the bridge");
            sender.send(&frame(f)).unwrap();
            let resend = Instant::now() + Duration::from_millis(500);
            while let Some(m) = to
                .recv(Some(resend.saturating_duration_since(Instant::now())))
                .unwrap()
            {
                if m.record == frame(f) {
                    break 'seen;
                }
            }
        }
    }
}

/// `buslab send` with can-utils' FD syntax and with an FD message of a database: on an FD bus
/// the frames go out as FD frames; buslab's own bus (classic) refuses them, naming itself.
#[test]
fn send_writes_fd_frames_on_an_fd_bus_and_a_classic_bus_refuses_them_by_name() {
    let fd_bus = FdBus::start();
    let dir = tempfile::tempdir().unwrap();
    let dbc = dir.path().join("fd.dbc");
    std::fs::write(
        &dbc,
        "BO_ 2147484304 Wide: 12 X\n SG_ Tail : 88|8@1+ (1,0) [0|255] \"\" X\n",
    )
    .unwrap();
    let url = format!("slcan:{}?fd=1", fd_bus.path.display());
    let out = buslab()
        .args(["send", &url, "123##1AABB", "124#01"])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    use buslab_slcan::AdapterEvent::{Transmit, TransmitFd};
    assert_eq!(fd_bus.next_frame_event(), TransmitFd(fd("123##1AABB")));
    assert_eq!(fd_bus.next_frame_event(), Transmit(frame("124#01")));
    let out = buslab()
        .args(["send", "--dbc"])
        .arg(&dbc)
        .args([&url, "Wide", "Tail=42"])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(
        fd_bus.next_frame_event(),
        TransmitFd(fd(&format!("00000290##0{}2A", "00".repeat(11))))
    );
    let serve = Serve::start(500_000);
    let out = buslab()
        .args(["send", "--bus", &serve.url, "123##1AABB"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(err.contains("classic CAN"), "{err}");
}
