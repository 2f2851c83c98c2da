//! The CAN client commands (`dump`, `send`, `gen`, `regs`, `status`) against `buslab bus serve`
//! (and a tiny plain socketcand for what a server without buslab's extensions gives).

mod bus_common;

use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpListener;
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::thread::{self, JoinHandle};
use std::time::Duration;

use bus_common::{Serve, frame};
use buslab_canbus::CanBus;

/// How long a test waits for something that normally comes within milliseconds: a deadline
/// for an event, not a measure of speed (CI machines are loaded).
const EVENT: Duration = Duration::from_secs(60);
const WAIT: Option<Duration> = Some(EVENT);

/// `buslab dump` in the background; returned once it said (with -v) that it listens, so
/// everything sent from then on reaches it. Its stderr is collected for `finish`.
struct Dump {
    child: Child,
    stderr: JoinHandle<String>,
}

fn dump(serve: &Serve, extra: &[&str]) -> Dump {
    let mut child = serve
        .buslab()
        .args(["-v", "dump", "--bus", &serve.url])
        .args(extra)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let (ready, listening) = mpsc::channel();
    let lines = BufReader::new(child.stderr.take().unwrap()).lines();
    let stderr = thread::spawn(move || {
        let mut all = String::new();
        for line in lines.map_while(Result::ok) {
            if line.contains("dump: listening") {
                let _ = ready.send(());
            }
            all.push_str(&line);
            all.push('\n');
        }
        all
    });
    if listening.recv_timeout(EVENT).is_err() {
        let _ = child.kill();
        let _ = child.wait();
        panic!("dump did not start listening: {}", stderr.join().unwrap());
    }
    Dump { child, stderr }
}

impl Dump {
    /// Waits for dump to end; its stdout.
    fn finish(self) -> String {
        let out = self.child.wait_with_output().unwrap();
        let err = self.stderr.join().unwrap();
        assert!(out.status.success(), "{err}");
        String::from_utf8_lossy(&out.stdout).into_owned()
    }
}

