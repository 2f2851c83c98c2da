//! python-can 4.6.1 (`interface='socketcand'`) and buslab's client on one `buslab bus serve`.

#[path = "support/outside_tools.rs"]
mod outside_tools;

mod bus_common;

use outside_tools::{python_can, root};
use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};
use std::time::Duration;

use bus_common::{Serve, frame};
use buslab_canbus::CanBus;

#[test]
fn python_can_detects_the_beacon() {
    let Some(python) = python_can() else {
        return;
    };
    let serve = Serve::start_with(500_000, &["--beacon"]);
    let out = Command::new(&python)
        .arg(root().join("tests/interop/can_detect_beacon.py"))
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(
        String::from_utf8_lossy(&out.stdout).trim(),
        format!("socketcand 127.0.0.1 {} vcan0", serve.addr.port())
    );
}

#[test]
fn python_can_exchanges_frames_and_sees_priority_order() {
    let Some(python) = python_can() else {
        return;
    };
    let serve = Serve::start(1_000_000);
    let mut child = Command::new(&python)
        .arg(root().join("tests/interop/can_socketcand_peer.py"))
        .arg(serve.addr.ip().to_string())
        .arg(serve.addr.port().to_string())
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .unwrap();
    let mut lines = BufReader::new(child.stdout.take().unwrap()).lines();
    let mut next = || {
        lines
            .next()
            .expect("python-can script ended early")
            .unwrap()
    };
    assert_eq!(next(), "ready");
    let mut me = serve.client();
    for f in ["123#1122", "1ABCDEF0#DEADBEEF", "321#R3"] {
        me.send(&frame(f)).unwrap();
    }
    assert_eq!(next(), "rx 123 0 0 2 1122");
    assert_eq!(next(), "rx 1ABCDEF0 1 0 4 DEADBEEF");
    // python-can cannot represent a received remote frame (socketcand raw mode has none):
    // it gets the ID with no data (docs/bus.md).
    assert_eq!(next(), "rx 321 0 0 0 -");
    assert_eq!(next(), "sent");
    // A deadline for frames that normally come within milliseconds.
    let wait = Some(Duration::from_secs(60));
    let got: Vec<String> = (0..3)
        .map(|_| me.recv(wait).unwrap().unwrap().record.to_string())
        .collect();
    // python-can's remote frame (`< send 321 3 >`) is a remote frame on the bus.
    assert_eq!(got, ["123#0102", "1ABCDEF0#DEAD", "321#R3"]);

    // Several nodes contend: the bus is kept busy by a top-priority sender, the contenders'
    // frames wait in their chips and go out in priority order.
    let mut blocker = serve.client();
    let mut contenders: Vec<_> = (0..3).map(|_| serve.client()).collect();
    for _ in 0..3000 {
        blocker.send(&frame("001#0102030405060708")).unwrap();
    }
    for (c, f) in contenders.iter_mut().zip(["300#03", "200#02", "100#01"]) {
        c.send(&frame(f)).unwrap();
    }
    assert_eq!(next(), "order 100 200 300");
    assert!(
        child.wait().unwrap().success(),
        "python-can script failed (stderr above)"
    );
}

/// Frames of python-can scripts that leave right after sending (issue 25): `buslab dump` saw 1
/// of 10 `with` blocks' frames, 6 of 200 before `shutdown()`, and `can.player` lost its last
/// ones, because the server took the node off the bus with its queue when the client left.
mod leaving_right_after_sending {
    use super::*;

    /// `python -c SCRIPT HOST PORT ARGS…` against `serve`, to the end.
    fn run(python: &std::path::Path, serve: &Serve, script: &str, args: &[&str]) {
        let out = Command::new(python)
            .args(["-c", script])
            .arg(serve.addr.ip().to_string())
            .arg(serve.addr.port().to_string())
            .args(args)
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "python-can failed: {}",
            String::from_utf8_lossy(&out.stderr)
        );
    }

    fn receive(rx: &mut buslab_socketcand::SocketcandBus, count: usize) -> Vec<String> {
        (0..count)
            .map(|k| {
                rx.recv(Some(Duration::from_secs(60)))
                    .unwrap()
                    .unwrap_or_else(|| panic!("frame {k} of {count} never came"))
                    .record
                    .to_string()
            })
            .collect()
    }

    const WITH: &str = r#"
import sys, can
host, port, n = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
with can.Bus(interface="socketcand", host=host, port=port, channel="vcan0") as bus:
    bus.send(can.Message(arbitration_id=0x100, data=[n], is_extended_id=False))
"#;

    #[test]
    fn python_can_with_blocks_run_back_to_back_each_deliver_their_frame() {
        let Some(python) = python_can() else {
            return;
        };
        let serve = Serve::start(500_000);
        let mut rx = serve.client();
        for n in 0..10 {
            run(&python, &serve, WITH, &[&n.to_string()]);
        }
        let want: Vec<String> = (0..10).map(|n| format!("100#{n:02X}")).collect();
        assert_eq!(receive(&mut rx, 10), want);
    }

    #[test]
    fn python_can_sending_200_frames_then_shutting_down_delivers_all_200() {
        let Some(python) = python_can() else {
            return;
        };
        let serve = Serve::start(500_000);
        let mut rx = serve.client();
        let script = r#"
import sys, can
host, port = sys.argv[1], int(sys.argv[2])
bus = can.Bus(interface="socketcand", host=host, port=port, channel="vcan0")
for n in range(200):
    bus.send(can.Message(arbitration_id=0x200, data=n.to_bytes(2, "big"), is_extended_id=False))
bus.shutdown()
"#;
        run(&python, &serve, script, &[]);
        let want: Vec<String> = (0..200).map(|n| format!("200#{n:04X}")).collect();
        assert_eq!(receive(&mut rx, 200), want);
    }

    #[test]
    fn python_can_player_delivers_every_frame_of_a_log() {
        let Some(python) = python_can() else {
            return;
        };
        let serve = Serve::start(500_000);
        let mut rx = serve.client();
        let mut log = tempfile::Builder::new().suffix(".log").tempfile().unwrap();
        let want: Vec<String> = (0..20).map(|n| format!("300#{n:04X}")).collect();
        for (n, f) in want.iter().enumerate() {
            use std::io::Write;
            writeln!(log, "({:.6}) vcan0 {f}", 1_700_000_000.0 + n as f64 * 0.001).unwrap();
        }
        let out = Command::new(&python)
            .args(["-m", "can.player", "-i", "socketcand", "-c", "vcan0"])
            .arg("--bus-kwargs")
            .arg(format!("host={}", serve.addr.ip()))
            .arg(format!("port={}", serve.addr.port()))
            .arg("--")
            .arg(log.path())
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "can.player failed: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        assert_eq!(receive(&mut rx, 20), want);
    }
}
