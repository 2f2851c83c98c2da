//! The CAN WebServer: pages rendered on the server that work without JavaScript (they reload
//! themselves every few seconds unless `?refresh=0`), and the live dashboard's files.

use std::fmt::Write as _;

use axum::extract::{Path, Query, State};
use axum::http::{HeaderValue, StatusCode, header};
use axum::response::{Html, IntoResponse, Response};
use buslab_view::{Cursor, Delta, ErrorSample, IdRow, LoadSample, LogFilter, NodeView};
use serde::Deserialize;

use crate::routes::{ApiError, App};

const STYLE: &str = include_str!("assets/style.css");
const DASHBOARD: &str = include_str!("assets/dashboard.html");
const DASHBOARD_JS: &str = include_str!("assets/dashboard.js");
const DEVICES_JS: &str = include_str!("assets/devices.js");

/// Frames on the overview.
const OVERVIEW_FRAMES: usize = 20;
/// Frames on the frames page at most.
const MAX_FRAMES: usize = 1000;

#[derive(Debug, Deserialize)]
pub struct PageQuery {
    /// Seconds between reloads; 0: never.
    refresh: Option<u32>,
    /// A candump filter for the frames page (`123`, `120:7F0`, `300~700`, comma-separated).
    filter: Option<String>,
    /// How many frames the frames page shows.
    n: Option<usize>,
}

/// The whole view now, with the newest `frames` frames passing `filter`.
fn snapshot(app: &App, filter: &LogFilter, frames: usize) -> Delta {
    let now = app.hub.now();
    app.hub.view().delta(&Cursor::start(), now, filter, frames)
}

pub async fn overview(State(app): State<App>, Query(q): Query<PageQuery>) -> Html<String> {
    let d = snapshot(&app, &LogFilter::all(), OVERVIEW_FRAMES);
    let mut b = String::new();
    bus_summary(&mut b, &app, &d);
    b.push_str("<h2>Nodes</h2>");
    nodes_table(&mut b, &d.nodes, app.hub.has_admin);
    b.push_str("<h2>Bus load</h2>");
    load_chart(&mut b, &d.load);
    let _ = write!(
        b,
        "<h2>Last frames</h2><p><a href=\"/frames\">more, with a filter</a></p>"
    );
    frames_table(&mut b, &d);
    b.push_str("<h2>Per ID</h2>");
    ids_table(&mut b, &d.ids);
    layout("bus", q.refresh.unwrap_or(2), &b)
}

pub async fn ids(State(app): State<App>, Query(q): Query<PageQuery>) -> Html<String> {
    let d = snapshot(&app, &LogFilter::all(), 0);
    let mut b = String::new();
    let _ = write!(
        b,
        "<h2>Per ID</h2><p>{} IDs; bytes that changed in the last second are marked.</p>",
        d.ids.len()
    );
    if d.ids_dropped > 0 {
        let _ = write!(
            b,
            "<p class=warn>{} frames of further IDs were counted only (the table is full).</p>",
            d.ids_dropped
        );
    }
    ids_table(&mut b, &d.ids);
    layout("per ID", q.refresh.unwrap_or(2), &b)
}

pub async fn frames(
    State(app): State<App>,
    Query(q): Query<PageQuery>,
) -> Result<Html<String>, ApiError> {
    let text = q.filter.clone().unwrap_or_default();
    let filter: LogFilter = text
        .parse()
        .map_err(|e: buslab_view::FilterError| ApiError::bad_request(e.to_string()))?;
    let n = q.n.unwrap_or(100);
    if n == 0 || n > MAX_FRAMES {
        return Err(ApiError::bad_request(format!(
            "n={n}: show 1 to {MAX_FRAMES} frames"
        )));
    }
    let d = snapshot(&app, &filter, n);
    let mut b = String::new();
    let _ = write!(
        b,
        "<h2>Frames</h2><form method=get action=/frames>\
         <label>filter <input name=filter value=\"{}\" placeholder=\"123, 120:7F0, 300~700\"></label> \
         <label>frames <input name=n type=number min=1 max={MAX_FRAMES} value={n}></label> \
         <input type=hidden name=refresh value={}> <button>show</button></form>",
        esc(&text),
        q.refresh.unwrap_or(2)
    );
    frames_table(&mut b, &d);
    Ok(layout("frames", q.refresh.unwrap_or(2), &b))
}

