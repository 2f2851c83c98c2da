//! `buslab.toml` from the command line: bad files refused with their line, special files
//! refused without reading, `config show`, the file's bus as the default, and the wizard on a
//! pseudo-terminal.

mod bus_common;

#[path = "../../slcan/tests/support/fake_adapter.rs"]
#[allow(dead_code)]
mod fake_adapter;

#[path = "support/pty_program.rs"]
mod pty_program;

use std::fs;
use std::path::Path;
use std::process::{Command, Output, Stdio};

use assert_cmd::cargo::CommandCargoExt;
use bus_common::{Serve, frame};
use buslab_canbus::CanBus;
use fake_adapter::{FakeAdapter, Kind};
use pty_program::{PtyProgram, Stderr};

/// How long a test waits for something that normally comes within milliseconds: a deadline
/// for an event, not a measure of speed (CI machines are loaded).
const EVENT: std::time::Duration = std::time::Duration::from_secs(60);

/// `buslab ARGS` with no configuration from the environment or the user's folder, in `dir`.
fn buslab(dir: &Path, args: &[&str]) -> Command {
    let mut cmd = Command::cargo_bin("buslab").unwrap();
    cmd.current_dir(dir)
        .env_remove("BUSLAB_CONFIG")
        .env("XDG_CONFIG_HOME", dir.join("xdg"))
        .env("HOME", dir)
        .args(args);
    cmd
}

fn run(dir: &Path, args: &[&str]) -> Output {
    buslab(dir, args).stdin(Stdio::null()).output().unwrap()
}

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// Runs `buslab status` with `text` as ./buslab.toml; it must fail with `expected`.
fn refused(text: &[u8], expected: &str) {
    let dir = tempfile::tempdir().unwrap();
    fs::write(dir.path().join("buslab.toml"), text).unwrap();
    let out = run(dir.path(), &["status"]);
    assert!(!out.status.success(), "{text:?} accepted");
    let err = stderr(&out);
    assert!(
        err.contains(expected),
        "{:?}: {err}\nexpected: {expected}",
        String::from_utf8_lossy(text)
    );
    assert_eq!(err.lines().count(), 1, "one line: {err}");
}

#[test]
fn bad_files_are_refused_with_their_line_key_and_what_is_allowed() {
    refused(
        b"bus = \"vcan0\"\nmail_id = \"0x700\"\n",
        "buslab.toml:2: mail_id = \"0x700\": must be an 11-bit identifier 0x000..=0x7EF (CAN 2.0A forbids 0x7F0..=0x7FF), written without quotes",
    );
    refused(
        b"\n[controller]\nbitrate = true\n",
        "buslab.toml:3: controller.bitrate = true: must be a bit rate 1..=1000000 bit/s: 125000, 125k",
    );
    refused(
        b"[mail]\ninterval = 60\n",
        "buslab.toml:2: mail.interval = 60: must be a duration with its unit from 1s to 1day, e.g. \"60s\" or \"5min\": write the unit",
    );
    refused(
        b"# JerryCAN\nidloader = 3\n",
        "buslab.toml:2: unknown key idloader (did you mean loader_id, JerryCAN's idloader?)",
    );
    refused(
        b"[mail]\nhost = \"x\"\npassword = \"hunter2\"\n",
        "buslab.toml:3: the mail password is never read from a file",
    );
    refused(b"bus = \"vcan0\n", "buslab.toml:1:");
    refused(b"nom_du_parametre = parametre\n", "buslab.toml:1:");
    refused(b"\x89PNG\r\n\x1a\n\0\0\0\rIHDR", "is not UTF-8 text");
}

#[test]
fn a_fifo_or_a_device_is_refused_without_being_read() {
    let dir = tempfile::tempdir().unwrap();
    let fifo = dir.path().join("fifo.toml");
    nix::unistd::mkfifo(&fifo, nix::sys::stat::Mode::S_IRWXU).unwrap();
    // No writer ever opens the FIFO: reading it would wait forever.
    for (path, kind) in [
        (fifo.to_str().unwrap(), "is a FIFO"),
        ("/dev/zero", "is a device"),
    ] {
        let out = run(dir.path(), &["--config", path, "config", "show"]);
        assert!(!out.status.success());
        let err = stderr(&out);
        assert!(err.contains(path) && err.contains(kind), "{err}");
    }
    let out = buslab(dir.path(), &["status"])
        .env("BUSLAB_CONFIG", &fifo)
        .stdin(Stdio::null())
        .output()
        .unwrap();
    assert!(
        stderr(&out).contains("(from $BUSLAB_CONFIG)"),
        "{}",
        stderr(&out)
    );
}

