//! can-utils habits of `gen` and `play` (cangen's interface first, canplayer's -I, standard
//! input and options, bare numbers in can-utils' units), and `buslab send` to SLCAN adapters
//! that still had the last session's answers queued (issue 25, deliverable 7).

mod bus_common;

#[path = "../../slcan/tests/support/fake_adapter.rs"]
#[allow(dead_code)]
mod fake_adapter;

use std::io::Write;
use std::process::{Command, Output, Stdio};
use std::time::Duration;

use bus_common::{Serve, frame};
use buslab_canbus::CanBus;
use fake_adapter::FakeAdapter;

/// How long a test waits for something that normally comes within milliseconds: a deadline
/// for an event, not a measure of speed (CI machines are loaded).
const EVENT: Duration = Duration::from_secs(60);

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

/// Runs `cmd` with `input` on its standard input.
fn with_stdin(mut cmd: Command, input: Vec<u8>) -> Output {
    let mut child = cmd
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut stdin = child.stdin.take().unwrap();
    // A writer thread: a player that stops reading early must not block the test.
    let writer = std::thread::spawn(move || {
        let _ = stdin.write_all(&input);
    });
    let out = child.wait_with_output().unwrap();
    writer.join().unwrap();
    out
}

/// Receives `n` frames on `me`, as text.
fn receive(me: &mut impl CanBus, n: usize) -> Vec<String> {
    (0..n)
        .map(|_| {
            me.recv(Some(EVENT))
                .unwrap()
                .expect("a frame")
                .record
                .to_string()
        })
        .collect()
}

/// Nothing more than what was received: a sentinel from another client comes next.
fn nothing_more(serve: &Serve, me: &mut impl CanBus) {
    // The other client stays until its frame was seen.
    let mut other = serve.client();
    other.send(&frame("7FF#5E")).unwrap();
    let m = me.recv(Some(EVENT)).unwrap().expect("the sentinel");
    assert_eq!(m.record, frame("7FF#5E"), "an extra frame was sent");
}

