//! The command-line tools with `--dbc FILE` (issue 29), run as a user runs them: `dump` and
//! `log cat` print each frame of a database message followed by its decoded signals (the
//! layout of `candump | cantools decode`, or `--single-line`), `-m/--message NAME` keeps the
//! frames of named messages, `log convert … OUT.csv --dbc` writes a table of signals,
//! `plot` draws signals over time, `send --dbc` encodes messages from signal values. Bad
//! input — a missing or garbage database, unknown names, values out of range — ends with a
//! clear error and a non-zero exit status, never a panic.

mod bus_common;

use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Child, Stdio};
use std::sync::mpsc;
use std::thread::{self, JoinHandle};
use std::time::Duration;

use assert_cmd::Command;
use bus_common::Serve;
use buslab_dbc::Database;
use buslab_dbc::text::DecodedMessage;

/// A deadline for an event that normally comes within a second (CI machines are loaded).
const EVENT: Duration = Duration::from_secs(60);

/// A small car: plain signals with units, a value table, a signed one with an offset, a
/// multiplexed message, an extended ID, and a signal name two messages share.
const DBC: &str = r#"VERSION ""

NS_ :

BS_:

BU_: ECU Dash

BO_ 291 Engine: 8 ECU
 SG_ Speed : 0|16@1+ (0.1,0) [0|6553.5] "km/h" Dash
 SG_ Rpm : 16|16@1+ (1,0) [0|8000] "rpm" Dash
 SG_ Mode : 32|2@1+ (1,0) [0|3] "" Dash
 SG_ Temp : 40|8@1- (1,-40) [-40|87] "degC" Dash

BO_ 292 Brake: 8 ECU
 SG_ Pressure : 0|16@1+ (0.1,0) [0|1000] "bar" Dash
 SG_ Mode : 16|2@1+ (1,0) [0|3] "" Dash

BO_ 1024 Muxed: 8 ECU
 SG_ Sel M : 0|8@1+ (1,0) [0|0] "" Dash
 SG_ A m0 : 8|16@1+ (0.5,0) [0|100] "V" Dash
 SG_ B m1 : 8|16@1+ (1,0) [0|0] "A" Dash

BO_ 2147484160 Ext: 4 ECU
 SG_ Counter : 0|8@1+ (1,0) [0|255] "" Dash

VAL_ 291 Mode 0 "Off" 1 "On" 2 "Eco" ;
"#;

/// Frames of every kind: known messages (Engine, both branches of Muxed, the extended Ext),
/// an ID the database does not have, a remote request for Engine.
const LOG: &str = "\
(1700000000.000100) can0 123#1027E803013C0000
(1700000000.000200) can0 400#00C8000000000000
(1700000000.000300) can0 400#0105000000000000
(1700000000.000400) can0 321#1122
(1700000000.000500) can0 123#R
(1700000000.000600) can1 00000200#07000000
";

fn buslab() -> Command {
    let mut c = Command::cargo_bin("buslab").unwrap();
    c.env_remove("BUSLAB_BUS").env_remove("RUST_LOG");
    c
}

/// A folder with `car.dbc` and `in.log`.
fn setup() -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("car.dbc"), DBC).unwrap();
    std::fs::write(dir.path().join("in.log"), LOG).unwrap();
    dir
}

fn stdout(dir: &Path, args: &[&str]) -> String {
    let out = buslab().args(args).current_dir(dir).output().unwrap();
    assert!(
        out.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).unwrap()
}

/// The error of a command that must fail: exit status 1, one `error:` line, no panic.
fn failure(dir: &Path, args: &[&str]) -> String {
    let out = buslab().args(args).current_dir(dir).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(
        !out.status.success(),
        "{args:?} should fail; stdout: {}",
        String::from_utf8_lossy(&out.stdout)
    );
    assert!(!err.contains("panicked"), "{args:?}: {err}");
    assert!(err.contains("error"), "{args:?}: {err}");
    err
}

/// Engine's decoded text for `payload` as the library spells it (the label of a value table is
/// the library's business; the layout around it is the tool's).
fn engine(payload: &[u8], single_line: bool) -> String {
    let db = Database::parse(DBC).unwrap();
    let message = db.message_by_name("Engine").unwrap();
    let values = message.decode(payload);
    let decoded = DecodedMessage {
        message,
        values: &values,
    };
    if single_line {
        decoded.to_string()
    } else {
        format!("{decoded:#}")
    }
}

