//! The CAN client commands (`dump`, `send`, `gen`, `regs`, `status`) against `buslab bus serve`.

mod bus_common;

use std::process::{Command, Stdio};
use std::time::Duration;

use bus_common::{Serve, frame};
use buslab_canbus::CanBus;

/// `buslab dump` in the background, printing `count` frames.
fn dump(serve: &Serve, extra: &[&str]) -> std::process::Child {
    let mut child = serve
        .buslab()
        .args(["dump", "--bus", &serve.url])
        .args(extra)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // Joined once the server lists it (dump prints nothing before the first frame).
    let mut probe = serve.client();
    for _ in 0..200 {
        if probe.nodes().unwrap().len() >= 2 {
            return child;
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    let _ = child.kill();
    let _ = child.wait();
    panic!("dump did not join");
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
    let out = child.wait_with_output().unwrap();
    assert!(out.status.success());
    assert_eq!(
        String::from_utf8_lossy(&out.stdout),
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
    let m = me.recv(Some(Duration::from_secs(5))).unwrap().unwrap();
    assert_eq!(m.frame, frame("00000005#01"));
}

#[test]
fn gen_increments_ids_and_data() {
    let serve = Serve::start(1_000_000);
    let mut me = serve.client();
    let (ok, _, err) = run(
        &serve,
        &[
            "gen", "-n", "20", "-g", "0", "-I", "i", "-L", "2", "-D", "i",
        ],
    );
    assert!(ok, "{err}");
    for i in 0..20u32 {
        let m = me.recv(Some(Duration::from_secs(5))).unwrap().unwrap();
        assert_eq!(m.frame.to_string(), format!("{i:03X}#{i:02X}00"));
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
    // The seed's 50 kbit/s registers on a 500 kbit/s bus: the frame cannot get through.
    let (ok, _, err) = run(
        &serve,
        &["send", "--btr", "07:4D", "--timeout", "300ms", "123#11"],
    );
    assert!(!ok);
    // Either still trying or given up (bus-off) when the timeout ends.
    assert!(err.contains("frames were"), "{err}");
    assert!(err.contains("timing:           mismatch"), "{err}");
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
    let mut lost = String::new();
    for _ in 0..100 {
        let (ok, out, err) = run(&serve, &["status", "--node", "loser"]);
        assert!(ok, "{err}");
        if out.contains("ALC:              0x") {
            lost = out;
            break;
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    // 0x400 (100 0000 0000) loses to 0x001 at its first bit.
    assert!(
        lost.contains("ALC:              0x00 arbitration lost at bit 0 (ID.28)"),
        "{lost}"
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
        ("socketcan:can0", "socketcan backend is not available yet"),
        ("slcan:/dev/ttyACM0", "slcan backend is not available yet"),
        ("tcp://x", "expected socketcand://HOST[:PORT]/CHANNEL"),
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
        let m = me.recv(Some(Duration::from_secs(5))).unwrap().unwrap();
        assert_eq!(m.frame, frame("0AA#55"));
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
    assert!(out.contains("bus_bitrate:      500000"), "{out}");
}

#[test]
fn dump_shows_error_frames_with_e() {
    let serve = Serve::start(500_000);
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("e.log");
    let child = dump(&serve, &["-e", "-n", "1", "-l", log.to_str().unwrap()]);
    let (ok, _, _) = run(
        &serve,
        &["send", "--btr", "07:4D", "--timeout", "300ms", "123#11"],
    );
    assert!(!ok);
    let (ok, _, err) = run(&serve, &["send", "321#01"]);
    assert!(ok, "{err}");
    let out = child.wait_with_output().unwrap();
    let out = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.contains("  vcan0  20000088   [8]  00 00 00 00 00 00 00 00   ERRORFRAME protocol-violation,bus-error\n"),
        "{out}"
    );
    assert!(out.ends_with("321   [1]  01\n"), "{out}");
    let log = std::fs::read_to_string(log).unwrap();
    assert!(log.contains(" vcan0 20000088#0000000000000000\n"), "{log}");
}
