//! The golden comparison: every DBC file of cantools' own tests (its 45.1.0 sdist,
//! `tests/files/dbc`) and of opendbc (its 0.3.1 wheel, `opendbc/dbc`) read by cantools and by
//! buslab, the models compared (messages, signals, layouts, scaling, ranges, units, comments,
//! value tables, multiplexing, cycle times, FD) and the same frames decoded by both, every
//! signal compared: raw value, physical value (equal as f64) and value-table label.
//!
//! `tests/cantools_golden.py` reads the files with cantools (its default strict loading; a
//! file it refuses is read again with `strict=False` and compared all the same) and makes the
//! frames: random payloads, all zeros, all ones, frames for every multiplexing branch and one
//! truncated payload per message. The differences that remain are deliberate: each is listed
//! in [`Difference`], explained in docs/dbc.md and pinned by a test in `tests/cantools.rs`.
//!
//! `scripts/setup-test-deps.sh` installs cantools into `.venv` and unpacks both corpora under
//! `target/`; without them this test fails (it does not skip).

use std::collections::{BTreeMap, HashMap};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

use buslab_can::Id;
use buslab_dbc::{ByteOrder, Database, Message, Multiplexing, Signal, ValueKind};

const CANTOOLS_DBC: &str = "target/cantools-sdist/cantools-45.1.0/tests/files/dbc";
const OPENDBC_DBC: &str = "target/opendbc-wheel/opendbc/dbc";

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// The DBC files of a corpus; there must be `count` of them.
fn corpus(dir: &str, count: usize) -> Vec<PathBuf> {
    let dir = root().join(dir);
    let entries = std::fs::read_dir(&dir).unwrap_or_else(|e| {
        panic!(
            "{}: {e}: run scripts/setup-test-deps.sh (it unpacks the DBC corpora)",
            dir.display()
        )
    });
    let mut files: Vec<PathBuf> = entries
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x.eq_ignore_ascii_case("dbc")))
        .collect();
    files.sort();
    assert_eq!(
        files.len(),
        count,
        "{}: {count} DBC files expected; run scripts/setup-test-deps.sh",
        dir.display()
    );
    files
}

/// The venv's python, with cantools 45.1.0.
fn python() -> PathBuf {
    let python = root().join(".venv/bin/python");
    let ok = Command::new(&python)
        .args([
            "-c",
            "import cantools; assert cantools.__version__ == '45.1.0', cantools.__version__",
        ])
        .status()
        .is_ok_and(|s| s.success());
    assert!(
        ok,
        "{} with cantools 45.1.0 is missing: run scripts/setup-test-deps.sh",
        python.display()
    );
    python
}

// --- What cantools says (tests/cantools_golden.py's records) --------------------------------

#[derive(Debug, Default)]
struct PyFile {
    path: PathBuf,
    /// Why strict loading refused it.
    refused: Option<String>,
    /// Why `strict=False` refused it too.
    refused_lenient: Option<String>,
    messages: Vec<PyMessage>,
}

#[derive(Debug)]
struct PyMessage {
    id: u32,
    extended: bool,
    name: String,
    length: usize,
    fd: bool,
    cycle_ms: Option<u64>,
    comment: Option<String>,
    senders: Vec<String>,
    signals: Vec<PySignal>,
    frames: Vec<PyFrame>,
}

#[derive(Debug)]
struct PySignal {
    name: String,
    start: u32,
    length: u32,
    big_endian: bool,
    signed: bool,
    float: bool,
    scale: f64,
    offset: f64,
    min: Option<f64>,
    max: Option<f64>,
    unit: Option<String>,
    comment: Option<String>,
    mux: String,
    choices: String,
    initial: Option<f64>,
    receivers: Vec<String>,
}

#[derive(Debug)]
enum Status {
    Ok,
    /// cantools refuses the frame: a multiplexor's value has no branch.
    NoBranch,
    /// cantools cannot decode the frame at all.
    Error(String),
}

#[derive(Debug)]
struct PyFrame {
    data: Vec<u8>,
    truncated: bool,
    status: Status,
    values: Vec<PyValue>,
}

