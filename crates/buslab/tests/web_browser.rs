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
        // The driver's own limits (a script: 30 s by default) are timing margins a loaded
        // machine runs out of: a page busy for longer fails the test instead of being waited
        // for. The hang guard bounds them.
        let hang_ms = HANG.as_millis() as u64;
        let caps = json!({"capabilities": {"alwaysMatch": {"browserName": "chrome",
            "timeouts": {"script": hang_ms, "pageLoad": hang_ms},
            "goog:loggingPrefs": {"browser": "ALL"},
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

    /// The element `css` finds first.
    fn find(&self, css: &str) -> String {
        let found = self.call(
            "POST",
            "/element",
            json!({ "using": "css selector", "value": css }),
        );
        // The W3C key, or whichever single key this chromedriver uses.
        found[ELEMENT]
            .as_str()
            .or_else(|| found.as_object()?.values().next()?.as_str())
            .unwrap_or_else(|| panic!("no element {css}: {found}"))
            .to_string()
    }

    /// Clicks `css`'s element. A page that is still growing (rows and panels appearing as
    /// the bus is heard) can move it between chromedriver's scroll and its click; then the
    /// click is tried again on the element where it now is, as a person clicks again.
    fn click(&self, css: &str) {
        let deadline = Instant::now() + HANG;
        loop {
            let id = self.find(css);
            let (status, text) = http(
                self.driver,
                "POST",
                &format!("/session/{}/element/{id}/click", self.session),
                "",
                "{}",
            );
            if status == 200 {
                return;
            }
            assert!(
                text.contains("element click intercepted"),
                "click {css}: {text}"
            );
            assert!(
                Instant::now() < deadline,
                "click {css}: another element stayed over it: {text}"
            );
            std::thread::sleep(Duration::from_millis(50));
        }
    }

    /// The browser's console messages since the last call that report a
    /// Content-Security-Policy violation.
    fn csp_violations(&self) -> Vec<String> {
        let log = self.call("POST", "/se/log", json!({ "type": "browser" }));
        log.as_array()
            .unwrap_or_else(|| panic!("no browser log: {log}"))
            .iter()
            .filter_map(|e| e["message"].as_str())
            .filter(|m| m.contains("Content Security Policy"))
            .map(str::to_string)
            .collect()
    }

    /// Opens each of the server's pages without JavaScript: the stylesheet applies and the
    /// browser reports no Content-Security-Policy violation; then checks that it would
    /// report one (an inline script put in by hand is refused).
    fn pages_work_under_the_policy(&self, base: &str, pages: &[&str]) {
        assert_eq!(self.csp_violations(), Vec::<String>::new(), "before");
        for page in pages {
            self.open(&format!("{base}{page}"));
            let nav = self
                .script("return getComputedStyle(document.querySelector('nav')).backgroundColor");
            assert_eq!(
                nav, "rgb(34, 51, 68)",
                "{page}: the stylesheet did not apply"
            );
            assert_eq!(self.csp_violations(), Vec::<String>::new(), "{page}");
        }
        let ran = self.script(
            "window.inlineRan = false; const s = document.createElement('script'); \
             s.textContent = 'window.inlineRan = true'; document.body.appendChild(s); \
             return window.inlineRan",
        );
        assert_eq!(ran, false, "an inline script ran");
        let refused = self.csp_violations();
        assert!(
            refused.iter().any(|m| m.contains("inline script")),
            "the violation was not reported: {refused:?}"
        );
    }

    /// A write from the page itself (with the token in its field), as its buttons do.
    fn js_write(&self, path: &str, body: &str) {
        let answer = self.call(
            "POST",
            "/execute/async",
            json!({
                "script": "const [path, body, done] = arguments; \
                           fetch(path, {method: 'POST', headers: {'Content-Type': 'application/json', \
                           'X-Buslab-Token': document.getElementById('token').value}, body}) \
                           .then(r => r.text().then(t => done([r.status, t])))",
                "args": [path, body],
            }),
        );
        assert_eq!(answer[0], 200, "{path}: {answer}");
    }

    /// Runs `script` until `done` holds for its value.
    fn until(&self, what: &str, script: &str, done: impl Fn(&Value) -> bool) -> Value {
        self.until_within(HANG, what, script, done)
    }

    /// As [`Browser::until`], for what takes `guard` plus the hang guard at most.
    fn until_within(
        &self,
        guard: Duration,
        what: &str,
        script: &str,
        done: impl Fn(&Value) -> bool,
    ) -> Value {
        let deadline = Instant::now() + guard + HANG;
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
    // The click's result in words, not the API's JSON.
    let result = browser.script("return document.getElementById('result').textContent");
    assert_eq!(
        result,
        "Done: the wire cut: engine on the far side, 5 % of the bits read there wrong, for 3.00 s.",
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
    // Everything above ran under the server's Content-Security-Policy (its own files only,
    // nothing inline), and so do the pages without JavaScript.
    browser.pages_work_under_the_policy(
        &base,
        &[
            "dashboard",
            "",
            "ids",
            "frames?filter=0C0",
            "nodes/1",
            "devices",
        ],
    );
}

/// Starts `buslab lab` with its devices; returns it and the dashboard's address with the
/// token in its fragment.
fn start_lab() -> (Kill, String) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_buslab"))
        .args(["lab", "--listen", "127.0.0.1:0", "--web", "127.0.0.1:0"])
        .env_remove("BUSLAB_BUS")
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let stderr = child.stderr.take().unwrap();
    let lab = Kill(child);
    let mut lines = BufReader::new(stderr).lines();
    let dashboard = loop {
        let line = lines.next().expect("the banner ended").unwrap();
        if let Some(url) = line.trim().strip_prefix("dashboard:") {
            break url.trim().to_string();
        }
    };
    // Keep reading the status lines so the lab never blocks on a full pipe.
    std::thread::spawn(move || lines.for_each(drop));
    (lab, dashboard)
}

/// SLIO `n`'s LED on pin `pin`: [on, pending] as the page shows it.
fn led(slio: &str, pin: u8) -> String {
    format!(
        "const b = document.querySelector('#slio-{slio} button.led[data-pin=\"{pin}\"]'); \
         return b ? [b.dataset.on === '1', b.dataset.pending === '1'] : null;"
    )
}

fn cell(slio: &str, key: &str) -> String {
    format!(
        "const t = document.querySelector('#slio-{slio} td[data-key=\"{key}\"]'); \
         return t ? t.textContent : null;"
    )
}

fn screenshot(browser: &Browser, path: &str, name: &str) {
    let png = browser.call("GET", path, Value::Null);
    let png = base64::engine::general_purpose::STANDARD
        .decode(png.as_str().unwrap())
        .unwrap();
    assert!(png.starts_with(b"\x89PNG"));
    let shot = Path::new(env!("CARGO_TARGET_TMPDIR")).join(name);
    std::fs::write(&shot, png).unwrap();
}

#[test]
fn the_lab_dashboard_shows_its_devices_and_an_led_follows_the_slio() {
    if !tools() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let (_lab, dashboard) = start_lab();
    let (base, token) = dashboard.split_once("dashboard#token=").unwrap();
    let addr: SocketAddr = base
        .strip_prefix("http://")
        .and_then(|r| r.strip_suffix('/'))
        .unwrap()
        .parse()
        .unwrap();
    let browser = Browser::start(&dir.path().join("profile"));
    browser.open(&dashboard);

    // The panels: three SLIO boards whose outputs the server learned by asking them, the
    // ZELLE cell, the CPU196 board with its identity.
    for slio in ["0", "3", "A"] {
        browser.until(
            &format!("SLIO {slio}'s outputs"),
            &cell(slio, "outputs"),
            |v| v.as_str().is_some_and(|s| s.len() == 4),
        );
    }
    browser.until(
        "the ZELLE panel",
        "return !!document.getElementById('zelle')",
        |v| v == true,
    );
    browser.until(
        "the CPU196 identity",
        "return document.querySelector('#cpu196 pre.identity')?.textContent",
        |v| v.as_str().is_some_and(|s| s.contains("serial")),
    );
    let before = browser.until("SLIO 3's LED P7", &led("3", 7), |v| !v.is_null());
    assert_eq!(
        before,
        json!([false, false]),
        "P7 starts off (MoniCAN's sign-on)"
    );

    // SLIO 3 off the wire: the click is sent and shows pending, and the LED stays off. The
    // proof that it had its chance to answer: SLIO 0, asked after it through the same queue,
    // answered.
    let header = format!("X-Buslab-Token: {token}\r\n");
    let (status, body) = http(
        addr,
        "POST",
        "/api/fault",
        &header,
        r#"{"kind":"disconnect","nodes":["slio3"]}"#,
    );
    assert_eq!(status, 200, "{body}");
    browser.click("#slio-3 button.led[data-pin=\"7\"]");
    browser.until("the click pending", &led("3", 7), |v| {
        *v == json!([false, true])
    });
    let replies = |slio: &str| {
        browser
            .script(&cell(slio, "replies"))
            .as_str()
            .unwrap()
            .parse::<u64>()
            .unwrap()
    };
    let answered = replies("0");
    browser.click("#slio-0 button.read");
    browser.until("SLIO 0's answer", &cell("0", "replies"), |v| {
        v.as_str().and_then(|s| s.parse::<u64>().ok()) > Some(answered)
    });
    assert_eq!(
        browser.script(&led("3", 7)),
        json!([false, true]),
        "the LED changed without the SLIO's confirmation"
    );

    // Back on the wire, MoniCAN calibrates SLIO 3 again and initialises it (every LED off):
    // its DATA_OUTPUT answer ends the pending mark. A click now is confirmed and the LED
    // turns on, with the SLIO's answer on the bus.
    let (status, body) = http(addr, "POST", "/api/repair", &header, "{}");
    assert_eq!(status, 200, "{body}");
    browser.until("SLIO 3 initialised again", &led("3", 7), |v| {
        *v == json!([false, false])
    });
    browser.click("#slio-3 button.led[data-pin=\"7\"]");
    browser.until("the LED on", &led("3", 7), |v| *v == json!([true, false]));
    let (status, body) = http(addr, "GET", "/api/state?filter=29D&n=1000", "", "");
    assert_eq!(status, 200);
    let state: Value = serde_json::from_str(&body).unwrap();
    let confirmed = state["delta"]["log"].as_array().unwrap().iter().any(|e| {
        let f = e["frame"].as_str().unwrap();
        // The SLIO's DATA_OUTPUT (register 3) with P7 high.
        f.len() == 10 && &f[5..6] == "3" && u16::from_str_radix(&f[6..10], 16).unwrap() & 0x80 != 0
    });
    assert!(confirmed, "no confirmation from SLIO 3 on the bus: {body}");

    // A conversion: the potentiometer of SLIO A, as the SLIO answers it.
    browser.click("#slio-A button.adc2");
    browser.until("SLIO A's ADC2", &cell("A", "adc2"), |v| {
        v.as_str().is_some_and(|s| s.ends_with(" V)"))
    });

    // Live plots: a ZELLE measurement and the CPU196 A/D stream, started by clicks.
    browser.click("#zelle button.measure");
    browser.click("#cpu196 button.start");
    browser.until(
        "the ZELLE plot",
        // With the panel's state line, which names an error if the run failed.
        "return [document.querySelector('#zelle polyline.ch2')?.getAttribute('points').split(' ').length, \
         document.querySelector('#zelle .state').textContent]",
        |v| v[0].as_u64() > Some(40),
    );
    // Each measured block is a line of its own: nothing is drawn across the gap while the
    // cell is read back (a line there would show values nobody measured).
    let blocks = browser.until(
        "two ZELLE blocks",
        "return [...document.querySelectorAll('#zelle polyline.ch1')].map(p => \
         p.getAttribute('points').split(' ').map(xy => Number(xy.split(',')[0])))",
        |v| v.as_array().is_some_and(|b| b.len() >= 2),
    );
    let (first, second) = (&blocks[0], &blocks[1]);
    assert_eq!(
        first.as_array().unwrap().len(),
        50,
        "one block: 50 scan cycles"
    );
    let end = first.as_array().unwrap().last().unwrap().as_f64().unwrap();
    let start = second[0].as_f64().unwrap();
    assert!(
        start > end,
        "the second block starts after the first ends: {blocks}"
    );
    browser.until(
        "the CPU196 plot",
        // With the panel's state line, which names an error if the run failed.
        "return [document.querySelector('#cpu196 polyline.ch1')?.getAttribute('points').split(' ').length, \
         document.querySelector('#cpu196 .state').textContent]",
        |v| v[0].as_u64() > Some(40),
    );
    screenshot(&browser, "/screenshot", "lab-dashboard.png");
    let id = browser.find("#devices");
    screenshot(
        &browser,
        &format!("/element/{id}/screenshot"),
        "web-devices.png",
    );
    browser.click("#cpu196 button.stop");
    browser.click("#zelle button.stop");
    browser.until(
        "the CPU196 stopped",
        "return document.querySelector('#cpu196 .state').textContent",
        |v| v.as_str().is_some_and(|s| s.contains("idle")),
    );
    browser.pages_work_under_the_policy(base, &["devices", "dashboard"]);
}

/// The page's own view of its charts: the server's time, and the engine's TEC samples.
const PAGE_CLOCK: &str = "return state.now";

/// The text of the elements `css` finds.
fn texts(css: &str) -> String {
    format!("return [...document.querySelectorAll('{css}')].map(e => e.textContent)")
}

/// A chart's polyline points of class `class`, as [x, y] in the chart's units.
fn points(chart: &str, class: &str) -> String {
    format!(
        "return [...document.querySelectorAll('#{chart} polyline.{class}')].flatMap(p => \
         p.getAttribute('points').split(' ').map(xy => xy.split(',').map(Number)))"
    )
}

#[test]
fn the_lab_dashboard_charts_the_experiment_in_its_window_on_axes_that_fit() {
    if !tools() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let (_lab, dashboard) = start_lab();
    let browser = Browser::start(&dir.path().join("profile"));
    // The window is a page setting (here from the address): 10 s, so that the test need not
    // wait 10 minutes to show what a user sees after them.
    const WINDOW: f64 = 10.0;
    browser.open(&format!("{dashboard}&window=10"));
    assert_eq!(
        browser.script("return document.getElementById('window').value"),
        "10"
    );
    // The lab runs longer than twice the window: a chart over the lab's age would squeeze
    // the 3-s experiment into less than 3/25 of its width.
    browser.until("the lab 25 s old", PAGE_CLOCK, |v| {
        v.as_f64().is_some_and(|t| t > 2.5 * WINDOW)
    });

    // The seed's experiment on the engine, from the dashboard.
    browser.until(
        "the engine to choose",
        "const s = document.getElementById('histnode'); \
         const o = [...s.options].find(o => o.textContent.endsWith(' engine')); \
         if (!o) return false; s.value = o.value; s.dispatchEvent(new Event('change')); return true",
        |v| v == true,
    );
    browser.click("#experiment");
    // The click's result in words.
    let result = browser.until(
        "the experiment's result",
        "return document.getElementById('result').textContent",
        |v| v.as_str().is_some_and(|r| r != "…" && !r.is_empty()),
    );
    assert_eq!(
        result,
        "Done: the wire cut: engine on the far side, 5 % of the bits read there wrong, for 3.00 s."
    );
    // The TEC climbs past error-passive (y of 128 on a 0..256 axis: 80 of 160).
    browser.until("the TEC past 128", &points("tecchart", "tec"), |v| {
        v.as_array()
            .is_some_and(|p| p.iter().any(|xy| xy[1].as_f64() <= Some(80.0)))
    });
    // Once the cut is over, its band has the width of 3 s in the 10-s window: 180 of 600.
    browser.until(
        "the cut over",
        "const f = [...state.faults.values()][0]; return f && state.now > f.until",
        |v| v == true,
    );
    // The chart is drawn at its next update after that (a loaded machine can be between two).
    let band = browser.until(
        "the chart drawn with the whole cut",
        "const b = document.querySelector('#tecchart rect.band'); \
         return b && [Number(b.getAttribute('width')), b.textContent, \
         document.querySelector('#tecchart text.bandlabel').textContent]",
        |v| {
            v[0].as_f64()
                .is_some_and(|w| (w - 600.0 * 3.0 / WINDOW).abs() < 0.2)
        },
    );
    let width = band[0].as_f64().unwrap();
    assert!(
        (width - 600.0 * 3.0 / WINDOW).abs() < 0.2,
        "the band is {width} wide: {band}"
    );
    assert_eq!(band[2], "cut at engine", "{band}");
    assert!(
        band[1]
            .as_str()
            .unwrap()
            .starts_with("the wire cut: engine"),
        "{band}"
    );
    // The axis is the window, and the curve stays in it.
    assert_eq!(
        browser.script(&texts("#tecchart text.xlabel")),
        json!(["−10 s", "−7.5 s", "−5 s", "−2.5 s", "now"])
    );
    let tec = browser.script(&points("tecchart", "tec"));
    assert!(
        tec.as_array().unwrap().iter().all(|xy| {
            let x = xy[0].as_f64().unwrap();
            (0.0..=600.0).contains(&x)
        }),
        "{tec}"
    );
    assert_eq!(
        browser.script(&texts("#tecchart text.ylabel")),
        json!(["0", "128", "256"]),
        "the counters reached bus-off: the axis goes to 256"
    );

    // The load axis fits the load: its scale is said, and the highest point of the line is
    // at half the height or above (not a flat line at the bottom of 0..100 %).
    let caption =
        browser.script("return document.querySelector('#loadchart text.caption').textContent");
    let caption = caption.as_str().unwrap().to_string();
    let top = caption
        .split("scale 0 to ")
        .nth(1)
        .and_then(|r| r.strip_suffix(" %)"))
        .unwrap_or_else(|| panic!("{caption}"))
        .to_string();
    assert_ne!(top, "100", "{caption}");
    let labels = browser.script(&texts("#loadchart text.ylabel"));
    assert_eq!(labels[2], format!("{top} %"), "{labels}");
    let load = browser.script(&points("loadchart", "load"));
    let highest = load
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|xy| xy[1].as_f64())
        .fold(f64::MAX, f64::min);
    assert!(
        highest <= 80.0,
        "the load line stays in the lower half: {load}"
    );

    // Frame times read as the time of day, with milliseconds.
    let time = browser.until(
        "a frame in the log",
        "return document.querySelector('#log span.t')?.textContent",
        |v| v.is_string(),
    );
    let time = time.as_str().unwrap();
    assert!(
        time.len() == 12 && time.as_bytes()[2] == b':' && time.as_bytes()[8] == b'.',
        "{time}"
    );

    // Error frames: noise on the whole bus until one is in the log, typed.
    browser.js_write("/api/fault", r#"{"kind":"noise","rate":0.01}"#);
    let line = browser.until(
        "an error frame in the log",
        "return document.querySelector('#log .errorframe')?.textContent",
        |v| v.is_string(),
    );
    browser.js_write("/api/repair", "{}");
    let line = line.as_str().unwrap();
    // candump's form: the error flag and the class as the ID (20000088#…).
    let frame = line.split_whitespace().nth(1).unwrap_or_default();
    assert!(
        frame.len() > 9 && frame.starts_with("2000") && frame.as_bytes()[8] == b'#',
        "candump's error-frame ID: {line}"
    );
    assert!(line.contains("ERRORFRAME"), "{line}");
    assert!(
        [
            "bus-error",
            "lost-arbitration",
            "controller-problem",
            "bus-off"
        ]
        .iter()
        .any(|w| line.contains(w)),
        "the classes in words: {line}"
    );
    let counted =
        browser.script("return Number(document.getElementById('errorframes').textContent)");
    assert!(counted.as_u64() > Some(0), "{counted}");

    // A refusal says why in words.
    browser.script("document.getElementById('token').value = 'not-the-token'");
    browser.click("#repair");
    let refused = browser.until(
        "the refusal",
        "return document.getElementById('result').textContent",
        |v| v.as_str().is_some_and(|r| r.starts_with("Not done")),
    );
    assert_eq!(
        refused,
        "Not done: wrong token in the X-Buslab-Token header"
    );
    screenshot(&browser, "/screenshot", "lab-dashboard-window.png");
}

/// Headless Chromium's own screenshot of `url` (`--screenshot`, as
/// /work/shared/facts/test-infrastructure.md §3 says: a fresh profile, a time limit). For the
/// pages without JavaScript: what the dashboard shows depends on when its updates come, which
/// only a WebDriver session can wait for.
fn chromium_screenshot(url: &str, profile: &Path, shot: &Path, height: u32) {
    let out = Command::new("/usr/bin/chromium")
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            "--no-first-run",
            "--hide-scrollbars",
        ])
        .arg(format!("--user-data-dir={}", profile.display()))
        .arg(format!("--window-size=1400,{height}"))
        .arg(format!("--screenshot={}", shot.display()))
        .arg("--timeout=10000")
        .arg(url)
        .output()
        .unwrap();
    assert!(out.status.success(), "{out:?}");
    let png = std::fs::read(shot).unwrap();
    assert!(png.starts_with(b"\x89PNG"), "{}", shot.display());
}

/// The screenshots of docs/web.md: the dashboard after 10 minutes of `buslab lab` with the
/// seed's experiment run from it (a click), then a moment of noise on the whole bus for error
/// frames in the log. Takes those 10 minutes, so only on demand:
/// `cargo test -p buslab --test web_browser -- --ignored ten_minutes`; the PNGs go to
/// `target/tmp/` (docs/img/ holds the committed ones).
#[test]
#[ignore = "runs the lab for 10 minutes: the acceptance screenshots of docs/web.md"]
fn the_dashboard_after_ten_minutes_of_lab_with_the_experiment() {
    const LAB_AGE: Duration = Duration::from_secs(600);
    assert!(tools(), "chromium and chromedriver are needed");
    let dir = tempfile::tempdir().unwrap();
    let out = Path::new(env!("CARGO_TARGET_TMPDIR"));
    let (_lab, dashboard) = start_lab();
    let base = dashboard.split_once("dashboard#").unwrap().0.to_string();
    let browser = Browser::start(&dir.path().join("profile"));
    browser.open(&dashboard);
    // The experiment half a minute before the 10 minutes are up: in the default 1-min window.
    browser.until_within(LAB_AGE, "the lab 9.5 min old", PAGE_CLOCK, |v| {
        v.as_f64().is_some_and(|t| t > 570.0)
    });
    browser.until(
        "the engine to choose",
        "const s = document.getElementById('histnode'); \
         const o = [...s.options].find(o => o.textContent.endsWith(' engine')); \
         if (!o) return false; s.value = o.value; s.dispatchEvent(new Event('change')); return true",
        |v| v == true,
    );
    browser.click("#experiment");
    browser.until(
        "the experiment's result",
        "return document.getElementById('result').textContent",
        |v| {
            v.as_str()
                .is_some_and(|r| r.starts_with("Done: the wire cut"))
        },
    );
    browser.until("the TEC past 128", &points("tecchart", "tec"), |v| {
        v.as_array()
            .is_some_and(|p| p.iter().any(|xy| xy[1].as_f64() <= Some(80.0)))
    });
    // 15 s later: a moment of noise on the whole bus (0.1 % of the bits, 300 ms), from the
    // fault form, for error frames in the log.
    browser.until(
        "15 s after the cut",
        "const f = [...state.faults.values()][0]; return f && state.now > f.t + 15",
        |v| v == true,
    );
    browser.script(
        "document.getElementById('kind').value = 'noise'; \
         document.getElementById('faultnodes').value = ''; \
         document.getElementById('rate').value = '0.001'; \
         document.getElementById('forms').value = '300'",
    );
    browser.click("#faultform button");
    browser.until(
        "the noise's result",
        "return document.getElementById('result').textContent",
        |v| v.as_str().is_some_and(|r| r.starts_with("Done: noise")),
    );
    browser.until("the lab 10 min old", PAGE_CLOCK, |v| {
        v.as_f64().is_some_and(|t| t > 600.0)
    });
    // The log shows the error frames only (candump's error mask), each in words.
    browser.script(
        "document.getElementById('filter').value = '#FFFFFFFF'; \
         document.getElementById('applyfilter').click()",
    );
    let errors = browser.until(
        "error frames in the log",
        "return document.querySelectorAll('#log .errorframe').length",
        |v| v.as_u64() >= Some(3),
    );
    eprintln!("{errors} error frames in the log");
    // The 3-s cut in the 1-min window: 30 of 600.
    let width = browser.script(
        "return Number(document.querySelector('#tecchart rect.band').getAttribute('width'))",
    );
    assert!((width.as_f64().unwrap() - 30.0).abs() < 0.2, "{width}");
    screenshot(&browser, "/screenshot", "dashboard-10min.png");
    let id = browser.find("#log");
    screenshot(
        &browser,
        &format!("/element/{id}/screenshot"),
        "dashboard-10min-errorframes.png",
    );
    // The whole 10 minutes: the page asks the server for them again, the axis is the window.
    browser.script(
        "const w = document.getElementById('window'); w.value = '600'; \
         w.dispatchEvent(new Event('change'))",
    );
    browser.until(
        "the 10-min axis with the lab's first minutes",
        "const x = [...document.querySelectorAll('#tecchart text.xlabel')].map(e => e.textContent); \
         const h = state.history.get(Number(document.getElementById('histnode').value)) || []; \
         return x[0] === '−10 min' && h.length > 0 && h[0].t < state.now - 590",
        |v| v == true,
    );
    screenshot(&browser, "/screenshot", "dashboard-10min-window-10min.png");
    // The engine's page without JavaScript: its TEC/REC over the last minute.
    chromium_screenshot(
        &format!("{base}nodes/2?refresh=0"),
        &dir.path().join("cli-profile"),
        &out.join("node-engine-10min.png"),
        700,
    );
}

/// A signal's value cell on the dashboard: [text, highlighted (changed lately), dimmed
/// (an inactive multiplexed branch)], or null while the page has no such row.
fn signal_value(signal: &str) -> String {
    format!(
        "const r = document.querySelector('#messages tr[data-signal=\"{signal}\"]'); \
         return r ? [r.querySelector('td.value').textContent, \
         !!r.querySelector('td.value mark'), r.classList.contains('inactive')] : null;"
    )
}

/// Issue 29: `buslab lab` decodes its own traffic with its DBC: the dashboard shows each
/// message's named signals, live (the counter's count rising, highlighted as it changes; the
/// engine's constant speed not), the SLIO replies by register, and plots a signal picked by a
/// click on its name. The screenshots go to the test's directory as `lab-dashboard-signals.png`
/// (the page), `web-signals.png` (the signals section), `web-signals-slio.png` (SLIO 3's
/// replies) and `web-signals-page.png` (`/signals`, without JavaScript).
#[test]
fn the_lab_dashboard_shows_named_signals_live_and_plots_one() {
    if !tools() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let (_lab, dashboard) = start_lab();
    let browser = Browser::start(&dir.path().join("profile"));
    // A 10-s window: the plot below spans it once the lab is that old.
    browser.open(&format!("{dashboard}&window=10"));
    browser.until(
        "the signals section",
        "return [document.getElementById('signals').hidden, \
         document.getElementById('dbcsize').textContent]",
        |v| v[0] == false && v[1] == "14",
    );
    // The lab's simulated nodes by name, with units and value tables.
    for (signal, shown) in [
        ("Engine.EngineSpeed", "4000 rpm"),
        ("Engine.VehicleSpeed", "60 km/h"),
        ("Brakes.BrakePressure", "32.0 bar"),
        ("Body.Lights", "low beam"),
        ("Dash.FuelLevel", "83.6 %"),
    ] {
        let v = browser.until(signal, &signal_value(signal), |v| !v.is_null());
        assert_eq!(
            v,
            json!([shown, false, false]),
            "{signal}: a constant value"
        );
    }
    // The counter counts: its value rises from update to update, highlighted as it changes.
    let count = |v: &Value| v[0].as_str().and_then(|s| s.parse::<u64>().ok());
    let first = browser.until("the counter", &signal_value("Counter.Count"), |v| {
        count(v).is_some()
    });
    let later = browser.until(
        "the counter rising, highlighted",
        &signal_value("Counter.Count"),
        |v| count(v) > count(&first) && v[1] == true,
    );
    assert_eq!(later[2], false, "{later}");
    // The SLIO boards' answers to the panels' reads: registers by name.
    let register = browser.until(
        "SLIO 3's answer",
        &signal_value("SLIO3_Reply.Register"),
        |v| !v.is_null(),
    );
    assert!(
        [
            "DATA_INPUT",
            "ADC",
            "DATA_OUTPUT",
            "OUTPUT_ENABLE",
            "DPM1",
            "DPM2"
        ]
        .contains(&register[0].as_str().unwrap()),
        "{register}"
    );

    // A conversion of SLIO 3's potentiometer from its panel, once MoniCAN has initialised it
    // (its switches readable; its writes would come after otherwise): the reply's register
    // is the ADC, in volts; what DATA_INPUT said is still there, dimmed (not in that frame).
    browser.until(
        "SLIO 3 initialised by MoniCAN",
        &cell("3", "switches"),
        |v| v.as_str().is_some_and(|s| s != "-"),
    );
    browser.until(
        "SLIO 3's pins",
        &signal_value("SLIO3_Reply.In_P13_Select"),
        |v| !v.is_null(),
    );
    browser.click("#slio-3 button.adc2");
    browser.until("SLIO 3's ADC", &signal_value("SLIO3_Reply.Register"), |v| {
        v[0] == "ADC"
    });
    let adc = browser.script(&signal_value("SLIO3_Reply.ADC"));
    assert!(
        adc[0].as_str().is_some_and(|s| s.ends_with(" V")) && adc[2] == false,
        "{adc}"
    );
    let pins = browser.script(&signal_value("SLIO3_Reply.In_P13_Select"));
    assert_eq!(pins[2], true, "DATA_INPUT's pins dimmed: {pins}");
    // The updates carry the signals that changed; the rows stay in the database's order,
    // the ADC (heard last, defined last) at the end.
    let order = browser.script(
        "return [...document.querySelectorAll('#messages tbody[data-id=\"29D\"] tr[data-signal]')]\
         .map(r => [Number(r.dataset.position), r.dataset.signal])",
    );
    let order = order.as_array().unwrap();
    assert!(
        order
            .windows(2)
            .all(|w| w[0][0].as_u64() < w[1][0].as_u64()),
        "{order:?}"
    );
    assert_eq!(order.last().unwrap()[1], "SLIO3_Reply.ADC", "{order:?}");

    // A click on a signal's name plots it: the counter as a rising line, on an axis that
    // says its scale, over the whole window once the lab is older than it.
    browser.until("the lab 12 s old", PAGE_CLOCK, |v| {
        v.as_f64().is_some_and(|t| t > 12.0)
    });
    browser.click("#messages button.plot[data-signal=\"Counter.Count\"]");
    assert_eq!(
        browser.script("return document.getElementById('plotsignal').value"),
        "Counter.Count"
    );
    let points = browser.until(
        "the counter plotted",
        "const l = document.querySelector('#signalchart polyline.signal'); \
         return l ? l.getAttribute('points').split(' ').map(xy => xy.split(',').map(Number)) : []",
        // Every frame of the window: 20 a second.
        |v| v.as_array().is_some_and(|p| p.len() > 2 * 150),
    );
    let ys: Vec<f64> = points
        .as_array()
        .unwrap()
        .iter()
        .map(|xy| xy[1].as_f64().unwrap())
        .collect();
    // Higher values are drawn higher (smaller y): the line never goes down.
    assert!(ys.windows(2).all(|w| w[1] <= w[0]), "{points}");
    assert!(ys.last() < ys.first(), "{points}");
    let xs: Vec<f64> = points
        .as_array()
        .unwrap()
        .iter()
        .map(|xy| xy[0].as_f64().unwrap())
        .collect();
    assert!(
        xs[0] < 1.0 && xs[xs.len() - 1] > 599.0,
        "the whole window: {points}"
    );
    let caption =
        browser.script("return document.querySelector('#signalchart text.caption').textContent");
    assert!(
        caption
            .as_str()
            .is_some_and(|c| c.starts_with("Counter.Count over the last 10 s (scale 0 to ")),
        "{caption}"
    );
    // The page's series is the server's: the count's latest values, in order.
    let series = browser.script("return state.plot.points.map(p => p[1])");
    let values: Vec<f64> = series
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    assert!(values.windows(2).all(|w| w[1] > w[0]), "{series}");

    screenshot(&browser, "/screenshot", "lab-dashboard-signals.png");
    browser.script("document.getElementById('signals').scrollIntoView(); return null");
    let id = browser.find("#signals");
    screenshot(
        &browser,
        &format!("/element/{id}/screenshot"),
        "web-signals.png",
    );
    // SLIO 3's register file, its ADC reply the last.
    browser.script(
        "document.querySelector('#messages tbody[data-id=\"29D\"]').scrollIntoView(); return null",
    );
    let id = browser.find(".signaltable");
    screenshot(
        &browser,
        &format!("/element/{id}/screenshot"),
        "web-signals-slio.png",
    );
    // The page without JavaScript has them too, and draws the plot on the server.
    let base = dashboard.split("dashboard#").next().unwrap();
    browser.open(&format!("{base}signals?plot=Counter.Count&refresh=0"));
    let page = browser.script(
        "return [document.querySelector('tr[data-signal=\"Engine.EngineSpeed\"] td.value').textContent, \
         document.querySelector('svg polyline.signal').getAttribute('points').split(' ').length]",
    );
    assert_eq!(page[0], "4000 rpm", "{page}");
    assert!(page[1].as_u64() > Some(2 * 150), "{page}");
    screenshot(&browser, "/screenshot", "web-signals-page.png");
    browser.pages_work_under_the_policy(
        base,
        &["dashboard", "signals", "signals?plot=Counter.Count"],
    );
}

/// Issue 26 (deliverable 4): the lab's switches and potentiometer from the devices panel. A
/// click flips switch 2 of SLIO 3 on the board; the panel reads the SLIO's pins again and
/// shows the switch as the SLIO reads it. The potentiometer turned to 2.5 V converts as
/// 512 (2.502 V). Meanwhile a `buslab dump` of the bus sees every frame sent to a SLIO with
/// 3 bytes (the panel's reads were 1-byte frames the SLIO ignores).
#[test]
fn the_lab_dashboard_flips_a_switch_and_turns_the_potentiometer() {
    if !tools() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let lab_dir = dir.path().join("lab");
    let mut child = Command::new(env!("CARGO_BIN_EXE_buslab"))
        .args([
            "lab",
            "--no-devices",
            "--listen",
            "127.0.0.1:0",
            "--web",
            "127.0.0.1:0",
        ])
        .arg("--dir")
        .arg(&lab_dir)
        .env_remove("BUSLAB_BUS")
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let stderr = child.stderr.take().unwrap();
    let _lab = Kill(child);
    let mut lines = BufReader::new(stderr).lines();
    let dashboard = loop {
        let line = lines.next().expect("the banner ended").unwrap();
        if let Some(url) = line.trim().strip_prefix("dashboard:") {
            break url.trim().to_string();
        }
    };
    std::thread::spawn(move || lines.for_each(drop));
    let bus_file = lab_dir.join("bus");
    let deadline = Instant::now() + HANG;
    let url = loop {
        if let Ok(text) = std::fs::read_to_string(&bus_file)
            && text.ends_with('\n')
        {
            break text.trim().to_string();
        }
        assert!(
            Instant::now() < deadline,
            "the lab never wrote {}",
            bus_file.display()
        );
        std::thread::sleep(Duration::from_millis(20));
    };
    // Every frame on the bus while the page is open.
    let mut dump = Command::new(env!("CARGO_BIN_EXE_buslab"))
        .args(["dump", "-L", "--bus", &url])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let captured = std::sync::Arc::new(std::sync::Mutex::new(Vec::<String>::new()));
    let into = captured.clone();
    let dump_lines = BufReader::new(dump.stdout.take().unwrap()).lines();
    let _dump = Kill(dump);
    std::thread::spawn(move || {
        for line in dump_lines.map_while(Result::ok) {
            if let Some(frame) = line.split_whitespace().nth(2) {
                into.lock().unwrap().push(frame.to_string());
            }
        }
    });

    let browser = Browser::start(&dir.path().join("profile"));
    browser.open(&dashboard);
    browser.until(
        "SLIO 3's switches as the SLIO reads them",
        &cell("3", "switches"),
        |v| v.as_str() == Some("0 0 0 0"),
    );
    browser.until("SLIO 3's board", &cell("3", "bench"), |v| {
        v.as_str()
            .is_some_and(|s| s.starts_with("switches 0 0 0 0"))
    });
    browser.click("#slio-3 button.switch[data-switch=\"2\"]");
    browser.until("the switch on the board", &cell("3", "bench"), |v| {
        v.as_str()
            .is_some_and(|s| s.starts_with("switches 0 0 1 0"))
    });
    browser.until(
        "the switch as SLIO 3 reads it",
        &cell("3", "switches"),
        |v| v.as_str() == Some("0 0 1 0"),
    );
    let label = browser.script(
        "return document.querySelector('#slio-3 button.switch[data-switch=\"2\"]').textContent",
    );
    assert_eq!(label, "S2 on");
    // The potentiometer: turned, then converted by the SLIO.
    browser.script("document.querySelector('#slio-3 input.pot').value = '2.5'; return null");
    browser.click("#slio-3 button.pot");
    browser.until("the potentiometer on the board", &cell("3", "bench"), |v| {
        v.as_str()
            .is_some_and(|s| s.ends_with("potentiometer 2.500 V"))
    });
    browser.click("#slio-3 button.adc2");
    browser.until("SLIO 3's ADC2", &cell("3", "adc2"), |v| {
        v.as_str() == Some("512 (2.502 V)")
    });
    // The panel's other frames: a read of the pins, an LED. First MoniCAN's initialisation
    // of SLIO A (P13 high: its switches readable), which the LED's write keeps; on a loaded
    // machine it can come after SLIO 3's.
    browser.until(
        "SLIO A initialised by MoniCAN (its switches readable)",
        &cell("A", "switches"),
        |v| v.as_str().is_some_and(|s| s != "-"),
    );
    let answered = browser.script(&cell("A", "replies"));
    browser.click("#slio-A button.read");
    browser.until("SLIO A's answer", &cell("A", "replies"), |v| *v != answered);
    browser.click("#slio-A button.led[data-pin=\"9\"]");
    browser.until("SLIO A's LED P9 on", &led("A", 9), |v| {
        *v == json!([true, false])
    });
    let id = browser.find("#slio-3");
    screenshot(
        &browser,
        &format!("/element/{id}/screenshot"),
        "web-slio-board.png",
    );
    browser.pages_work_under_the_policy(
        dashboard.split("dashboard#").next().unwrap(),
        &["devices", "dashboard"],
    );
    // Every frame sent to a SLIO while the page was open: 3 bytes (`29C#000000`).
    let frames = captured.lock().unwrap().clone();
    let to_slios: Vec<&String> = frames
        .iter()
        .filter(|f| {
            let id = f.split('#').next().unwrap_or("");
            id.len() == 3
                && u16::from_str_radix(id, 16).is_ok_and(|raw| {
                    buslab_slio::SlioId::from_id(buslab_can::Id::standard(raw).unwrap())
                        .is_some_and(|(_, d)| d == buslab_slio::Direction::ToSlio)
                })
        })
        .collect();
    for want in ["29C#000000", "394#000000", "394#032200"] {
        assert!(
            to_slios.iter().any(|f| *f == want),
            "the panel's {want}: {to_slios:?}"
        );
    }
    for f in &to_slios {
        assert_eq!(f.len(), "29C#000000".len(), "{f} is not a 3-byte frame");
    }
    eprintln!(
        "{} frames on the bus, {} to the SLIOs, all of 3 bytes",
        frames.len(),
        to_slios.len()
    );
}
