//! The rough edges a new user met in the first hour (issue 26, points 9 and 10): each test is
//! named after what the user saw.

mod bus_common;
#[path = "support/outside_tools.rs"]
mod outside_tools;
#[path = "support/pty_program.rs"]
mod pty_program;

use std::io::{BufRead, BufReader, Read};
use std::process::{Child, Command, Output, Stdio};

use buslab_canbus::CanBus;

use bus_common::Serve;
use outside_tools::{python_can, root};
use pty_program::{CEILING, PtyProgram};

/// `buslab` with no configuration file and no bus from the environment: the defaults.
fn buslab() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_buslab"));
    c.env_remove("BUSLAB_BUS")
        .env_remove("BUSLAB_CONFIG")
        .arg("--no-config");
    c
}

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

fn stdout(out: &Output) -> String {
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// Reads `child`'s stderr line by line until a line contains `last` (the end of a banner), then
/// stops the child and returns every line it wrote to stderr, to its end.
fn banner_then_stop(mut child: Child, last: &str) -> Vec<String> {
    let mut err = BufReader::new(child.stderr.take().unwrap());
    let mut lines = Vec::new();
    loop {
        let mut line = String::new();
        if err.read_line(&mut line).unwrap() == 0 {
            panic!("stderr ended before {last:?}:\n{}", lines.join("\n"));
        }
        let done = line.contains(last);
        lines.push(line.trim_end().to_string());
        if done {
            break;
        }
    }
    child.kill().unwrap();
    let mut rest = String::new();
    err.read_to_string(&mut rest).unwrap();
    child.wait().unwrap();
    lines.extend(rest.lines().map(str::to_string));
    lines
}

#[test]
fn dump_with_a_filter_and_no_bus_suggests_the_bus_first() {
    // `dump --bus URL 123:7FF` said `unknown backend "123"`.
    let out = buslab()
        .args(["dump", "--bus", "socketcand://127.0.0.1:1/vcan0", "123:7FF"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = stderr(&out);
    assert!(err.contains("\"123:7FF\" is a filter, not a bus"), "{err}");
    assert!(err.contains("vcan0,123:7FF"), "{err}");
    assert!(err.contains("URL,123:7FF"), "{err}");
    assert!(!err.contains("unknown backend"), "{err}");
}

#[test]
fn an_interface_that_does_not_exist_is_reported_once_with_what_to_do() {
    // `No such device (os error 19)` was printed twice. Whether this machine has SocketCAN or
    // not, the reason comes once and the hint after it.
    let out = buslab()
        .args(["dump", "buslabnosuch0"])
        .stdin(Stdio::null())
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = stderr(&out);
    assert_eq!(err.matches("(os error").count(), 1, "{err}");
    assert!(
        err.contains("ip link add dev buslabnosuch0 type vcan")
            || err.contains("this kernel has no SocketCAN"),
        "{err}"
    );
    assert_eq!(err.lines().count(), 1, "{err}");
}

#[test]
fn web_token_prints_the_dashboard_address_with_its_token() {
    // `web --token` printed the dashboard's address without `#token=`, so the dashboard
    // opened from it could not write.
    let serve = Serve::start(500_000);
    for quiet in [false, true] {
        let mut command = buslab();
        if quiet {
            command.arg("-q");
        }
        let child = command
            .args([
                "web",
                "--bus",
                &serve.url,
                "--listen",
                "127.0.0.1:0",
                "--token",
            ])
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let lines = banner_then_stop(child, "writes allowed with the header");
        let header_token = lines
            .iter()
            .find(|l| l.contains("writes allowed"))
            .and_then(|l| l.rsplit(' ').next())
            .unwrap()
            .to_string();
        assert_eq!(header_token.len(), 32, "{lines:?}");
        let dashboard = lines
            .iter()
            .find(|l| l.contains("live dashboard:"))
            .unwrap_or_else(|| panic!("{lines:?}"));
        assert!(
            dashboard.ends_with(&format!("/dashboard#token={header_token}")),
            "{dashboard}"
        );
        // `-q` leaves out `Ctrl-C to stop`, as the lab does; the addresses stay.
        assert_eq!(
            lines.iter().any(|l| l == "Ctrl-C to stop"),
            !quiet,
            "quiet {quiet}: {lines:?}"
        );
    }
}

#[test]
fn cpu196_serve_with_q_does_not_say_ctrl_c_to_stop() {
    for quiet in [false, true] {
        let mut command = buslab();
        if quiet {
            command.arg("-q");
        }
        let child = command
            .args(["cpu196", "serve"])
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let lines = banner_then_stop(child, "CPU196 board model serving at");
        let banner = lines.iter().find(|l| l.contains("serving at")).unwrap();
        assert_eq!(banner.contains("Ctrl-C to stop"), !quiet, "{lines:?}");
    }
}

#[test]
fn identifier_defaults_are_shown_in_hex() {
    // `mail --id [default: 1792]` where everything else says 0x700.
    let help = |args: &[&str]| stdout(&buslab().args(args).output().unwrap());
    assert!(help(&["mail", "--help"]).contains("[default: 0x700]"));
    assert!(help(&["load", "--help"]).contains("[default: 0x000]"));
    // From the configuration, in hex too.
    let mut c = Command::new(env!("CARGO_BIN_EXE_buslab"));
    let out = c
        .env_remove("BUSLAB_CONFIG")
        .args(["--no-config", "--set", "mail_id=291", "mail", "--help"])
        .output()
        .unwrap();
    assert!(
        stdout(&out).contains("[default: 0x123]"),
        "{}",
        stdout(&out)
    );
}

#[test]
fn quiet_help_says_what_q_does_for_that_command() {
    // Every subcommand's `-q` help mentioned `sim` and `lab`.
    let quiet_line = |args: &[&str]| {
        let out = buslab().args(args).output().unwrap();
        stdout(&out)
            .lines()
            .find(|l| l.contains("--quiet"))
            .unwrap_or_else(|| panic!("{args:?}: no -q in\n{}", stdout(&out)))
            .to_string()
    };
    for args in [
        &["dump", "--help"][..],
        &["bus", "serve", "--help"],
        &["status", "--help"],
    ] {
        let line = quiet_line(args);
        assert!(
            line.ends_with("Fewer log lines: errors only (RUST_LOG overrides)"),
            "{line}"
        );
    }
    assert!(quiet_line(&["sim", "--help"]).contains("only the summary"));
    assert!(quiet_line(&["lab", "--help"]).contains("no status line"));
}

#[test]
fn monitor_shows_the_frames_it_sends() {
    // `buslab monitor` did not show the frames it sent with `s`: no backend hands a client
    // its own frames.
    let serve = Serve::start(500_000);
    // Another node on the bus, which acknowledges the monitor's frame and receives it.
    let mut other = serve.client();
    let mut command = buslab();
    command.args(["-q", "monitor", "--bus", &serve.url]);
    let mut monitor = PtyProgram::spawn(command, 30, 110, pty_program::Stderr::Null);
    monitor.wait_for_contents("the monitor's screen", |t| t.contains("q quit"));
    monitor.type_keys("s123#1122\r");
    monitor.wait_for_contents("the sent frame in the table and the log", |t| {
        t.contains("123#1122  TX") && t.lines().any(|l| l.contains("123") && l.contains("11 22"))
    });
    let got = other
        .recv(Some(CEILING))
        .unwrap()
        .expect("the monitor's frame");
    assert_eq!(got.record.to_string(), "123#1122");
    // A frame another node sends is not marked.
    other.send(&"456#33".parse().unwrap()).unwrap();
    monitor.wait_for_contents("the other node's frame", |t| t.contains("456#33"));
    let log_line = monitor
        .contents()
        .lines()
        .find(|l| l.contains("456#33"))
        .unwrap()
        .to_string();
    assert!(!log_line.contains("TX"), "{log_line}");
    monitor.type_keys("q");
    assert!(monitor.wait_exit().success());
}

/// The python-can example of docs/bus.md, as printed there.
fn python_example() -> String {
    let doc = std::fs::read_to_string(root().join("docs/bus.md")).unwrap();
    let section = doc
        .split("\n## python-can\n")
        .nth(1)
        .expect("a python-can section");
    let code = section
        .split("```python\n")
        .nth(1)
        .and_then(|rest| rest.split("```").next())
        .expect("a python block in docs/bus.md's python-can section");
    code.to_string()
}

#[test]
fn the_python_can_example_of_the_docs_runs_as_printed() {
    // On an empty bus the example printed `None`, then python-can's warning
    // `SocketCanDaemonBus was not properly shut down`.
    let Some(python) = python_can() else {
        return;
    };
    let example = python_example();
    assert!(example.contains("port=29536"), "{example}");
    let dir = tempfile::tempdir().unwrap();
    let scenario = dir.path().join("sender.toml");
    std::fs::write(
        &scenario,
        "bitrate = 125000\n[[nodes]]\nname = \"sender\"\n  [[nodes.traffic]]\n  kind = \"periodic\"\n  frame = \"456#AABB\"\n  period = \"100ms\"\n",
    )
    .unwrap();
    let run = |serve: &Serve| {
        let script = dir.path().join("example.py");
        let code = example.replace("port=29536", &format!("port={}", serve.addr.port()));
        std::fs::write(&script, code).unwrap();
        let out = Command::new(&python).arg(&script).output().unwrap();
        assert!(out.status.success(), "{}", stderr(&out));
        assert_eq!(stderr(&out), "", "python-can's warnings");
        stdout(&out)
    };
    // Alone on the bus: nobody else sends, and a client does not get its own frames.
    let alone = run(&Serve::start(125_000));
    assert_eq!(alone, "no frame from another node within 10 s\n");
    // Beside a node that sends.
    let beside = run(&Serve::start_with(
        125_000,
        &["--nodes", scenario.to_str().unwrap()],
    ));
    assert!(
        beside.contains("ID:      456") && beside.contains("aa bb") && beside.contains("Rx"),
        "{beside}"
    );
    // What the docs say it prints.
    let doc = std::fs::read_to_string(root().join("docs/bus.md")).unwrap();
    assert!(doc.contains("it prints `no frame from another node within 10 s`"));
    let printed = doc
        .lines()
        .find(|l| l.starts_with("Timestamp: "))
        .expect("the example's output in docs/bus.md");
    let shape = |line: &str| line.split_once("ID:").unwrap().1.trim().to_string();
    assert_eq!(shape(printed), shape(beside.trim()));
}

/// The load `log info` prints for one interface: the percentage and the rest of the line.
fn load_of(info: &str) -> (f64, String) {
    let line = info
        .lines()
        .find(|l| l.starts_with("can0 "))
        .unwrap_or_else(|| panic!("no can0 line:\n{info}"));
    let load = line.split_once(", load ").unwrap().1;
    let percent = load.split(' ').next().unwrap().parse().unwrap();
    (percent, load.to_string())
}

#[test]
fn log_info_takes_the_load_at_the_logs_bit_rate_or_says_its_assumption() {
    // `log info` on a 125 kbit/s log said `load 4.3 % at 500 kbit/s` where the lab said
    // 17.1 %: a candump log does not carry its bit rate, a TRC header does.
    let dir = tempfile::tempdir().unwrap();
    // An 8-byte frame every ms for 2 s: 112 bits each with stuffing and the intermission, so
    // 2001 × 112 bits in 2 s at 125 kbit/s: 89.6 %.
    let log: String = (0..=2000)
        .map(|ms| {
            format!(
                "({}.{:06}) can0 123#1122334455667788\n",
                100 + ms / 1000,
                (ms % 1000) * 1000
            )
        })
        .collect();
    let candump = dir.path().join("lab.log");
    std::fs::write(&candump, log).unwrap();
    let info = |args: &[&str]| {
        let out = buslab().args(["log", "info"]).args(args).output().unwrap();
        assert!(out.status.success(), "{}", stderr(&out));
        load_of(&stdout(&out))
    };
    let path = candump.to_str().unwrap();
    let (assumed, text) = info(&[path]);
    assert_eq!(
        text,
        format!(
            "{assumed:.1} % if the bus ran at 500 kbit/s (the log does not give its bit rate: --bitrate N says it)"
        )
    );
    let (given, text) = info(&[path, "--bitrate", "125000"]);
    assert_eq!(text, format!("{given:.1} % at 125 kbit/s (--bitrate)"));
    assert_eq!(given, 89.6);
    assert!((given - 4.0 * assumed).abs() < 0.3, "{given} vs {assumed}");

    // The same frames in a TRC file whose header names 125 kBit/s (PCAN-View's table).
    let trc = dir.path().join("lab.trc");
    let out = buslab()
        .args(["-q", "log", "convert", path, trc.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", stderr(&out));
    let text = std::fs::read_to_string(&trc).unwrap();
    let (first, rest) = text.split_once("\r\n").unwrap();
    std::fs::write(
        &trc,
        format!(
            "{first}\r\n;   Bus  Name         Connection        Protocol  Bit rate\r\n\
             ;   1    Connection1  lab@pcan_usb      CAN       125 kBit/s\r\n;---\r\n{rest}"
        ),
    )
    .unwrap();
    let trc = trc.to_str().unwrap();
    let (from_header, text) = info(&[trc]);
    assert_eq!(from_header, given);
    assert_eq!(
        text,
        format!("{given:.1} % at 125 kbit/s (the log's header)")
    );
    let (_, text) = info(&[trc, "--bitrate", "500000"]);
    assert_eq!(
        text,
        format!("{assumed:.1} % at 500 kbit/s (--bitrate; the log's header says 125 kbit/s)")
    );
}

#[test]
fn test_setup_says_what_it_would_install_and_installs_nothing_without_root_and_apt() {
    // `scripts/test.sh` installed packages as root without saying so first. Here the tools
    // are hidden (a PATH with only what the script itself runs, no apt-get): the setup lists
    // what it lacks and stops before installing anything.
    let bin = tempfile::tempdir().unwrap();
    for tool in [
        "bash", "cargo", "id", "ls", "grep", "tr", "cmp", "ldd", "dirname", "cat", "python3",
    ] {
        let found = Command::new("sh")
            .args(["-c", &format!("command -v {tool}")])
            .output()
            .unwrap();
        let path = String::from_utf8_lossy(&found.stdout).trim().to_string();
        if !path.is_empty() {
            std::os::unix::fs::symlink(&path, bin.path().join(tool)).unwrap();
        }
    }
    let setup = |args: &[&str]| {
        Command::new(bin.path().join("bash"))
            .arg(root().join("scripts/setup-test-deps.sh"))
            .args(args)
            .env("PATH", bin.path())
            .output()
            .unwrap()
    };
    let check = setup(&["--check"]);
    assert_eq!(check.status.code(), Some(1), "{}", stderr(&check));
    let listed = stdout(&check);
    assert!(
        listed.starts_with("setup-test-deps: the test tools this machine lacks:\n"),
        "{listed}"
    );
    assert!(
        listed.contains("  Debian, with apt-get as root: sigrok-cli "),
        "{listed}"
    );
    assert!(listed.contains(" tshark "), "{listed}");

    let install = setup(&[]);
    assert!(!install.status.success());
    assert!(
        stdout(&install).starts_with(
            "setup-test-deps: the test tools this machine lacks, to be installed now:\n"
        ),
        "{}",
        stdout(&install)
    );
    let err = stderr(&install);
    assert!(
        err.contains("installing Debian packages needs root and apt-get"),
        "{err}"
    );
    assert!(err.contains("nothing was installed"), "{err}");
    assert!(err.contains("--no-setup"), "{err}");
}