const ENGINE: [u8; 8] = [0x10, 0x27, 0xE8, 0x03, 0x01, 0x3C, 0x00, 0x00];

/// Compared with `python -m cantools decode car.dbc` (cantools 45.1.0) on the same lines:
/// the same layout; cantools prints `Unknown frame id …` after a frame it does not know,
/// where buslab leaves the line as it was.
#[test]
fn log_cat_decodes_like_cantools_decode_and_leaves_other_frames_unchanged() {
    let dir = setup();
    let out = stdout(dir.path(), &["log", "cat", "in.log", "--dbc", "car.dbc"]);
    let want = format!(
        "(1700000000.000100) can0 123#1027E803013C0000 ::\n{}\n\
         (1700000000.000200) can0 400#00C8000000000000 ::\n\
         Muxed(\n    Sel: 0,\n    A: 100.0 V\n)\n\
         (1700000000.000300) can0 400#0105000000000000 ::\n\
         Muxed(\n    Sel: 1,\n    B: 5 A\n)\n\
         (1700000000.000400) can0 321#1122\n\
         (1700000000.000500) can0 123#R\n\
         (1700000000.000600) can1 00000200#07000000 ::\n\
         Ext(\n    Counter: 7\n)\n",
        engine(&ENGINE, false)
    );
    assert_eq!(out, want);
    // The scaled values, spelled out once by hand.
    assert!(
        out.contains("Speed: 1000.0 km/h,\n    Rpm: 1000 rpm,\n")
            && out.contains("Temp: 20 degC\n)")
            && out.contains("On"),
        "{out}"
    );
}

#[test]
fn single_line_puts_the_message_on_the_frames_line() {
    let dir = setup();
    let out = stdout(
        dir.path(),
        &["log", "cat", "in.log", "--dbc", "car.dbc", "--single-line"],
    );
    let lines: Vec<&str> = out.lines().collect();
    assert_eq!(
        lines,
        [
            format!(
                "(1700000000.000100) can0 123#1027E803013C0000 :: {}",
                engine(&ENGINE, true)
            )
            .as_str(),
            "(1700000000.000200) can0 400#00C8000000000000 :: Muxed(Sel: 0, A: 100.0 V)",
            "(1700000000.000300) can0 400#0105000000000000 :: Muxed(Sel: 1, B: 5 A)",
            "(1700000000.000400) can0 321#1122",
            "(1700000000.000500) can0 123#R",
            "(1700000000.000600) can1 00000200#07000000 :: Ext(Counter: 7)",
        ]
    );
    // Without --dbc the options that need it are refused by name.
    for extra in [&["--single-line"][..], &["--message", "Engine"]] {
        let err = failure(dir.path(), &[&["log", "cat", "in.log"][..], extra].concat());
        assert!(err.contains("--dbc <FILE>"), "{err}");
    }
}

#[test]
fn message_names_filter_frames_and_unknown_names_are_refused_with_close_ones() {
    let dir = setup();
    let args = ["log", "cat", "in.log", "--dbc", "car.dbc", "--single-line"];
    let out = stdout(dir.path(), &[&args[..], &["-m", "Ext,Muxed"]].concat());
    assert_eq!(
        out,
        "(1700000000.000200) can0 400#00C8000000000000 :: Muxed(Sel: 0, A: 100.0 V)\n\
         (1700000000.000300) can0 400#0105000000000000 :: Muxed(Sel: 1, B: 5 A)\n\
         (1700000000.000600) can1 00000200#07000000 :: Ext(Counter: 7)\n"
    );
    // The remote request for Engine is a frame of Engine.
    let out = stdout(dir.path(), &[&args[..], &["--message", "Engine"]].concat());
    assert_eq!(out.lines().count(), 2, "{out}");
    assert!(out.ends_with("(1700000000.000500) can0 123#R\n"), "{out}");

    let err = failure(dir.path(), &[&args[..], &["-m", "engine"]].concat());
    assert!(
        err.contains("--message engine: car.dbc has no message \"engine\"; close names: Engine"),
        "{err}"
    );
    let err = failure(dir.path(), &[&args[..], &["-m", "Gearbox"]].concat());
    assert!(
        err.contains("its messages: Engine, Brake, Muxed, Ext"),
        "{err}"
    );
    // log convert keeps the named messages in any format.
    let out = stdout(
        dir.path(),
        &[
            "log", "convert", "in.log", "out.log", "--dbc", "car.dbc", "-m", "Muxed",
        ],
    );
    assert!(out.is_empty());
    assert_eq!(
        std::fs::read_to_string(dir.path().join("out.log")).unwrap(),
        "(1700000000.000200) can0 400#00C8000000000000\n\
         (1700000000.000300) can0 400#0105000000000000\n"
    );
}