#[test]
fn show_tells_where_each_value_came_from() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("xdg/buslab/buslab.toml");
    fs::create_dir_all(file.parent().unwrap()).unwrap();
    fs::write(&file, "bus = \"can0\"\n\n[controller]\nbitrate = 125000\n").unwrap();
    let out = buslab(dir.path(), &["--set", "mail.port=993", "config", "show"])
        .env("BUSLAB_MAIL_ID", "0x701")
        .env("BUSLAB_MAIL_PASSWORD", "hunter2")
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", stderr(&out));
    let text = String::from_utf8(out.stdout).unwrap();
    let line = |start: &str| {
        text.lines()
            .find(|l| l.starts_with(start))
            .unwrap_or_else(|| panic!("no {start:?} in\n{text}"))
            .to_string()
    };
    let path = file.display().to_string();
    assert!(line("# configuration file:").contains("in the user's configuration directory"));
    assert!(
        line("bus = \"can0\"").ends_with(&format!("# {path}:1")),
        "{text}"
    );
    assert!(
        line("bitrate = 125000").ends_with(&format!("# {path}:4")),
        "{text}"
    );
    assert!(
        line("mail_id = 0x701").ends_with("# environment BUSLAB_MAIL_ID"),
        "{text}"
    );
    assert!(line("port = 993").ends_with("# --set"), "{text}");
    assert!(line("loader_id = 0x000").ends_with("# default"), "{text}");
    assert!(line("# bit timing:").contains("125000 bit/s"), "{text}");
    assert!(
        !text.contains("hunter2") && text.contains("from $BUSLAB_MAIL_PASSWORD"),
        "{text}"
    );
    // ./buslab.toml comes before the user's file.
    fs::write(dir.path().join("buslab.toml"), "bus = \"can1\"\n").unwrap();
    let text = String::from_utf8(run(dir.path(), &["config", "show"]).stdout).unwrap();
    assert!(text.contains("bus = \"can1\""), "{text}");
}

#[test]
fn commands_take_the_bus_from_the_file_when_none_is_given() {
    let dir = tempfile::tempdir().unwrap();
    // Port 1 on the loopback: nothing listens, so the error names the bus that was tried.
    fs::write(
        dir.path().join("buslab.toml"),
        "bus = \"socketcand://127.0.0.1:1/can7\"\n",
    )
    .unwrap();
    for args in [&["send", "123#11"][..], &["status"], &["dump", "-n", "1"]] {
        let out = run(dir.path(), args);
        assert!(!out.status.success(), "{args:?}");
        assert!(
            stderr(&out).contains("127.0.0.1:1"),
            "{args:?}: {}",
            stderr(&out)
        );
    }
    let help = String::from_utf8(run(dir.path(), &["status", "--help"]).stdout).unwrap();
    assert!(
        help.contains("[default: socketcand://127.0.0.1:1/can7]"),
        "{help}"
    );
    // An option still wins.
    let out = run(dir.path(), &["status", "--bus", "socketcand://127.0.0.1:2"]);
    assert!(stderr(&out).contains("127.0.0.1:2"), "{}", stderr(&out));
    // -w writes the file's log_file; without one it says so.
    let out = run(dir.path(), &["dump", "-w", "-n", "1"]);
    assert!(stderr(&out).contains("log_file"), "{}", stderr(&out));
}

/// `buslab config wizard` on a pseudo-terminal.
fn wizard(dir: &Path, out: &Path) -> PtyProgram {
    let mut command = buslab(dir, &["config", "wizard", "--out", out.to_str().unwrap()]);
    command.env("TERM", "xterm");
    PtyProgram::spawn(command, 100, 120, Stderr::Terminal)
}

/// Waits until the screen shows `text` (a question, an error), then types `keys`.
fn answer(w: &mut PtyProgram, text: &str, keys: &str) {
    w.wait_for_text(text);
    w.type_keys(keys);
}

const ENTER: &str = "\r";
const ERASE: &str = "\x7f\x7f\x7f\x7f\x7f\x7f\x7f\x7f";

