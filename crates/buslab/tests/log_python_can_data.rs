//! python-can's own test logs: the files of `test/data` in python-can 4.6.1's source
//! distribution (Vector ASC and BLF, PEAK TRC 1.0..2.1, a gzip-compressed ASC), and python-can's
//! example messages (its `test/data/example_data.py`) written by python-can's writer of each
//! format (candump log, ASC, BLF, TRC, CSV, SQLite). python-can reads every file, buslab reads
//! the same file, and the two must give the same frames: time, channel, ID, flags, data,
//! direction, as far as the format carries them.
//!
//! The differences that remain are deliberate, pinned file by file in `EXPECTED` and
//! explained in docs/logs.md: buslab takes a classic frame of a CANFD line as classic and an FD
//! length in a classic ASC line (`d 40`) as that CAN FD frame; a classical DLC 9..15 is 8
//! bytes; a standard ID above 0x7FF is refused.
//!
//! `scripts/setup-test-deps.sh` downloads the sdist (pinned by hash) into
//! `target/python-can-sdist/`; under `CI=1` a missing download fails the test.

#[path = "support/outside_tools.rs"]
mod outside_tools;

use std::collections::BTreeMap;
use std::fmt;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

use buslab_logs::{
    Direction, Format, Message, OpenOptions, Problem, ReadError, Record, open_source,
};
use outside_tools::{present, python_can, root};

/// python-can holds times as float seconds (steps of 0.24 µs at today's epoch, 0.48 µs at
/// the 2.46e9 s of its BLF test files) and computes them in floats; buslab keeps nanoseconds.
/// Equal means within a microsecond.
const FLOAT_SECONDS: f64 = 1e-6;

/// The sdist's test/data, when scripts/setup-test-deps.sh has unpacked it.
fn data_dir() -> Option<PathBuf> {
    let dir = root().join("target/python-can-sdist/python_can-4.6.1/test/data");
    present(dir.join("logfile.asc").is_file(), "python-can's test data").then_some(dir)
}

/// A message as python-can gives it (tests/interop/can_log_fields.py).
#[derive(Debug)]
struct PyMessage {
    time: f64,
    channel: Option<String>,
    kind: char,
    extended: bool,
    id: u32,
    dlc: usize,
    data: Vec<u8>,
    rx: bool,
}

impl fmt::Display for PyMessage {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{} ch {:?} {} {}{:X} dlc {} data {:02X?} {}",
            self.time,
            self.channel,
            self.kind,
            if self.extended { "x" } else { "" },
            self.id,
            self.dlc,
            self.data,
            if self.rx { "Rx" } else { "Tx" }
        )
    }
}

fn parse_message(line: &str) -> PyMessage {
    let f: Vec<&str> = line.split(' ').collect();
    assert_eq!(f.len(), 8, "{line}");
    let data = if f[6] == "-" {
        Vec::new()
    } else {
        (0..f[6].len())
            .step_by(2)
            .map(|i| u8::from_str_radix(&f[6][i..i + 2], 16).unwrap())
            .collect()
    };
    PyMessage {
        time: f[0].parse().unwrap(),
        channel: (f[1] != "None").then(|| f[1].to_string()),
        kind: f[2].chars().next().unwrap(),
        extended: f[3] == "x",
        id: u32::from_str_radix(f[4], 16).unwrap(),
        dlc: f[5].parse().unwrap(),
        data,
        rx: f[7] == "R",
    }
}

/// What python-can reads of each file (one python process for all of them).
fn python_reads(python: &Path, files: &[PathBuf]) -> BTreeMap<PathBuf, Vec<PyMessage>> {
    let out = Command::new(python)
        .arg(root().join("tests/interop/can_log_fields.py"))
        .args(files)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let mut by_file = BTreeMap::new();
    let mut current: Option<PathBuf> = None;
    for line in String::from_utf8(out.stdout).unwrap().lines() {
        if let Some(path) = line.strip_prefix("file ") {
            current = Some(PathBuf::from(path));
            by_file.insert(PathBuf::from(path), Vec::new());
        } else if let Some(error) = line.strip_prefix("error ") {
            panic!("python-can cannot read {current:?}: {error}");
        } else {
            let file = current.clone().expect("a file line first");
            by_file.get_mut(&file).unwrap().push(parse_message(line));
        }
    }
    by_file
}