#[test]
fn convert_to_csv_writes_a_row_per_frame_and_a_column_per_signal() {
    let dir = setup();
    let out = buslab()
        .args(["log", "convert", "in.log", "out.csv", "--dbc", "car.dbc"])
        .current_dir(dir.path())
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(
        err.contains("6 entries") && err.contains("2 left out (error frames, remote frames"),
        "{err}"
    );
    let csv = std::fs::read_to_string(dir.path().join("out.csv")).unwrap();
    assert_eq!(
        csv,
        "time,id,message,Engine.Speed,Engine.Rpm,Engine.Mode,Engine.Temp,Brake.Pressure,Brake.Mode,Muxed.Sel,Muxed.A,Muxed.B,Ext.Counter\n\
         1700000000.000100,0x123,Engine,1000.0,1000,1,20,,,,,,\n\
         1700000000.000200,0x400,Muxed,,,,,,,0,100.0,,\n\
         1700000000.000300,0x400,Muxed,,,,,,,1,,5,\n\
         1700000000.000600,0x00000200,Ext,,,,,,,,,,7\n"
    );
    // --message narrows the columns to its messages' signals.
    stdout(
        dir.path(),
        &[
            "log", "convert", "in.log", "out.csv", "--dbc", "car.dbc", "-m", "Muxed", "-q",
        ],
    );
    assert_eq!(
        std::fs::read_to_string(dir.path().join("out.csv")).unwrap(),
        "time,id,message,Muxed.Sel,Muxed.A,Muxed.B\n\
         1700000000.000200,0x400,Muxed,0,100.0,\n\
         1700000000.000300,0x400,Muxed,1,,5\n"
    );
    // Signals are written to CSV only; another format with --dbc needs --message.
    let err = failure(
        dir.path(),
        &["log", "convert", "in.log", "out.blf", "--dbc", "car.dbc"],
    );
    assert!(
        err.contains("--dbc writes decoded signals to a CSV file, and out.blf is blf"),
        "{err}"
    );
    assert!(!dir.path().join("out.blf").exists());
}

#[test]
fn an_empty_log_gives_a_table_with_its_header() {
    let dir = setup();
    std::fs::write(dir.path().join("empty.log"), "").unwrap();
    stdout(
        dir.path(),
        &[
            "log",
            "convert",
            "empty.log",
            "out.csv",
            "--dbc",
            "car.dbc",
            "-m",
            "Ext",
            "-q",
        ],
    );
    assert_eq!(
        std::fs::read_to_string(dir.path().join("out.csv")).unwrap(),
        "time,id,message,Ext.Counter\n"
    );
}

/// 101 Engine frames 10 ms apart, Speed rising by 1 km/h and Mode counting 0, 1, 2; 50 Muxed
/// frames alternating between the branches (A = i V on Sel 0, B on Sel 1).
fn ramp_log() -> String {
    let at = |us: u32| format!("{}.{:06}", 1_700_000_000 + us / 1_000_000, us % 1_000_000);
    let mut log = String::new();
    for i in 0..=100u32 {
        let speed = (i * 10).to_le_bytes();
        log.push_str(&format!(
            "({}) can0 123#{:02X}{:02X}0000{:02X}000000\n",
            at(i * 10_000),
            speed[0],
            speed[1],
            i % 3
        ));
        if i % 2 == 0 && i < 100 {
            let sel = (i / 2) % 2;
            log.push_str(&format!(
                "({}) can0 400#{sel:02X}{:02X}000000000000\n",
                at(i * 10_000 + 5_000),
                i * 2
            ));
        }
    }
    log
}

