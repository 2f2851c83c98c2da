//! `buslab log convert|info|cat` and `buslab play` as a user runs them: bad input named and
//! skipped on request, nothing read lost on errors and signals, an SQLite log that survives
//! `kill -9` up to its last commit, canplayer's pacing and interface assignments.

mod bus_common;

use std::io::Write;
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use bus_common::{Serve, frame};
use buslab_canbus::CanBus;

/// A deadline for an event that normally comes within a second (CI machines are loaded).
const EVENT: Duration = Duration::from_secs(60);

fn buslab() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_buslab"));
    c.env_remove("BUSLAB_BUS");
    c
}

fn run(args: &[&str], dir: &Path) -> (bool, String, String) {
    let out = buslab().args(args).current_dir(dir).output().unwrap();
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// `n` candump lines from the `from`th on, a millisecond apart.
fn lines(n: u64, from: u64) -> String {
    (from..from + n)
        .map(|i| {
            format!(
                "({}.{:06}) can0 {:03X}#{:02X}\n",
                1_700_000_000 + i / 1000,
                i % 1000 * 1000,
                i % 0x800,
                i % 256
            )
        })
        .collect()
}

/// Equal texts, or the first line that differs (not the whole flood).
fn assert_same_lines(got: &str, want: &str) {
    let first = got.lines().zip(want.lines()).position(|(g, w)| g != w);
    assert!(
        first.is_none() && got.lines().count() == want.lines().count(),
        "first difference at line {first:?}: {:?} vs {:?}; {} vs {} lines",
        first.and_then(|i| got.lines().nth(i)),
        first.and_then(|i| want.lines().nth(i)),
        got.lines().count(),
        want.lines().count()
    );
}

#[test]
fn a_bad_line_stops_the_conversion_naming_it_and_keeps_what_came_before() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("in.log"),
        "(1.000000) can0 123#11\n(2.000000) can0 123#1\n(3.000000) can0 7FF#R\n",
    )
    .unwrap();
    let (ok, _, err) = run(&["log", "convert", "in.log", "out.csv"], dir.path());
    assert!(!ok);
    assert!(
        err.contains("in.log: line 2:")
            && err.contains("odd number")
            && err.contains("--skip-bad")
            && err.contains("out.csv holds the 1 entry before it"),
        "{err}"
    );
    let (ok, out, _) = run(&["log", "cat", "out.csv"], dir.path());
    assert!(ok);
    assert_eq!(out, "(0000000001.000000) can0 123#11\n");
    // --skip-bad goes on and counts.
    let (ok, _, err) = run(
        &["log", "convert", "--skip-bad", "in.log", "out.csv"],
        dir.path(),
    );
    assert!(ok, "{err}");
    assert!(
        err.contains("2 entries, 1 bad skipped") && err.contains("line 2"),
        "{err}"
    );
    let (_, out, _) = run(&["log", "cat", "out.csv"], dir.path());
    assert_eq!(out.lines().count(), 2, "{out}");
}

#[test]
fn inputs_must_be_regular_files_and_formats_known() {
    let dir = tempfile::tempdir().unwrap();
    let (ok, _, err) = run(
        &["log", "cat", "/dev/zero", "--from", "candump"],
        dir.path(),
    );
    assert!(
        !ok && err.contains("/dev/zero") && err.contains("character device"),
        "{err}"
    );
    std::fs::write(dir.path().join("x.mf4"), "").unwrap();
    let (ok, _, err) = run(&["log", "info", "x.mf4"], dir.path());
    assert!(
        !ok && err.contains("\"mf4\"") && err.contains("--from"),
        "{err}"
    );
    std::fs::write(dir.path().join("a.log"), lines(3, 0)).unwrap();
    let (ok, _, err) = run(
        &["log", "convert", "a.log", "./a.log", "--to", "asc"],
        dir.path(),
    );
    assert!(!ok && err.contains("both input and output"), "{err}");
}