pub async fn node(
    State(app): State<App>,
    Path(number): Path<u32>,
    Query(q): Query<PageQuery>,
) -> Result<Html<String>, ApiError> {
    let d = snapshot(&app, &LogFilter::all(), 0);
    let Some(n) = d.nodes.iter().find(|n| n.number == number) else {
        return Err(ApiError::new(
            StatusCode::NOT_FOUND,
            format!("node {number} is not on the bus (see / for the nodes)"),
        ));
    };
    let mut b = String::new();
    let _ = write!(b, "<h2>Node {} {}</h2>", n.number, esc(&n.name));
    nodes_table(&mut b, std::slice::from_ref(n), true);
    let _ = write!(
        b,
        "<dl><dt>STATUS</dt><dd>{}</dd><dt>ALC</dt><dd>{}</dd><dt>ECC</dt><dd>{}</dd></dl>",
        esc(n.status.as_deref().unwrap_or("-")),
        esc(n.alc.as_deref().unwrap_or("-")),
        esc(n.ecc.as_deref().unwrap_or("-"))
    );
    b.push_str("<h3>TEC and REC over time</h3>");
    history_chart(&mut b, &n.history);
    Ok(layout(
        &format!("node {number}"),
        q.refresh.unwrap_or(2),
        &b,
    ))
}

pub async fn dashboard() -> Html<&'static str> {
    Html(DASHBOARD)
}

pub async fn asset(Path(name): Path<String>) -> Result<Response, ApiError> {
    let (body, kind) = match name.as_str() {
        "style.css" => (STYLE, "text/css; charset=utf-8"),
        "dashboard.js" => (DASHBOARD_JS, "text/javascript; charset=utf-8"),
        "devices.js" => (DEVICES_JS, "text/javascript; charset=utf-8"),
        _ => {
            return Err(ApiError::new(
                StatusCode::NOT_FOUND,
                format!("no asset {name:?}: there are style.css, dashboard.js and devices.js"),
            ));
        }
    };
    let mut r = body.into_response();
    r.headers_mut()
        .insert(header::CONTENT_TYPE, HeaderValue::from_static(kind));
    Ok(r)
}

fn layout(title: &str, refresh: u32, body: &str) -> Html<String> {
    let reload = if refresh > 0 {
        format!("<meta http-equiv=refresh content={refresh}>")
    } else {
        String::new()
    };
    let toggle = if refresh > 0 {
        "<a href=\"?refresh=0\">stop reloading</a>"
    } else {
        "<a href=\"?refresh=2\">reload every 2 s</a>"
    };
    Html(format!(
        "<!doctype html><html lang=en><head><meta charset=utf-8>{reload}\
         <title>buslab: {}</title><link rel=stylesheet href=/assets/style.css></head><body>\
         <nav><b>buslab</b> <a href=/>bus</a> <a href=/ids>per ID</a> <a href=/frames>frames</a> <a href=/devices>devices</a> <a href=/dashboard>live dashboard</a> <span class=right>{toggle}</span></nav>\
         <main>{body}</main></body></html>",
        esc(title)
    ))
}