#[test]
fn plot_draws_signals_over_the_logs_time_a_multiplexed_one_where_its_branch_is_active() {
    let dir = setup();
    std::fs::write(dir.path().join("ramp.log"), ramp_log()).unwrap();
    stdout(
        dir.path(),
        &[
            "plot",
            "--dbc",
            "car.dbc",
            "ramp.log",
            "Speed",
            "Engine.Mode",
            "A",
            "-o",
            "ramp.svg",
        ],
    );
    let svg = std::fs::read_to_string(dir.path().join("ramp.svg")).unwrap();
    let seen = buslab_plot::inspect::parse(&svg).unwrap();
    let speed = seen.panel("Engine.Speed").unwrap();
    assert_eq!(speed.legend(), ["Engine.Speed"]);
    assert_eq!(speed.value_title(), Some("Engine.Speed (km/h)"));
    // From the log's first entry; a second is shown in ms.
    assert_eq!(speed.time_title(), Some("time (ms)"));
    let points = speed.series("Engine.Speed").unwrap();
    let (first, last) = (points[0], *points.last().unwrap());
    assert!(first.0.abs() < 5.0 && first.1.abs() < 0.5, "{first:?}");
    assert!(
        (last.0 - 1000.0).abs() < 5.0 && (last.1 - 100.0).abs() < 0.5,
        "{last:?}"
    );
    // A value table is spelled out in its signal's caption.
    let mode = seen.panel("Engine.Mode (0 Off, 1 On, 2 Eco)").unwrap();
    let modes = mode.series("Engine.Mode").unwrap();
    assert!(modes.iter().all(|p| p.1 > -0.1 && p.1 < 2.1), "{modes:?}");
    // A: only the frames with Sel = 0 (i = 0, 4, 8 … 96, at i × 10 + 5 ms), A = i V.
    let a = seen.panel("Muxed.A").unwrap().series("Muxed.A").unwrap();
    assert_eq!(a.len(), 25, "{a:?}");
    for (k, p) in a.iter().enumerate() {
        let i = 4.0 * k as f64;
        assert!(
            (p.0 - (i * 10.0 + 5.0)).abs() < 5.0 && (p.1 - i).abs() < 1.0,
            "point {k}: {p:?}"
        );
    }
}

#[test]
fn plot_refuses_unknown_and_ambiguous_names_and_a_bad_figure_name_before_reading() {
    let dir = setup();
    let plot = |extra: &[&str]| {
        failure(
            dir.path(),
            &[&["plot", "--dbc", "car.dbc", "in.log"][..], extra].concat(),
        )
    };
    let err = plot(&["Sped", "-o", "x.svg"]);
    assert!(
        err.contains("car.dbc has no signal \"Sped\"; close names: Engine.Speed"),
        "{err}"
    );
    let err = plot(&["Mode", "-o", "x.svg"]);
    assert!(
        err.contains("Mode is a signal of 2 messages: name one as Engine.Mode or Brake.Mode"),
        "{err}"
    );
    let err = plot(&["Engine.Pressure", "-o", "x.svg"]);
    assert!(
        err.contains("message Engine of car.dbc has no signal \"Pressure\"; its signals: Speed, Rpm, Mode, Temp"),
        "{err}"
    );
    let err = plot(&["Speed", "-o", "x.png"]);
    assert!(err.contains("-o x.png: the figure is SVG"), "{err}");
    // A signal no frame carries: nothing to draw, nothing written.
    let err = plot(&["Brake.Pressure", "-o", "x.svg"]);
    assert!(err.contains("-o x.svg: nothing written"), "{err}");
    assert!(!dir.path().join("x.svg").exists());
}