fn run(serve: &Serve, args: &[&str]) -> (bool, String, String) {
    let out = serve
        .buslab()
        .args(args)
        .args(["--bus", &serve.url])
        .output()
        .unwrap();
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn send_and_dump_with_a_candump_log() {
    let serve = Serve::start(500_000);
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("x.log");
    let child = dump(&serve, &["-n", "4", "-l", log.to_str().unwrap()]);
    let (ok, _, err) = run(
        &serve,
        &["send", "123#1122", "1ABCDEF0#DEADBEEF", "321#R3", "7FF#"],
    );
    assert!(ok, "{err}");
    assert_eq!(
        child.finish(),
        "  vcan0  123   [2]  11 22\n  vcan0  1ABCDEF0   [4]  DE AD BE EF\n  vcan0       321   [3]  remote request\n  vcan0       7FF   [0] \n"
    );
    let log = std::fs::read_to_string(log).unwrap();
    let frames: Vec<&str> = log
        .lines()
        .map(|l| {
            let (ts, rest) = l.split_once(' ').unwrap();
            assert!(
                ts.starts_with('(') && ts.ends_with(')') && ts.contains('.'),
                "{l}"
            );
            rest
        })
        .collect();
    assert_eq!(
        frames,
        [
            "vcan0 123#1122",
            "vcan0 1ABCDEF0#DEADBEEF",
            "vcan0 321#R3",
            "vcan0 7FF#"
        ]
    );
}

#[test]
fn a_frame_the_bus_receives_comes_to_the_library_client_too() {
    let serve = Serve::start(500_000);
    let mut me = serve.client();
    let (ok, _, err) = run(&serve, &["send", "00000005#01"]);
    assert!(ok, "{err}");
    let m = me.recv(WAIT).unwrap().unwrap();
    assert_eq!(m.record, frame("00000005#01"));
}

#[test]
fn gen_increments_ids_and_data() {
    let serve = Serve::start(1_000_000);
    let mut me = serve.client();
    let (ok, _, err) = run(
        &serve,
        &[
            "gen", "-n", "20", "-g", "0s", "-I", "i", "-L", "2", "-D", "i",
        ],
    );
    assert!(ok, "{err}");
    for i in 0..20u32 {
        let m = me.recv(WAIT).unwrap().unwrap();
        assert_eq!(m.record.to_string(), format!("{i:03X}#{i:02X}00"));
    }
}

#[test]
fn gen_refuses_bad_modes_by_name() {
    let serve = Serve::start(500_000);
    for (args, want) in [
        (&["gen", "-L", "9"][..], "DLC \"9\" is out of range 0..8"),
        (&["gen", "-I", "800"][..], "ID 800 needs -e"),
        (&["gen", "-D", "ABC"][..], "data \"ABC\" must be 0..8 bytes"),
        (
            &["gen", "-D", "1122", "-L", "3"][..],
            "data has 2 bytes but -L says 3",
        ),
        // A bare gap is cangen's milliseconds (can_utils_habits.rs); not a number is refused.
        (
            &["gen", "-g", "1.2.3"][..],
            "duration \"1.2.3\" is not a number",
        ),
        (
            &["dump", "-t", "q"][..],
            "timestamp mode \"q\" must be a (absolute), d (delta) or z (from zero)",
        ),
    ] {
        let (ok, _, err) = run(&serve, args);
        assert!(!ok && err.contains(want), "{args:?}: {err}");
    }
}

#[test]
fn wrong_bit_timing_is_an_induced_error_seen_in_status_and_regs() {
    let serve = Serve::start(500_000);
    let mut listener = serve.client();
    listener.set_name("pc").unwrap();
    // The seed's 50 kbit/s registers on a 500 kbit/s bus: the frame cannot get through; the
    // node goes bus-off and the frame is given up.
    let (ok, _, err) = run(&serve, &["send", "--btr", "07:4D", "123#11"]);
    assert!(!ok);
    assert!(err.contains("1 of 1 frames were not sent"), "{err}");
    // It went bus-off; by the time the status is printed it may be back (on an idle bus a
    // chip at any bit rate reads the 128 × 11 recessive bits of its recovery).
    assert!(
        err.lines()
            .any(|l| l.starts_with("bus_off:") && l.split_whitespace().nth(1) != Some("0")),
        "{err}"
    );
    assert!(
        err.contains("50000 bit/s (does not match the bus: cannot communicate)"),
        "{err}"
    );
    assert!(err.contains("ECC:              0x"), "{err}");
    // The listener saw the garbage too: its ECC and RXERR tell.
    let (ok, out, err) = run(&serve, &["status", "--node", "pc"]);
    assert!(ok, "{err}");
    assert!(out.starts_with("node 1 (pc)\n"), "{out}");
    assert!(out.contains("STATUS:           SR=0x"), "{out}");
    assert!(out.contains("ECC:              0x"), "{out}");
    assert!(!out.contains("RXERR:            0\n"), "{out}");
    assert!(
        listener
            .recv(Some(Duration::from_millis(50)))
            .unwrap()
            .is_none()
    );
}

#[test]
fn arbitration_loss_shows_in_status_and_regs() {
    let serve = Serve::start(1_000_000);
    let _rx = serve.client();
    let mut blocker = serve.client();
    let mut loser = serve.client();
    loser.set_name("loser").unwrap();
    for _ in 0..3000 {
        blocker.send(&frame("001#0102030405060708")).unwrap();
    }
    loser.send(&frame("400#01")).unwrap();
    // Sent only once the blocker is through: by then it lost arbitration.
    let report = loser.flush(EVENT).unwrap();
    assert_eq!((report.sent, report.failed), (1, 0));
    let (ok, out, err) = run(&serve, &["status", "--node", "loser"]);
    assert!(ok, "{err}");
    // 0x400 (100 0000 0000) loses to 0x001 at its first bit.
    assert!(
        out.contains("ALC:              0x00 arbitration lost at bit 0 (ID.28)"),
        "{out}"
    );
    let (ok, out, err) = run(&serve, &["regs", "--node", "loser"]);
    assert!(ok, "{err}");
    assert!(
        out.starts_with("node 3 (loser)\nPeliCAN registers, operating mode\n"),
        "{out}"
    );
    assert!(out.contains("  6 BTR0   00\n"), "{out}");
    assert!(out.contains("SR"), "{out}");
}

#[test]
fn status_and_regs_name_a_missing_node() {
    let serve = Serve::start(500_000);
    let (ok, _, err) = run(&serve, &["regs", "--node", "42"]);
    assert!(!ok && err.contains("no node 42"), "{err}");
    let (ok, _, err) = run(&serve, &["status", "--node", "ghost"]);
    assert!(!ok && err.contains("no node ghost"), "{err}");
}

#[test]
fn other_backends_and_bad_urls_are_refused_clearly() {
    let bin = env!("CARGO_BIN_EXE_buslab");
    for (url, want) in [
        ("socketcan:nosuchcan9", "cannot open socketcan:nosuchcan9: "),
        (
            "slcan:/nonexistent/ttyACM0",
            "cannot open slcan:/nonexistent/ttyACM0: cannot open serial port",
        ),
        (
            "tcp://x",
            "unknown backend \"tcp\": expected socketcand://HOST[:PORT][/CHANNEL]",
        ),
        ("socketcand://h:99999/x", "port \"99999\" must be a number"),
    ] {
        let out = Command::new(bin)
            .args(["dump", "--bus", url])
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success() && err.contains(want), "{url}: {err}");
    }
    // Nobody listening: says where it tried.
    let out = Command::new(bin)
        .args(["send", "--bus", "socketcand://127.0.0.1:1/vcan0", "123#"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("cannot join socketcand://127.0.0.1:1/vcan0"),
        "{err}"
    );
    assert!(
        err.contains("start a bus with `buslab bus serve` or `buslab lab`"),
        "{err}"
    );
}

#[test]
fn scenario_nodes_share_the_wire_with_clients() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("s.toml");
    std::fs::write(
        &path,
        "bitrate = 500000\n[[nodes]]\nname = \"ecu\"\n  [[nodes.traffic]]\n  kind = \"periodic\"\n  frame = \"0AA#55\"\n  period = \"1ms\"\n",
    )
    .unwrap();
    let serve = Serve::start_with(500_000, &["--nodes", path.to_str().unwrap()]);
    let mut me = serve.client();
    for _ in 0..3 {
        let m = me.recv(WAIT).unwrap().unwrap();
        assert_eq!(m.record, frame("0AA#55"));
    }
    // And the scenario node acknowledges a client's frame: the sender completes.
    let (ok, _, err) = run(&serve, &["send", "123#01"]);
    assert!(ok, "{err}");
}