#[test]
fn the_wizard_asks_checks_each_answer_and_writes_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("etc").join("buslab.toml");
    let mut w = wizard(dir.path(), &out);
    answer(&mut w, "Controller mode", &format!("Basic{ENTER}"));
    answer(&mut w, "Acceptance filter", &format!("basic{ENTER}"));
    answer(&mut w, "Acceptance filter from", &format!("ACR{ENTER}"));
    answer(&mut w, "Acceptance code", &format!("0x1E0{ENTER}"));
    // The refused answer stays on the line, to be corrected.
    answer(
        &mut w,
        "# must be at most 0xFF here",
        &format!("{ERASE}0xE0{ENTER}"),
    );
    answer(&mut w, "Acceptance mask", &format!("0x0F{ENTER}"));
    w.wait_for_text("standard 0x700..=0x77F (128 IDs), data and remote frames");
    answer(&mut w, "Keep this filter?", ENTER);
    answer(&mut w, "Bus timing", &format!("bit rate{ENTER}"));
    answer(&mut w, "Crystal frequency", ENTER);
    answer(&mut w, "Bit rate (", &format!("125000{ENTER}"));
    answer(&mut w, "Sample point", ENTER);
    answer(
        &mut w,
        "Output control register",
        &format!("{ERASE}0xD9{ENTER}"),
    );
    answer(
        &mut w,
        // The refusal ("#"), not the help below the question, which says the same.
        "# must be an OCR value",
        &format!("{ERASE}0x1A{ENTER}"),
    );
    answer(&mut w, "Clock output", &format!("n{ENTER}"));
    answer(&mut w, "Bus CAN commands use", &format!("can0{ENTER}"));
    answer(&mut w, "Identifier of the loader", ENTER);
    answer(
        &mut w,
        "Identifier of the mail notifier",
        &format!("0x701{ENTER}"),
    );
    answer(&mut w, "IMAP server", &format!("imap.example.org{ENTER}"));
    answer(&mut w, "Its port", ENTER);
    answer(&mut w, "Mailbox user", &format!("jerry{ENTER}"));
    answer(&mut w, "How often the mailbox", &format!("30s{ENTER}"));
    answer(&mut w, "Manager's pause", ENTER);
    answer(
        &mut w,
        "Log file of received frames",
        &format!("frames.log{ENTER}"),
    );
    answer(&mut w, "Write ", ENTER);
    let status = w.wait_exit();
    let transcript = w.contents();
    assert!(status.success(), "{status}\n{transcript}");
    assert!(
        transcript.contains("125000 bit/s: BTR0=0x03 BTR1=0x1C"),
        "{transcript}"
    );
    assert!(transcript.contains("Wrote "), "{transcript}");
    let text = fs::read_to_string(&out).unwrap();
    for line in [
        "mode = \"BasicCAN\"",
        "filter = \"basic\"",
        "acceptance_code = 0xE0",
        "acceptance_mask = 0x0F",
        "bitrate = 125000",
        "output_control = 0x1A",
        "clock_out = false",
        "bus = \"can0\"",
        "mail_id = 0x701",
        "host = \"imap.example.org\"",
        "interval = \"30s\"",
        "log_file = \"frames.log\"",
    ] {
        assert!(text.lines().any(|l| l == line), "{line:?} not in\n{text}");
    }
    // The file reads back as the configuration in use.
    let show = run(
        dir.path(),
        &["--config", out.to_str().unwrap(), "config", "show"],
    );
    assert!(show.status.success(), "{}", stderr(&show));
    let shown = String::from_utf8(show.stdout).unwrap();
    assert!(
        shown.contains("registers: CDR=0x08 OCR=0x1A ACR=E0 AMR=0F"),
        "{shown}"
    );
}

#[test]
fn the_wizard_needs_a_terminal() {
    let dir = tempfile::tempdir().unwrap();
    let out = run(dir.path(), &["config", "wizard", "--out", "x.toml"]);
    assert!(!out.status.success());
    assert!(stderr(&out).contains("on a terminal"), "{}", stderr(&out));
    assert!(!dir.path().join("x.toml").exists());
}

#[test]
fn a_subcommand_s_own_config_option_is_not_the_file() {
    let dir = tempfile::tempdir().unwrap();
    // `cpu196 start --config N` is a configuration set: it reaches the command (which then
    // cannot open the port), neither read as a file nor a clash of options.
    let out = run(
        dir.path(),
        &[
            "cpu196",
            "--port",
            "/nonexistent/pty",
            "start",
            "--config",
            "3",
        ],
    );
    assert_eq!(out.status.code(), Some(1), "{}", stderr(&out));
    assert!(
        stderr(&out).contains("/nonexistent/pty"),
        "{}",
        stderr(&out)
    );
}