fn bus_summary(b: &mut String, app: &App, d: &Delta) {
    let load = d
        .load
        .last()
        .and_then(|l| l.percent)
        .map_or("unknown".to_string(), |p| format!("{p:.1} %"));
    let bitrate = d
        .bitrate
        .map_or("unknown".to_string(), |r| format!("{r} bit/s"));
    let _ = write!(
        b,
        "<h2>Bus</h2><table class=kv><tr><th>channel</th><td>{}</td></tr>\
         <tr><th>bit rate</th><td>{bitrate}</td></tr><tr><th>load</th><td id=load>{load}</td></tr>\
         <tr><th>frames</th><td id=frames>{}</td></tr><tr><th>frames/s</th><td>{}</td></tr></table>",
        esc(&app.hub.channel),
        d.frames,
        d.frames_per_s
    );
    if let Some(why) = app.hub.failure() {
        let _ = write!(
            b,
            "<p class=warn>The bus stopped: {} (the pages show its last state).</p>",
            esc(&why)
        );
    }
}

fn nodes_table(b: &mut String, nodes: &[NodeView], has_admin: bool) {
    if nodes.is_empty() {
        b.push_str(if has_admin {
            "<p>No other node on the bus.</p>"
        } else {
            "<p>This bus does not tell of its nodes (only a buslab bus does).</p>"
        });
        return;
    }
    b.push_str(
        "<table class=nodes><tr><th>node</th><th>name</th><th>state</th><th>TEC</th><th>REC</th>\
         <th>STATUS</th><th>sent</th><th>received</th><th>bus errors</th><th>bus-off</th>\
         <th>arbitration lost</th></tr>",
    );
    for n in nodes {
        let _ = write!(
            b,
            "<tr class=\"{}\"><td><a href=/nodes/{}>{}</a></td><td>{}</td><td>{}</td><td>{}</td>\
             <td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
            state_class(&n.state),
            n.number,
            n.number,
            esc(&n.name),
            esc(&n.state),
            opt(n.tec),
            opt(n.rec),
            n.sr.map_or("-".to_string(), |sr| format!("0x{sr:02X}")),
            n.sent,
            n.received,
            n.bus_errors,
            n.bus_off,
            n.arbitration_lost
        );
    }
    b.push_str("</table>");
}

fn state_class(state: &str) -> &'static str {
    match state {
        "error-passive" => "passive",
        "bus-off" => "busoff",
        _ => "active",
    }
}

fn opt(v: Option<u8>) -> String {
    v.map_or("-".to_string(), |v| v.to_string())
}

fn frames_table(b: &mut String, d: &Delta) {
    if d.log.is_empty() {
        b.push_str("<p>No frames yet.</p>");
        return;
    }
    b.push_str("<table class=frames><tr><th>time (s)</th><th>frame</th></tr>");
    for e in d.log.iter().rev() {
        let _ = write!(
            b,
            "<tr><td>{:.6}</td><td><code>{}</code></td></tr>",
            e.time,
            esc(&e.frame)
        );
    }
    b.push_str("</table>");
}

fn ids_table(b: &mut String, rows: &[IdRow]) {
    if rows.is_empty() {
        b.push_str("<p>No frames yet.</p>");
        return;
    }
    b.push_str(
        "<table class=ids><tr><th>ID</th><th>count</th><th>period (ms)</th><th>DLC</th>\
         <th>data</th><th>age (ms)</th></tr>",
    );
    for r in rows {
        let period = r.period_ms.map_or("-".to_string(), |p| format!("{p:.1}"));
        let _ = write!(
            b,
            "<tr><td><code>{}</code></td><td>{}</td><td>{period}</td><td>{}</td><td><code>",
            r.id, r.count, r.dlc
        );
        if r.remote {
            b.push_str("remote");
        }
        for (i, pair) in r.data.as_bytes().chunks(2).enumerate() {
            let byte = std::str::from_utf8(pair).unwrap_or("??");
            if r.changed & (1 << i) != 0 {
                let _ = write!(b, "<mark>{byte}</mark> ");
            } else {
                let _ = write!(b, "{byte} ");
            }
        }
        let _ = write!(b, "</code></td><td>{}</td></tr>", r.age_ms);
    }
    b.push_str("</table>");
}