#[test]
fn a_scenario_at_another_bit_rate_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("s.toml");
    std::fs::write(&path, "bitrate = 125000\n[[nodes]]\nname = \"a\"\n").unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_buslab"))
        .args(["bus", "serve", "--listen", "127.0.0.1:0", "--nodes"])
        .arg(&path)
        .stdout(Stdio::null())
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("runs at 125000 bit/s but the bus at 500000 bit/s"),
        "{err}"
    );
}

#[test]
fn serve_at_max_speed_delivers_every_frame_in_order() {
    let serve = Serve::start_with(1_000_000, &["--speed", "max"]);
    let mut rx = serve.client();
    let mut tx = serve.client();
    let frames: Vec<_> = (0..500u32)
        .map(|i| frame(&format!("123#{:08X}", i)))
        .collect();
    for f in &frames {
        tx.send(f).unwrap();
    }
    let report = tx.flush(EVENT).unwrap();
    assert_eq!((report.sent, report.failed), (500, 0));
    for want in &frames {
        let got = rx.recv(WAIT).unwrap().expect("every frame arrives");
        assert_eq!(&got.record, want);
    }
}

#[test]
fn serve_names_a_bad_speed_and_what_is_allowed() {
    for bad in ["fast", "0", "-2", "2000000", "nan"] {
        let out = Command::new(env!("CARGO_BIN_EXE_buslab"))
            .args(["bus", "serve", "--listen", "127.0.0.1:0"])
            .arg(format!("--speed={bad}"))
            .stdout(Stdio::null())
            .output()
            .unwrap();
        assert!(!out.status.success(), "--speed {bad} accepted");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            err.contains(&format!("speed {bad}")) || err.contains(&format!("speed \"{bad}\"")),
            "{bad}: {err}"
        );
        assert!(
            err.contains("\"max\"") && err.contains("0.001..=1000000"),
            "{bad}: {err}"
        );
    }
}

#[test]
fn serve_refuses_a_busy_address() {
    let serve = Serve::start(500_000);
    let out = Command::new(env!("CARGO_BIN_EXE_buslab"))
        .args(["bus", "serve", "--listen", &serve.addr.to_string()])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains(&format!("cannot listen on {}", serve.addr)),
        "{err}"
    );
}

