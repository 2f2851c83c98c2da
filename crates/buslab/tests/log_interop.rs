//! Log files with tools nobody here wrote: python-can 4.6.1 reads every file buslab writes and
//! buslab reads every file python-can writes (ASC, BLF, TRC, CSV, SQLite, candump log);
//! can-utils' log2asc/asc2log against buslab's ASC; tshark decodes buslab's pcap and pcapng,
//! and editcap's conversions of them read back; error frames byte for byte through every
//! format (python-can reading the BLF, CSV and SQLite); Wireshark's exported PDUs
//! (text2pcap -P) read, other link types refused. Installed by scripts/setup-test-deps.sh;
//! under CI=1 a missing tool fails the test. python-can's own test logs:
//! log_python_can_data.rs.

#[path = "support/outside_tools.rs"]
mod outside_tools;

use outside_tools::{python_can, root, tool};
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

/// The reference log: standard, extended, remote with a DLC, empty, an error frame, two
/// interfaces, both directions, sub-millisecond times.
const REFERENCE: &str = "\
(1700000000.000000) can0 123#1122 R
(1700000000.001500) can1 12345678#DEADBEEF T
(1700000000.002000) can0 7FF#R3 R
(1700000000.003250) can0 000# R
(1700000000.004000) can0 20000088#0000020A00000000
(1700000000.005000) can1 1FFFFFFF#0102030405060708 R
";

fn run(cmd: &mut Command) -> String {
    let out: Output = cmd.output().unwrap();
    assert!(
        out.status.success(),
        "{cmd:?}: {}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).unwrap()
}

fn buslab() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_buslab"));
    c.arg("-q");
    c
}

fn reference(dir: &Path) -> PathBuf {
    let path = dir.join("ref.log");
    std::fs::write(&path, REFERENCE).unwrap();
    path
}

/// Lines `TIME REST` equal when REST is and the times (seconds, in brackets or not) are within
/// 2 µs (float seconds round, python-can's BLF writer truncates to the nanosecond).
fn assert_same(what: &str, got: &str, want: &str) {
    let split = |line: &str| {
        let (t, rest) = line.trim().split_once(' ').unwrap_or((line, ""));
        let t: f64 = t
            .trim_matches(|c| c == '(' || c == ')')
            .parse()
            .unwrap_or(f64::NAN);
        (t, rest.trim().to_string())
    };
    let got: Vec<_> = got
        .lines()
        .filter(|l| !l.trim().is_empty())
        .map(split)
        .collect();
    let want: Vec<_> = want
        .lines()
        .filter(|l| !l.trim().is_empty())
        .map(split)
        .collect();
    let same = got.len() == want.len()
        && got
            .iter()
            .zip(&want)
            .all(|(g, w)| g.1 == w.1 && (g.0 - w.0).abs() <= 2e-6);
    assert!(same, "{what}:\n got {got:#?}\nwant {want:#?}");
}

#[test]
fn python_can_reads_every_format_buslab_writes() {
    let Some(python) = python_can() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let input = reference(dir.path());
    let abs = |t: &str| format!("1700000000.{t}");
    // What python-can reads back, per format: the channel as python-can names it (ASC and BLF
    // count from 0, TRC from 1, CSV and SQLite have none), the direction where the format
    // keeps it (buslab's candump log writes none, as candump -l), ASC times from the start.
    let frames = [
        ("000000", "123#1122", 0, 'R'),
        ("001500", "12345678#DEADBEEF", 1, 'T'),
        ("002000", "7FF#R3", 0, 'R'),
        ("003250", "000#", 0, 'R'),
        ("004000", "ERR", 0, 'R'),
        ("005000", "1FFFFFFF#0102030405060708", 1, 'R'),
    ];
    let expect = |ext: &str| -> String {
        frames
            .iter()
            .filter(|f| !(ext == "trc" && f.1 == "ERR"))
            .map(|(t, frame, ch, dir)| {
                let time = if ext == "asc" {
                    format!("0.{t}")
                } else {
                    abs(t)
                };
                let channel = match ext {
                    "log" if *frame == "ERR" => "None".to_string(),
                    "log" => format!("can{ch}"),
                    "asc" | "blf" => ch.to_string(),
                    "trc" => (ch + 1).to_string(),
                    _ => "None".to_string(),
                };
                let dir = match ext {
                    "asc" | "blf" | "trc" => *dir,
                    _ => 'R',
                };
                format!("{time} {channel} {frame} {dir}\n")
            })
            .collect()
    };
    for ext in ["log", "asc", "blf", "trc", "csv", "db"] {
        let file = dir.path().join(format!("buslab.{ext}"));
        run(buslab().args(["log", "convert"]).arg(&input).arg(&file));
        let got = run(Command::new(&python)
            .arg(root().join("tests/interop/can_logs.py"))
            .arg("read")
            .arg(&file));
        assert_same(ext, &got, &expect(ext));
    }
}