#[test]
fn info_counts_interfaces_ids_span_and_load() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("a.log"),
        "(10.000000) can0 123#1122\n(10.500000) can0 123#R2\n(11.000000) can1 12345678#\n\
         (11.000000) can0 20000004#0004000000000000\n",
    )
    .unwrap();
    let (ok, out, err) = run(&["log", "info", "a.log", "--bitrate", "125000"], dir.path());
    assert!(ok, "{err}");
    assert!(out.contains("3 frames, 1 error frames"), "{out}");
    assert!(out.contains("10.000000 .. 11.000000 (1.00 s)"), "{out}");
    assert!(
        out.contains("can0        2 frames (0 extended, 1 remote), 1 error frames, 1 IDs"),
        "{out}"
    );
    // 123#1122 (63 bits with stuffing here, + 3 intermission) and 123#R2 (47 + 3) in 1 s at
    // 125 kbit/s: about 0.09 %.
    assert!(out.contains("load 0.1 % at 125 kbit/s"), "{out}");
}

/// `log info --plot`: the load over time per interface, read back from the SVG: a busy second,
/// a silent one, a light one.
#[test]
fn info_plot_shows_the_load_over_time_per_interface() {
    let dir = tempfile::tempdir().unwrap();
    // can0: an 8-byte frame every ms for 1 s, nothing for 1 s, one every 10 ms for 1 s;
    // can1: a 1-byte frame every 10 ms for 3 s.
    let mut entries: Vec<(u64, &str, &str)> = (0..1000)
        .map(|i| (i * 1000, "can0", "123#1122334455667788"))
        .chain((0..100).map(|i| (2_000_000 + i * 10_000, "can0", "123#1122334455667788")))
        .chain((0..300).map(|i| (i * 10_000, "can1", "7FF#00")))
        .collect();
    entries.sort();
    let log: String = entries
        .iter()
        .map(|(us, name, frame)| {
            format!(
                "({}.{:06}) {name} {frame}\n",
                100 + us / 1_000_000,
                us % 1_000_000
            )
        })
        .collect();
    std::fs::write(dir.path().join("a.log"), log).unwrap();
    let (ok, out, err) = run(&["log", "info", "a.log", "--plot", "load.svg"], dir.path());
    assert!(ok, "{err}");
    assert!(out.contains("can0        1100 frames"), "{out}");
    let svg = std::fs::read_to_string(dir.path().join("load.svg")).unwrap();
    let seen = buslab_plot::inspect::parse(&svg).unwrap();
    let caption = seen
        .texts()
        .into_iter()
        .find(|t| t.starts_with("bus load per "))
        .unwrap_or_else(|| panic!("no load panel: {:?}", seen.texts()))
        .to_owned();
    let panel = seen.panel(&caption).unwrap();
    assert_eq!(panel.legend(), ["can0", "can1"]);
    assert_eq!(panel.value_title(), Some("load (%)"));
    assert_eq!(panel.time_title(), Some("time (s)"));
    // The 8-byte frame is 111 bits with its stuff bits and intermission (as `log info`
    // counts them): every ms at 500 kbit/s that is 22.2 %; every 10 ms 2.2 %.
    let can0 = panel.series("can0").unwrap();
    let mean = |from: f64, to: f64| {
        let inside: Vec<f64> = can0
            .iter()
            .filter(|p| from <= p.0 && p.0 < to)
            .map(|p| p.1)
            .collect();
        assert!(inside.len() >= 5, "{from}..{to}: {can0:?}");
        inside.iter().sum::<f64>() / inside.len() as f64
    };
    let (busy, silent, light) = (mean(0.1, 0.9), mean(1.1, 1.9), mean(2.1, 2.9));
    assert!((busy - 22.2).abs() < 1.5, "busy second: {busy} %");
    assert!(silent < 0.5, "silent second: {silent} %");
    assert!((light - 2.2).abs() < 1.0, "light second: {light} %");
    let can1 = panel.series("can1").unwrap();
    assert!(can1.iter().all(|p| p.1 < 3.0), "{can1:?}");
    assert!(can1.last().unwrap().0 > 2.9, "drawn to the end");

    // The figure's name is checked before the log is read.
    let (ok, out, err) = run(&["log", "info", "a.log", "--plot", "load.png"], dir.path());
    assert!(!ok && out.is_empty(), "{out}");
    assert!(err.contains("ending in .svg"), "{err}");
}

#[test]
fn cat_prints_candump_lines_and_no_progress_when_piped() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("a.log"), lines(20_000, 0)).unwrap();
    let (ok, _, err) = run(&["log", "convert", "a.log", "a.blf"], dir.path());
    assert!(ok, "{err}");
    // Piped stderr: only the summary, no bar.
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(!err.contains('\r') && !err.contains('['), "{err}");
    let (ok, out, _) = run(&["log", "cat", "a.blf"], dir.path());
    assert!(ok);
    assert_same_lines(&out, &lines(20_000, 0));
}

