//! `buslab sendfile` / `buslab recvfile` across the virtual bus, and the seed's cut-wire
//! experiment: the sender is alone on its piece of wire (no node acknowledges, its TEC climbs to
//! error-passive and the controller retransmits the first frame), then the receiver is
//! connected (the repair) and the file arrives whole, once.

mod bus_common;

use std::io::{BufRead, BufReader};
use std::process::{Child, Output, Stdio};
use std::time::{Duration, Instant};

use bus_common::Serve;

const BITRATE: u32 = 500_000;

/// How long `bytes` may take on the bus: worst-case frame bits, x20 for a loaded machine,
/// with a floor of 30 s.
fn deadline_for(bytes: usize) -> Duration {
    let frames = bytes / 8 + 1;
    let on_the_bus = Duration::from_secs_f64(frames as f64 * 160.0 / f64::from(BITRATE));
    (on_the_bus * 20).max(Duration::from_secs(30))
}

/// Waits for `child` until `deadline` (killed and a panic after it).
fn finish(mut child: Child, deadline: Duration, what: &str) -> Output {
    let start = Instant::now();
    while child.try_wait().unwrap().is_none() {
        if start.elapsed() > deadline {
            let _ = child.kill();
            panic!("{what} did not finish within {deadline:?}");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    child.wait_with_output().unwrap()
}

/// Bytes that look random (a fixed xorshift sequence).
fn random_bytes(len: usize) -> Vec<u8> {
    let mut x: u64 = 0x9E37_79B9_7F4A_7C15;
    (0..len)
        .map(|_| {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            (x >> 24) as u8
        })
        .collect()
}

#[test]
fn a_file_sent_over_a_cut_wire_arrives_whole_once_repaired() {
    let serve = Serve::start(BITRATE);
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("in.bin");
    let output = dir.path().join("out.bin");
    // A multiple of 8: the last frame is empty.
    let data = random_bytes(24_000);
    std::fs::write(&input, &data).unwrap();
    let deadline = deadline_for(data.len());

    let mut sender = serve
        .buslab()
        .args(["sendfile", "--id", "0x123", input.to_str().unwrap()])
        .args(["--bus", &serve.url])
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // The cut: nobody acknowledges; the sender says so and keeps retransmitting.
    let mut sender_err = BufReader::new(sender.stderr.take().unwrap());
    let mut said = String::new();
    while !said.contains("no frame got through") {
        let mut line = String::new();
        assert!(
            sender_err.read_line(&mut line).unwrap() > 0,
            "the sender ended before it said the wire carries nothing: {said}"
        );
        said.push_str(&line);
    }
    assert!(said.contains("error-passive"), "{said}");
    assert!(
        sender.try_wait().unwrap().is_none(),
        "the sender gave up: {said}"
    );

    // The repair: a receiver on the wire.
    let receiver = serve
        .buslab()
        .args(["recvfile", "--id", "0x123", output.to_str().unwrap()])
        .args(["--bus", &serve.url])
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let received = finish(receiver, deadline, "recvfile");
    let recv_err = String::from_utf8_lossy(&received.stderr);
    assert!(received.status.success(), "{recv_err}");
    assert!(
        recv_err.contains("received 24000 bytes on ID 123"),
        "{recv_err}"
    );
    let sent = finish(sender, deadline, "sendfile");
    assert!(sent.status.success());
    let mut rest = String::new();
    std::io::Read::read_to_string(&mut sender_err, &mut rest).unwrap();
    assert!(
        rest.contains("sent") && rest.contains("24000 bytes"),
        "{rest}"
    );
    assert!(std::fs::read(&output).unwrap() == data, "the file differs");
}

#[test]
fn a_receiver_that_gets_nothing_writes_nothing() {
    let serve = Serve::start(BITRATE);
    let dir = tempfile::tempdir().unwrap();
    let output = dir.path().join("out.bin");
    let out = serve
        .buslab()
        .args(["recvfile", "--id", "0x123", output.to_str().unwrap()])
        .args(["--bus", &serve.url, "--timeout", "500ms"])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        stderr.contains("no file began on ID 123 within"),
        "{stderr}"
    );
    assert!(!output.exists());
}
