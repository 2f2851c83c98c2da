//! `buslab sendfile` / `buslab recvfile` across the virtual bus, and the seed's cut-wire
//! experiment with a real file: the wire is broken (a scenario fault holds the bus dominant for
//! its first seconds) while the receiver listens and the sender starts; the sender says nothing
//! gets through and keeps trying; once the fault ends (the repair) the file arrives whole, once.

mod bus_common;

use std::io::{BufRead, BufReader, Read};
use std::process::{Child, ChildStderr, Output, Stdio};
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

/// How long the scenario keeps the wire broken from the server's start: the receiver and the
/// sender must both be on the bus before (they start at once; the test says so if not).
const BROKEN_FOR_S: u64 = 10;

/// Reads `child`'s stderr lines until one contains `what`.
fn wait_line(err: &mut BufReader<ChildStderr>, what: &str, who: &str) -> String {
    let mut said = String::new();
    while !said.contains(what) {
        let mut line = String::new();
        assert!(
            err.read_line(&mut line).unwrap() > 0,
            "{who} ended before it said {what:?}: {said}"
        );
        said.push_str(&line);
    }
    said
}

#[test]
fn a_file_sent_over_a_broken_wire_arrives_whole_once_repaired() {
    let dir = tempfile::tempdir().unwrap();
    let scenario = dir.path().join("broken.toml");
    std::fs::write(
        &scenario,
        format!(
            "bitrate = {BITRATE}\nduration = \"3600s\"\n\n[[nodes]]\nname = \"bystander\"\n\n\
             [[faults]]\nkind = \"stuck_dominant\"\nstart = 0\nend = \"{BROKEN_FOR_S}s\"\n"
        ),
    )
    .unwrap();
    let started = Instant::now();
    let serve = Serve::start_with(BITRATE, &["--nodes", scenario.to_str().unwrap()]);
    let input = dir.path().join("in.bin");
    let output = dir.path().join("out.bin");
    // A multiple of 8: the last frame is empty.
    let data = random_bytes(24_000);
    std::fs::write(&input, &data).unwrap();
    let deadline = deadline_for(data.len()) + Duration::from_secs(BROKEN_FOR_S);

    let mut receiver = serve
        .buslab()
        .args(["recvfile", "--id", "0x123", output.to_str().unwrap()])
        .args(["--bus", &serve.url])
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut recv_err = BufReader::new(receiver.stderr.take().unwrap());
    wait_line(&mut recv_err, "waiting for a file on ID 123", "recvfile");

    let mut sender = serve
        .buslab()
        .args(["sendfile", "--id", "0x123", input.to_str().unwrap()])
        .args(["--bus", &serve.url])
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut send_err = BufReader::new(sender.stderr.take().unwrap());
    wait_line(&mut send_err, "no frame got through", "sendfile");
    assert!(
        started.elapsed() < Duration::from_secs(BROKEN_FOR_S),
        "the machine is too slow for this test: the sender started after the repair"
    );
    assert!(!output.exists(), "nothing arrives while the wire is broken");

    let received = finish(receiver, deadline, "recvfile");
    assert!(received.status.success());
    let mut said = String::new();
    recv_err.read_to_string(&mut said).unwrap();
    assert!(said.contains("received 24000 bytes on ID 123"), "{said}");
    let sent = finish(sender, deadline, "sendfile");
    assert!(sent.status.success());
    let mut said = String::new();
    send_err.read_to_string(&mut said).unwrap();
    assert!(
        said.contains("sent") && said.contains("24000 bytes"),
        "{said}"
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
    // Its temporary file, made before the first frame, went with it.
    let left: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
    assert!(left.is_empty(), "left behind: {left:?}");
}

#[test]
fn recvfile_refuses_an_output_it_cannot_write_before_any_frame() {
    // Regression: recvfile checked OUT only once the whole transfer was in, then failed and
    // the file was lost. Now it says so at once (here without --timeout: it would otherwise
    // wait for a file for ever).
    let serve = Serve::start(BITRATE);
    let dir = tempfile::tempdir().unwrap();
    let fifo = dir.path().join("fifo");
    nix::unistd::mkfifo(&fifo, nix::sys::stat::Mode::S_IRWXU).unwrap();
    for (output, why) in [
        (dir.path().to_path_buf(), "a folder, not a regular file"),
        (fifo.clone(), "a FIFO, not a regular file"),
        (dir.path().join("missing/out.bin"), "missing/out.bin"),
    ] {
        let child = serve
            .buslab()
            .args(["recvfile", "--id", "0x123"])
            .arg(&output)
            .args(["--bus", &serve.url])
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let out = finish(child, deadline_for(0), "recvfile");
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{stderr}");
        assert!(stderr.contains(why), "{}: {stderr}", output.display());
        assert!(!stderr.contains("waiting for a file"), "{stderr}");
    }
    let names: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(names, ["fifo"], "nothing was made or left");
}