#[test]
fn escape_in_the_wizard_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("buslab.toml");
    let mut w = wizard(dir.path(), &out);
    answer(&mut w, "Controller mode", ENTER);
    answer(&mut w, "Acceptance filter", "\x1b");
    let status = w.wait_exit();
    assert_eq!(status.code(), Some(1), "{}", w.contents());
    assert!(
        w.contents().contains("cancelled; nothing written"),
        "{}",
        w.contents()
    );
    assert!(!out.exists());
}

/// `buslab ARGS` in the background, its standard error read line by line; returned once a
/// line contains `ready` (dump -v says it listens).
struct Background {
    child: std::process::Child,
    stderr: std::thread::JoinHandle<String>,
}

impl Background {
    fn start(mut cmd: Command, ready: &'static str) -> Self {
        use std::io::{BufRead, BufReader};
        let mut child = cmd
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let (tx, rx) = std::sync::mpsc::channel();
        let lines = BufReader::new(child.stderr.take().unwrap()).lines();
        let stderr = std::thread::spawn(move || {
            let mut all = String::new();
            for line in lines.map_while(Result::ok) {
                if line.contains(ready) {
                    let _ = tx.send(());
                }
                all.push_str(&line);
                all.push('\n');
            }
            all
        });
        if rx.recv_timeout(EVENT).is_err() {
            let _ = child.kill();
            let _ = child.wait();
            panic!("{ready:?} never came: {}", stderr.join().unwrap());
        }
        Self { child, stderr }
    }

    /// Waits for the end; standard output and error.
    fn finish(self) -> (String, String) {
        let out = self.child.wait_with_output().unwrap();
        let err = self.stderr.join().unwrap();
        assert!(out.status.success(), "{err}");
        (String::from_utf8_lossy(&out.stdout).into_owned(), err)
    }
}

/// The IDs of candump lines (`  vcan0  123   [1]  11`).
fn ids(dump: &str) -> Vec<String> {
    dump.lines()
        .filter_map(|l| l.split_whitespace().nth(1).map(str::to_string))
        .collect()
}

