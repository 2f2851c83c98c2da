//! Logs survive their writer: `buslab dump -l FILE` and `buslab log convert --follow` killed
//! with SIGKILL at varied moments (after N frames printed, after N entries flushed) leave a
//! file that buslab **and** python-can (tshark for pcap/pcapng) read with every frame printed
//! or flushed before the kill; a closed stdout, SIGTERM/SIGHUP/SIGINT and a full disk
//! (RLIMIT_FSIZE: EFBIG) finish the log or leave it as its last flush made it.
//!
//! Run with `--nocapture` to see the tables (format × trial × frames printed vs read back).

mod bus_common;
#[path = "support/outside_tools.rs"]
mod outside_tools;

use std::io::{BufRead, BufReader, Write};
use std::path::Path;
use std::process::{Child, ChildStdout, Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use bus_common::Serve;
use outside_tools::{python_can, root, tool};

/// A deadline for an event that normally comes within a second (CI machines are loaded).
const EVENT: Duration = Duration::from_secs(60);

/// Every format `-l` writes, by extension.
const FORMATS: [&str; 8] = ["log", "asc", "blf", "trc", "csv", "pcap", "pcapng", "db"];

fn buslab() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_buslab"));
    c.env_remove("BUSLAB_BUS").env_remove("RUST_LOG");
    c
}

/// A frame as a log shows it: time (`SEC.USEC`) and can-utils' frame text.
#[derive(Clone, Debug, PartialEq, Eq)]
struct Seen {
    time: String,
    frame: String,
}

/// `(SEC.USEC) IFACE FRAME [R|T]` → time and frame.
fn candump_line(line: &str) -> Option<Seen> {
    let mut parts = line.split_whitespace();
    let time = parts
        .next()?
        .strip_prefix('(')?
        .strip_suffix(')')?
        .to_string();
    let _iface = parts.next()?;
    let frame = parts.next()?.to_string();
    Some(Seen { time, frame })
}

/// Traffic on `serve`'s bus until dropped: one frame a millisecond.
struct Traffic(Child);

impl Traffic {
    fn start(serve: &Serve) -> Self {
        Self(
            buslab()
                .args(["gen", "-q", "--bus", &serve.url, "-g", "1ms"])
                .stdout(Stdio::null())
                .stderr(Stdio::null())
                .spawn()
                .unwrap(),
        )
    }
}

impl Drop for Traffic {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// `buslab -v ARGS` with its stdout and stderr lines as they come.
struct Running {
    child: Child,
    stdout: Option<BufReader<ChildStdout>>,
    stderr: mpsc::Receiver<String>,
    stderr_all: Vec<String>,
}

impl Running {
    fn start(cmd: &mut Command) -> Self {
        let mut child = cmd
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let stdout = Some(BufReader::new(child.stdout.take().unwrap()));
        let (tx, stderr) = mpsc::channel();
        let lines = BufReader::new(child.stderr.take().unwrap()).lines();
        std::thread::spawn(move || {
            for line in lines.map_while(Result::ok) {
                if tx.send(line).is_err() {
                    break;
                }
            }
        });
        Self {
            child,
            stdout,
            stderr,
            stderr_all: Vec::new(),
        }
    }

    /// Waits for a stderr line that `want` accepts; returns it.
    fn wait_stderr(&mut self, what: &str, want: impl Fn(&str) -> bool) -> String {
        let deadline = Instant::now() + EVENT;
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            match self.stderr.recv_timeout(left) {
                Ok(line) => {
                    self.stderr_all.push(line.clone());
                    if want(&line) {
                        return line;
                    }
                }
                Err(_) => panic!("never saw {what}; stderr: {:#?}", self.stderr_all),
            }
        }
    }

    /// The next whole line. A line cut by the kill (the pipe took part of a write, CI
    /// 2026-11-29: `(1795917208.81416`) was never printed: it ends the output.
    fn next_stdout_line(&mut self) -> Option<String> {
        let mut line = String::new();
        match self.stdout.as_mut()?.read_line(&mut line) {
            Ok(0) | Err(_) => None,
            Ok(_) if !line.ends_with('\n') => None,
            Ok(_) => Some(line.trim_end().to_string()),
        }
    }

