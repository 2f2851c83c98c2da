//! `buslab web` on a running virtual bus: the pages show its nodes and frames, the token rule
//! holds, and the seed's cut-wire experiment started through the API makes the cut sender
//! error-passive, then repair brings it back.

mod bus_common;

use std::io::{BufRead, BufReader, Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::process::{Child, Stdio};
use std::time::{Duration, Instant};

use bus_common::Serve;

/// Only a guard against a hang: every wait ends on what it waits for first.
const HANG: Duration = Duration::from_secs(120);
const TOKEN: &str = "cli-test-token";

struct Web(Child);

impl Drop for Web {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn exchange(addr: SocketAddr, raw: &str) -> (u16, String) {
    let mut s = TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(HANG)).unwrap();
    s.write_all(raw.as_bytes()).unwrap();
    let mut text = String::new();
    let _ = s.read_to_string(&mut text);
    let status = text
        .split_whitespace()
        .nth(1)
        .and_then(|c| c.parse().ok())
        .unwrap_or(0);
    let body = text.split_once("\r\n\r\n").map_or("", |p| p.1).to_string();
    (status, body)
}

fn get(addr: SocketAddr, path: &str) -> (u16, String) {
    get_as(addr, "localhost", path)
}

/// A GET naming `host` in its Host header.
fn get_as(addr: SocketAddr, host: &str, path: &str) -> (u16, String) {
    exchange(
        addr,
        &format!("GET {path} HTTP/1.1\r\nHost: {host}\r\nConnection: close\r\n\r\n"),
    )
}

/// Starts `buslab web` with `args` on `serve`'s bus; its address.
fn start_web(serve: &Serve, args: &[&str]) -> (Web, SocketAddr) {
    let mut child = serve
        .buslab()
        .args(["web", "--bus", &serve.url, "--listen", "127.0.0.1:0"])
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let mut line = String::new();
    BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut line)
        .unwrap();
    let web = Web(child);
    let addr = line
        .trim()
        .strip_prefix("http://")
        .and_then(|r| r.strip_suffix('/'))
        .unwrap_or_else(|| panic!("no URL from buslab web: {line:?}"))
        .parse()
        .unwrap();
    (web, addr)
}

fn post(addr: SocketAddr, path: &str, token: Option<&str>, body: &str) -> (u16, String) {
    let header = token.map_or(String::new(), |t| format!("X-Buslab-Token: {t}\r\n"));
    exchange(
        addr,
        &format!(
            "POST {path} HTTP/1.1\r\nHost: localhost\r\nConnection: close\r\n{header}\
             Content-Length: {}\r\n\r\n{body}",
            body.len()
        ),
    )
}

/// The engine node's entry in `/api/state`, once `done` holds for it.
fn engine_until(addr: SocketAddr, what: &str, done: impl Fn(&serde_json::Value) -> bool) {
    let deadline = Instant::now() + HANG;
    loop {
        let (status, body) = get(addr, "/api/state?n=10");
        assert_eq!(status, 200, "{body}");
        let state: serde_json::Value = serde_json::from_str(&body).unwrap();
        let engine = state["delta"]["nodes"]
            .as_array()
            .unwrap()
            .iter()
            .find(|n| n["name"] == "engine")
            .cloned();
        if engine.as_ref().is_some_and(&done) {
            return;
        }
        assert!(Instant::now() < deadline, "never {what}: {body}");
        std::thread::sleep(Duration::from_millis(50));
    }
}

