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
        .map(|_| me.recv(wait).unwrap().unwrap().frame.to_string())
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
