//! The CAN WebServer: pages rendered on the server that work without JavaScript (they reload
//! themselves every few seconds unless `?refresh=0`), and the live dashboard's files.

use std::fmt::Write as _;

use axum::extract::{Path, Query, State};
use axum::http::{HeaderValue, StatusCode, header};
use axum::response::{Html, IntoResponse, Response};
use std::time::Duration;

use buslab_bus::Timestamp;
use buslab_view::{Cursor, Delta, ErrorSample, IdRow, LogEntry, LogFilter, MessageRow, NodeView};
use serde::Deserialize;

use crate::app::App;
use crate::chart::{self, Band, Chart, Series, TimeAxis, nice_top};
use crate::error::ApiError;
use crate::html::esc;
use crate::request::{DEFAULT_WINDOW, MAX_WINDOW, plot_name};

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
    /// Seconds the time charts show (60 unless given, at most 600).
    window: Option<u64>,
    /// The signal the signals page plots, `MESSAGE.SIGNAL`.
    plot: Option<String>,
}

impl PageQuery {
    fn window(&self) -> Result<Duration, ApiError> {
        match self.window {
            None => Ok(DEFAULT_WINDOW),
            Some(s) if (1..=MAX_WINDOW.as_secs()).contains(&s) => Ok(Duration::from_secs(s)),
            Some(s) => Err(ApiError::bad_request(format!(
                "window={s}: the charts show from 1 to {} seconds",
                MAX_WINDOW.as_secs()
            ))),
        }
    }
}

/// The whole view now, with the newest `frames` frames passing `filter` and the charts'
/// `window`.
fn snapshot(app: &App, filter: &LogFilter, frames: usize, window: Duration) -> Delta {
    let now = app.hub.now();
    app.hub
        .view()
        .delta_within(&Cursor::start(), now, filter, frames, window)
}

pub async fn overview(
    State(app): State<App>,
    Query(q): Query<PageQuery>,
) -> Result<Html<String>, ApiError> {
    let window = q.window()?;
    let d = snapshot(&app, &LogFilter::all(), OVERVIEW_FRAMES, window);
    let mut b = String::new();
    bus_summary(&mut b, &app, &d);
    if let Some(join) = &app.join {
        join_table(&mut b, &join.report());
    }
    b.push_str("<h2>Nodes</h2>");
    nodes_table(&mut b, &d.nodes, app.hub.has_admin);
    b.push_str("<h2>Bus load</h2>");
    load_chart(&mut b, &d, window);
    let _ = write!(
        b,
        "<h2>Last frames</h2><p><a href=\"/frames\">more, with a filter</a></p>"
    );
    frames_table(&mut b, &d);
    b.push_str("<h2>Per ID</h2>");
    ids_table(&mut b, &d.ids);
    Ok(layout("bus", q.refresh.unwrap_or(2), &b))
}