#[test]
fn a_long_conversion_shows_progress_on_a_terminal() {
    // util-linux's `script` gives the command a pseudo-terminal and records what it draws.
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("a.log"), lines(100_000, 0)).unwrap();
    let command = format!("{} log convert a.log a.asc", env!("CARGO_BIN_EXE_buslab"));
    let out = Command::new("script")
        .args(["-qec", &command, "typescript"])
        .current_dir(dir.path())
        .stdin(Stdio::null())
        .output()
        .expect("script (util-linux) runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let screen = std::fs::read_to_string(dir.path().join("typescript")).unwrap();
    assert!(
        screen.contains("frames/s") && screen.contains("MiB"),
        "{screen}"
    );
    assert_eq!(entries_in(&dir.path().join("a.asc")), 100_000);
}

/// `buslab log cat FILE` line count, or 0 while it cannot be read yet.
fn entries_in(path: &Path) -> usize {
    let out = buslab().args(["log", "cat"]).arg(path).output().unwrap();
    if out.status.success() {
        out.stdout.iter().filter(|&&b| b == b'\n').count()
    } else {
        0
    }
}

fn wait_for_entries(path: &Path, n: usize, child: &mut Child) {
    let deadline = Instant::now() + EVENT;
    loop {
        if entries_in(path) == n {
            return;
        }
        assert!(
            child.try_wait().unwrap().is_none(),
            "the converter ended early"
        );
        assert!(
            Instant::now() < deadline,
            "{} never held {n} entries (has {})",
            path.display(),
            entries_in(path)
        );
        std::thread::sleep(Duration::from_millis(100));
    }
}

fn append(path: &Path, text: &str) {
    let mut f = std::fs::OpenOptions::new().append(true).open(path).unwrap();
    f.write_all(text.as_bytes()).unwrap();
}

#[test]
fn a_followed_sqlite_log_survives_kill_9_up_to_its_last_commit() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("live.log");
    let db = dir.path().join("live.db");
    std::fs::write(&input, lines(300, 0)).unwrap();
    let mut child = buslab()
        .args(["log", "convert", "--follow"])
        .arg(&input)
        .arg(&db)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    // Committed while the converter runs, without being stopped.
    wait_for_entries(&db, 300, &mut child);
    append(&input, &lines(200, 300));
    wait_for_entries(&db, 500, &mut child);
    child.kill().unwrap(); // SIGKILL
    child.wait().unwrap();
    assert_eq!(entries_in(&db), 500);
    let (ok, out, err) = run(&["log", "cat", "live.db"], dir.path());
    assert!(ok, "{err}");
    assert_same_lines(&out, &lines(500, 0));
}

#[test]
fn sigterm_and_sighup_finish_a_followed_log() {
    for signal in ["TERM", "HUP", "INT"] {
        let dir = tempfile::tempdir().unwrap();
        let input = dir.path().join("live.log");
        let out = dir.path().join("live.asc");
        std::fs::write(&input, lines(50, 0)).unwrap();
        let mut child = buslab()
            .args(["log", "convert", "--follow"])
            .arg(&input)
            .arg(&out)
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        wait_for_entries(&out, 50, &mut child);
        let status = Command::new("kill")
            .arg(format!("-{signal}"))
            .arg(child.id().to_string())
            .status()
            .unwrap();
        assert!(status.success());
        let result = child.wait_with_output().unwrap();
        assert!(
            result.status.success(),
            "SIG{signal}: {}",
            String::from_utf8_lossy(&result.stderr)
        );
        let text = std::fs::read_to_string(&out).unwrap();
        assert!(text.ends_with("End TriggerBlock\n"), "SIG{signal}: {text}");
        assert_eq!(entries_in(&out), 50);
    }
}