#[test]
fn send_refuses_unknown_names_and_bad_values_saying_what_is_allowed() {
    let dir = setup();
    // Nothing is sent: every one is refused before the bus is opened (none listens there).
    let send = |words: &[&str]| {
        failure(
            dir.path(),
            &[
                &[
                    "send",
                    "--bus",
                    "socketcand://127.0.0.1:1/vcan0",
                    "--dbc",
                    "car.dbc",
                ][..],
                words,
            ]
            .concat(),
        )
    };
    for (words, want) in [
        (
            &["Engine", "Speed=7000"][..],
            "Engine.Speed = 7000 is out of range: allowed 0 ..= 6553.5",
        ),
        (
            &["Engine", "Temp=-41"],
            "Engine.Temp = -41 is out of range: allowed -40 ..= 87",
        ),
        (
            &["Engine", "Speed=fast"],
            "Engine.Speed=fast: not a number (allowed 0 ..= 6553.5 km/h)",
        ),
        (
            &["Engine", "Mode=Sport"],
            "Engine.Mode=Sport: neither a number (allowed 0 ..= 3) nor a label of its value table (Off, On, Eco)",
        ),
        (
            &["Engine", "Sped=1"],
            "message Engine of car.dbc has no signal \"Sped\"; close names: Speed",
        ),
        (
            &["Engien", "Speed=1"],
            "car.dbc has no message \"Engien\"; close names: Engine",
        ),
        (
            &["Engine", "Speed"],
            "Speed is a signal of Engine: give its value, e.g. Speed=1",
        ),
        (
            &["Muxed", "Sel=0", "B=1"],
            "Muxed.B is not sent when Sel = 0",
        ),
        (&["Engine", "Speed=NaN"], "Engine.Speed = NaN: not a number"),
    ] {
        let err = send(words);
        assert!(err.contains(want), "{words:?}: {err}");
    }
    // An interface's URL may hold `=`: it is still the interface (the error is the
    // adapter's, after the message was encoded).
    let err = failure(
        dir.path(),
        &[
            "send",
            "--dbc",
            "car.dbc",
            "slcan:/nonexistent/tty?bitrate=500000",
            "Engine",
            "Speed=1",
        ],
    );
    assert!(err.contains("/nonexistent/tty"), "{err}");
    assert!(!err.contains("signal") && !err.contains("message"), "{err}");
    // Without --bus a first word that is no message is the interface, as cansend's; a
    // signal after it says so.
    let err = failure(
        dir.path(),
        &["send", "--dbc", "car.dbc", "Engien", "Speed=1"],
    );
    assert!(
        err.contains("(Engien was taken as the interface: car.dbc has no message \"Engien\"; close names: Engine)"),
        "{err}"
    );
}

/// `buslab dump` in the background, returned once it listens (-v says so).
struct Dump {
    child: Child,
    stderr: JoinHandle<String>,
}

impl Dump {
    fn start(serve: &Serve, dir: &Path, extra: &[&str]) -> Self {
        let mut child = serve
            .buslab()
            .args(["-v", "dump", "--bus", &serve.url])
            .args(extra)
            .current_dir(dir)
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
        Self { child, stderr }
    }

    fn finish(self) -> String {
        let out = self.child.wait_with_output().unwrap();
        let err = self.stderr.join().unwrap();
        assert!(out.status.success(), "{err}");
        String::from_utf8(out.stdout).unwrap()
    }
}

#[test]
fn send_encodes_messages_by_signal_and_dump_decodes_what_the_bus_carries() {
    let serve = Serve::start(500_000);
    let dir = setup();
    let dump = Dump::start(
        &serve,
        dir.path(),
        &["--dbc", "car.dbc", "-m", "Engine,Muxed", "-n", "2"],
    );
    let out = serve
        .buslab()
        .args(["send", "--bus", &serve.url, "--dbc", "car.dbc"])
        .args(["Engine", "Speed=88.5", "Mode=On", "Temp=-3", "321#11"])
        .args(["Muxed", "Sel=1", "B=7"])
        .current_dir(dir.path())
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    // Speed 885 × 0.1, Mode 1 (On), Temp 37 − 40; 321 is not one of the --message ones.
    let engine_bytes = [0x75, 0x03, 0x00, 0x00, 0x01, 0x25, 0x00, 0x00];
    assert_eq!(
        Dump::finish(dump),
        format!(
            "  vcan0  123   [8]  75 03 00 00 01 25 00 00 ::\n{}\n\
             \x20 vcan0  400   [8]  01 07 00 00 00 00 00 00 ::\nMuxed(\n    Sel: 1,\n    B: 7 A\n)\n",
            engine(&engine_bytes, false)
        )
    );
    assert!(
        engine(&engine_bytes, false).contains("Speed: 88.5 km/h,\n    Rpm: 0 rpm,"),
        "the frame carries the values given"
    );
}

