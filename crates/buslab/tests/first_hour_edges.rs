//! The rough edges a new user met in the first hour (issue 26, points 9 and 10): each test is
//! named after what the user saw.

mod bus_common;
#[path = "support/outside_tools.rs"]
mod outside_tools;

use std::io::{BufRead, BufReader, Read};
use std::process::{Child, Command, Output, Stdio};

use bus_common::Serve;

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