#[test]
fn status_without_a_node_lists_every_other_node() {
    let serve = Serve::start(500_000);
    let mut a = serve.client();
    a.set_name("alpha").unwrap();
    let mut b = serve.client();
    b.set_name("beta").unwrap();
    let (ok, out, err) = run(&serve, &["status"]);
    assert!(ok, "{err}");
    let heads: Vec<&str> = out.lines().filter(|l| l.starts_with("node ")).collect();
    assert_eq!(heads, ["node 1 (alpha)", "node 2 (beta)"]);
    assert!(
        out.contains("\nbus:              500000 bit/s, load "),
        "{out}"
    );
}

#[test]
fn dump_shows_error_frames_with_e() {
    let serve = Serve::start(500_000);
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("e.log");
    let child = dump(&serve, &["-e", "-n", "1", "-l", log.to_str().unwrap()]);
    let (ok, _, _) = run(&serve, &["send", "--btr", "07:4D", "123#11"]);
    assert!(!ok);
    let (ok, _, err) = run(&serve, &["send", "321#01"]);
    assert!(ok, "{err}");
    let out = child.finish();
    // candump -e's words, one class per line: what Linux's SJA1000 driver reports for a bus
    // error (protocol violation + bus error, with the type and place from ECC and the
    // counters; which error the mistimed node meets depends on when it sends).
    let first = out.lines().next().unwrap_or_default();
    assert!(
        first.starts_with("  vcan0  20000288   [8]  ") && first.ends_with("   ERRORFRAME"),
        "{out}"
    );
    assert!(out.contains("\n\tprotocol-violation{{"), "{out}");
    assert!(out.contains("\n\tbus-error\n"), "{out}");
    assert!(out.contains("\n\terror-counter-tx-rx{{"), "{out}");
    assert!(out.ends_with("321   [1]  01\n"), "{out}");
    let log = std::fs::read_to_string(log).unwrap();
    assert!(log.contains(" vcan0 20000288#"), "{log}");
}

#[test]
fn dump_views_like_candump_t_a_x() {
    let serve = Serve::start(500_000);
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("x.log");
    let child = dump(
        &serve,
        &[
            "-t",
            "z",
            "-a",
            "-x",
            "-n",
            "2",
            "-l",
            log.to_str().unwrap(),
        ],
    );
    let (ok, _, err) = run(&serve, &["send", "123#4142", "124#00"]);
    assert!(ok, "{err}");
    let out = child.finish();
    let lines: Vec<&str> = out.lines().collect();
    assert_eq!(
        lines[0],
        " (000.000000)  vcan0  RX - -  123   [2]  41 42                     'AB'"
    );
    // Since the first frame: bus time, as long as the server took to get the second.
    let (stamp, rest) = lines[1].split_at(13);
    assert!(
        stamp.starts_with(" (") && stamp.ends_with(")") && stamp.as_bytes()[5] == b'.',
        "{out}"
    );
    assert_eq!(
        rest,
        "  vcan0  RX - -  124   [1]  00                        '.'"
    );
    // The log gets R (received) after each frame, as candump -x writes it.
    let log = std::fs::read_to_string(log).unwrap();
    assert!(log.ends_with(" vcan0 124#00 R\n"), "{log}");
}

/// A socketcand without buslab's extensions: greets, opens, takes frames silently, and
/// answers everything else `< error unknown command >`.
fn plain_socketcand() -> (String, JoinHandle<()>) {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let url = format!("socketcand://{}/vcan0", listener.local_addr().unwrap());
    let server = thread::spawn(move || {
        for stream in listener.incoming().take(3) {
            let mut s = stream.unwrap();
            s.write_all(b"< hi >").unwrap();
            let mut deframer = buslab_socketcand::Deframer::new();
            let mut buf = [0u8; 1024];
            while let Ok(n @ 1..) = s.read(&mut buf) {
                deframer.push(&buf[..n]);
                while let Some(Ok(element)) = deframer.next_element() {
                    let answer: &[u8] = match element.split_whitespace().next() {
                        Some("open" | "rawmode") => b"< ok >",
                        Some("send") => b"",
                        _ => b"< error unknown command >",
                    };
                    let _ = s.write_all(answer);
                }
            }
        }
    });
    (url, server)
}