#[test]
fn the_cut_wire_experiment_from_the_web_api() {
    let dir = tempfile::tempdir().unwrap();
    let scenario = dir.path().join("engine.toml");
    std::fs::write(
        &scenario,
        "bitrate = 500000\n[[nodes]]\nname = \"engine\"\n  [[nodes.traffic]]\n  kind = \"periodic\"\n  frame = \"0C0#0FA0\"\n  period = \"2ms\"\n  start = \"1ms\"\n[[nodes]]\nname = \"dash\"\n",
    )
    .unwrap();
    let serve = Serve::start_with(500_000, &["--nodes", scenario.to_str().unwrap()]);
    let (_web, addr) = start_web(&serve, &["--token", TOKEN]);

    engine_until(addr, "error-active with frames sent", |e| {
        e["state"] == "error-active" && e["sent"].as_u64() > Some(0)
    });
    // The frames reach the pages through the server's own client, maybe a little later.
    let deadline = Instant::now() + HANG;
    loop {
        let (_, page) = get(addr, "/?refresh=0");
        if page.contains("engine") && page.contains("0C0#0FA0") {
            break;
        }
        assert!(Instant::now() < deadline, "no frames on the page: {page}");
        std::thread::sleep(Duration::from_millis(50));
    }

    let cut = r#"{"kind":"cut","nodes":["engine"],"rate":0.05}"#;
    let (status, body) = post(addr, "/api/fault", None, cut);
    assert_eq!(status, 401, "{body}");
    let (status, body) = post(addr, "/api/fault", Some(TOKEN), cut);
    assert_eq!(status, 200, "{body}");
    engine_until(addr, "error-passive after the cut", |e| {
        e["state"] != "error-active" && e["tec"].as_u64() >= Some(128)
    });
    let (status, body) = post(addr, "/api/repair", Some(TOKEN), "");
    assert_eq!(status, 200, "{body}");
    engine_until(addr, "error-active again after the repair", |e| {
        e["state"] == "error-active" && e["tec"].as_u64() < Some(128)
    });
    // An unknown node is refused with the server's reason.
    let (status, body) = post(
        addr,
        "/api/fault",
        Some(TOKEN),
        r#"{"kind":"disconnect","nodes":["nobody"]}"#,
    );
    assert_eq!(status, 400, "{body}");
    assert!(body.contains("nobody"), "{body}");
}

