//! Out-of-range numbers on the CAN client and server command lines are refused by name,
//! never a panic (found in review).

mod bus_common;

use std::process::Command;

use bus_common::Serve;
use buslab_canbus::CanBus;

/// Runs buslab; nobody listens on port 1, so a command that gets past its options fails there.
fn buslab(args: &[&str]) -> (bool, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_buslab"))
        .args(args)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(!err.contains("panicked"), "{args:?} panicked: {err}");
    (out.status.success(), err)
}

const NOBODY: &str = "socketcand://127.0.0.1:1/vcan0";

#[test]
fn send_timeout_must_be_a_sane_duration_with_a_unit() {
    for bad in ["1e300s", "nans", "inf", "1e19", "-1s", "0.5", "101days"] {
        let (ok, err) = buslab(&["send", "--bus", NOBODY, &format!("--timeout={bad}"), "123#"]);
        assert!(!ok, "{bad}");
        assert!(err.contains(&format!("duration \"{bad}\"")), "{bad}: {err}");
    }
    // A bare number is refused: it could mean seconds or milliseconds.
    let (ok, err) = buslab(&["send", "--bus", NOBODY, "--timeout", "2", "123#"]);
    assert!(!ok && err.contains("has no unit"), "{err}");
    // A good one gets as far as connecting.
    let (ok, err) = buslab(&["send", "--bus", NOBODY, "--timeout", "500ms", "123#"]);
    assert!(!ok && err.contains("cannot join"), "{err}");
}

#[test]
fn gen_gap_must_be_a_sane_duration_with_a_unit() {
    // (A bare number is cangen's milliseconds: can_utils_habits.rs.)
    for bad in ["1e300ms", "NaN", "1e22", "-5ms", "101days"] {
        let (ok, err) = buslab(&["gen", "--bus", NOBODY, "-n", "1", &format!("--gap={bad}")]);
        assert!(!ok, "{bad}");
        assert!(err.contains(&format!("duration \"{bad}\"")), "{bad}: {err}");
    }
    let (ok, err) = buslab(&["gen", "--bus", NOBODY, "-n", "1", "-g", "0s"]);
    assert!(!ok && err.contains("cannot join"), "{err}");
}

#[test]
fn gen_names_its_node_as_docs_bus_md_shows() {
    // docs/bus.md: `buslab gen … --name loser`, then `buslab status --node loser`. Alone on
    // the bus its frame gets no ACK, and the failure shows the node's status by name.
    let serve = Serve::start(500_000);
    let out = serve
        .buslab()
        .args(["gen", "--bus", &serve.url, "--name", "genny"])
        // Nobody acknowledges: it fails whenever the timeout ends.
        .args(["-n", "1", "-g", "0s", "-I", "123", "-L", "1", "-D", "11"])
        .args(["--timeout", "1s"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{err}");
    assert!(err.contains("\nnode 1 (genny)\n"), "{err}");
}

#[test]
fn an_endless_scenario_file_is_refused_not_read_forever() {
    // `read_to_string("/dev/zero")` grew until memory ran out; a FIFO blocked forever.
    let dir = tempfile::tempdir().unwrap();
    let fifo = dir.path().join("scenario.toml");
    assert!(
        std::process::Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .unwrap()
            .success()
    );
    let fifo = fifo.to_string_lossy().into_owned();
    for (path, why) in [("/dev/zero", "is a device"), (fifo.as_str(), "is a FIFO")] {
        let (ok, err) = buslab(&["sim", path]);
        assert!(!ok);
        assert!(
            err.contains(&format!("{path} {why}, not a regular file")),
            "{err}"
        );
        let (ok, err) = buslab(&["bus", "serve", "--listen", "127.0.0.1:0", "--nodes", path]);
        assert!(!ok);
        assert!(
            err.contains(&format!("{path} {why}, not a regular file")),
            "{err}"
        );
    }
}

#[test]
fn ids_follow_the_digit_rule_and_jerrycan_ids_are_read_the_jerrycan_way() {
    // `0x800#` was taken as an extended ID despite the "3 or 8 digits" rule; `+f` passed as a
    // hex byte.
    for (args, needle) in [
        (
            &["send", "--bus", NOBODY, "0x800#"][..],
            "must be 3 hex digits",
        ),
        (
            &["send", "--bus", NOBODY, "--btr", "+f:4D", "123#"],
            "BTR0:BTR1",
        ),
        (
            &["gen", "--bus", NOBODY, "-n", "1", "-D", "+f"],
            "must be 0..8 bytes of hex",
        ),
        (
            &["gen", "--bus", NOBODY, "-n", "1", "-I", "+1"],
            "must be hex",
        ),
        (
            &["send", "--bus", NOBODY, "--jerrycan", "1000#"],
            "JerryCAN ID",
        ),
    ] {
        let (ok, err) = buslab(args);
        assert!(!ok, "{args:?}");
        assert!(err.contains(needle), "{args:?}: {err}");
    }
    // Seed 002 §5.4.4.4: JerryCAN's 246 is the ID 123h.
    let serve = Serve::start(500_000);
    let mut rx = serve.client();
    let out = serve
        .buslab()
        .args(["send", "--bus", &serve.url, "--jerrycan", "246#1122"])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let got = rx
        .recv(Some(std::time::Duration::from_secs(30)))
        .unwrap()
        .expect("the frame");
    assert_eq!(got.record.to_string(), "123#1122");
}

#[test]
fn gen_as_fast_as_the_bus_takes_them_confirms_every_frame() {
    // `gen -g 0 -n 40000` ran 20000 frames ahead of the bus: its last `< buslab_status >`
    // waited behind them, timed out after 5 s, and the last frames were lost as it left.
    const COUNT: usize = 40_000;
    let serve = Serve::start(500_000);
    let mut rx = serve.client();
    let reader = std::thread::spawn(move || {
        let mut got = 0;
        while got < COUNT {
            match rx.recv(Some(std::time::Duration::from_secs(60))).unwrap() {
                Some(_) => got += 1,
                None => break,
            }
        }
        got
    });
    let out = serve
        .buslab()
        .args(["gen", "--bus", &serve.url, "-g", "0s", "-n"])
        .arg(COUNT.to_string())
        .args(["-L", "8", "-I", "i"])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(reader.join().unwrap(), COUNT);
}