/// Plays `log` to `serve` with `args` and returns the frames a listener received and the
/// gaps between them (by the bus's own timestamps); waits for `expect` frames, then for a
/// sentinel sent after play ended (so any extra frame would show). With `warm_up`, the log's
/// first frame is left out of both: a node's first frame after it joins the bus may come late
/// (it waits for the bus), which would make the first gap look short.
fn play(
    serve: &Serve,
    log: &str,
    args: &[&str],
    expect: usize,
    warm_up: bool,
) -> (Vec<String>, Vec<Duration>) {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("play.log"), log).unwrap();
    let mut me = serve.client();
    let mut cmd = serve.buslab();
    cmd.args(["-q", "play", "play.log", "--bus", &serve.url])
        .args(args)
        .current_dir(dir.path());
    let player = std::thread::spawn(move || cmd.output().unwrap());
    let mut got = Vec::new();
    let mut at = Vec::new();
    for _ in 0..expect {
        let m = me.recv(Some(EVENT)).unwrap().expect("a played frame");
        at.push(m.at);
        got.push(m.record.to_string());
    }
    let out = player.join().unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let mut other = serve.client();
    other.send(&frame("7FF#5E")).unwrap();
    let m = me.recv(Some(EVENT)).unwrap().expect("the sentinel");
    assert_eq!(m.record, frame("7FF#5E"), "an extra frame was played");
    if warm_up {
        got.remove(0);
        at.remove(0);
    }
    let gaps = at.windows(2).map(|w| w[1].saturating_since(w[0])).collect();
    (got, gaps)
}

#[test]
fn play_paces_frames_by_their_timestamps_speed_and_gap() {
    let serve = Serve::start(500_000);
    let log = "(99.000000) can0 100#\n\
               (100.000000) can0 101#01\n(100.400000) can0 102#02\n(100.800000) can0 103#03\n";
    // A frame is never sent before its time; it reaches the bus after a path whose delay
    // varies, so a gap may look shorter by how much later the previous frame got there: the
    // bound allows 40 % of a gap for that (without pacing the gaps would be ~0, and at the
    // wrong speed half or twice as long).
    let floor = |d: f64| Duration::from_secs_f64(d * 0.6);
    let (got, gaps) = play(&serve, log, &[], 4, true);
    assert_eq!(got, ["101#01", "102#02", "103#03"]);
    assert!(gaps.iter().all(|g| *g >= floor(0.4)), "{gaps:?}");
    // Half speed: twice the gaps.
    let (_, gaps) = play(&serve, log, &["--speed", "0.5"], 4, true);
    assert!(gaps.iter().all(|g| *g >= floor(0.8)), "{gaps:?}");
    // Timestamps ignored, a gap instead (all at one instant in the file).
    let same = "(5.000000) can0 100#\n\
                (5.000000) can0 101#01\n(5.000000) can0 102#02\n(5.000000) can0 103#03\n";
    let (_, gaps) = play(&serve, same, &["-t", "-g", "300ms"], 4, true);
    assert!(gaps.iter().all(|g| *g >= floor(0.3)), "{gaps:?}");
    // Two loops.
    let (got, _) = play(&serve, same, &["-t", "-l", "2"], 8, false);
    assert_eq!(
        got,
        [
            "100#", "101#01", "102#02", "103#03", "100#", "101#01", "102#02", "103#03"
        ]
    );
}

#[test]
fn play_sends_only_the_assigned_interfaces_and_no_error_frames() {
    let serve = Serve::start(500_000);
    let log = "(1.000000) can0 100#00\n(1.001000) can1 200#01\n\
               (1.002000) can1 20000004#0004000000000000\n(1.003000) can0 101#02\n\
               (1.004000) can1 12345678#03\n";
    // vcan0 is the server's channel: can1's frames go there, can0's nowhere.
    let (got, _) = play(&serve, log, &["vcan0=can1"], 2, false);
    assert_eq!(got, ["200#01", "12345678#03"]);
    let (got, _) = play(&serve, log, &[], 4, false);
    assert_eq!(got, ["100#00", "200#01", "101#02", "12345678#03"]);
    let (ok, _, err) = run(&["play", "x.log", "vcan0"], Path::new("."));
    assert!(!ok && err.contains("WRITE=LOG"), "{err}");
}

/// `log info` on a log with CAN FD frames counts them apart (their time on the wire needs a
/// data bit rate no log gives, so the load leaves them out and says so).
#[test]
fn info_counts_can_fd_frames_apart_from_the_load() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("fd.log"),
        "(1.000000) can0 123#11\n(1.100000) can0 333##1112233\n(1.200000) can0 12345678##0\n",
    )
    .unwrap();
    let (ok, out, err) = run(&["log", "info", "fd.log"], dir.path());
    assert!(ok, "{err}");
    assert!(
        out.contains("can0        3 frames (1 extended, 0 remote, 2 CAN FD, not in the load)"),
        "{out}"
    );
}