/// Issue 26, point 6 (its acceptance): the assistant configured the controller JerryCAN then
/// used (seed 002 §5.4.2). Here the wizard, typed on a terminal, chooses a filter by the IDs
/// wanted and a bit rate written as people write it (with Ctrl-U erasing a first try); then
/// `buslab dump` on a bus served at that rate shows only the IDs the filter lets through: its
/// own SJA1000 on the bus filters them, as the real card did.
#[test]
fn the_wizard_s_filter_and_bit_rate_reach_the_client_s_sja1000_and_dump_shows_only_those_ids() {
    let serve = Serve::start(125_000);
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("buslab.toml");
    let mut w = wizard(dir.path(), &out);
    answer(&mut w, "Controller mode", ENTER);
    answer(&mut w, "Acceptance filter", &format!("single{ENTER}"));
    answer(&mut w, "Acceptance filter from", ENTER);
    // The question itself (its words are also in the answer to the one before).
    answer(&mut w, "? IDs to let through", &format!("100-1FF{ENTER}"));
    w.wait_for_text("exactly the 256 IDs asked for");
    w.wait_for_text("standard 0x100..=0x1FF (256 IDs), data and remote frames");
    answer(&mut w, "Keep this filter?", ENTER);
    answer(&mut w, "Bus timing", &format!("bit rate{ENTER}"));
    answer(&mut w, "Crystal frequency", ENTER);
    // A first try erased with Ctrl-U (inquire's prompt typed a `u` there), then 125k.
    answer(&mut w, "Bit rate (", &format!("500 kbit/s\x15125k{ENTER}"));
    answer(&mut w, "Sample point", ENTER);
    w.wait_for_text("125000 bit/s: BTR0=0x03 BTR1=0x1C");
    answer(&mut w, "Output control register", ENTER);
    answer(&mut w, "Clock output", ENTER);
    answer(&mut w, "CLKOUT divider", ENTER);
    answer(
        &mut w,
        "Bus CAN commands use",
        &format!("{}{ENTER}", serve.url),
    );
    for question in [
        "Identifier of the loader",
        "Identifier of the mail notifier",
        "IMAP server",
        "Its port",
        "Mailbox user",
        "How often the mailbox",
        "Manager's pause",
        "Log file of received frames",
        "Write ",
    ] {
        answer(&mut w, question, ENTER);
    }
    let status = w.wait_exit();
    let screen = w.contents();
    assert!(status.success(), "{status}\n{screen}");
    // Each question, redrawn at every key (the bus's help wraps over two rows), ends as one
    // line with its answer: none is left behind half typed.
    assert!(!screen.lines().any(|l| l.starts_with("? ")), "{screen}");
    assert!(
        screen.contains("> Bit rate (e.g. 125000, 125k, 500 kbit/s, 1M) 125k\n"),
        "{screen}"
    );
    let text = fs::read_to_string(&out).unwrap();
    for line in [
        "bitrate = 125000",
        "filter = \"single\"",
        "acceptance_code = 0x20000000",
        "acceptance_mask = 0x1FFFFFFF",
        &format!("bus = \"{}\"", serve.url),
    ] {
        assert!(text.lines().any(|l| l == line), "{line:?} not in\n{text}");
    }
    // `dump` with that file: its node joins with the filter and the bit rate.
    let mut cmd = buslab(dir.path(), &["-v", "dump", "-n", "3"]);
    cmd.stdin(Stdio::null());
    let dump = Background::start(cmd, "dump: listening");
    let mut sender = serve.client();
    for f in [
        "000#01",
        "0FF#02",
        "100#03",
        "200#04",
        "123#05",
        "7FF#06",
        "12345678#07",
        "1FF#08",
    ] {
        sender.send(&frame(f)).unwrap();
    }
    let report = sender.flush(EVENT).unwrap();
    assert_eq!(report.failed, 0);
    let (shown, err) = dump.finish();
    assert_eq!(ids(&shown), ["100", "123", "1FF"], "{shown}\n{err}");
    assert!(
        err.contains("the acceptance filter (controller.filter/acceptance_code/acceptance_mask): applied: this client's own SJA1000 on the virtual bus"),
        "{err}"
    );
    assert!(!err.contains("not applied"), "{err}");
}

/// The controller's settings reach the client's own SJA1000 through bus serve's extension
/// (`< buslab_controller … >`), and read back from its registers with `buslab regs`.
#[test]
fn the_controller_settings_are_in_the_client_s_registers() {
    let serve = Serve::start(125_000);
    let dir = tempfile::tempdir().unwrap();
    let regs = |sets: &[&str]| {
        let mut args = Vec::new();
        for set in sets {
            args.extend(["--set", set]);
        }
        args.extend(["regs", "--bus", &serve.url]);
        let out = run(dir.path(), &args);
        assert!(out.status.success(), "{}", stderr(&out));
        String::from_utf8(out.stdout).unwrap()
    };
    let register = |dump: &str, name: &str| {
        dump.lines()
            .find(|l| l.split_whitespace().nth(1) == Some(name))
            .and_then(|l| l.split_whitespace().nth(2).map(str::to_string))
            .unwrap_or_else(|| panic!("no {name} in\n{dump}"))
    };
    // Nothing configured: the node as the bus gives it (PeliCAN, single filter, 125 kbit/s).
    let plain = regs(&[]);
    assert!(plain.contains("PeliCAN registers"), "{plain}");
    assert_eq!(register(&plain, "MOD"), "08");
    assert_eq!(register(&plain, "OCR"), "DA");
    let set = regs(&[
        "controller.mode=listen-only",
        "controller.filter=dual",
        "controller.acceptance_code=0x20054000",
        "controller.acceptance_mask=0x0000001F",
        "controller.bitrate=125 kbit/s",
        "controller.sample_point=75",
        "controller.output_control=0x1A",
        "controller.clock_out=false",
    ]);
    // MOD: listen-only (LOM), dual filter (AFM clear); BTR for 125 kbit/s at 75 %; OCR; CDR
    // with the PeliCAN bit and CLKOUT off.
    assert_eq!(register(&set, "MOD"), "02", "{set}");
    assert_eq!(register(&set, "BTR0"), "43", "{set}");
    assert_eq!(register(&set, "BTR1"), "3A", "{set}");
    assert_eq!(register(&set, "OCR"), "1A", "{set}");
    assert_eq!(register(&set, "CDR"), "88", "{set}");
    let basic = regs(&["controller.mode=BasicCAN", "controller.clock_divider=4"]);
    assert!(basic.contains("BasicCAN registers"), "{basic}");
    assert_eq!(register(&basic, "CDR"), "01", "{basic}");
    // A bit rate that is not the bus's is applied, and said: the node cannot communicate.
    let out = run(
        dir.path(),
        &[
            "--set",
            "controller.bitrate=500k",
            "regs",
            "--bus",
            &serve.url,
        ],
    );
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(
        stderr(&out).contains("this node's bit rate from the configuration (500000 bit/s, BTR0=0x00 BTR1=0x1C) is not the bus's (125000 bit/s): it cannot communicate"),
        "{}",
        stderr(&out)
    );
    // A combination the chip refuses stops the command with the reason.
    let out = run(
        dir.path(),
        &[
            "--set",
            "controller.bitrate=500k",
            "--set",
            "controller.crystal_hz=1000000",
            "regs",
            "--bus",
            &serve.url,
        ],
    );
    assert!(!out.status.success());
    assert!(
        stderr(&out).contains("controller.bitrate"),
        "{}",
        stderr(&out)
    );
}