pub async fn ids(State(app): State<App>, Query(q): Query<PageQuery>) -> Html<String> {
    let d = snapshot(&app, &LogFilter::all(), 0, DEFAULT_WINDOW);
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
    let d = snapshot(&app, &filter, n, DEFAULT_WINDOW);
    let mut b = String::new();
    let _ = write!(
        b,
        "<h2>Frames</h2><form method=get action=/frames>\
         <label>filter <input name=filter value=\"{}\" placeholder=\"123, 120:7F0, 300~700, #FFFFFFFF\"></label> \
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
    let window = q.window()?;
    let d = snapshot(&app, &LogFilter::all(), 0, window);
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
    history_chart(&mut b, &d, &n.history, window);
    Ok(layout(
        &format!("node {number}"),
        q.refresh.unwrap_or(2),
        &b,
    ))
}

/// `/signals`: with a DBC database, each message seen with its signals' latest values (marked
/// when they changed in the last second, dimmed when the last frame did not carry them), and
/// with `?plot=MESSAGE.SIGNAL` that signal over the window, as steps.
pub async fn signals(
    State(app): State<App>,
    Query(q): Query<PageQuery>,
) -> Result<Html<String>, ApiError> {
    let window = q.window()?;
    let plot = plot_name(q.plot.as_deref())?;
    let refresh = q.refresh.unwrap_or(2);
    let now = app.hub.now();
    let (rows, series, size) = {
        let view = app.hub.view();
        let Some(size) = view.database().map(|db| db.messages().len()) else {
            let b = "<h2>Signals</h2><p>No DBC database: start <code>buslab web</code> with                      <code>--dbc FILE</code> (<code>buslab lab</code> has its own).</p>";
            return Ok(layout("signals", refresh, b));
        };
        let series = match plot.as_deref() {
            None => None,
            Some(name) => {
                let key = view
                    .signal(name)
                    .map_err(|e| ApiError::bad_request(format!("plot: {e}")))?;
                Some(view.series(&key, &Cursor::start(), now, window))
            }
        };
        (
            view.messages_page(now, 0, view.message_count()),
            series,
            size,
        )
    };
    let t = now.as_secs_f64();
    let mut b = String::new();
    let _ = write!(
        b,
        "<h2>Signals</h2><p>{} of the database's {size} messages seen; values that changed in          the last second are marked, those the last frame did not carry (another multiplexed          branch) are grey. A signal's name plots it.</p>",
        rows.len()
    );
    if let Some(series) = &series {
        signal_chart(&mut b, series, t, window);
    }
    let link = |signal: &str| {
        format!(
            "/signals?plot={}&amp;window={}&amp;refresh={refresh}",
            url_part(signal),
            window.as_secs()
        )
    };
    signals_table(&mut b, &rows, plot.as_deref(), link);
    Ok(layout("signals", refresh, &b))
}

/// A signal's values over the window as steps, on an axis that fits them.
fn signal_chart(b: &mut String, series: &buslab_view::Series, now: f64, window: Duration) {
    let from = now - window.as_secs_f64();
    let pieces = chart::steps(&series.points, now);
    let shown = pieces
        .iter()
        .flatten()
        .filter(|p| p.0 >= from)
        .map(|p| p.1)
        .chain(
            // The value held at the window's left edge.
            series
                .points
                .iter()
                .rev()
                .find(|p| p.0 < from && p.1.is_finite())
                .map(|p| p.1),
        );
    let (min, max) = shown.fold((0.0f64, 0.0f64), |(lo, hi), v| (lo.min(v), hi.max(v)));
    let (bottom, top) = chart::signal_axis(min, max);
    let name = format!("{}.{}", series.message, series.signal);
    let unit = if series.unit.is_empty() {
        String::new()
    } else {
        format!(" {}", series.unit)
    };
    let caption = if series.points.is_empty() {
        format!("{name}: no value yet")
    } else {
        format!(
            "{name} over the last {} (scale {} to {}{unit}; a value holds until a frame changes it)",
            chart::window_words(window),
            chart::label(bottom),
            chart::label(top)
        )
    };
    Chart {
        x: (from, now),
        axis: TimeAxis::Ago,
        bottom,
        top,
        unit: &series.unit,
        caption,
        rules: Vec::new(),
        bands: Vec::new(),
        series: vec![Series {
            class: "signal",
            pieces: pieces.iter().map(Vec::as_slice).collect(),
        }],
    }
    .render(b);
}

/// Each message's own row, then its signals' (the name a link from `link`).
fn signals_table(
    b: &mut String,
    rows: &[MessageRow],
    plotted: Option<&str>,
    link: impl Fn(&str) -> String,
) {
    b.push_str(
        "<table class=signals><tr><th>ID</th><th>message / signal</th><th>value</th>         <th>count</th><th>period (ms)</th></tr>",
    );
    for m in rows {
        let _ = write!(
            b,
            "<tr class=message><td>{}</td><td>{}</td><td></td><td>{}</td><td>{}</td></tr>",
            esc(&m.id),
            esc(&m.name),
            m.count,
            m.period_ms.map_or("-".into(), |p| format!("{p:.1}"))
        );
        for s in &m.signals {
            let full = format!("{}.{}", m.name, s.name);
            let mut class = if s.active { "" } else { "inactive" }.to_string();
            if plotted == Some(full.as_str()) {
                class += " plotted";
            }
            let value = esc(&s.text());
            let value = if s.changed {
                format!("<mark>{value}</mark>")
            } else {
                value
            };
            let _ = write!(
                b,
                "<tr class=\"{}\" data-signal=\"{}\"><td></td><td><a class=plot href=\"{}\">{}</a></td>\
                 <td class=value>{value}</td><td></td><td></td></tr>",
                class.trim(),
                esc(&full),
                link(&full),
                esc(&s.name)
            );
        }
    }
    b.push_str("</table>");
}

/// `text` safe in a URL's query (DBC names are identifiers; anything else is escaped).
fn url_part(text: &str) -> String {
    text.bytes()
        .map(|c| match c {
            b'A'..=b'Z' | b'a'..=b'z' | b'0'..=b'9' | b'_' | b'.' | b'-' => {
                char::from(c).to_string()
            }
            _ => format!("%{c:02X}"),
        })
        .collect()
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
         <nav><b>buslab</b> <a href=/>bus</a> <a href=/ids>per ID</a> <a href=/frames>frames</a> <a href=/signals>signals</a> <a href=/devices>devices</a> <a href=/dashboard>live dashboard</a> <span class=right>{toggle}</span></nav>\
         <main>{body}</main></body></html>",
        esc(title)
    ))
}

