//! A real browser on `buslab web`'s live dashboard: headless Chromium driven over WebDriver
//! (Debian's `chromium` and `chromium-driver`, installed by scripts/setup-test-deps.sh). The
//! page's script fills the per-ID table from the live updates; a click on the seed's
//! experiment cuts the wire at a node, and its row turns error-passive (or bus-off). The
//! screenshot is left in the test's directory as `web-dashboard.png`.

mod bus_common;

use std::io::{BufRead, BufReader, Read, Write};
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use base64::Engine;
use bus_common::Serve;
use serde_json::{Value, json};

/// Only a guard against a hang: every wait ends on what it waits for first.
const HANG: Duration = Duration::from_secs(180);
const TOKEN: &str = "browser-test-token";
const ELEMENT: &str = "element-6066-11e4-a52f-4ce4e7b81d6e";

struct Kill(Child);

impl Drop for Kill {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn tools() -> bool {
    let found =
        Path::new("/usr/bin/chromium").exists() && Path::new("/usr/bin/chromedriver").exists();
    if !found {
        assert!(
            std::env::var_os("CI").is_none(),
            "chromium or chromedriver is missing: scripts/setup-test-deps.sh installs them"
        );
        eprintln!("skipped: no chromium/chromedriver (scripts/setup-test-deps.sh installs them)");
    }
    found
}

/// One HTTP request on its own connection: (status, body).
fn http(addr: SocketAddr, method: &str, path: &str, headers: &str, body: &str) -> (u16, String) {
    let mut s = TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(HANG)).unwrap();
    write!(
        s,
        "{method} {path} HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n{headers}\
         Content-Type: application/json\r\nContent-Length: {}\r\n\r\n{body}",
        body.len()
    )
    .unwrap();
    // chromedriver keeps the connection open whatever the request says: read by length.
    let mut reader = BufReader::new(s);
    let mut status_line = String::new();
    reader.read_line(&mut status_line).unwrap();
    let status = status_line
        .split_whitespace()
        .nth(1)
        .and_then(|c| c.parse().ok())
        .unwrap_or(0);
    let mut length = None;
    let mut chunked = false;
    loop {
        let mut line = String::new();
        if reader.read_line(&mut line).unwrap() == 0 || line == "\r\n" {
            break;
        }
        let lower = line.to_ascii_lowercase();
        if let Some(v) = lower.strip_prefix("content-length:") {
            length = v.trim().parse::<usize>().ok();
        }
        chunked |= lower.starts_with("transfer-encoding:") && lower.contains("chunked");
    }
    let mut body = Vec::new();
    if chunked {
        loop {
            let mut size = String::new();
            reader.read_line(&mut size).unwrap();
            let n = usize::from_str_radix(size.trim(), 16).unwrap();
            let mut chunk = vec![0; n + 2];
            reader.read_exact(&mut chunk).unwrap();
            if n == 0 {
                break;
            }
            body.extend_from_slice(&chunk[..n]);
        }
    } else if let Some(n) = length {
        body.resize(n, 0);
        reader.read_exact(&mut body).unwrap();
    } else {
        reader.read_to_end(&mut body).unwrap();
    }
    (status, String::from_utf8_lossy(&body).to_string())
}

/// A WebDriver session on chromedriver.
struct Browser {
    driver: SocketAddr,
    session: String,
    _chromedriver: Kill,
}

impl Browser {
    fn start(profile: &Path) -> Self {
        let port = TcpListener::bind("127.0.0.1:0")
            .unwrap()
            .local_addr()
            .unwrap()
            .port();
        let child = Command::new("/usr/bin/chromedriver")
            .arg(format!("--port={port}"))
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        let chromedriver = Kill(child);
        let driver: SocketAddr = format!("127.0.0.1:{port}").parse().unwrap();
        let deadline = Instant::now() + HANG;
        while TcpStream::connect(driver).is_err() {
            assert!(Instant::now() < deadline, "chromedriver never listened");
            std::thread::sleep(Duration::from_millis(20));
        }
        let caps = json!({"capabilities": {"alwaysMatch": {"browserName": "chrome",
            "goog:chromeOptions": {"binary": "/usr/bin/chromium", "args": [
                "--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
                "--disable-component-update", "--disable-sync", "--no-first-run",
                "--window-size=1400,1800", format!("--user-data-dir={}", profile.display())]}}}});
        let (status, body) = http(driver, "POST", "/session", "", &caps.to_string());
        assert_eq!(status, 200, "{body}");
        let v: Value = serde_json::from_str(&body).unwrap();
        let session = v["value"]["sessionId"].as_str().unwrap().to_string();
        Self {
            driver,
            session,
            _chromedriver: chromedriver,
        }
    }

    fn call(&self, method: &str, path: &str, body: Value) -> Value {
        let (status, text) = http(
            self.driver,
            method,
            &format!("/session/{}{path}", self.session),
            "",
            &if body.is_null() {
                String::new()
            } else {
                body.to_string()
            },
        );
        assert_eq!(status, 200, "{method} {path}: {text}");
        serde_json::from_str::<Value>(&text).unwrap()["value"].take()
    }

