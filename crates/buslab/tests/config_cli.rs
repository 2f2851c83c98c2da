//! `buslab.toml` from the command line: bad files refused with their line, special files
//! refused without reading, `config show`, the file's bus as the default, and the wizard on a
//! pseudo-terminal.

#[path = "support/pty_program.rs"]
mod pty_program;

use std::fs;
use std::path::Path;
use std::process::{Command, Output, Stdio};

use assert_cmd::cargo::CommandCargoExt;
use pty_program::{PtyProgram, Stderr};

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
        "buslab.toml:3: controller.bitrate = true: must be a bit rate in bit/s",
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
    answer(&mut w, "Acceptance code", &format!("0x1E0{ENTER}"));
    answer(
        &mut w,
        "must be at most 0xFF here",
        &format!("{ERASE}0xE0{ENTER}"),
    );
    answer(&mut w, "Acceptance mask", &format!("0x0F{ENTER}"));
    answer(&mut w, "Crystal frequency", ENTER);
    answer(&mut w, "Bus timing from", ENTER);
    answer(&mut w, "Bit rate in bit/s", &format!("125000{ENTER}"));
    answer(&mut w, "Sample point", ENTER);
    answer(
        &mut w,
        "Output control register",
        &format!("{ERASE}0xD9{ENTER}"),
    );
    answer(
        &mut w,
        "whose OCMODE (bits 1..0) is not 01",
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