#[test]
fn a_plain_socketcand_gets_frames_but_no_confirmation_status_or_registers() {
    let (url, server) = plain_socketcand();
    let bin = env!("CARGO_BIN_EXE_buslab");
    let out = Command::new(bin)
        .args(["send", "--bus", &url, "--name", "x", "123#11"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(err.contains("--name x is ignored"), "{err}");
    assert!(
        err.contains("cannot confirm that the 1 frame(s) were sent"),
        "{err}"
    );
    for (args, want) in [
        (
            &["status"][..],
            "the server has no node status (not a buslab bus)",
        ),
        (
            &["regs", "--node", "1"][..],
            "the server has no register access (not a buslab bus)",
        ),
    ] {
        let out = Command::new(bin)
            .args(args)
            .args(["--bus", &url])
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            !out.status.success() && err.contains(want),
            "{args:?}: {err}"
        );
    }
    server.join().unwrap();
}

#[test]
fn dump_logs_in_every_format_its_extension_names() {
    let serve = Serve::start(500_000);
    let dir = tempfile::tempdir().unwrap();
    let frames = ["123#1122", "1ABCDEF0#DEADBEEF", "7FF#"];
    // The frames as `log cat` prints any log back (candump lines, after the timestamp).
    let want = ["vcan0 123#1122", "vcan0 1ABCDEF0#DEADBEEF", "vcan0 7FF#"];
    for ext in ["log", "asc", "blf", "trc", "csv", "pcap", "pcapng", "db"] {
        let log = dir.path().join(format!("x.{ext}"));
        let child = dump(&serve, &["-n", "3", "-l", log.to_str().unwrap()]);
        let (ok, _, err) = run(&serve, &[&["send"][..], &frames].concat());
        assert!(ok, "{err}");
        child.finish();
        let out = serve
            .buslab()
            .args(["log", "cat"])
            .arg(&log)
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{ext}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let text = String::from_utf8_lossy(&out.stdout);
        let got: Vec<&str> = text.lines().map(|l| l.split_once(' ').unwrap().1).collect();
        // Only candump and pcapng keep interface names; the others keep a channel number or
        // nothing (docs/logs.md): only the frames are compared.
        if !matches!(ext, "log" | "pcapng") {
            let frames_only: Vec<&str> = got.iter().map(|l| l.split_once(' ').unwrap().1).collect();
            assert_eq!(frames_only, frames, "{ext}: {text}");
        } else {
            assert_eq!(got, want, "{ext}: {text}");
        }
    }
}

#[test]
fn a_terminated_dump_finishes_its_blf_log() {
    let serve = Serve::start(500_000);
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("live.blf");
    let child = dump(&serve, &["-l", log.to_str().unwrap()]);
    let (ok, _, err) = run(&serve, &["send", "123#01", "124#02"]);
    assert!(ok, "{err}");
    // dump printed both frames, so both are in the writer; SIGTERM must close the file
    // properly (BLF's last container and header counts).
    let mut child = child;
    let mut stdout = BufReader::new(child.child.stdout.take().unwrap());
    for _ in 0..2 {
        let mut line = String::new();
        stdout.read_line(&mut line).unwrap();
    }
    nix::sys::signal::kill(
        nix::unistd::Pid::from_raw(child.child.id() as i32),
        nix::sys::signal::Signal::SIGTERM,
    )
    .unwrap();
    let status = child.child.wait().unwrap();
    assert!(status.success(), "{}", child.stderr.join().unwrap());
    let out = serve
        .buslab()
        .args(["log", "cat"])
        .arg(&log)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8_lossy(&out.stdout);
    let got: Vec<&str> = text
        .lines()
        .map(|l| l.rsplit_once(' ').unwrap().1)
        .collect();
    assert_eq!(got, ["123#01", "124#02"], "{text}");
}

#[test]
fn dump_refuses_an_unknown_log_extension() {
    let out = Command::new(env!("CARGO_BIN_EXE_buslab"))
        .args([
            "dump",
            "--bus",
            "socketcand://127.0.0.1:1/can0",
            "-l",
            "x.mf4",
        ])
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("\"mf4\"") && err.contains(".blf"), "{err}");
}