    fn kill_9(&mut self) {
        self.child.kill().unwrap(); // SIGKILL
        self.child.wait().unwrap();
    }

    /// The stderr lines so far and until the process's end.
    fn stderr_text(&mut self) -> String {
        while let Ok(line) = self.stderr.recv_timeout(EVENT) {
            self.stderr_all.push(line);
        }
        self.stderr_all.join("\n")
    }
}

impl Drop for Running {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// What buslab reads back: the entries, and the error that stopped it, if one did.
fn buslab_reads(path: &Path) -> (Vec<Seen>, Option<String>) {
    let out = buslab().args(["log", "cat"]).arg(path).output().unwrap();
    let seen = String::from_utf8_lossy(&out.stdout)
        .lines()
        .filter_map(candump_line)
        .collect();
    let error = (!out.status.success()).then(|| String::from_utf8_lossy(&out.stderr).into_owned());
    (seen, error)
}

/// What python-can reads back (frames only: its ASC times count from the first frame), or
/// tshark for the pcap formats; `None` when the tool is missing (outside CI).
fn outside_reads(
    python: Option<&Path>,
    path: &Path,
    ext: &str,
) -> Option<(Vec<String>, Option<String>)> {
    if ext.starts_with("pcap") {
        if !tool("tshark") {
            return None;
        }
        // AUTOSAR NM's dissector would take some IDs (ID 0) and hide their data bytes.
        let out = Command::new("tshark")
            .args(["--disable-protocol", "autosar-nm", "-r"])
            .arg(path)
            .args([
                "-T",
                "fields",
                "-e",
                "can.id",
                "-e",
                "can.flags.xtd",
                "-e",
                "data.data",
            ])
            .stderr(Stdio::piped())
            .output()
            .unwrap();
        let frames = String::from_utf8_lossy(&out.stdout)
            .lines()
            .map(|l| {
                let f: Vec<&str> = l.split('\t').collect();
                let id: u32 = f[0].parse().unwrap();
                let id = if f[1] == "1" {
                    format!("{id:08X}")
                } else {
                    format!("{id:03X}")
                };
                format!("{id}#{}", f.get(2).unwrap_or(&"").to_uppercase())
            })
            .collect();
        let err: String = String::from_utf8_lossy(&out.stderr)
            .lines()
            .filter(|l| !l.starts_with("Running as user"))
            .collect();
        return Some((frames, (!err.is_empty()).then_some(err)));
    }
    let python = python?;
    let out = Command::new(python)
        .arg(root().join("tests/interop/can_logs_after_kill.py"))
        .arg(path)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "python-can on {}: {}",
        path.display(),
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8_lossy(&out.stdout).into_owned();
    let mut frames = Vec::new();
    let mut stopped = None;
    for line in text.lines() {
        if let Some(why) = line.strip_prefix("# stopped: ") {
            stopped = Some(why.to_string());
        } else if let Some((_, frame)) = line.split_once(' ') {
            frames.push(frame.to_string());
        }
    }
    Some((frames, stopped))
}

/// One kill and what came back.
struct Trial {
    what: String,
    ext: &'static str,
    /// Frames printed (dump) or reported flushed (convert) before the kill.
    promised: usize,
    buslab: usize,
    outside: Option<usize>,
    notes: String,
}

fn print_table(title: &str, trials: &[Trial]) {
    eprintln!("\n{title}");
    eprintln!(
        "{:<8} {:<22} {:>9} {:>13} {:>20}  notes",
        "format", "trial", "promised", "buslab reads", "python-can/tshark"
    );
    for t in trials {
        eprintln!(
            "{:<8} {:<22} {:>9} {:>13} {:>20}  {}",
            t.ext,
            t.what,
            t.promised,
            t.buslab,
            t.outside.map_or("skipped".to_string(), |n| n.to_string()),
            t.notes
        );
    }
}

/// Checks that the log at `path` holds `promised` first (times and frames for buslab, frames
/// for the outside reader), and makes the table row.
fn check(
    what: String,
    ext: &'static str,
    path: &Path,
    promised: &[Seen],
    python: Option<&Path>,
) -> Trial {
    let (read, error) = buslab_reads(path);
    let mut notes = Vec::new();
    if let Some(e) = &error {
        notes.push(format!("buslab stopped: {}", e.trim()));
    }
    assert!(
        read.len() >= promised.len() && read[..promised.len()] == *promised,
        "{ext} {what}: buslab read {} entries, {} promised; first difference at {:?}; {error:?}",
        read.len(),
        promised.len(),
        read.iter().zip(promised).position(|(r, p)| r != p)
    );
    let outside = outside_reads(python, path, ext).map(|(frames, stopped)| {
        let want: Vec<&String> = promised.iter().map(|s| &s.frame).collect();
        let got: Vec<&String> = frames.iter().take(want.len()).collect();
        assert_eq!(
            got,
            want,
            "{ext} {what}: the outside reader does not hold the promised frames ({} read; {stopped:?})",
            frames.len()
        );
        if let Some(s) = stopped {
            notes.push(format!("outside reader stopped after them: {s}"));
        }
        frames.len()
    });
    Trial {
        what,
        ext,
        promised: promised.len(),
        buslab: read.len(),
        outside,
        notes: notes.join("; "),
    }
}

/// The frames `dump -L` printed in its lines.
fn printed(lines: &[String]) -> Vec<Seen> {
    lines.iter().filter_map(|l| candump_line(l)).collect()
}

#[test]
fn kill_9_of_dump_keeps_every_printed_frame_in_every_format() {
    let python = python_can();
    let serve = Serve::start(500_000);
    let _traffic = Traffic::start(&serve);
    let dir = tempfile::tempdir().unwrap();
    let mut trials = Vec::new();
    for ext in FORMATS {
        // Killed before any frame is printed, after the first, and later on.
        for (trial, kill_after) in [0usize, 1, 40, 400].into_iter().enumerate() {
            let path = dir.path().join(format!("dump{trial}.{ext}"));
            let mut dump = Running::start(
                buslab()
                    .args(["-v", "dump", "--bus", &serve.url, "-L", "-l"])
                    .arg(&path),
            );
            dump.wait_stderr("dump: listening", |l| l.contains("dump: listening"));
            let mut lines = Vec::new();
            while lines.len() < kill_after {
                match dump.next_stdout_line() {
                    Some(line) => lines.push(line),
                    None => panic!("dump ended: {}", dump.stderr_text()),
                }
            }
            dump.kill_9();
            // What it printed before it died is still in the pipe.
            while let Some(line) = dump.next_stdout_line() {
                lines.push(line);
            }
            let promised = printed(&lines);
            assert_eq!(promised.len(), lines.len(), "{lines:?}");
            trials.push(check(
                format!("killed after {kill_after} lines"),
                ext,
                &path,
                &promised,
                python.as_deref(),
            ));
        }
    }
    print_table(
        "buslab dump -L -l FILE, kill -9 after N lines printed (promised = lines printed)",
        &trials,
    );
}

/// `n` candump lines from the `from`th on, a millisecond apart.
fn lines(n: usize, from: usize) -> String {
    (from..from + n)
        .map(|i| {
            format!(
                "({}.{:06}) can0 {:03X}#{:02X}{:02X}\n",
                1_700_000_000 + i / 1000,
                i % 1000 * 1000,
                i % 0x800,
                i % 256,
                i / 256 % 256
            )
        })
        .collect()
}

fn append(path: &Path, text: &str) {
    let mut f = std::fs::OpenOptions::new().append(true).open(path).unwrap();
    f.write_all(text.as_bytes()).unwrap();
}

/// The `N` of convert's `-v` line `OUT: N entries flushed`.
fn flushed(line: &str) -> Option<usize> {
    line.strip_suffix(" entries flushed")?
        .rsplit(' ')
        .next()?
        .parse()
        .ok()
}

#[test]
fn kill_9_of_a_followed_conversion_keeps_every_flushed_entry_in_every_format() {
    let python = python_can();
    let dir = tempfile::tempdir().unwrap();
    let mut trials = Vec::new();
    const CHUNK: usize = 150;
    for ext in FORMATS {
        for (trial, chunks) in [1usize, 3].into_iter().enumerate() {
            let input = dir.path().join(format!("in{trial}-{ext}.log"));
            let output = dir.path().join(format!("out{trial}.{ext}"));
            std::fs::write(&input, "").unwrap();
            let mut convert = Running::start(
                buslab()
                    .args(["-v", "log", "convert", "--follow"])
                    .arg(&input)
                    .arg(&output),
            );
            // Each chunk once the one before was reported flushed.
            let mut reported = 0;
            for k in 0..chunks {
                append(&input, &lines(CHUNK, k * CHUNK));
                let want = (k + 1) * CHUNK;
                while reported < want {
                    let line = convert.wait_stderr("a flush", |l| flushed(l).is_some());
                    reported = flushed(&line).unwrap();
                }
            }
            // More that nobody was told about, then the kill.
            append(&input, &lines(CHUNK, chunks * CHUNK));
            convert.kill_9();
            let promised: Vec<Seen> = lines(reported, 0)
                .lines()
                .filter_map(candump_line)
                .collect();
            let mut row = check(
                format!("killed after {chunks} flushes"),
                ext,
                &output,
                &promised,
                python.as_deref(),
            );
            row.ext = ext;
            trials.push(row);
        }
    }
    print_table(
        "buslab log convert --follow IN OUT, kill -9 after the Nth reported flush (promised = entries reported flushed)",
        &trials,
    );
}

/// The bug: `buslab dump -l p.blf | head -n 5` exited at once when `head` left, its BLF a
/// header of zeros (144 bytes), its ASC without the end line.
#[test]
fn a_closed_stdout_finishes_the_log() {
    let python = python_can();
    let serve = Serve::start(500_000);
    let _traffic = Traffic::start(&serve);
    let dir = tempfile::tempdir().unwrap();
    let mut trials = Vec::new();
    for ext in FORMATS {
        let path = dir.path().join(format!("head.{ext}"));
        let mut dump = Running::start(
            buslab()
                .args(["-v", "dump", "--bus", &serve.url, "-L", "-l"])
                .arg(&path),
        );
        let mut first = Vec::new();
        while first.len() < 5 {
            first.push(dump.next_stdout_line().expect("dump ended"));
        }
        // `head -n 5` exits: the pipe's reading end closes.
        dump.stdout = None;
        let status = dump.child.wait().unwrap();
        let err = dump.stderr_text();
        assert!(status.success(), "{ext}: {status}: {err}");
        if ext == "asc" {
            let text = std::fs::read_to_string(&path).unwrap();
            assert!(text.ends_with("End TriggerBlock\n"), "{text}");
        }
        if ext == "blf" {
            let bytes = std::fs::read(&path).unwrap();
            let objects = u32::from_le_bytes(bytes[32..36].try_into().unwrap()) as usize;
            let size = u64::from_le_bytes(bytes[16..24].try_into().unwrap());
            assert_eq!(size, bytes.len() as u64, "the header's file size");
            assert_eq!(
                objects,
                buslab_reads(&path).0.len(),
                "the header's object count"
            );
        }
        let mut row = check(
            "head -n 5".into(),
            ext,
            &path,
            &printed(&first),
            python.as_deref(),
        );
        let (_, error) = buslab_reads(&path);
        assert_eq!(error, None, "{ext}: a finished log reads to its end");
        row.notes = status.to_string();
        trials.push(row);
    }
    print_table("buslab dump -L -l FILE | head -n 5", &trials);
}

#[test]
fn sigterm_sighup_and_sigint_finish_a_dumped_log() {
    let serve = Serve::start(500_000);
    let _traffic = Traffic::start(&serve);
    let dir = tempfile::tempdir().unwrap();
    for ext in ["asc", "blf"] {
        for signal in ["TERM", "HUP", "INT"] {
            let path = dir.path().join(format!("sig{signal}.{ext}"));
            let mut dump = Running::start(
                buslab()
                    .args(["-v", "dump", "--bus", &serve.url, "-L", "-l"])
                    .arg(&path),
            );
            let mut lines = Vec::new();
            while lines.len() < 20 {
                lines.push(dump.next_stdout_line().expect("dump ended"));
            }
            let sent = Command::new("kill")
                .arg(format!("-{signal}"))
                .arg(dump.child.id().to_string())
                .status()
                .unwrap();
            assert!(sent.success());
            while let Some(line) = dump.next_stdout_line() {
                lines.push(line);
            }
            let status = dump.child.wait().unwrap();
            assert!(status.success(), "SIG{signal}: {}", dump.stderr_text());
            let (read, error) = buslab_reads(&path);
            assert_eq!(error, None, "SIG{signal} {ext}");
            // Finished: every printed frame, and nothing more is pending in the writer.
            assert_eq!(read, printed(&lines), "SIG{signal} {ext}");
            if ext == "asc" {
                let text = std::fs::read_to_string(&path).unwrap();
                assert!(text.ends_with("End TriggerBlock\n"), "SIG{signal}");
            }
        }
    }
}

/// A full disk, as RLIMIT_FSIZE makes it (EFBIG; no mount needed): dump stops with an error
/// naming the log and what it keeps, and the log reads with every frame printed before.
#[test]
fn a_file_size_limit_stops_dump_with_an_error_and_a_readable_log() {
    if !tool("prlimit") {
        return;
    }
    let python = python_can();
    let serve = Serve::start(500_000);
    let _traffic = Traffic::start(&serve);
    let dir = tempfile::tempdir().unwrap();
    let mut trials = Vec::new();
    const LIMIT: u64 = 40_000;
    for ext in FORMATS {
        let path = dir.path().join(format!("full.{ext}"));
        let mut cmd = Command::new("prlimit");
        cmd.arg(format!("--fsize={LIMIT}"))
            .arg(env!("CARGO_BIN_EXE_buslab"))
            .args(["dump", "--bus", &serve.url, "-L", "-l"])
            .arg(&path)
            .env_remove("BUSLAB_BUS");
        let mut dump = Running::start(&mut cmd);
        let mut lines = Vec::new();
        while let Some(line) = dump.next_stdout_line() {
            lines.push(line);
        }
        let status = dump.child.wait().unwrap();
        let err = dump.stderr_text();
        assert!(!status.success(), "{ext}: dump went on past the limit");
        // SQLite says it in its words (SQLITE_IOERR_WRITE).
        let why = if ext == "db" {
            "Error writing to disk"
        } else {
            "File too large"
        };
        assert!(
            err.contains("cannot write the log") && err.contains(why),
            "{ext}: {err}"
        );
        let size = std::fs::metadata(&path).unwrap().len();
        assert!(size <= LIMIT, "{ext}: {size} bytes");
        let mut row = check(
            "ulimit -f 40000 B".into(),
            ext,
            &path,
            &printed(&lines),
            python.as_deref(),
        );
        let (_, error) = buslab_reads(&path);
        assert_eq!(error, None, "{ext}: the log is cut back to its last flush");
        // The reason, as the message gives it after what the log keeps.
        row.notes = err
            .lines()
            .find_map(|l| l.split_once("(every one printed): "))
            .map(|(_, why)| why.to_string())
            .unwrap_or_default();
        trials.push(row);
    }
    print_table("prlimit --fsize=40000 buslab dump -L -l FILE", &trials);
}