/// The load (or, when the bus's load is unknown, frames per second) as an SVG line.
fn load_chart(b: &mut String, load: &[LoadSample]) {
    if load.len() < 2 {
        b.push_str("<p>Measuring (one point a second).</p>");
        return;
    }
    let percent = load.iter().all(|l| l.percent.is_some());
    let values: Vec<(f64, f64)> = load
        .iter()
        .map(|l| (l.t, l.percent.unwrap_or(l.frames as f64)))
        .collect();
    let top = if percent {
        100.0
    } else {
        values.iter().map(|v| v.1).fold(1.0, f64::max)
    };
    let unit = if percent { "% load" } else { "frames/s" };
    line_chart(b, &[("load", &values)], top, unit, &[]);
}

fn history_chart(b: &mut String, history: &[ErrorSample]) {
    if history.len() < 2 {
        b.push_str("<p>No history yet (this bus may not report error counters).</p>");
        return;
    }
    let tec: Vec<(f64, f64)> = history.iter().map(|s| (s.t, f64::from(s.tec))).collect();
    let rec: Vec<(f64, f64)> = history.iter().map(|s| (s.t, f64::from(s.rec))).collect();
    line_chart(
        b,
        &[("tec", &tec), ("rec", &rec)],
        256.0,
        "TEC (red), REC (blue)",
        &[(96.0, "warning 96"), (128.0, "passive 128")],
    );
}

/// A small SVG line chart: `series` as (x, y) points, y from 0 to `top`, with labelled
/// horizontal rules.
fn line_chart(
    b: &mut String,
    series: &[(&str, &[(f64, f64)])],
    top: f64,
    unit: &str,
    rules: &[(f64, &str)],
) {
    const W: f64 = 600.0;
    const H: f64 = 160.0;
    let xs = series.iter().flat_map(|s| s.1.iter().map(|p| p.0));
    let (x0, x1) = xs.fold((f64::MAX, f64::MIN), |(lo, hi), x| (lo.min(x), hi.max(x)));
    let span = (x1 - x0).max(1e-9);
    let px = |x: f64| (x - x0) / span * W;
    let py = |y: f64| H - (y / top).clamp(0.0, 1.0) * H;
    let _ = write!(
        b,
        "<svg class=chart viewBox=\"-40 -10 {} {}\" width=640 height=190 role=img \
         aria-label=\"{}\"><rect x=0 y=0 width={W} height={H} class=frame />",
        W + 50.0,
        H + 30.0,
        esc(unit)
    );
    for (y, label) in rules {
        let _ = write!(
            b,
            "<line class=rule x1=0 x2={W} y1={0:.1} y2={0:.1} /><text x=4 y={1:.1}>{2}</text>",
            py(*y),
            py(*y) - 2.0,
            esc(label)
        );
    }
    let _ = write!(
        b,
        "<text x=-38 y=10>{top:.0}</text><text x=-38 y={H}>0</text>\
         <text x=0 y={}>{:.0} s</text><text x={} y={}>{:.0} s</text><text x=200 y={}>{}</text>",
        H + 16.0,
        x0,
        W - 40.0,
        H + 16.0,
        x1,
        H + 16.0,
        esc(unit)
    );
    for (name, points) in series {
        let mut d = String::new();
        for (x, y) in points.iter() {
            let _ = write!(d, "{:.1},{:.1} ", px(*x), py(*y));
        }
        let _ = write!(b, "<polyline class={name} points=\"{d}\" />");
    }
    b.push_str("</svg>");
}

/// HTML-escapes text (node names and filters come from outside).
pub fn esc(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            c => out.push(c),
        }
    }
    out
}