/// The lowest file descriptor number `pid` does not have open (the one its next `accept` gets).
fn lowest_free_fd(pid: u32, skip: &[u32]) -> u32 {
    let open: Vec<u32> = std::fs::read_dir(format!("/proc/{pid}/fd"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_str().unwrap().parse().unwrap())
        .collect();
    (0..)
        .find(|n| !open.contains(n) && !skip.contains(n))
        .unwrap()
}

fn read_element(stream: &mut std::net::TcpStream) -> String {
    let mut text = Vec::new();
    let mut byte = [0u8; 1];
    while text.last() != Some(&b'>') {
        stream.read_exact(&mut byte).unwrap();
        text.push(byte[0]);
    }
    String::from_utf8(text).unwrap()
}

/// A connection that comes while the server has no file descriptor left waits in the listen
/// queue, and the listener reports it once: the server must try again by itself, and let it
/// in as soon as a descriptor is free (here: when another client leaves).
#[test]
fn a_connection_the_server_had_no_descriptor_for_gets_in_when_one_is_free() {
    let log = tempfile::NamedTempFile::new().unwrap();
    let mut serve = Serve::start_logging(125_000, &[], log.reopen().unwrap().into());
    let (addr, pid) = (serve.addr, serve.pid());
    // Room for exactly one more descriptor: the first client's.
    let first_fd = lowest_free_fd(pid, &[]);
    let limit = lowest_free_fd(pid, &[first_fd]);
    let status = Command::new("prlimit")
        .arg(format!("--pid={pid}"))
        .arg(format!("--nofile={limit}:{limit}"))
        .status()
        .unwrap();
    assert!(status.success(), "prlimit failed");

    let mut first = std::net::TcpStream::connect(addr).unwrap();
    first.set_read_timeout(WAIT).unwrap();
    assert_eq!(read_element(&mut first), "< hi >");
    let mut second = std::net::TcpStream::connect(addr).unwrap();
    second.set_read_timeout(WAIT).unwrap();
    // The server saw the second connection and could not take it.
    let warned = || std::fs::read_to_string(log.path()).unwrap();
    while !warned().contains("cannot accept a connection") {
        assert!(!serve.has_ended(), "bus serve ended: {}", warned());
        thread::sleep(Duration::from_millis(10));
    }
    drop(first);
    assert_eq!(read_element(&mut second), "< hi >", "{}", warned());
}

/// What a departed client's node did with the frames it handed over is logged, with the
/// reason for those it dropped (the log said `left: sent 1, received 0, lost 0` while frames
/// were lost), and so is an element its close cut short.
#[test]
fn a_departed_clients_dropped_frames_are_logged_with_the_reason() {
    let log = tempfile::NamedTempFile::new().unwrap();
    let serve = Serve::start_logging(500_000, &[], log.reopen().unwrap().into());
    let text = || std::fs::read_to_string(log.path()).unwrap();
    let wait_for = |want: &str| {
        let started = std::time::Instant::now();
        while !text().contains(want) {
            assert!(
                started.elapsed() < EVENT,
                "no {want:?} in the log:\n{}",
                text()
            );
            thread::sleep(Duration::from_millis(10));
        }
    };
    let mut watcher = serve.client();
    // Its connector pulled: nobody hears it, so its frames can never go.
    let mut zombie = std::net::TcpStream::connect(serve.addr).unwrap();
    zombie.set_read_timeout(WAIT).unwrap();
    zombie
        .write_all(
            b"< open vcan0 >< rawmode >< buslab_name zombie >< buslab_fault 0 disconnect zombie >",
        )
        .unwrap();
    for _ in 0..5 {
        read_element(&mut zombie);
    }
    zombie
        .write_all(b"< send 123 1 01 >< send 123 1 02 >< send 123 1 03 >< send 1")
        .unwrap();
    drop(zombie);
    wait_for("(zombie) left:");
    let all = text();
    assert!(
        all.contains("(zombie) left: sent 0, dropped 3 (none sent for 1.00 s of bus time)"),
        "{all}"
    );
    assert!(
        all.contains("closed in the middle of an element: 8 bytes discarded (\"< send 1\")"),
        "{all}"
    );
    // A client whose frame went: nothing dropped.
    let mut sender = std::net::TcpStream::connect(serve.addr).unwrap();
    sender.set_read_timeout(WAIT).unwrap();
    sender
        .write_all(b"< open vcan0 >< rawmode >< buslab_name sender >< send 321 1 AA >")
        .unwrap();
    for _ in 0..4 {
        read_element(&mut sender);
    }
    drop(sender);
    assert_eq!(watcher.recv(WAIT).unwrap().unwrap().record, frame("321#AA"));
    wait_for("(sender) left:");
    assert!(
        text().contains("(sender) left: sent 1, dropped 0, received 0"),
        "{}",
        text()
    );
}
