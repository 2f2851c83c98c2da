//! Text a bus server sends reaches the terminal with its control characters written out: a
//! hostile socketcand server (written here, speaking buslab's extensions) names a node
//! `ESC[2J…` and answers an error with an escape sequence; `buslab status`, `buslab regs` and
//! the error line print them as `\x1B[2J…`, never the escape byte itself.

use std::io::{Read, Write};
use std::net::TcpListener;
use std::process::Command;
use std::thread;

use buslab_canbus::{
    BusSummary, CanMode, ErrorRegisters, ErrorState, NodeCounters, NodeInfo, NodeRegisters,
    NodeStatus, RegisterDump, Status,
};
use buslab_socketcand::reply::{nodes_fields, regs_fields, status_fields};

/// The name the hostile server gives node 2: clear the screen, home, a name.
const EVIL: &str = "\x1b[2J\x1b[Hevil";

fn status(number: u32, name: &str) -> NodeStatus {
    NodeStatus {
        number,
        name: name.into(),
        state: ErrorState::Active,
        errors: Some(ErrorRegisters {
            alc: None,
            ecc: None,
            rxerr: 0,
            txerr: 0,
        }),
        sr: Some(Status(0x0C)),
        timing: None,
        counters: NodeCounters::default(),
        tx_queued: 0,
        bus: BusSummary {
            bitrate: 125_000,
            load_percent: 0.0,
            frames: 0,
            errors: 0,
        },
    }
}

/// The reply to one element, raw (no sanitising on this side: the server is hostile).
fn answer(element: &str) -> String {
    let words: Vec<&str> = element.split_whitespace().collect();
    let reply = |name: &str, fields: Vec<String>| format!("< {name} {} >", fields.join(" "));
    match words.as_slice() {
        ["open", ..] | ["rawmode"] | ["buslab_ext"] => "< ok >".into(),
        ["buslab_nodes"] => reply(
            "buslab_nodes",
            nodes_fields(&[
                NodeInfo {
                    number: 1,
                    name: "me".into(),
                },
                NodeInfo {
                    number: 2,
                    name: EVIL.into(),
                },
            ]),
        ),
        ["buslab_status"] => reply("buslab_status", status_fields(&status(1, "me"))),
        ["buslab_status", "2"] => reply("buslab_status", status_fields(&status(2, EVIL))),
        ["buslab_regs", "2"] => reply(
            "buslab_regs",
            regs_fields(&NodeRegisters {
                number: 2,
                name: EVIL.into(),
                dump: RegisterDump {
                    mode: CanMode::Peli,
                    reset_mode: false,
                    values: vec![Some(0); 128],
                },
            }),
        ),
        _ => "< error \x1b]0;owned\x07no such node\x1b[31m >".into(),
    }
}

/// A hostile server for `connections` clients; its URL.
fn hostile_server(connections: usize) -> String {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let url = format!("socketcand://{}/vcan0", listener.local_addr().unwrap());
    thread::spawn(move || {
        for stream in listener.incoming().take(connections) {
            let mut s = stream.unwrap();
            s.write_all(b"< hi >").unwrap();
            let mut deframer = buslab_socketcand::Deframer::new();
            let mut buf = [0u8; 1024];
            while let Ok(n @ 1..) = s.read(&mut buf) {
                deframer.push(&buf[..n]);
                while let Some(Ok(element)) = deframer.next_element() {
                    let _ = s.write_all(answer(&element).as_bytes());
                }
            }
        }
    });
    url
}

fn buslab(url: &str, args: &[&str]) -> (bool, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_buslab"))
        .args(args)
        .args(["--bus", url])
        .env_remove("BUSLAB_BUS")
        .output()
        .unwrap();
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).to_string(),
        String::from_utf8_lossy(&out.stderr).to_string(),
    )
}

#[test]
fn node_names_from_a_server_reach_the_terminal_written_out() {
    // Regression: `buslab status` printed a node's name as the server sent it, so a server
    // could clear the user's screen (ESC[2J) or worse.
    let url = hostile_server(3);
    let (ok, out, err) = buslab(&url, &["status"]);
    assert!(ok, "{err}");
    assert!(
        !out.contains('\x1b'),
        "an escape byte reached stdout: {out:?}"
    );
    assert!(out.contains("\\x1B[2J\\x1B[Hevil"), "{out}");

    let (ok, out, err) = buslab(&url, &["regs", "--node", "2"]);
    assert!(ok, "{err}");
    assert!(!out.contains('\x1b'), "{out:?}");
    assert!(out.contains("node 2 (\\x1B[2J\\x1B[Hevil)"), "{out}");

    // An error the server words reaches the terminal without its escape sequences.
    let (ok, _, err) = buslab(&url, &["status", "--node", "9"]);
    assert!(!ok);
    assert!(!err.contains(['\x1b', '\x07']), "{err:?}");
    assert!(err.contains("no such node"), "{err}");
}

#[test]
fn an_error_quoting_a_name_with_an_escape_sequence_prints_it_written_out() {
    // Any error line, whatever it quotes (here a file name), keeps its own line breaks and
    // writes every other control character out.
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("\x1b[2Jgone.bin");
    let out = Command::new(env!("CARGO_BIN_EXE_buslab"))
        .args(["sendfile", "--id", "0x123"])
        .arg(&missing)
        .env_remove("BUSLAB_BUS")
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(!err.contains('\x1b'), "{err:?}");
    assert!(err.contains("\\x1B[2Jgone.bin"), "{err}");
}