/// Every entry and every error of buslab reading `path` as `buslab log cat` does.
fn buslab_reads(path: &Path) -> Vec<Result<Message, ReadError>> {
    let format = Format::from_path(path).unwrap();
    let mut source = open_source(path, format, &OpenOptions::default())
        .unwrap_or_else(|e| panic!("buslab cannot open {}: {e}", path.display()));
    let mut out = Vec::new();
    loop {
        let mut entry = Message::default();
        match source.reader.read_into(&mut entry) {
            Ok(true) => out.push(Ok(entry)),
            Ok(false) => return out,
            Err(e) => {
                let fatal = e.is_fatal();
                out.push(Err(e));
                if fatal {
                    return out;
                }
            }
        }
    }
}

/// A deliberate difference between python-can's reading and buslab's.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
enum Deliberate {
    /// `d 40` and 64 bytes in a classic ASC line (python-can 3's FD frame): python-can keeps 8
    /// of the bytes, buslab reads the 64-byte CAN FD frame.
    FdLengthInClassicLine,
    /// A classic frame in a CANFD line (Vector's flags without EDL): python-can marks it FD,
    /// buslab reads the classic frame (same ID, data, DLC).
    ClassicInFdLine,
    /// A classical DLC 9..15 (8 data bytes): python-can gives the FD length of that DLC,
    /// buslab an 8-byte frame (the same 8 bytes).
    ClassicDlcAbove8,
    /// A standard ID above 0x7FF: python-can keeps it, buslab refuses the frame naming it.
    StandardIdAbove7ff,
}

/// How buslab names python-can's channel in `format` (`None`: python-can gives none).
fn interface(ext: &str, channel: &str) -> String {
    match (ext, channel.parse::<u32>()) {
        // ASC and BLF: python-can counts channels from 0, buslab names channel N `can{N-1}`.
        ("asc" | "blf" | "gz", Ok(n)) => format!("can{n}"),
        // TRC: python-can gives the bus number, from 1.
        ("trc", Ok(n)) => format!("can{}", n.saturating_sub(1)),
        _ => channel.to_string(),
    }
}

/// Whether buslab's `got` is python-can's `want`: `Ok(None)` the same, `Ok(Some(_))` a
/// deliberate difference, `Err` any other difference.
fn compare(
    ext: &str,
    want: &PyMessage,
    got: &Result<Message, ReadError>,
) -> Result<Option<Deliberate>, String> {
    let entry = match got {
        Ok(entry) => entry,
        Err(e) => {
            return match e.problem() {
                Problem::Frame(buslab_can::ParseError::IdOutOfRange {
                    extended: false, ..
                })
                | Problem::Expected { .. }
                    if !want.extended
                        && want.id > 0x7FF
                        && matches!(want.kind, 'D' | 'R' | 'F') =>
                {
                    Ok(Some(Deliberate::StandardIdAbove7ff))
                }
                _ => Err(format!("python-can reads {want}, buslab: {e}")),
            };
        }
    };
    let mismatch = |what: &str| Err(format!("{what}: python-can reads {want}, buslab {entry:?}"));
    let t = entry.at.as_secs_f64();
    if (t - want.time).abs() > FLOAT_SECONDS {
        return mismatch("time");
    }
    match &want.channel {
        Some(channel) if interface(ext, channel) != entry.channel => return mismatch("channel"),
        // python-can gives no channel: CSV and SQLite have none (buslab reads them on can0);
        // its candump reader drops an error frame's.
        None if !matches!(ext, "log") && entry.channel != "can0" => return mismatch("channel"),
        _ => {}
    }
    let rx = entry.direction.unwrap_or(Direction::Rx) == Direction::Rx;
    if rx != want.rx {
        return mismatch("direction");
    }
    match (&entry.record, want.kind) {
        (Record::Error(e), 'E') => {
            // Where python-can's reader keeps an error frame's ID and bytes (BLF, CSV, SQLite);
            // its ASC and candump readers give none.
            if matches!(ext, "blf" | "csv" | "db") {
                let (class, data) = e.encode();
                if class != want.id || data[..e.data_len()] != want.data[..] {
                    return mismatch("error frame");
                }
            }
            Ok(None)
        }
        (Record::Frame(f), 'D' | 'R' | 'F') => {
            let id = f.id().as_raw();
            if id != want.id || f.is_extended() != want.extended {
                return mismatch("ID");
            }
            if f.is_remote() != (want.kind == 'R' || (want.kind == 'F' && want.data.is_empty())) {
                return mismatch("remote");
            }
            if !f.is_remote() && f.payload() != &want.data[..] {
                return mismatch("data");
            }
            let deliberate = if want.kind == 'F' {
                Some(Deliberate::ClassicInFdLine)
            } else if usize::from(f.dlc()) != want.dlc {
                if want.dlc > 8 && f.dlc() == 8 {
                    Some(Deliberate::ClassicDlcAbove8)
                } else {
                    return mismatch("DLC");
                }
            } else {
                None
            };
            Ok(deliberate)
        }
        (Record::Fd(f), 'F') => {
            if f.id().as_raw() != want.id || f.is_extended() != want.extended {
                return mismatch("ID");
            }
            if f.payload() != &want.data[..] {
                return mismatch("data");
            }
            Ok(None)
        }
        (Record::Fd(f), 'D')
            if f.payload().len() == want.dlc && f.payload().starts_with(&want.data) =>
        {
            Ok(Some(Deliberate::FdLengthInClassicLine))
        }
        _ => mismatch("kind"),
    }
}