/// A joined bus's counters: what it sent, and per peer what came, was lost or came late.
fn join_table(b: &mut String, r: &buslab_join::JoinReport) {
    let _ = write!(
        b,
        "<h2>Joined buses</h2><p>this member {}: sent {}, unsent {}, echoes dropped {}, \
         garbage {}</p><table><tr><th>from</th><th>received</th><th>lost</th><th>reordered</th>\
         <th>duplicates</th><th>late</th></tr>",
        esc(&r.origin),
        r.sent,
        r.unsent,
        r.echoes,
        r.garbage
    );
    for p in &r.peers {
        let _ = write!(
            b,
            "<tr><td>{}</td><td>{}</td><td class={}>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
            esc(&p.origin),
            p.received,
            if p.lost > 0 { "warn" } else { "ok" },
            p.lost,
            p.reordered,
            p.duplicates,
            p.late
        );
    }
    b.push_str("</table>");
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
    b.push_str("<table class=frames><tr><th>time (UTC)</th><th>frame</th></tr>");
    for e in d.log.iter().rev() {
        let _ = write!(
            b,
            "<tr{}><td>{}</td><td>{}</td></tr>",
            if e.error.is_some() {
                " class=errorframe"
            } else {
                ""
            },
            time_of_day(e.at),
            entry_text(e)
        );
    }
    b.push_str("</table>");
}

/// A frame's time as a person reads it: the time of day (UTC) with milliseconds for a
/// wall-clock timestamp, seconds for a simulation's (which start near 0).
pub fn time_of_day(t: Timestamp) -> String {
    let (secs, micros) = t.secs_and_micros();
    // Before 2001: no wall clock, a simulation's own seconds.
    if !(1_000_000_000..100_000_000_000).contains(&secs) {
        return format!("{}.{:03} s", secs, micros / 1000);
    }
    let ms = (secs % 86_400) * 1000 + u64::from(micros / 1000);
    format!(
        "{:02}:{:02}:{:02}.{:03}",
        ms / 3_600_000,
        ms / 60_000 % 60,
        ms / 1000 % 60,
        ms % 1000
    )
}