/// On an SLCAN adapter the controller's settings go where the adapter has a command: the bit
/// rate (`S4`), listen-only (`L`), the acceptance mask and code (`m`, `M`) on an adapter
/// that answers as Lawicel's; each frame is checked as the configured filter would, and what
/// the adapter has no command for is said once.
#[test]
fn the_controller_settings_reach_an_slcan_adapter_where_it_has_them() {
    let dir = tempfile::tempdir().unwrap();
    let sets = [
        "controller.bitrate=125k",
        "controller.mode=listen-only",
        "controller.filter=single",
        "controller.acceptance_code=0x24600000",
        "controller.acceptance_mask=0x001FFFFF",
        "controller.output_control=0x1A",
    ];
    let fake = FakeAdapter::start(Kind::Model);
    let mut args: Vec<&str> = Vec::new();
    for set in &sets {
        args.extend(["--set", set]);
    }
    let url = format!("slcan:{}", fake.path());
    args.extend(["-v", "dump", "--bus", &url, "-n", "2"]);
    let mut cmd = buslab(dir.path(), &args);
    cmd.stdin(Stdio::null());
    let dump = Background::start(cmd, "dump: listening");
    let lines = fake.seen(|s| s.lines.clone());
    for expected in ["S4", "m001FFFFF", "M24600000", "L"] {
        assert!(
            lines.iter().any(|l| l == expected),
            "{expected} not in {lines:?}"
        );
    }
    // 0x123 only (data and remote frames; any data): the others are not shown.
    for line in ["t1001AA", "t1231BB", "t1241CC", "T001234561DD", "r1230"] {
        fake.deliver(line);
    }
    let (shown, err) = dump.finish();
    assert_eq!(ids(&shown), ["123", "123"], "{shown}\n{err}");
    assert_eq!(
        err.matches("the output control (controller.output_control) from the configuration not applied: an SLCAN adapter has no command for it").count(),
        1,
        "{err}"
    );
    assert!(
        err.contains("acceptance code and mask sent to the adapter (M/m)"),
        "{err}"
    );

    // CANable's firmware: its M is the silent mode, so no M/m; the filter is checked here.
    let canable = FakeAdapter::start(Kind::Canable);
    let url = format!("slcan:{}", canable.path());
    let mut args: Vec<&str> = Vec::new();
    for set in &sets[2..5] {
        args.extend(["--set", set]);
    }
    args.extend(["-v", "dump", "--bus", &url, "-n", "1"]);
    let mut cmd = buslab(dir.path(), &args);
    cmd.stdin(Stdio::null());
    let dump = Background::start(cmd, "dump: listening");
    let lines = canable.seen(|s| s.lines.clone());
    assert!(
        !lines
            .iter()
            .any(|l| l.len() == 9 && (l.starts_with('M') || l.starts_with('m'))),
        "{lines:?}"
    );
    for line in ["t1001AA", "t1231BB"] {
        canable.deliver(line);
    }
    let (shown, err) = dump.finish();
    assert_eq!(ids(&shown), ["123"], "{shown}\n{err}");
    assert!(
        err.contains("this adapter has no acceptance filter command"),
        "{err}"
    );
}