#[test]
fn the_lab_starts_the_web_pages_and_prints_the_dashboard_with_its_token() {
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_buslab"))
        .args([
            "lab",
            "--no-devices",
            "--listen",
            "127.0.0.1:0",
            "--web",
            "127.0.0.1:0",
            "--allow-host",
            "bench.lab",
        ])
        .env_remove("BUSLAB_BUS")
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let stderr = child.stderr.take().unwrap();
    let _lab = Web(child);
    let mut lines = BufReader::new(stderr).lines();
    let dashboard = loop {
        let line = lines.next().expect("the banner ended").unwrap();
        if let Some(url) = line.trim().strip_prefix("dashboard:") {
            break url.trim().to_string();
        }
    };
    // Keep reading the status lines so the lab never blocks on a full pipe.
    std::thread::spawn(move || lines.for_each(drop));
    let (base, token) = dashboard
        .split_once("dashboard#token=")
        .unwrap_or_else(|| panic!("{dashboard}"));
    let addr: SocketAddr = base
        .strip_prefix("http://")
        .and_then(|r| r.strip_suffix('/'))
        .unwrap()
        .parse()
        .unwrap();
    let deadline = Instant::now() + HANG;
    loop {
        let (status, body) = get(addr, "/api/state?n=1");
        assert_eq!(status, 200, "{body}");
        let state: serde_json::Value = serde_json::from_str(&body).unwrap();
        if state["delta"]["frames"].as_u64() > Some(0)
            && !state["delta"]["nodes"].as_array().unwrap().is_empty()
        {
            assert_eq!(state["writable"], true);
            break;
        }
        assert!(
            Instant::now() < deadline,
            "the lab's pages never showed its bus: {body}"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
    let frame = r#"{"frame":"7AB#01"}"#;
    assert_eq!(post(addr, "/api/send", None, frame).0, 401);
    let (status, body) = post(addr, "/api/send", Some(token), frame);
    assert_eq!(status, 202, "{body}");
    // The lab's pages answer to the name given with --allow-host, not to others.
    assert_eq!(get_as(addr, "bench.lab:8080", "/").0, 200);
    let (status, body) = get_as(addr, "evil.example", "/api/state");
    assert_eq!(status, 403, "{body}");
}

#[test]
fn buslab_web_refuses_foreign_hosts_and_frees_places_held_by_stalled_requests() {
    let serve = Serve::start(500_000);
    // One place only, and a short request timeout (a hidden option, for tests).
    let (_web, addr) = start_web(
        &serve,
        &[
            "--max-connections",
            "1",
            "--request-timeout",
            "1s",
            "--allow-host",
            "bench.lab",
        ],
    );
    let (status, body) = get_as(addr, "evil.example:8080", "/");
    assert_eq!(status, 403, "{body}");
    assert!(body.contains("--allow-host"), "{body}");
    // (A connection that comes before the last one let go of the only place gets 503.)
    let served = |host: &str| {
        let deadline = Instant::now() + HANG;
        loop {
            match get_as(addr, host, "/") {
                (200, _) => return Instant::now(),
                (503 | 0, _) => assert!(Instant::now() < deadline, "never served"),
                (status, body) => panic!("{status}: {body}"),
            }
        }
    };
    served("bench.lab");
    // The place held by a write whose body never comes is freed after the timeout: the
    // server answers 408, and serves the next client.
    let started = loop {
        let mut stalled = TcpStream::connect(addr).unwrap();
        stalled.set_read_timeout(Some(HANG)).unwrap();
        let started = Instant::now();
        write!(
            stalled,
            "POST /api/send HTTP/1.1\r\nHost: localhost\r\nContent-Length: 50\r\n\r\n"
        )
        .unwrap();
        let mut said = String::new();
        let _ = stalled.read_to_string(&mut said);
        if said.starts_with("HTTP/1.1 408") {
            assert!(said.contains("did not arrive within 1000 ms"), "{said}");
            break started;
        }
        // The last client had not let go of the place yet.
        assert!(
            said.is_empty() || said.starts_with("HTTP/1.1 503"),
            "{said}"
        );
    };
    assert!(started.elapsed() >= Duration::from_secs(1));
    served("localhost");
}

#[test]
fn error_frames_of_a_buslab_bus_reach_the_web_log_with_their_class() {
    let dir = tempfile::tempdir().unwrap();
    let scenario = dir.path().join("engine.toml");
    std::fs::write(
        &scenario,
        "bitrate = 500000\n[[nodes]]\nname = \"engine\"\n  [[nodes.traffic]]\n  kind = \"periodic\"\n  frame = \"0C0#0FA0\"\n  period = \"2ms\"\n  start = \"1ms\"\n[[nodes]]\nname = \"dash\"\n",
    )
    .unwrap();
    let serve = Serve::start_with(500_000, &["--nodes", scenario.to_str().unwrap()]);
    let (_web, addr) = start_web(&serve, &["--token", TOKEN]);
    engine_until(addr, "sending", |e| e["sent"].as_u64() > Some(0));
    // Noise on the whole bus until an error frame reaches the web server's log (its own
    // node sees the bus errors, as a SocketCAN node would).
    let (status, body) = post(
        addr,
        "/api/fault",
        Some(TOKEN),
        r#"{"kind":"noise","rate":0.01}"#,
    );
    assert_eq!(status, 200, "{body}");
    assert!(
        body.contains(
            r#""done":"noise on the whole bus: 1 % of the bits read wrong, until repaired""#
        ),
        "{body}"
    );
    let deadline = Instant::now() + HANG;
    let error = loop {
        let (_, body) = get(addr, "/api/state?n=10&filter=%23FFFFFFFF");
        let state: serde_json::Value = serde_json::from_str(&body).unwrap();
        if let Some(e) = state["delta"]["log"].as_array().unwrap().first() {
            break e.clone();
        }
        assert!(Instant::now() < deadline, "no error frame: {body}");
        std::thread::sleep(Duration::from_millis(50));
    };
    let (status, body) = post(addr, "/api/repair", Some(TOKEN), "");
    assert_eq!(status, 200, "{body}");
    // candump's form (the error flag and the class) and the class in words.
    let frame = error["frame"].as_str().unwrap();
    let class = error["error"]["class"].as_u64().unwrap();
    assert_eq!(
        &frame[..9],
        format!("{:08X}#", 0x2000_0000 | class),
        "{error}"
    );
    let words = error["error"]["classes"].as_array().unwrap();
    assert!(!words.is_empty(), "{error}");
    let (_, page) = get(addr, "/frames?filter=%23FFFFFFFF&refresh=0");
    assert!(page.contains("<b>ERRORFRAME</b>"), "{page}");
}