#[test]
fn gen_takes_the_interface_first_as_cangen() {
    let serve = Serve::start(500_000);
    let mut me = serve.client();
    // `cangen vcan0 -g 4 -I 42A -L 1 -D i`: the interface first, -g 4 in milliseconds.
    let out = serve
        .buslab()
        .args([
            "gen", &serve.url, "-g", "4", "-I", "42A", "-L", "1", "-D", "i",
        ])
        .args(["-n", "3", "--timeout", "60s"])
        .output()
        .unwrap();
    let err = text(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert_eq!(receive(&mut me, 3), ["42A#00", "42A#01", "42A#02"]);
    assert!(
        err.contains("-g 4: a number without a unit is taken as milliseconds, as cangen takes it (write -g 4ms to say so)"),
        "{err}"
    );
    nothing_more(&serve, &mut me);

    // With a unit, no warning; the interface and --bus together are refused.
    let out = serve
        .buslab()
        .args([
            "gen", &serve.url, "-g", "0s", "-I", "100", "-L", "0", "-n", "1",
        ])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert!(!text(&out.stderr).contains("without a unit"));
    assert_eq!(receive(&mut me, 1), ["100#"]);
    let out = serve
        .buslab()
        .args(["gen", &serve.url, "--bus", &serve.url, "-n", "1"])
        .output()
        .unwrap();
    assert!(
        !out.status.success() && text(&out.stderr).contains("the bus is given twice"),
        "{}",
        text(&out.stderr)
    );
    for (bad, want) in [
        ("1.2.3", "duration \"1.2.3\" is not a number"),
        ("-4", "duration \"-4\" must be a number with a unit"),
        ("99999999999999", "is longer than the longest accepted"),
    ] {
        let out = serve
            .buslab()
            .args(["gen", &serve.url, "-n", "1", &format!("-g={bad}")])
            .output()
            .unwrap();
        let err = text(&out.stderr);
        assert!(!out.status.success() && err.contains(want), "{bad}: {err}");
    }
}

const LOG: &str = "(1.000000) can0 100#01\n(1.001000) can1 200#02\n(1.002000) can0 101#03\n";

#[test]
fn play_reads_a_file_given_with_i_or_standard_input() {
    let serve = Serve::start(500_000);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("trace.log");
    std::fs::write(&path, LOG).unwrap();
    let mut me = serve.client();

    // canplayer -I FILE.
    let out = serve
        .buslab()
        .args(["play", "-I", path.to_str().unwrap(), "--bus", &serve.url])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert_eq!(receive(&mut me, 3), ["100#01", "200#02", "101#03"]);
    assert!(text(&out.stderr).contains("played 3 frames from"));

    // `-` and no file at all (canplayer's default) read standard input; with -I every word is
    // an assignment.
    for args in [&["play", "-"][..], &["play"][..], &["play", "-I", "-"][..]] {
        let mut cmd = serve.buslab();
        cmd.args(args).args(["--bus", &serve.url]);
        let out = with_stdin(cmd, LOG.as_bytes().to_vec());
        let err = text(&out.stderr);
        assert!(out.status.success(), "{args:?}: {err}");
        assert!(
            err.contains("played 3 frames from standard input (1 time)"),
            "{err}"
        );
        assert_eq!(receive(&mut me, 3), ["100#01", "200#02", "101#03"]);
    }
    let mut cmd = serve.buslab();
    cmd.args(["play", "-I", "-", "vcan0=can1", "--bus", &serve.url]);
    let out = with_stdin(cmd, LOG.as_bytes().to_vec());
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert_eq!(receive(&mut me, 1), ["200#02"]);
    nothing_more(&serve, &mut me);
}

#[test]
fn play_from_standard_input_refuses_garbage_by_name() {
    let serve = Serve::start(500_000);
    let play = |input: Vec<u8>, extra: &[&str]| {
        let mut cmd = serve.buslab();
        cmd.args(["play", "-", "--bus", &serve.url]).args(extra);
        let out = with_stdin(cmd, input);
        (out.status.success(), text(&out.stderr))
    };
    // Binary noise: the line is named, and what was played before it.
    let (ok, err) = play(b"(1.0) can0 100#01\n\xff\xfe\x00garbage\n".to_vec(), &[]);
    assert!(!ok, "{err}");
    assert!(
        err.contains("standard input: line 2: line is not UTF-8 text")
            && err.contains("1 frames were played"),
        "{err}"
    );
    let (ok, err) = play(b"\xff\xfe\x00\x01\x02\n".to_vec(), &[]);
    assert!(
        !ok && err.contains("standard input: line 1:") && err.contains("0 frames were played"),
        "{err}"
    );
    // Text that is no log line is skipped, as canplayer does, and said.
    let (ok, err) = play(b"hello\nworld\n".to_vec(), &[]);
    assert!(ok, "{err}");
    assert!(
        err.contains("standard input: 2 line(s) were no candump log lines")
            && err.contains("played 0 frames from standard input"),
        "{err}"
    );
    // A line without an end, 8 MiB long: read as it comes, refused by its length.
    let (ok, err) = play(vec![b'('; 8 << 20], &[]);
    assert!(
        !ok && err.contains("line 1: line is longer than 4096 bytes"),
        "{err}"
    );
    // A stream cannot be played twice, nor be a database.
    let (ok, err) = play(Vec::new(), &["-l", "2"]);
    assert!(
        !ok && err.contains("standard input can be read only once"),
        "{err}"
    );
    let (ok, err) = play(Vec::new(), &["--from", "sqlite"]);
    assert!(
        !ok && err.contains("an SQLite log is read from a file"),
        "{err}"
    );
    // Other formats come through the same way: a pcap that is not one.
    let (ok, err) = play(b"not a capture at all".to_vec(), &["--from", "pcap"]);
    assert!(!ok && err.contains("standard input:"), "{err}");
}

#[test]
fn play_takes_canplayer_options() {
    let serve = Serve::start(500_000);
    let dir = tempfile::tempdir().unwrap();
    // A gap of 1000 s in the middle: -s 1 skips it (as canplayer -s 1).
    let log = "(1.000000) can0 100#01\n(1001.000000) can0 100#02\n(1001.001000) can0 100#03\n";
    std::fs::write(dir.path().join("gap.log"), log).unwrap();
    let mut me = serve.client();
    let out = serve
        .buslab()
        .args(["play", "gap.log", "--bus", &serve.url, "-s", "1", "-g", "2"])
        .current_dir(dir.path())
        .output()
        .unwrap();
    let err = text(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert_eq!(receive(&mut me, 3), ["100#01", "100#02", "100#03"]);
    assert!(
        err.contains("-s 1: a number without a unit is taken as seconds, as canplayer takes it")
            && err.contains("-g 2: a number without a unit is taken as milliseconds"),
        "{err}"
    );

    // -n COUNT, -t; -v shows each frame sent with its log interface.
    let out = serve
        .buslab()
        .args([
            "-v", "play", "gap.log", "--bus", &serve.url, "-n", "2", "-t",
        ])
        .current_dir(dir.path())
        .output()
        .unwrap();
    let err = text(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert_eq!(receive(&mut me, 2), ["100#01", "100#02"]);
    assert!(
        err.contains(&format!("{} (can0) 100#01", serve.url)) && err.contains("played 2 frames"),
        "{err}"
    );
    nothing_more(&serve, &mut me);

    // canplayer's stdout hook: can1's lines printed, can0's sent.
    std::fs::write(dir.path().join("two.log"), LOG).unwrap();
    let out = serve
        .buslab()
        .args(["play", "two.log", "--bus", &serve.url, "-t"])
        .args(["stdout=can1", &format!("{}=can0", serve.url)])
        .current_dir(dir.path())
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert_eq!(text(&out.stdout), "(0000000001.001000) can1 200#02\n");
    assert_eq!(receive(&mut me, 2), ["100#01", "101#03"]);
    nothing_more(&serve, &mut me);

    // What does not fit is refused with the reason.
    for (flag, want) in [
        (
            "-x",
            "-x (canplayer's \"disable local loopback\") is not offered",
        ),
        ("-i", "-i (canplayer's interactive mode) is not offered"),
    ] {
        let out = serve
            .buslab()
            .args(["play", "two.log", "--bus", &serve.url, flag])
            .current_dir(dir.path())
            .output()
            .unwrap();
        assert!(
            !out.status.success() && text(&out.stderr).contains(want),
            "{}",
            text(&out.stderr)
        );
    }
}

/// Issue 25: against an emulated CANable, `buslab send` failed 1–3 times in 6 with `the
/// adapter refused "O" (answered BEL)`: the CR of the last session's `C` came late and shifted
/// the answers. Each fake here holds that answer (and a frame) until the next session writes,
/// and writes its answers one by one.
#[test]
fn send_through_an_slcan_adapter_six_times_in_a_row() {
    for kind in fake_adapter::ALL {
        let fake = FakeAdapter::start(kind);
        fake.pace_answers(true);
        fake.hold_close_answers();
        let url = format!("slcan:{}?bitrate=500000", fake.path());
        for n in 0..6 {
            let out = Command::new(env!("CARGO_BIN_EXE_buslab"))
                .args(["send", &url, &format!("123#{n:02X}")])
                .output()
                .unwrap();
            assert!(
                out.status.success(),
                "{kind:?}, send {n}: {}",
                text(&out.stderr)
            );
        }
        fake.wait_for(EVENT, |s| s.transmitted.len() == 6 && !s.open);
        let sent = fake.seen(|s| s.transmitted.clone());
        let want: Vec<String> = (0..6).map(|n| format!("123#{n:02X}")).collect();
        assert_eq!(sent, want, "{kind:?}");
    }
}