/// A log entry as HTML: the frame, or an error frame with its classes in can-utils' words.
fn entry_text(e: &LogEntry) -> String {
    match &e.error {
        None => format!("<code>{}</code>", esc(&e.frame)),
        Some(err) => {
            let mut words = err.classes.join(", ");
            if let (Some(tec), Some(rec)) = (err.tec, err.rec) {
                let _ = write!(words, " (TEC {tec}, REC {rec})");
            }
            format!(
                "<code>{}</code> <b>ERRORFRAME</b> {}",
                esc(&e.frame),
                esc(&words)
            )
        }
    }
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

/// The load (or, when the bus's load is unknown, frames per second) over the window as an
/// SVG line, on an axis that fits it.
fn load_chart(b: &mut String, d: &Delta, window: Duration) {
    if d.load.len() < 2 {
        b.push_str("<p>Measuring (one point a second).</p>");
        return;
    }
    let percent = d.load.iter().all(|l| l.percent.is_some());
    let values: Vec<(f64, f64)> = d
        .load
        .iter()
        .map(|l| (l.t, l.percent.unwrap_or(l.frames as f64)))
        .collect();
    let max = values.iter().map(|v| v.1).fold(0.0, f64::max);
    let (top, unit, what) = if percent {
        (nice_top(max, 1.0).min(100.0), "%", "bus load")
    } else {
        (nice_top(max, 1.0), "frames/s", "frames per second")
    };
    Chart {
        x: (d.t - window.as_secs_f64(), d.t),
        axis: TimeAxis::Ago,
        bottom: 0.0,
        top,
        unit,
        caption: format!(
            "{what} over the last {} (scale 0 to {} {unit})",
            chart::window_words(window),
            chart::label(top)
        ),
        rules: Vec::new(),
        bands: fault_bands(d),
        series: vec![Series {
            class: "load",
            pieces: vec![&values],
        }],
    }
    .render(b);
}

/// The faults put on the wire from this server, as bands.
fn fault_bands(d: &Delta) -> Vec<Band> {
    d.faults
        .iter()
        .map(|f| Band {
            from: f.t,
            to: f.until.unwrap_or(d.t),
            label: f.label.clone(),
            what: f.what.clone(),
        })
        .collect()
}

fn history_chart(b: &mut String, d: &Delta, history: &[ErrorSample], window: Duration) {
    if history.len() < 2 {
        b.push_str("<p>No history yet (this bus may not report error counters).</p>");
        return;
    }
    let tec: Vec<(f64, f64)> = history.iter().map(|s| (s.t, f64::from(s.tec))).collect();
    let rec: Vec<(f64, f64)> = history.iter().map(|s| (s.t, f64::from(s.rec))).collect();
    let from = d.t - window.as_secs_f64();
    let max = history
        .iter()
        .filter(|s| s.t >= from)
        .map(|s| f64::from(s.tec.max(s.rec)))
        .fold(0.0, f64::max);
    let top = chart::counter_top(max);
    Chart {
        x: (from, d.t),
        axis: TimeAxis::Ago,
        bottom: 0.0,
        top,
        unit: "",
        caption: format!(
            "TEC (red) and REC (blue) over the last {} (scale 0 to {})",
            chart::window_words(window),
            chart::label(top)
        ),
        rules: vec![(96.0, "warning 96"), (128.0, "passive 128")],
        bands: fault_bands(d),
        series: vec![
            Series {
                class: "tec",
                pieces: vec![&tec],
            },
            Series {
                class: "rec",
                pieces: vec![&rec],
            },
        ],
    }
    .render(b);
}

/// Volts over the seconds measured, 0 to 5 V (the devices' range).
fn volts_chart(b: &mut String, series: Vec<Series<'_>>, caption: &str) {
    let xs = series
        .iter()
        .flat_map(|s| s.pieces.iter().flat_map(|p| p.iter().map(|v| v.0)));
    let (x0, x1) = xs.fold((f64::MAX, f64::MIN), |(lo, hi), x| (lo.min(x), hi.max(x)));
    Chart {
        x: (x0, x1.max(x0 + 1e-3)),
        axis: TimeAxis::Seconds,
        bottom: 0.0,
        top: 5.0,
        unit: "V",
        caption: caption.to_string(),
        rules: Vec::new(),
        bands: Vec::new(),
        series,
    }
    .render(b);
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
        if z.series.iter().flatten().map(Vec::len).sum::<usize>() > 1 {
            // Each block apart: the cell measured nothing between two.
            let series = z
                .series
                .iter()
                .enumerate()
                .map(|(k, blocks)| Series {
                    class: ["ch1", "ch2", "ch3", "ch4"][k % 4],
                    pieces: blocks.iter().map(Vec::as_slice).collect(),
                })
                .collect();
            volts_chart(&mut b, series, "volts over the seconds of the run");
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
        if c.series.iter().take(4).any(|(_, s)| s.len() > 1) {
            let series = c
                .series
                .iter()
                .take(4)
                .enumerate()
                .map(|(k, (_, s))| Series {
                    class: ["ch1", "ch2", "ch3", "ch4"][k],
                    pieces: vec![s.as_slice()],
                })
                .collect();
            volts_chart(&mut b, series, "A/D stream, volts");
        }
        if !c.text.is_empty() {
            let _ = write!(b, "<h4>THREAD text</h4><pre>{}</pre>", esc(&c.text));
        }
    }
    layout("devices", q.refresh.unwrap_or(2), &b)
}