/// One file's comparison: "N same" and the deliberate differences, or the first other one.
fn compare_file(path: &Path, want: &[PyMessage]) -> Result<String, String> {
    let ext = path.extension().unwrap().to_str().unwrap();
    let got = buslab_reads(path);
    if got.len() != want.len() {
        return Err(format!(
            "python-can reads {} messages, buslab {} entries and errors: {got:?}",
            want.len(),
            got.len()
        ));
    }
    let mut same = 0;
    let mut deliberate: BTreeMap<Deliberate, usize> = BTreeMap::new();
    for (i, (w, g)) in want.iter().zip(&got).enumerate() {
        match compare(ext, w, g).map_err(|e| format!("message {}: {e}", i + 1))? {
            None => same += 1,
            Some(d) => *deliberate.entry(d).or_default() += 1,
        }
    }
    let mut summary = format!("{same} same");
    for (d, n) in deliberate {
        summary.push_str(&format!(", {n} {d:?}"));
    }
    Ok(summary)
}

/// What each file gives: the messages read identically and the deliberate differences.
const EXPECTED: &[(&str, &str)] = &[
    ("issue_1256.asc", "1457 same"),
    ("issue_1299.asc", "3 same, 1 ClassicDlcAbove8"),
    ("issue_1905.blf", "22 same"),
    ("logfile.asc", "19 same, 1 ClassicInFdLine"),
    ("logfile_errorframes.asc", "12 same"),
    ("single_frame.asc", "0 same, 1 FdLengthInClassicLine"),
    ("single_frame_us_locale.asc", "1 same"),
    ("test_CanErrorFrameExt.blf", "2 same"),
    ("test_CanErrorFrames.asc", "4 same"),
    ("test_CanFdMessage.asc", "3 same"),
    ("test_CanFdMessage.blf", "0 same, 2 StandardIdAbove7ff"),
    ("test_CanFdMessage64.asc", "2 same"),
    ("test_CanFdMessage64.blf", "0 same, 2 StandardIdAbove7ff"),
    ("test_CanFdRemoteMessage.asc", "0 same, 1 ClassicInFdLine"),
    ("test_CanMessage.asc", "2 same"),
    ("test_CanMessage.asc.gz", "2 same"),
    ("test_CanMessage.blf", "0 same, 2 StandardIdAbove7ff"),
    ("test_CanMessage.trc", "2 same"),
    ("test_CanMessage2.blf", "0 same, 2 StandardIdAbove7ff"),
    ("test_CanMessage_V1_0_BUS1.trc", "11 same"),
    ("test_CanMessage_V1_1.trc", "11 same"),
    ("test_CanMessage_V1_3.trc", "11 same"),
    ("test_CanMessage_V2_0_BUS1.trc", "11 same"),
    ("test_CanMessage_V2_1.trc", "11 same"),
    ("test_CanRemoteMessage.asc", "3 same"),
];