#[test]
fn buslab_reads_every_format_python_can_writes() {
    let Some(python) = python_can() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    // What `buslab log cat -x` shows of python-can's files. python-can's candump writer drops
    // the RTR DLC and writes any error frame with the bus-error class (its data bytes kept,
    // and read back byte for byte); its TRC writer leaves remote
    // and error frames out; CSV and SQLite keep no channel and no direction; ASC keeps only
    // "ErrorFrame" (read back as a bus error, as asc2log does).
    let expect = |ext: &str| -> String {
        let mut lines = vec![
            "(1700000000.000000) can0 123#1122 R",
            "(1700000000.001500) can1 12345678#DEADBEEF T",
            "(1700000000.002000) can0 7FF#R3 R",
            "(1700000000.003250) can0 000# R",
            "(1700000000.004000) can0 20000088#0000020A00000000 R",
            "(1700000000.005000) can1 1FFFFFFF#0102030405060708 R",
        ]
        .into_iter()
        .map(String::from)
        .collect::<Vec<_>>();
        match ext {
            "log" => {
                lines[2] = "(1700000000.002000) can0 7FF#R R".into();
                lines[4] = "(1700000000.004000) can0 20000080#0000020A00000000".into();
            }
            "asc" => lines[4] = "(1700000000.004000) can0 20000080#0000000000000000 R".into(),
            "trc" => {
                lines.remove(4);
                lines.remove(2);
            }
            "csv" | "db" => {
                for l in &mut lines {
                    let cut = l.trim_end_matches(" R").trim_end_matches(" T");
                    *l = cut.replace("can1", "can0");
                }
            }
            _ => {}
        }
        lines.join("\n") + "\n"
    };
    for ext in ["log", "asc", "blf", "trc", "csv", "db"] {
        let file = dir.path().join(format!("python.{ext}"));
        let mut child = Command::new(&python)
            .arg(root().join("tests/interop/can_logs.py"))
            .arg("write")
            .arg(&file)
            .stdin(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        use std::io::Write;
        child
            .stdin
            .take()
            .unwrap()
            .write_all(REFERENCE.as_bytes())
            .unwrap();
        assert!(child.wait().unwrap().success(), "python-can writing {ext}");
        let got = run(buslab().args(["log", "cat", "-x"]).arg(&file));
        assert_same(ext, &got, &expect(ext));
    }
}

#[test]
fn log2asc_and_asc2log_agree_with_buslab() {
    if !tool("log2asc") || !tool("asc2log") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let input = reference(dir.path());
    // log2asc's ASC, read by buslab: every frame, the date line giving the absolute time
    // (log2asc writes the first frame's local time; buslab reads it in the same zone).
    let theirs = dir.path().join("log2asc.asc");
    run(Command::new("log2asc")
        .arg("-I")
        .arg(&input)
        .arg("-O")
        .arg(&theirs)
        .args(["can0", "can1"]));
    let got = run(buslab().args(["log", "cat", "-x"]).arg(&theirs));
    let bus_error = REFERENCE.replace("20000088#0000020A00000000", "20000080#0000000000000000 R");
    assert_same("log2asc → buslab", &got, &bus_error);
    // buslab's ASC, read by asc2log: the same frames, channels and directions. asc2log cannot
    // read any date without a de_DE locale (it takes the current time), so times count from
    // the first frame.
    let ours = dir.path().join("buslab.asc");
    run(buslab().args(["log", "convert"]).arg(&input).arg(&ours));
    let back = run(Command::new("asc2log")
        .arg("-I")
        .arg(&ours)
        .stderr(Stdio::null()));
    let rebase = |text: &str| -> String {
        let mut first = None;
        text.lines()
            .filter(|l| !l.trim().is_empty())
            .map(|l| {
                let (t, rest) = l.split_once(' ').unwrap();
                let t: f64 = t.trim_matches(|c| c == '(' || c == ')').parse().unwrap();
                let zero = *first.get_or_insert(t);
                format!("{:.6} {rest}\n", t - zero)
            })
            .collect()
    };
    // asc2log writes no direction after an error frame.
    let want = REFERENCE.replace("20000088#0000020A00000000", "20000080#0000000000000000");
    assert_same("buslab → asc2log", &rebase(&back), &rebase(&want));
}

#[test]
fn tshark_decodes_buslab_pcap_and_pcapng() {
    if !tool("tshark") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let input = reference(dir.path());
    // can.id, extended, remote, error flag, can.len, data, time (tshark 4.0 fields).
    let rows = "\
291\t0\t0\t0\t2\t1122\t1700000000.000000000
305419896\t1\t0\t0\t4\tdeadbeef\t1700000000.001500000
2047\t0\t1\t0\t3\t000000\t1700000000.002000000
0\t0\t0\t0\t0\t\t1700000000.003250000
\t\t\t1\t8\t\t1700000000.004000000
536870911\t1\t0\t0\t8\t0102030405060708\t1700000000.005000000
";
    for ext in ["pcap", "pcapng"] {
        let file = dir.path().join(format!("buslab.{ext}"));
        run(buslab().args(["log", "convert"]).arg(&input).arg(&file));
        let mut fields = vec![];
        if ext == "pcapng" {
            fields.push("frame.interface_name");
        }
        fields.extend([
            "can.id",
            "can.flags.xtd",
            "can.flags.rtr",
            "can.flags.err",
            "can.len",
            "data.data",
            "frame.time_epoch",
        ]);
        let mut cmd = Command::new("tshark");
        cmd.arg("-r").arg(&file).args(["-T", "fields"]);
        for f in &fields {
            cmd.args(["-e", f]);
        }
        let got = run(cmd.stderr(Stdio::null()));
        let want: String = if ext == "pcapng" {
            rows.lines()
                .zip(["can0", "can1", "can0", "can0", "can0", "can1"])
                .map(|(r, i)| format!("{i}\t{r}\n"))
                .collect()
        } else {
            rows.to_string()
        };
        assert_eq!(got, want, "{ext}");
        // The error frame in Wireshark's words, from the class bits buslab wrote.
        let verbose = run(Command::new("tshark")
            .arg("-r")
            .arg(&file)
            .args(["-V", "-Y", "can.flags.err == 1"])
            .stderr(Stdio::null()));
        assert!(
            verbose.contains("Protocol violation: True") && verbose.contains("Bus error: True"),
            "{ext}: {verbose}"
        );
    }
}

#[test]
fn editcap_conversions_read_back() {
    if !tool("editcap") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let input = reference(dir.path());
    let pcap = dir.path().join("buslab.pcap");
    let pcapng = dir.path().join("buslab.pcapng");
    run(buslab().args(["log", "convert"]).arg(&input).arg(&pcap));
    run(buslab().args(["log", "convert"]).arg(&input).arg(&pcapng));
    let plain = |keep_interfaces: bool| -> String {
        REFERENCE
            .lines()
            .map(|l| {
                let l = l.trim_end_matches(" R").trim_end_matches(" T");
                let l = if keep_interfaces {
                    l.to_string()
                } else {
                    l.replace("can1", "can0")
                };
                l + "\n"
            })
            .collect()
    };
    for (from, format, to, interfaces) in [
        (&pcapng, "pcap", "e.pcap", false),
        (&pcapng, "nsecpcap", "n.pcap", false),
        (&pcap, "pcapng", "e.pcapng", false),
        (&pcapng, "pcapng", "same.pcapng", true),
    ] {
        let out = dir.path().join(to);
        run(Command::new("editcap")
            .args(["-F", format])
            .arg(from)
            .arg(&out)
            .stderr(Stdio::null()));
        let got = run(buslab().args(["log", "cat"]).arg(&out));
        assert_same(
            &format!("editcap -F {format} {}", from.display()),
            &got,
            &plain(interfaces),
        );
    }
}

/// Error frames as logs hold them: counters without their class, bytes no class explains,
/// fewer than 8 bytes, unknown class bits.
const ERROR_FRAMES: &str = "\
(1700000000.000000) can0 20000088#0000020A00000102
(1700000000.001000) can0 20000080#0000040200000001
(1700000000.002000) can0 20000004#0004
(1700000000.003000) can0 20000040#
(1700000000.004000) can0 3FFFFFFF#0102030405060708
(1700000000.005000) can0 20000204#0020000000008005
";

/// Issue 25: reading a candump log rewrote error frames (`20000088#…` became `20000288#…`,
/// `20000080#0000040200000001` lost its protocol bytes). Converted through every format
/// that holds error frames, one after the other, and back to candump, each comes back byte
/// for byte; python-can reads the same class and bytes from the BLF, CSV and SQLite files.
#[test]
fn error_frames_survive_every_format_byte_for_byte() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("errors.log");
    std::fs::write(&input, ERROR_FRAMES).unwrap();
    let chain = ["asc", "blf", "pcap", "pcapng", "csv", "db", "log"];
    let mut from = input.clone();
    for ext in chain {
        let to = dir.path().join(format!("chain.{ext}"));
        run(buslab().args(["log", "convert"]).arg(&from).arg(&to));
        let got = run(buslab().args(["log", "cat"]).arg(&to));
        assert_eq!(got, ERROR_FRAMES, "{} → {ext}", from.display());
        from = to;
    }
    let Some(python) = python_can() else {
        return;
    };
    for ext in ["blf", "csv", "db"] {
        let file = dir.path().join(format!("chain.{ext}"));
        let out = run(Command::new(&python)
            .arg(root().join("tests/interop/can_log_fields.py"))
            .arg(&file));
        // TIME CHANNEL KIND EXT ID DLC DATA DIR: the class as the ID, the bytes as the data.
        let got: Vec<String> = out
            .lines()
            .skip(1)
            .map(|l| {
                let f: Vec<&str> = l.split(' ').collect();
                assert_eq!(f[2], "E", "{ext}: {l}");
                let data = if f[6] == "-" { "" } else { f[6] };
                format!(
                    "{:08X}#{data}",
                    0x2000_0000 | u32::from_str_radix(f[4], 16).unwrap()
                )
            })
            .collect();
        let want: Vec<&str> = ERROR_FRAMES
            .lines()
            .map(|l| l.split(' ').nth(2).unwrap())
            .collect();
        assert_eq!(got, want, "python-can reading buslab's {ext}");
    }
}