    fn open(&self, url: &str) {
        self.call("POST", "/url", json!({ "url": url }));
    }

    fn script(&self, script: &str) -> Value {
        self.call(
            "POST",
            "/execute/sync",
            json!({ "script": script, "args": [] }),
        )
    }

    fn click(&self, css: &str) {
        let found = self.call(
            "POST",
            "/element",
            json!({ "using": "css selector", "value": css }),
        );
        // The W3C key, or whichever single key this chromedriver uses.
        let id = found[ELEMENT]
            .as_str()
            .or_else(|| found.as_object()?.values().next()?.as_str())
            .unwrap_or_else(|| panic!("no element {css}: {found}"))
            .to_string();
        self.call("POST", &format!("/element/{id}/click"), json!({}));
    }

    /// Runs `script` until `done` holds for its value.
    fn until(&self, what: &str, script: &str, done: impl Fn(&Value) -> bool) -> Value {
        let deadline = Instant::now() + HANG;
        loop {
            let v = self.script(script);
            if done(&v) {
                return v;
            }
            assert!(
                Instant::now() < deadline,
                "the page never showed {what}: {v}"
            );
            std::thread::sleep(Duration::from_millis(50));
        }
    }
}

impl Drop for Browser {
    fn drop(&mut self) {
        let path = format!("/session/{}", self.session);
        let _ = http(self.driver, "DELETE", &path, "", "");
    }
}

const ID_COUNT: &str = "const r = document.querySelector('#ids tr[data-id=\"0C0\"]'); \
     return r ? Number(r.cells[1].textContent) : 0;";
const ENGINE_ROW: &str = "const r = [...document.querySelectorAll('#nodes tbody tr')]\
     .find(r => r.cells[1].textContent === 'engine'); \
     return r ? [r.className, r.cells[2].textContent] : null;";

#[test]
fn the_dashboard_in_chromium_updates_live_and_a_click_cuts_the_wire() {
    if !tools() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let scenario = dir.path().join("engine.toml");
    std::fs::write(
        &scenario,
        "bitrate = 125000\n[[nodes]]\nname = \"engine\"\n  [[nodes.traffic]]\n  kind = \"periodic\"\n  frame = \"0C0#0FA0\"\n  period = \"10ms\"\n  start = \"1ms\"\n[[nodes]]\nname = \"dash\"\n",
    )
    .unwrap();
    let serve = Serve::start_with(125_000, &["--nodes", scenario.to_str().unwrap()]);
    let mut child = serve
        .buslab()
        .args([
            "web",
            "--bus",
            &serve.url,
            "--listen",
            "127.0.0.1:0",
            "--token",
            TOKEN,
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let mut line = String::new();
    BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut line)
        .unwrap();
    let _web = Kill(child);
    let base = line.trim().to_string();
    assert!(base.starts_with("http://127.0.0.1:"), "{line:?}");

    let browser = Browser::start(&dir.path().join("profile"));
    browser.open(&format!("{base}dashboard#token={TOKEN}"));
    // The per-ID table fills, then its count goes on rising: the page is live.
    let first = browser.until("the 0C0 row", ID_COUNT, |v| v.as_u64() > Some(0));
    browser.until("the 0C0 count rising", ID_COUNT, |v| {
        v.as_u64() > first.as_u64()
    });
    let row = browser.until("the engine node", ENGINE_ROW, |v| !v.is_null());
    assert_eq!(row[1], "error-active", "{row}");

    // The node chosen for the TEC chart is the first, the engine: one click cuts its wire.
    browser.until(
        "the engine chosen",
        "return document.getElementById('histnode').selectedOptions[0]?.textContent",
        |v| v.as_str().is_some_and(|s| s.ends_with("engine")),
    );
    browser.click("#experiment");
    let row = browser.until("the engine leave error-active", ENGINE_ROW, |v| {
        v[0] == "passive" || v[0] == "busoff"
    });
    assert!(row[1] == "error-passive" || row[1] == "bus-off", "{row}");
    let result = browser.script("return document.getElementById('result').textContent");
    assert!(
        result.as_str().is_some_and(|r| r.starts_with("done")),
        "{result}"
    );
    // The TEC chart has its curve.
    let points = browser.script(
        "return document.querySelector('#tecchart polyline.tec').getAttribute('points').split(' ').length",
    );
    assert!(points.as_u64() > Some(2), "{points}");

    let png = browser.call("GET", "/screenshot", Value::Null);
    let png = base64::engine::general_purpose::STANDARD
        .decode(png.as_str().unwrap())
        .unwrap();
    assert!(png.starts_with(b"\x89PNG"));
    let shot = Path::new(env!("CARGO_TARGET_TMPDIR")).join("web-dashboard.png");
    std::fs::write(&shot, png).unwrap();
}