/// `/devices`: the bench's device panels without JavaScript (read-only: a write needs the
/// token in a header, which only the dashboard's script sends).
pub async fn devices(State(app): State<App>, Query(q): Query<PageQuery>) -> Html<String> {
    let v = app.hub.devices.view();
    let mut b = String::new();
    b.push_str("<h2>Devices</h2>");
    if v.slio.is_empty() && v.zelle.is_none() && v.cpu196.is_none() {
        b.push_str("<p>This server shows the bus only (`buslab lab` adds its devices).</p>");
    }
    if !v.slio.is_empty() {
        b.push_str(
            "<h3>SLIO boards</h3><p>What each SLIO confirmed; set the LEDs from the \
             <a href=/dashboard>live dashboard</a>.</p><table class=slio><tr><th>SLIO</th>\
             <th>IDs</th><th>LEDs P7 P8 P9 P11 P12</th><th>switches P0..P3</th><th>ADC1</th>\
             <th>ADC2</th><th>DPM1</th><th>DPM2</th><th>status</th></tr>",
        );
        for s in &v.slio {
            let leds: String = s
                .leds
                .iter()
                .map(|l| match l.on {
                    Some(true) => "<span class=\"led on\">●</span>",
                    Some(false) => "<span class=led>○</span>",
                    None => "<span class=led>?</span>",
                })
                .collect();
            let switches = s.switches.map_or("-".to_string(), |sw| {
                sw.iter().map(|&on| if on { '1' } else { '0' }).collect()
            });
            let analog = |a: &Option<crate::devices::slio::Analog>| {
                a.map_or("-".to_string(), |a| {
                    format!("{} ({:.3} V)", a.code, a.volts)
                })
            };
            let _ = write!(
                b,
                "<tr><td>{}</td><td>{}/{}</td><td>{leds}</td><td><code>{switches}</code></td>\
                 <td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
                esc(&s.slio),
                s.command_id,
                s.reply_id,
                analog(&s.adc[0]),
                analog(&s.adc[1]),
                analog(&s.dpm[0]),
                analog(&s.dpm[1]),
                esc(s
                    .status
                    .as_deref()
                    .unwrap_or(if s.heard { "-" } else { "not heard yet" }))
            );
        }
        b.push_str("</table>");
    }
    if let Some(z) = &v.zelle {
        let _ = write!(
            b,
            "<h3>ZELLE cell</h3><p>on <code>{}</code>: {}</p>",
            esc(&z.port),
            esc(z.busy.as_deref().unwrap_or("idle"))
        );
        if let Some(e) = &z.error {
            let _ = write!(b, "<p class=warn>{}</p>", esc(e));
        }
        if z.series.iter().any(|s| s.len() > 1) {
            let named: Vec<(String, &[(f64, f64)])> = z
                .series
                .iter()
                .enumerate()
                .map(|(k, s)| (format!("ch{}", k % 4 + 1), s.as_slice()))
                .collect();
            let series: Vec<(&str, &[(f64, f64)])> =
                named.iter().map(|(n, s)| (n.as_str(), *s)).collect();
            line_chart(&mut b, &series, 5.0, "volts over time", &[]);
        }
        if let Some(ram) = &z.ram {
            let _ = write!(b, "<h4>RAM from 0800h</h4><pre>{}</pre>", esc(ram));
        }
    }
    if let Some(c) = &v.cpu196 {
        let _ = write!(
            b,
            "<h3>CPU196 board</h3><p>on <code>{}</code>: {}</p><pre>{}</pre>",
            esc(&c.port),
            esc(c.running.as_deref().unwrap_or("not streaming")),
            esc(c.identity.as_deref().unwrap_or("identity not read yet"))
        );
        if let Some(e) = &c.error {
            let _ = write!(b, "<p class=warn>{}</p>", esc(e));
        }
        let series: Vec<(&str, &[(f64, f64)])> = c
            .series
            .iter()
            .take(4)
            .enumerate()
            .map(|(k, (_, s))| (["ch1", "ch2", "ch3", "ch4"][k], s.as_slice()))
            .collect();
        if series.iter().any(|s| s.1.len() > 1) {
            line_chart(&mut b, &series, 5.0, "A/D stream, volts", &[]);
        }
        if !c.text.is_empty() {
            let _ = write!(b, "<h4>THREAD text</h4><pre>{}</pre>", esc(&c.text));
        }
    }
    layout("devices", q.refresh.unwrap_or(2), &b)
}