/// Issue 25: a Wireshark pcapng of exported PDUs (link type 252) read as 0 entries, exit 0.
/// Wireshark's text2pcap writes buslab's SocketCAN records as exported PDUs of its
/// `can-bigendian` dissector: buslab reads the same frames; PDUs of another dissector and a
/// capture of another link type are errors naming them.
#[test]
fn wireshark_exported_pdus_read_and_other_link_types_refused() {
    if !tool("tshark") || !tool("text2pcap") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("in.log");
    let frames = "(1700000000.000000) can0 123#1122\n(1700000000.001000) can0 12345678#DEADBEEF\n\
                  (1700000000.002000) can0 7FF#R3\n(1700000000.003000) can0 20000088#0000020A00000102\n";
    std::fs::write(&input, frames).unwrap();
    let pcap = dir.path().join("in.pcap");
    run(buslab().args(["log", "convert"]).arg(&input).arg(&pcap));
    // The packets as hex, the way text2pcap takes them.
    let hex = dir.path().join("hex.txt");
    let dump = run(Command::new("tshark")
        .arg("-r")
        .arg(&pcap)
        .arg("-x")
        .stderr(Stdio::null()));
    std::fs::write(&hex, dump).unwrap();
    let records = |text: &str| -> Vec<String> {
        text.lines()
            .map(|l| l.split(' ').nth(2).unwrap().to_string())
            .collect()
    };
    for (args, name) in [
        (&["-P", "can-bigendian"][..], "upper.pcapng"),
        (&["-F", "pcap", "-P", "can-bigendian"][..], "upper.pcap"),
    ] {
        let out = dir.path().join(name);
        run(Command::new("text2pcap")
            .args(["-q"])
            .args(args)
            .arg(&hex)
            .arg(&out)
            .stderr(Stdio::null()));
        let got = run(buslab().args(["log", "cat"]).arg(&out));
        assert_eq!(records(&got), records(frames), "{name}");
    }
    let refused = |args: &[&str], name: &str, want: &str| {
        let out = dir.path().join(name);
        run(Command::new("text2pcap")
            .args(["-q"])
            .args(args)
            .arg(&hex)
            .arg(&out)
            .stderr(Stdio::null()));
        let o = buslab().args(["log", "cat"]).arg(&out).output().unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(
            !o.status.success() && o.stdout.is_empty() && err.contains(want),
            "{name}: {err}"
        );
    };
    refused(&["-P", "sip"], "sip.pcapng", "dissector sip");
    refused(
        &["-l", "1"],
        "ethernet.pcapng",
        "link type 1 (Ethernet) is not CAN",
    );
    refused(
        &["-F", "pcap", "-l", "1"],
        "ethernet.pcap",
        "link type 1 (Ethernet) is not CAN",
    );
}