/// A file of bytes that are no DBC: a fixed pseudo-random sequence.
fn garbage(len: usize) -> Vec<u8> {
    let mut x: u32 = 0x2545_F491;
    (0..len)
        .map(|_| {
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
            x as u8
        })
        .collect()
}

#[test]
fn every_command_refuses_a_missing_or_garbage_database_naming_it() {
    let dir = setup();
    let d = dir.path();
    std::fs::write(d.join("noise.dbc"), garbage(4096)).unwrap();
    std::fs::write(d.join("cut.dbc"), &DBC[..DBC.find("BO_ 292").unwrap() - 20]).unwrap();
    std::fs::write(
        d.join("wide.dbc"),
        "BO_ 291 Engine: 8 ECU\n SG_ Speed : 600|16@1+ (1,0) [0|0] \"\" Vector__XXX\n",
    )
    .unwrap();
    std::fs::create_dir(d.join("folder.dbc")).unwrap();
    let commands: [&[&str]; 5] = [
        &["log", "cat", "in.log"],
        &["log", "convert", "in.log", "out.csv"],
        &["plot", "in.log", "Speed", "-o", "x.svg"],
        &["send", "--bus", "socketcand://127.0.0.1:1/vcan0", "Engine"],
        &["dump", "--bus", "socketcand://127.0.0.1:1/vcan0"],
    ];
    for command in commands {
        for (file, want) in [
            ("missing.dbc", "missing.dbc"),
            ("noise.dbc", "DBC file noise.dbc: line "),
            ("cut.dbc", "DBC file cut.dbc: line "),
            (
                "wide.dbc",
                "DBC file wide.dbc: line 2: signal Engine.Speed: start bit 600 is past 64 bytes",
            ),
            ("folder.dbc", "folder.dbc is a folder"),
        ] {
            let err = failure(d, &[command, &["--dbc", file]].concat());
            assert!(err.contains(want), "{command:?} --dbc {file}: {err}");
            assert_eq!(err.lines().count(), 1, "{command:?} --dbc {file}: {err}");
        }
    }
    assert!(!d.join("out.csv").exists() && !d.join("x.svg").exists());
}

/// Nothing acknowledged is lost: once `-v` said an entry was flushed, its row is in the file,
/// even after `kill -9`.
#[test]
fn a_followed_csv_holds_every_flushed_row_after_kill_9() {
    let dir = setup();
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_buslab"))
        .args([
            "-v", "log", "convert", "in.log", "out.csv", "--dbc", "car.dbc",
        ])
        .args(["--follow", "-m", "Muxed"])
        .env_remove("RUST_LOG")
        .current_dir(dir.path())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let (tx, flushed) = mpsc::channel();
    let lines = BufReader::new(child.stderr.take().unwrap()).lines();
    thread::spawn(move || {
        for line in lines.map_while(Result::ok) {
            if line.contains("entries flushed") {
                let _ = tx.send(line);
            }
        }
    });
    let wait_for = |want: &str| loop {
        match flushed.recv_timeout(EVENT) {
            Ok(line) if line.contains(want) => break,
            Ok(_) => continue,
            Err(_) => panic!("never saw {want:?}"),
        }
    };
    // The two Muxed frames (the other four are not kept).
    wait_for("out.csv: 2 entries flushed");
    let header = "time,id,message,Muxed.Sel,Muxed.A,Muxed.B\n";
    let rows = "1700000000.000200,0x400,Muxed,0,100.0,\n1700000000.000300,0x400,Muxed,1,,5\n";
    assert_eq!(
        std::fs::read_to_string(dir.path().join("out.csv")).unwrap(),
        format!("{header}{rows}")
    );
    let mut log = std::fs::OpenOptions::new()
        .append(true)
        .open(dir.path().join("in.log"))
        .unwrap();
    std::io::Write::write_all(&mut log, b"(1700000001.000000) can0 400#0109000000000000\n")
        .unwrap();
    wait_for("out.csv: 3 entries flushed");
    child.kill().unwrap();
    child.wait().unwrap();
    assert_eq!(
        std::fs::read_to_string(dir.path().join("out.csv")).unwrap(),
        format!("{header}{rows}1700000001.000000,0x400,Muxed,1,,9\n")
    );
}