fn table(results: &[(String, Result<String, String>)]) -> (String, usize) {
    let mut text = String::new();
    let mut identical = 0;
    for (name, result) in results {
        let line = match result {
            Ok(summary) => {
                if !summary.contains(", ") {
                    identical += 1;
                }
                summary.clone()
            }
            Err(e) => format!("DIFFERS: {e}"),
        };
        text.push_str(&format!("{name:32} {line}\n"));
    }
    (text, identical)
}

#[test]
fn buslab_reads_python_cans_test_logs_as_python_can_does() {
    let (Some(python), Some(dir)) = (python_can(), data_dir()) else {
        return;
    };
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| Format::from_path(p).is_ok())
        .collect();
    files.sort();
    let names: Vec<String> = files
        .iter()
        .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
        .collect();
    let expected_names: Vec<&str> = EXPECTED.iter().map(|(n, _)| *n).collect();
    assert_eq!(names, expected_names, "the log files of test/data");
    let read = python_reads(&python, &files);
    let results: Vec<(String, Result<String, String>)> = files
        .iter()
        .zip(&names)
        .map(|(path, name)| (name.clone(), compare_file(path, &read[path])))
        .collect();
    let (text, identical) = table(&results);
    println!(
        "python-can 4.6.1 test/data, read by python-can and buslab: {identical}/{} files identical\n{text}",
        files.len()
    );
    for ((name, result), (_, want)) in results.iter().zip(EXPECTED) {
        assert_eq!(result.as_deref(), Ok(*want), "{name}\n{text}");
    }
}

/// python-can's example messages written by its own writers: the formats its test data has
/// no file of (candump log, CSV, SQLite) and its writers of the others.
#[test]
fn buslab_reads_python_cans_example_messages_as_python_can_does() {
    let (Some(python), Some(dir)) = (python_can(), data_dir()) else {
        return;
    };
    let out_dir = tempfile::tempdir().unwrap();
    let written = Command::new(&python)
        .env("PYTHONPATH", &dir)
        .arg(root().join("tests/interop/can_log_fields.py"))
        .arg("--write-examples")
        .arg(out_dir.path())
        .output()
        .unwrap();
    assert!(
        written.status.success(),
        "{}",
        String::from_utf8_lossy(&written.stderr)
    );
    let files: Vec<PathBuf> = String::from_utf8(written.stdout)
        .unwrap()
        .lines()
        .map(PathBuf::from)
        .collect();
    let read = python_reads(&python, &files);
    let results: Vec<(String, Result<String, String>)> = files
        .iter()
        .map(|path| {
            let name = path.file_name().unwrap().to_string_lossy().into_owned();
            (name, compare_file(path, &read[path]))
        })
        .collect();
    let (text, identical) = table(&results);
    println!(
        "python-can 4.6.1 example_data written by python-can, read by python-can and buslab: {identical}/{} files identical\n{text}",
        files.len()
    );
    // 23 messages (16 frames, 4 remote, 3 error frames); python-can's TRC writer leaves
    // remote and error frames out.
    let want = [
        ("examples.log", "23 same"),
        ("examples.asc", "23 same"),
        ("examples.blf", "23 same"),
        ("examples.trc", "16 same"),
        ("examples.csv", "23 same"),
        ("examples.db", "23 same"),
    ];
    for ((name, result), (want_name, want)) in results.iter().zip(want) {
        assert_eq!(name, want_name);
        assert_eq!(result.as_deref(), Ok(want), "{name}\n{text}");
    }
}

/// The time of one of python-can's BLF test files, exactly: its SYSTEMTIME start (ms) plus the
/// object's nanoseconds (python-can's float gives 2459565876.494607).
#[test]
fn blf_times_are_exact_to_the_nanosecond() {
    let Some(dir) = data_dir() else { return };
    let got = buslab_reads(&dir.join("test_CanErrorFrameExt.blf"));
    let first = got[0].as_ref().unwrap();
    assert_eq!(
        first.at,
        buslab_logs::Timestamp::since_epoch(Duration::new(2_459_565_876, 494_606_882))
    );
}