#[derive(Debug)]
struct PyValue {
    name: String,
    raw: String,
    physical: f64,
    label: Option<String>,
}

fn unhex(field: &str) -> Option<String> {
    (field != "-").then(|| String::from_utf8(bytes(field)).expect("UTF-8 text"))
}

fn bytes(field: &str) -> Vec<u8> {
    if field == "-" {
        return Vec::new();
    }
    (0..field.len())
        .step_by(2)
        .map(|i| u8::from_str_radix(&field[i..i + 2], 16).expect("hex"))
        .collect()
}

fn float(field: &str) -> Option<f64> {
    (field != "-").then(|| field.parse().expect("a float"))
}

fn list(field: &str) -> Vec<String> {
    if field == "-" {
        Vec::new()
    } else {
        field.split(',').map(str::to_string).collect()
    }
}

fn cantools_reads(python: &Path, files: &[PathBuf]) -> Vec<PyFile> {
    let out = Command::new(python)
        .arg(root().join("crates/dbc/tests/cantools_golden.py"))
        .args(files)
        .output()
        .expect("run cantools_golden.py");
    assert!(
        out.status.success(),
        "cantools_golden.py failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let mut parsed: Vec<PyFile> = Vec::new();
    for line in String::from_utf8(out.stdout).unwrap().lines() {
        let f: Vec<&str> = line.split('\t').collect();
        if f[0] == "file" {
            parsed.push(PyFile {
                path: PathBuf::from(f[1]),
                ..PyFile::default()
            });
            continue;
        }
        let file = parsed.last_mut().expect("a file record first");
        match f[0] {
            "refused" => file.refused = unhex(f[1]),
            "refused-lenient" => file.refused_lenient = unhex(f[1]),
            "lenient" => {}
            "message" => file.messages.push(PyMessage {
                id: f[1].parse().unwrap(),
                extended: f[2] == "1",
                name: f[3].to_string(),
                length: f[4].parse().unwrap(),
                fd: f[5] == "1",
                cycle_ms: (f[6] != "-").then(|| f[6].parse().unwrap()),
                comment: unhex(f[7]),
                senders: list(f[8]),
                signals: Vec::new(),
                frames: Vec::new(),
            }),
            "signal" => file.messages.last_mut().unwrap().signals.push(PySignal {
                name: f[1].to_string(),
                start: f[2].parse().unwrap(),
                length: f[3].parse().unwrap(),
                big_endian: f[4] == "be",
                signed: f[5] == "1",
                float: f[6] == "1",
                scale: float(f[7]).unwrap(),
                offset: float(f[8]).unwrap(),
                min: float(f[9]),
                max: float(f[10]),
                unit: unhex(f[11]),
                comment: unhex(f[12]),
                mux: f[13].to_string(),
                choices: f[14].to_string(),
                initial: float(f[15]),
                receivers: list(f[16]),
            }),
            "frame" => {
                let status = match f[3].split_once(':') {
                    None => Status::Ok,
                    Some(("nobranch", _)) => Status::NoBranch,
                    Some(("error", what)) => Status::Error(unhex(what).unwrap_or_default()),
                    Some(other) => panic!("frame status {other:?}"),
                };
                file.messages.last_mut().unwrap().frames.push(PyFrame {
                    data: bytes(f[1]),
                    truncated: f[2] == "1",
                    status,
                    values: Vec::new(),
                });
            }
            "value" => {
                let frame = file.messages.last_mut().unwrap().frames.last_mut().unwrap();
                frame.values.push(PyValue {
                    name: f[1].to_string(),
                    raw: f[2].to_string(),
                    physical: float(f[3]).unwrap(),
                    label: unhex(f[4]),
                });
            }
            other => panic!("unknown record {other:?}"),
        }
    }
    parsed
}

// --- The comparison -------------------------------------------------------------------------

/// The counts the lead quotes, per corpus.
#[derive(Default)]
struct Tally {
    files: usize,
    /// Loaded by cantools' strict loading, and compared.
    strict: usize,
    /// Refused by strict loading, loaded with `strict=False`, and compared.
    lenient: usize,
    /// Refused by cantools even with `strict=False` (not compared), with the reasons.
    cantools_refuses: Vec<String>,
    /// Refused by buslab and by cantools' strict loading.
    both_refuse: Vec<String>,
    /// Refused by buslab (each must be one cantools refuses too).
    buslab_refuses: Vec<String>,
    messages: usize,
    signals: usize,
    frames: usize,
    values: usize,
    /// Frames cantools refuses (a multiplexor value without a branch): compared with the
    /// signals it decodes before it gives up.
    no_branch_frames: usize,
    /// Frames cantools cannot decode at all (a layout strict loading refuses).
    undecodable_frames: usize,
    undecodable: BTreeMap<String, usize>,
    /// Deliberate differences by reason.
    explained: BTreeMap<&'static str, usize>,
    mismatches: Vec<String>,
}

/// The differences one file shows: unexplained ones, and the deliberate ones counted by
/// their reason (each in docs/dbc.md, pinned in tests/cantools.rs).
#[derive(Default)]
struct Findings {
    mismatches: Vec<String>,
    explained: BTreeMap<&'static str, usize>,
}

/// cantools reads every DBC file as Windows-1252; buslab reads UTF-8 when the bytes are UTF-8.
const ENCODING: &str = "text of a UTF-8 file: cantools reads it as Windows-1252";
/// `[0.0|0.0]`: no range for buslab (as `[0|0]`), 0..=0 for cantools.
const ZERO_RANGE: &str = "range [0.0|0.0]: no range for buslab, 0 to 0 for cantools";

/// The text cantools makes of `text`'s UTF-8 bytes, reading them as Windows-1252.
fn as_cp1252(text: &str) -> String {
    can_dbc::decode_cp1252(text.as_bytes())
        .map(|t| t.into_owned())
        .unwrap_or_default()
}

impl Findings {
    fn explain(&mut self, reason: &'static str) {
        *self.explained.entry(reason).or_default() += 1;
    }
}

fn same(a: f64, b: f64) -> bool {
    a == b || (a.is_nan() && b.is_nan())
}

/// Our multiplexing in the spelling of cantools_golden.py's MUX field.
fn mux_field(message: &Message, signal: &Signal) -> String {
    let mut parts = Vec::new();
    if signal.is_multiplexor() {
        parts.push("M".to_string());
    }
    if let Multiplexing::Multiplexed {
        multiplexor,
        values,
        ..
    } = signal.multiplexing()
    {
        let mut ids: Vec<u64> = values.iter().flat_map(|r| r.clone()).collect();
        ids.sort_unstable();
        ids.dedup();
        let ids: Vec<String> = ids.iter().map(u64::to_string).collect();
        parts.push(format!(
            "{}:{}",
            message.signals()[*multiplexor].name(),
            ids.join(",")
        ));
    }
    if parts.is_empty() {
        "-".into()
    } else {
        parts.join(";")
    }
}

fn choices_field(signal: &Signal, label: impl Fn(&str) -> String) -> String {
    if signal.choices().is_empty() {
        return "-".into();
    }
    let mut choices = signal.choices().to_vec();
    choices.sort_by_key(|(k, _)| *k);
    // cantools keeps the last label of a value given twice.
    choices.dedup_by(|later, earlier| {
        if later.0 == earlier.0 {
            earlier.1 = later.1.clone();
            true
        } else {
            false
        }
    });
    let fields: Vec<String> = choices
        .iter()
        .map(|(k, text)| {
            let hex: String = label(text).bytes().map(|b| format!("{b:02x}")).collect();
            format!("{k}={}", if hex.is_empty() { "-" } else { &hex })
        })
        .collect();
    fields.join(",")
}

fn compare_signal(message: &Message, ours: &Signal, py: &PySignal, found: &mut Findings) {
    let at = format!("{}.{}", message.name(), ours.name());
    let mut differ = |what: &str, a: String, b: String| {
        if a != b {
            found
                .mismatches
                .push(format!("{at}: {what}: buslab {a}, cantools {b}"));
        }
    };
    differ("start", ours.start_bit().to_string(), py.start.to_string());
    differ("length", ours.size().to_string(), py.length.to_string());
    differ(
        "byte order",
        (ours.byte_order() == ByteOrder::BigEndian).to_string(),
        py.big_endian.to_string(),
    );
    // A float's sign is in its bits: the `-` of its SG_ line means nothing.
    if !py.float {
        differ(
            "signed",
            (ours.kind() == ValueKind::Signed).to_string(),
            py.signed.to_string(),
        );
    }
    differ(
        "float",
        matches!(ours.kind(), ValueKind::Float32 | ValueKind::Float64).to_string(),
        py.float.to_string(),
    );
    differ(
        "factor",
        format!("{:?}", ours.factor()),
        format!("{:?}", py.scale),
    );
    differ(
        "offset",
        format!("{:?}", ours.offset()),
        format!("{:?}", py.offset),
    );
    differ("multiplexing", mux_field(message, ours), py.mux.clone());
    differ(
        "start value",
        format!("{:?}", ours.start_value()),
        format!("{:?}", py.initial),
    );
    differ(
        "receivers",
        ours.receivers().join(","),
        py.receivers.join(","),
    );
    let range = ours.range().map(|(a, b)| (Some(a), Some(b)));
    let range = range.unwrap_or((None, None));
    if range == (None, None) && (py.min, py.max) == (Some(0.0), Some(0.0)) {
        found.explain(ZERO_RANGE);
    } else {
        differ(
            "range",
            format!("{range:?}"),
            format!("{:?}", (py.min, py.max)),
        );
    }
    // Text: equal, or equal once read as cantools reads the file.
    let texts = [
        (
            "unit",
            Some(ours.unit())
                .filter(|u| !u.is_empty())
                .map(str::to_string),
            py.unit.clone(),
        ),
        (
            "comment",
            ours.comment().map(str::to_string),
            py.comment.clone(),
        ),
    ];
    for (what, a, b) in texts {
        if a == b {
            continue;
        }
        if a.as_deref().map(as_cp1252) == b {
            found.explain(ENCODING);
        } else {
            found
                .mismatches
                .push(format!("{at}: {what}: buslab {a:?}, cantools {b:?}"));
        }
    }
    let table = choices_field(ours, str::to_string);
    if table != py.choices {
        if choices_field(ours, as_cp1252) == py.choices {
            found.explain(ENCODING);
        } else {
            found.mismatches.push(format!(
                "{at}: value table: buslab {table}, cantools {}",
                py.choices
            ));
        }
    }
}

fn compare_message(ours: &Message, py: &PyMessage, found: &mut Findings) {
    let mut differ = |what: &str, a: String, b: String| {
        if a != b {
            found
                .mismatches
                .push(format!("{}: {what}: buslab {a}, cantools {b}", py.name));
        }
    };
    differ("name", ours.name().into(), py.name.clone());
    differ("length", ours.length().to_string(), py.length.to_string());
    differ("FD", ours.is_fd().to_string(), py.fd.to_string());
    differ(
        "cycle time",
        format!("{:?}", ours.cycle_time()),
        format!("{:?}", py.cycle_ms.map(Duration::from_millis)),
    );
    let comment = ours.comment().map(str::to_string);
    if comment.as_deref().map(as_cp1252) == py.comment && comment != py.comment {
        found.explain(ENCODING);
    } else {
        differ(
            "comment",
            format!("{comment:?}"),
            format!("{:?}", py.comment.as_deref()),
        );
    }
    let mut differ = |what: &str, a: String, b: String| {
        if a != b {
            found
                .mismatches
                .push(format!("{}: {what}: buslab {a}, cantools {b}", py.name));
        }
    };
    differ("senders", ours.senders().join(","), py.senders.join(","));
    let mut names: Vec<&str> = ours.signals().iter().map(Signal::name).collect();
    let mut py_names: Vec<&str> = py.signals.iter().map(|s| s.name.as_str()).collect();
    names.sort_unstable();
    py_names.sort_unstable();
    differ("signals", names.join(","), py_names.join(","));
    for py_signal in &py.signals {
        if let Some((_, signal)) = ours.signal_by_name(&py_signal.name) {
            compare_signal(ours, signal, py_signal, found);
        }
    }
}

/// One frame decoded by buslab against cantools' values; returns the values compared.
fn compare_frame(message: &Message, frame: &PyFrame, found: &mut Findings) -> usize {
    let decoded = message.decode(&frame.data);
    let mut ours: HashMap<&str, _> = decoded
        .iter()
        .map(|d| (message.signals()[d.signal].name(), *d))
        .collect();
    let at = |what: String| {
        format!(
            "{} frame {:02x?}{}: {what}",
            message.name(),
            frame.data,
            if frame.truncated { " (truncated)" } else { "" }
        )
    };
    let mut compared = 0;
    for value in &frame.values {
        let Some(d) = ours.remove(value.name.as_str()) else {
            found
                .mismatches
                .push(at(format!("{} not decoded by buslab", value.name)));
            continue;
        };
        compared += 1;
        let signal = &message.signals()[d.signal];
        let raw_same = match signal.kind() {
            ValueKind::Float32 | ValueKind::Float64 => {
                let py: f64 = value.raw.parse().expect("a float raw value");
                same(
                    signal.physical(d.raw) - signal.offset(),
                    py * signal.factor(),
                ) || same(
                    if signal.kind() == ValueKind::Float32 {
                        f64::from(f32::from_bits(d.raw as u32))
                    } else {
                        f64::from_bits(d.raw)
                    },
                    py,
                )
            }
            ValueKind::Signed => value.raw == signal.integer(d.raw).to_string(),
            ValueKind::Unsigned => value.raw == d.raw.to_string(),
        };
        if !raw_same {
            found.mismatches.push(at(format!(
                "{} raw: buslab {:#x}, cantools {}",
                value.name, d.raw, value.raw
            )));
        }
        if !same(d.physical, value.physical) {
            found.mismatches.push(at(format!(
                "{} physical: buslab {:?}, cantools {:?}",
                value.name, d.physical, value.physical
            )));
        }
        let label = signal.choice(d.raw);
        if label.map(as_cp1252) == value.label && label != value.label.as_deref() {
            found.explain(ENCODING);
        } else if label != value.label.as_deref() {
            found.mismatches.push(at(format!(
                "{} label: buslab {label:?}, cantools {:?}",
                value.name, value.label
            )));
        }
    }
    for name in ours.keys() {
        found
            .mismatches
            .push(at(format!("{name} decoded by buslab only")));
    }
    compared
}

fn compare_file(py: &PyFile, tally: &mut Tally) {
    tally.files += 1;
    let name = py.path.file_name().unwrap().to_string_lossy().into_owned();
    let bytes = std::fs::read(&py.path).unwrap();
    let ours = Database::from_bytes(&bytes);
    if let Some(why) = &py.refused_lenient {
        tally.cantools_refuses.push(format!(
            "{name}: {}; buslab: {}",
            why.lines().next().unwrap_or(""),
            match &ours {
                Ok(db) => format!("loads {} messages", db.messages().len()),
                Err(e) => format!("refuses too: {e}"),
            }
        ));
        return;
    }
    let db = match ours {
        Ok(db) => db,
        // Both refuse it (cantools loads it only when told not to check).
        Err(e) if py.refused.is_some() => {
            tally.both_refuse.push(format!(
                "{name}: cantools: {}; buslab: {e}",
                py.refused
                    .as_deref()
                    .unwrap_or("")
                    .lines()
                    .next()
                    .unwrap_or("")
            ));
            return;
        }
        Err(e) => {
            let line = format!("{name}: buslab refuses ({e}), cantools loads it");
            tally.buslab_refuses.push(line.clone());
            tally.mismatches.push(line);
            return;
        }
    };
    if py.refused.is_some() {
        tally.lenient += 1;
    } else {
        tally.strict += 1;
    }
    let mut found = Findings::default();
    if db.messages().len() != py.messages.len() {
        found.mismatches.push(format!(
            "{} messages in buslab, {} in cantools",
            db.messages().len(),
            py.messages.len()
        ));
    }
    for py_message in &py.messages {
        let id = if py_message.extended {
            Id::extended(py_message.id)
        } else {
            Id::standard(py_message.id as u16)
        }
        .unwrap();
        let Some(message) = db.message(id) else {
            found
                .mismatches
                .push(format!("{}: no message {id} in buslab", py_message.name));
            continue;
        };
        tally.messages += 1;
        tally.signals += py_message.signals.len();
        compare_message(message, py_message, &mut found);
        for frame in &py_message.frames {
            tally.frames += 1;
            match &frame.status {
                Status::Ok => {}
                Status::NoBranch => tally.no_branch_frames += 1,
                Status::Error(why) => {
                    tally.undecodable_frames += 1;
                    *tally
                        .undecodable
                        .entry(format!("{name}: {why}"))
                        .or_default() += 1;
                    continue;
                }
            }
            tally.values += compare_frame(message, frame, &mut found);
        }
    }
    tally
        .mismatches
        .extend(found.mismatches.into_iter().map(|m| format!("{name}: {m}")));
    for (reason, count) in found.explained {
        *tally.explained.entry(reason).or_default() += count;
    }
}

#[test]
fn buslab_decodes_every_corpus_dbc_as_cantools_does() {
    let python = python();
    let corpora = [
        ("cantools 45.1.0 tests/files/dbc", corpus(CANTOOLS_DBC, 89)),
        ("opendbc 0.3.1 opendbc/dbc", corpus(OPENDBC_DBC, 58)),
    ];
    let mut report = String::new();
    let mut all_mismatches = Vec::new();
    let mut all_buslab_refuses = Vec::new();
    writeln!(
        report,
        "{:<34} {:>5} {:>6} {:>7} {:>8} {:>8} {:>7} {:>9} {:>8} {:>10}",
        "corpus",
        "files",
        "strict",
        "lenient",
        "messages",
        "signals",
        "frames",
        "values",
        "nobranch",
        "mismatches"
    )
    .unwrap();
    let mut refused = String::new();
    let mut explained = String::new();
    for (label, files) in &corpora {
        let mut tally = Tally::default();
        for file in cantools_reads(&python, files) {
            compare_file(&file, &mut tally);
        }
        writeln!(
            report,
            "{label:<34} {:>5} {:>6} {:>7} {:>8} {:>8} {:>7} {:>9} {:>8} {:>10}",
            tally.files,
            tally.strict,
            tally.lenient,
            tally.messages,
            tally.signals,
            tally.frames,
            tally.values,
            tally.no_branch_frames,
            tally.mismatches.len()
        )
        .unwrap();
        for line in &tally.both_refuse {
            writeln!(refused, "  {line}").unwrap();
        }
        for line in &tally.cantools_refuses {
            writeln!(refused, "  {line}").unwrap();
        }
        for (why, frames) in &tally.undecodable {
            writeln!(
                refused,
                "  {why}: {frames} frames cantools cannot decode with strict=False, not compared"
            )
            .unwrap();
        }
        for (reason, count) in &tally.explained {
            writeln!(explained, "  {label}: {count} × {reason}").unwrap();
        }
        all_mismatches.extend(tally.mismatches);
        all_buslab_refuses.extend(tally.buslab_refuses);
    }
    eprintln!("{report}");
    eprintln!(
        "files refused by cantools (strict) and buslab, or by cantools even with strict=False:\n{refused}"
    );
    eprintln!("deliberate differences (docs/dbc.md):\n{explained}");
    for m in all_mismatches.iter().take(400) {
        eprintln!("MISMATCH {m}");
    }
    assert!(
        all_buslab_refuses.is_empty(),
        "buslab refuses files cantools loads: {all_buslab_refuses:#?}"
    );
    assert!(
        all_mismatches.is_empty(),
        "{} mismatches with cantools (first ones above)",
        all_mismatches.len()
    );
}
