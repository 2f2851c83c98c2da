// buslab's live dashboard: applies the server's deltas (docs/web.md) to the page. Plain DOM,
// no library; text from the bus goes in as text, never as markup.
"use strict";

const MAX_LOG_LINES = 500;
const MAX_HISTORY = 4096;
const WINDOWS = [10, 30, 60, 300, 600]; // seconds the time charts can show
const $ = (id) => document.getElementById(id);

const state = {
  rows: new Map(),      // ID -> <tr>
  load: [],             // {t, percent, frames}
  history: new Map(),   // node number -> [{t, tec, rec, state}]
  names: new Map(),     // node number -> name
  faults: new Map(),    // mark id -> {t, until, label, what}
  now: 0,               // the server's view time of the last update (seconds)
  held: 0,
  lastTime: null,       // the time of the last log line (for "since the previous frame")
  source: null,
  messages: new Map(),  // DBC message ID -> <tbody> of its signals
  signalNames: new Set(), // "Message.Signal" offered in the plot's choice
  plot: null,           // the plotted signal: {message, signal, unit, points: [[t, value]]}
};

function text(tag, value, cls) {
  const el = document.createElement(tag);
  el.textContent = value;
  if (cls) el.className = cls;
  return el;
}

// Settings may come in the address's fragment (never sent to the server):
// #token=...&window=10&plot=Counter.Count
function fragment(name) {
  const m = location.hash.match(new RegExp("[#&]" + name + "=([A-Za-z0-9._-]+)"));
  return m ? m[1] : null;
}

// Seconds the time charts show.
function windowSeconds() {
  return Number($("window").value) || 60;
}

function connect() {
  if (state.source) state.source.close();
  const filter = $("filter").value.trim();
  const query = new URLSearchParams({ window: windowSeconds() });
  if (filter) query.set("filter", filter);
  const plot = $("plotsignal").value;
  if (plot) query.set("plot", plot);
  const url = "/api/events?" + query;
  $("filtererror").textContent = "";
  const source = new EventSource(url);
  state.source = source;
  source.addEventListener("update", (e) => apply(JSON.parse(e.data)));
  source.onopen = () => { $("link").textContent = "live"; };
  source.onerror = () => {
    $("link").textContent = "reconnecting";
    // A bad filter is refused with 400: say why (asked of the finite state, not the stream).
    fetch("/api/state?n=0&" + query).then((r) => r.ok ? null : r.text()).then((why) => {
      if (why) { $("filtererror").textContent = why; source.close(); }
    }).catch(() => {});
  };
}

function apply(d) {
  if (d.full) {
    state.rows.clear();
    $("ids").tBodies[0].replaceChildren();
    state.load = [];
    state.history.clear();
    state.faults.clear();
    state.lastTime = null;
    $("log").replaceChildren();
    for (const entry of state.messages.values()) entry.body.remove();
    state.messages.clear();
  }
  state.now = d.t;
  $("frames").textContent = d.frames;
  $("errorframes").textContent = d.error_frames;
  $("fps").textContent = d.frames_per_s;
  $("bitrate").textContent = d.bitrate ? d.bitrate + " bit/s" : "unknown";
  $("lost").textContent = d.lost;
  if (d.bus_failure) $("link").textContent = "bus stopped: " + d.bus_failure;
  for (const row of d.ids) applyRow(row);
  for (const s of d.load) state.load.push(s);
  state.load = inWindow(state.load);
  for (const f of d.faults) state.faults.set(f.id, f);
  const from = state.now - windowSeconds();
  for (const [id, f] of state.faults) if (f.until != null && f.until < from) state.faults.delete(id);
  const last = state.load[state.load.length - 1];
  if (last) $("load").textContent = last.percent == null ? "unknown" : last.percent.toFixed(1) + " %";
  drawLoad();
  applyNodes(d.nodes);
  appendLog(d.log, d.log_skipped);
  for (const m of d.messages || []) applyMessage(m);
  if (d.plot) applyPlot(d.plot);
  if (!$("signals").hidden) drawSignal();
  if (d.devices) applyDevices(d.devices);
}

// A DBC message's rows: its own (ID, name, count, period), then one per signal: the name (a
// button that plots it), the value (the label, or the number and its unit) marked when it
// changed lately, dimmed when its multiplexed branch was not in the last frame. An update
// carries the signals whose rows changed; rows are updated in place (a name clicked while its
// value changes stays the same button), a new one goes in its place in the database's order.
function applyMessage(m) {
  let entry = state.messages.get(m.id);
  if (!entry) {
    const body = document.createElement("tbody");
    body.dataset.id = m.id;
    const head = document.createElement("tr");
    head.className = "message";
    for (let i = 0; i < 5; i++) head.appendChild(document.createElement("td"));
    body.appendChild(head);
    entry = { body, head, rows: new Map() };
    state.messages.set(m.id, entry);
    const table = $("messages");
    const key = (id) => (id.length > 3 ? "1" : "0") + id.padStart(8, "0");
    const after = [...table.tBodies].find((b) => key(b.dataset.id) > key(m.id));
    table.insertBefore(body, after || null);
  }
  const c = entry.head.cells;
  c[0].textContent = m.id;
  c[1].textContent = m.name;
  c[3].textContent = m.count;
  c[4].textContent = m.period_ms == null ? "-" : m.period_ms.toFixed(1);
  const plotted = $("plotsignal").value;
  for (const s of m.signals) {
    const full = m.name + "." + s.name;
    let tr = entry.rows.get(s.name);
    if (!tr) {
      tr = document.createElement("tr");
      tr.dataset.signal = full;
      tr.dataset.position = s.position;
      tr.appendChild(document.createElement("td"));
      const name = text("button", s.name, "plot");
      name.type = "button";
      name.dataset.signal = full;
      name.title = "plot " + full;
      tr.appendChild(document.createElement("td")).appendChild(name);
      const cell = document.createElement("td");
      cell.className = "value";
      tr.appendChild(cell);
      tr.appendChild(document.createElement("td"));
      tr.appendChild(document.createElement("td"));
      // The rows are in the database's order: before the first one after it.
      const next = [...entry.body.rows].find((r) => Number(r.dataset.position) > s.position);
      entry.body.insertBefore(tr, next || null);
      entry.rows.set(s.name, tr);
      if (!state.signalNames.has(full)) {
        state.signalNames.add(full);
        const o = text("option", full);
        o.value = full;
        $("plotsignal").appendChild(o);
      }
    }
    tr.className = (s.active ? "" : "inactive") + (full === plotted ? " plotted" : "");
    const value = s.label != null ? s.label : s.number + (s.unit ? " " + s.unit : "");
    const cell = tr.cells[2];
    cell.title = "raw " + s.raw;
    cell.replaceChildren(s.changed ? text("mark", value) : document.createTextNode(value));
  }
}

// The plotted signal's values: all of the window in a whole update, new ones after.
function applyPlot(p) {
  if (p.full || !state.plot) state.plot = { message: p.message, signal: p.signal, unit: p.unit, points: [] };
  for (const point of p.points) state.plot.points.push(point);
  const from = state.now - windowSeconds();
  let first = state.plot.points.findIndex((q) => q[0] >= from);
  if (first < 0) first = state.plot.points.length;
  state.plot.points = state.plot.points.slice(Math.max(first - 1, 0)).slice(-MAX_HISTORY);
}

// The plotted signal as steps: each value holds until the next one (a signal's value is
// what its last frame said), the last one until now; a value that is no number breaks it.
function drawSignal() {
  const name = $("plotsignal").value;
  const from = state.now - windowSeconds();
  const p = name && state.plot && state.plot.message + "." + state.plot.signal === name ? state.plot : null;
  const points = p ? p.points : [];
  const pieces = [];
  let piece = [];
  let last = null;
  for (const [t, v] of points) {
    if (v == null) {
      if (piece.length) pieces.push(piece);
      piece = [];
      last = null;
      continue;
    }
    if (last != null) piece.push([t, last]);
    piece.push([t, v]);
    last = v;
  }
  if (last != null) piece.push([state.now, last]);
  if (piece.length) pieces.push(piece);
  const shown = pieces.flat().filter((q) => q[0] >= from).map((q) => q[1]);
  // The value held at the window's left edge counts too.
  const before = points.filter((q) => q[0] < from && q[1] != null).pop();
  if (before) shown.push(before[1]);
  const max = Math.max(0, ...shown), min = Math.min(0, ...shown);
  let top = max > 0 ? niceTop(max, 0) : 0;
  let bottom = min < 0 ? -niceTop(-min, 0) : 0;
  if (top === bottom) top = bottom + 1;
  const unit = p ? p.unit : "";
  const caption = p
    ? name + " over the last " + windowText() + " (scale " + label(bottom) + " to " + label(top) +
      (unit ? " " + unit : "") + "; a value holds until a frame changes it)"
    : "pick a signal to plot: click its name in the table";
  drawChart($("signalchart"), {
    x0: from, x1: state.now, axis: "ago", top, bottom, unit, caption, bands: faultBands(),
    series: [{ name: "signal", pieces }],
  });
}

// Plots `name` ("Message.Signal"): the server sends its values of the window again.
function plotSignal(name) {
  if (name && !state.signalNames.has(name)) {
    state.signalNames.add(name);
    const o = text("option", name);
    o.value = name;
    $("plotsignal").appendChild(o);
  }
  $("plotsignal").value = name;
  state.plot = null;
  for (const tr of document.querySelectorAll("#messages tr[data-signal]")) {
    tr.classList.toggle("plotted", tr.dataset.signal === name);
  }
  drawSignal();
  connect();
}

// The samples of the window and the one before it (where the line comes from).
function inWindow(samples) {
  const from = state.now - windowSeconds();
  let first = samples.findIndex((s) => s.t >= from);
  if (first < 0) first = samples.length;
  return samples.slice(Math.max(first - 1, 0));
}

function applyRow(r) {
  let tr = state.rows.get(r.id);
  if (!tr) {
    tr = document.createElement("tr");
    tr.dataset.id = r.id;
    for (let i = 0; i < 5; i++) tr.appendChild(document.createElement("td"));
    state.rows.set(r.id, tr);
    // Keep the table sorted by ID (the server sorts too: standard before extended, by value).
    const body = $("ids").tBodies[0];
    const key = (id) => (id.length > 3 ? "1" : "0") + id.padStart(8, "0");
    const after = [...body.rows].find((x) => key(x.dataset.id) > key(r.id));
    body.insertBefore(tr, after || null);
  }
  const c = tr.cells;
  c[0].replaceChildren(text("code", r.id));
  c[1].textContent = r.count;
  c[2].textContent = r.period_ms == null ? "-" : r.period_ms.toFixed(1);
  c[3].textContent = r.dlc;
  const data = document.createElement("code");
  if (r.remote) data.appendChild(document.createTextNode("remote "));
  for (let i = 0; i * 2 < r.data.length; i++) {
    const byte = r.data.substr(i * 2, 2);
    data.appendChild((r.changed >> i) & 1 ? text("mark", byte) : document.createTextNode(byte));
    data.appendChild(document.createTextNode(" "));
  }
  c[4].replaceChildren(data);
}

// A run of equal samples is kept as its first and last (as the server keeps it).
function keepSample(h, s) {
  const same = (a) => a && a.tec === s.tec && a.rec === s.rec && a.state === s.state;
  if (h.length >= 2 && same(h[h.length - 1]) && same(h[h.length - 2])) h[h.length - 1] = s;
  else h.push(s);
}

function applyNodes(nodes) {
  const body = $("nodes").tBodies[0];
  body.replaceChildren();
  const select = $("histnode");
  const chosen = select.value;
  for (const n of nodes) {
    state.names.set(n.number, n.name);
    const h = state.history.get(n.number) || [];
    for (const s of n.history) keepSample(h, s);
    state.history.set(n.number, inWindow(h).slice(-MAX_HISTORY));
    const tr = document.createElement("tr");
    tr.className = n.state === "error-passive" ? "passive" : n.state === "bus-off" ? "busoff" : "active";
    for (const v of [n.number, n.name, n.state, n.tec ?? "-", n.rec ?? "-", n.status ?? "-",
      n.alc ?? "-", n.ecc ?? "-", n.sent, n.received, n.bus_errors, n.bus_off]) {
      tr.appendChild(text("td", v));
    }
    body.appendChild(tr);
  }
  const numbers = nodes.map((n) => String(n.number));
  if ([...select.options].map((o) => o.value).join() !== numbers.join()) {
    select.replaceChildren(...nodes.map((n) => {
      const o = text("option", n.number + " " + n.name);
      o.value = n.number;
      return o;
    }));
    if (numbers.includes(chosen)) select.value = chosen;
    if (!$("faultnodes").value && nodes.length) $("faultnodes").value = nodes[0].name;
  }
  drawHistory();
}

// A frame's time as chosen: the time of day (local, with ms), the time since the previous
// frame shown (candump -t d), or the seconds as the bus gives them (candump -t a).
function timeText(t, previous) {
  const format = $("timefmt").value;
  if (format === "delta") return "+" + (previous == null ? 0 : t - previous).toFixed(6);
  if (format === "epoch" || t < 1e9) return t.toFixed(6);
  const d = new Date(t * 1000);
  const two = (n) => String(n).padStart(2, "0");
  return two(d.getHours()) + ":" + two(d.getMinutes()) + ":" + two(d.getSeconds()) + "." +
    String(d.getMilliseconds()).padStart(3, "0");
}

function logLine(e) {
  const line = document.createElement("div");
  line.dataset.time = e.time;
  line.appendChild(text("span", timeText(e.time, state.lastTime), "t"));
  state.lastTime = e.time;
  line.appendChild(document.createTextNode("  "));
  line.appendChild(text("code", e.frame));
  if (e.error) {
    // As `buslab dump -e` says it: the error classes in can-utils' words.
    line.className = "errorframe";
    let words = e.error.classes.join(", ");
    if (e.error.tec != null) words += " (TEC " + e.error.tec + ", REC " + e.error.rec + ")";
    line.appendChild(text("b", "  ERRORFRAME "));
    line.appendChild(text("span", words, "classes"));
  }
  return line;
}

function appendLog(entries, skipped) {
  if ($("pause").checked) {
    state.held += entries.length + skipped;
    $("held").textContent = state.held;
    return;
  }
  const log = $("log");
  const atBottom = log.scrollTop + log.clientHeight >= log.scrollHeight - 4;
  if (skipped) log.appendChild(text("div", "… " + skipped + " frames not shown (too many at once)"));
  for (const e of entries) log.appendChild(logLine(e));
  while (log.childNodes.length > MAX_LOG_LINES) log.removeChild(log.firstChild);
  if (atBottom) log.scrollTop = log.scrollHeight;
}

function retime() {
  let previous = null;
  for (const line of $("log").children) {
    const span = line.querySelector("span.t");
    if (!span) continue;
    const t = Number(line.dataset.time);
    span.textContent = timeText(t, previous);
    previous = t;
  }
}

const SVG = "http://www.w3.org/2000/svg";
function svg(tag, attrs, content) {
  const el = document.createElementNS(SVG, tag);
  for (const [k, v] of Object.entries(attrs)) el.setAttribute(k, v);
  if (content != null) el.textContent = content;
  return el;
}

// The top of a y axis for values up to max: 1, 2, 2.5 or 5 times a power of ten, at least
// floor (as the server's pages: crates/web/src/chart.rs).
function niceTop(max, floor) {
  if (!(max > floor)) return floor;
  const power = Math.pow(10, Math.floor(Math.log10(max)));
  for (const m of [1, 2, 2.5, 5, 10]) if (m * power >= max) return m * power;
  return 10 * power;
}

// The row of each band label ([x, characters]): the first of three where it does not run
// into the label before it.
function labelRows(labels) {
  const ends = [-Infinity, -Infinity, -Infinity];
  return labels.map(([x, chars], i) => {
    let row = ends.findIndex((end) => end < x);
    if (row < 0) row = i % 3;
    ends[row] = x + chars * 5.6 + 4;
    return row;
  });
}

// The top of a TEC/REC axis: the next power of two above max, from 8 to 256.
function counterTop(max) {
  let top = 8;
  while (top <= max && top < 256) top *= 2;
  return top;
}

function label(v) {
  return String(Math.round(v * 1000) / 1000);
}

function ago(seconds) {
  return seconds >= 120 ? "−" + label(seconds / 60) + " min" : "−" + label(seconds) + " s";
}

// The points of a piece inside [x0, x1], the line cut where it crosses an edge.
function clip(piece, x0, x1) {
  const at = (a, b, x) => [x, a[1] + (b[0] > a[0] ? (x - a[0]) / (b[0] - a[0]) : 0) * (b[1] - a[1])];
  const out = [];
  for (let i = 0; i < piece.length; i++) {
    const p = piece[i], q = i > 0 ? piece[i - 1] : null;
    if (p[0] < x0) continue;
    if (q && q[0] < x0) out.push(at(q, p, x0));
    if (p[0] > x1) {
      if (q && q[0] <= x1) out.push(at(q, p, x1));
      break;
    }
    out.push(p);
  }
  return out;
}

// A line chart as the server draws one (chart.rs): 600 x 160, x from x0 to x1 (axis "ago":
// a window ending now; "seconds": as they are), y from bottom (0 unless given) to top with its unit, labelled
// rules, shaded bands {from, to, label, what}, series {name, pieces}: a gap between two
// pieces stays a gap.
function drawChart(el, o) {
  const W = 600, H = 160;
  el.setAttribute("viewBox", "-50 -10 660 200");
  const span = Math.max(o.x1 - o.x0, 1e-9);
  const bottom = o.bottom || 0;
  const px = (x) => ((x - o.x0) / span) * W;
  const py = (y) => H - Math.min(Math.max((y - bottom) / (o.top - bottom), 0), 1) * H;
  const parts = [svg("rect", { x: 0, y: 0, width: W, height: H, class: "frame" })];
  const bands = (o.bands || []).map((b) => ({ ...b, a: Math.max(px(b.from), 0), z: Math.min(px(b.to), W) }))
    .filter((b) => b.z > b.a);
  // A label starts at its band, or further left where it would run out of the chart.
  for (const b of bands) b.x = Math.max(Math.min(b.a + 2, W - b.label.length * 5.6), 0);
  const rows = labelRows(bands.map((b) => [b.x, b.label.length]));
  bands.forEach((b, i) => {
    const band = svg("rect", { class: "band", x: b.a.toFixed(1), y: 0, width: (b.z - b.a).toFixed(1), height: H });
    band.appendChild(svg("title", {}, b.what));
    parts.push(band, svg("text", { class: "bandlabel", x: b.x.toFixed(1), y: 10 + 11 * rows[i] }, b.label));
  });
  for (const [y, name] of o.rules || []) {
    if (y > o.top) continue;
    parts.push(svg("line", { class: "rule", x1: 0, x2: W, y1: py(y), y2: py(y) }));
    parts.push(svg("text", { x: 4, y: py(y) - 2 }, name));
  }
  for (let k = 0; k <= 2; k++) {
    const v = bottom + (o.top - bottom) * k / 2;
    parts.push(svg("line", { class: "grid", x1: -4, x2: 0, y1: py(v), y2: py(v) }));
    parts.push(svg("text", { class: "ylabel", x: -6, y: py(v) + 4 }, label(v) + (o.unit ? " " + o.unit : "")));
  }
  for (let k = 0; k <= 4; k++) {
    const x = o.x0 + (k / 4) * (o.x1 - o.x0);
    const name = o.axis === "ago" ? (k === 4 ? "now" : ago(o.x1 - x)) : label(Math.round(x * 10) / 10) + " s";
    parts.push(svg("text", { class: "xlabel", x: (k / 4) * W, y: H + 14 }, name));
  }
  parts.push(svg("text", { class: "caption", x: W / 2, y: H + 28 }, o.caption));
  for (const s of o.series) {
    for (const piece of s.pieces) {
      const points = clip(piece, o.x0, o.x1);
      if (!points.length) continue;
      const pts = points.map((p) => px(p[0]).toFixed(1) + "," + py(p[1]).toFixed(1)).join(" ");
      parts.push(svg("polyline", { class: s.name, points: pts }));
    }
  }
  el.replaceChildren(...parts);
}

// The devices' plots: series ({name, points} or {name, pieces}) over their own seconds, y
// from 0 to top.
function chart(el, series, top, caption, rules, unit) {
  const all = series.map((s) => ({ name: s.name, pieces: s.pieces || [s.points] }));
  const xs = all.flatMap((s) => s.pieces.flat().map((p) => p[0]));
  const x0 = xs.length ? Math.min(...xs) : 0;
  const x1 = xs.length ? Math.max(...xs) : 1;
  drawChart(el, { x0, x1: Math.max(x1, x0 + 1e-3), axis: "seconds", top, unit: unit || "",
    caption, rules, series: all });
}

function windowText() {
  const s = windowSeconds();
  return s >= 120 ? s / 60 + " min" : s + " s";
}

function faultBands() {
  return [...state.faults.values()].map((f) => ({ from: f.t, to: f.until ?? state.now, label: f.label, what: f.what }));
}

function drawLoad() {
  const known = state.load.every((s) => s.percent != null);
  const points = state.load.map((s) => [s.t, known ? s.percent : s.frames]);
  const from = state.now - windowSeconds();
  const max = Math.max(0, ...points.filter((p) => p[0] >= from).map((p) => p[1]));
  const top = known ? Math.min(niceTop(max, 1), 100) : niceTop(max, 1);
  const unit = known ? "%" : "frames/s";
  const caption = (known ? "bus load" : "frames per second") + " over the last " + windowText() +
    " (scale 0 to " + label(top) + " " + unit + ")";
  $("loadscale").textContent = "(scale 0 to " + label(top) + " " + unit + ")";
  drawChart($("loadchart"), {
    x0: from, x1: state.now, axis: "ago", top, unit, caption, bands: faultBands(),
    series: [{ name: "load", pieces: [points] }],
  });
}

function drawHistory() {
  const h = state.history.get(Number($("histnode").value)) || [];
  const from = state.now - windowSeconds();
  const max = Math.max(0, ...h.filter((s) => s.t >= from).map((s) => Math.max(s.tec, s.rec)));
  const top = counterTop(max);
  drawChart($("tecchart"), {
    x0: from, x1: state.now, axis: "ago", top, unit: "",
    caption: "TEC (red) and REC (blue) over the last " + windowText() + " (scale 0 to " + top + ")",
    rules: [[96, "warning 96"], [128, "passive 128"]],
    bands: faultBands(),
    series: [
      { name: "tec", pieces: [h.map((s) => [s.t, s.tec])] },
      { name: "rec", pieces: [h.map((s) => [s.t, s.rec])] },
    ],
  });
}

// What a device write asked for, in words, when its answer does not say.
function describe(path, body) {
  const a = body.action;
  if (path === "/api/slio") {
    const who = "SLIO " + body.slio + ": ";
    if (a === "output") return who + "P" + body.pin + " " + (body.on ? "on" : "off") +
      " asked (the LED follows when the SLIO confirms)";
    if (a === "dpm") return who + "DPM" + body.output + " duty " + body.duty + " asked";
    if (a === "convert") return who + "ADC" + body.input + " conversion asked";
    if (a === "read") return who + "its registers asked";
  }
  if (path === "/api/zelle") {
    if (a === "measure") return "ZELLE cell: measuring channels " + body.channels.join(" and ") +
      ", " + body.chunks + " blocks of " + body.cycles + " scan cycles every " + body.interval_ms + " ms";
    if (a === "stop") return "ZELLE cell: the run stops after the block under way";
    if (a === "ram") return "ZELLE cell: reading " + body.len + " bytes of RAM from 0800h";
  }
  if (path === "/api/cpu196") {
    if (a === "start") return "CPU196 board: streaming bank " + body.bank + ", configuration set " + body.config;
    if (a === "stop") return "CPU196 board: streaming stops";
    if (a === "identify") return "CPU196 board: identity asked";
  }
  return "done";
}

// Sends a write; the result line says what was done, or why not, in words.
async function write(path, body) {
  const result = $("result");
  result.className = "";
  result.textContent = "…";
  let r;
  try {
    r = await fetch(path, {
      method: "POST",
      headers: { "Content-Type": "application/json", "X-Buslab-Token": $("token").value.trim() },
      body: JSON.stringify(body),
    });
  } catch (e) {
    result.className = "warn";
    result.textContent = "Not sent: the server did not answer (" + e.message + ").";
    return;
  }
  const answer = await r.text();
  if (r.ok) {
    let done = null;
    try { done = JSON.parse(answer).done; } catch (e) { /* not JSON: say what was asked */ }
    result.textContent = "Done: " + (done || describe(path, body)) + ".";
    return;
  }
  result.className = "warn";
  let why = answer.trim();
  const retry = r.headers.get("Retry-After");
  if (r.status === 429 && retry) why += " (asked to wait " + retry + " s)";
  result.textContent = "Not done: " + why;
}

function nodesField() {
  return $("faultnodes").value.split(",").map((s) => s.trim()).filter((s) => s);
}

function fault(kind, forMs) {
  const body = { kind, nodes: nodesField() };
  const rate = parseFloat($("rate").value);
  if (kind === "cut" || kind === "noise") body.rate = rate;
  if (forMs) body.for_ms = forMs;
  return write("/api/fault", body);
}

document.addEventListener("DOMContentLoaded", () => {
  const token = fragment("token");
  if (token) $("token").value = token;
  const chosen = Number(fragment("window"));
  if (WINDOWS.includes(chosen)) $("window").value = String(chosen);
  const plot = fragment("plot");
  if (plot) {
    state.signalNames.add(plot);
    const o = text("option", plot);
    o.value = plot;
    $("plotsignal").appendChild(o);
    $("plotsignal").value = plot;
  }
  fetch("/api/state?n=0&window=1").then((r) => r.json()).then((s) => {
    $("channel").textContent = s.channel;
    $("writable").textContent = s.writable ? "(needs the server's token)" : "(this server is read-only)";
    if (s.dbc_messages != null) {
      $("signals").hidden = false;
      $("dbcsize").textContent = s.dbc_messages;
      drawSignal();
    }
  }).catch(() => {});
  $("plotsignal").addEventListener("change", () => plotSignal($("plotsignal").value));
  $("messages").addEventListener("click", (e) => {
    const button = e.target.closest("button.plot");
    if (button) plotSignal(button.dataset.signal);
  });
  $("sendform").addEventListener("submit", (e) => {
    e.preventDefault();
    write("/api/send", { frame: $("frame").value.trim() });
  });
  $("faultform").addEventListener("submit", (e) => {
    e.preventDefault();
    const ms = parseInt($("forms").value, 10);
    fault($("kind").value, ms > 0 ? ms : null);
  });
  $("experiment").addEventListener("click", () => {
    const n = Number($("histnode").value);
    if (state.names.has(n)) $("faultnodes").value = state.names.get(n);
    $("kind").value = "cut";
    $("rate").value = "0.05";
    fault("cut", 3000);
  });
  $("repair").addEventListener("click", () => write("/api/repair", {}));
  $("histnode").addEventListener("change", drawHistory);
  // A longer window needs what the page did not keep: the server sends it again.
  $("window").addEventListener("change", connect);
  $("timefmt").addEventListener("change", retime);
  $("applyfilter").addEventListener("click", connect);
  $("filter").addEventListener("keydown", (e) => { if (e.key === "Enter") connect(); });
  $("clear").addEventListener("click", () => {
    $("log").replaceChildren();
    state.held = 0;
    state.lastTime = null;
    $("held").textContent = 0;
  });
  $("pause").addEventListener("change", () => { if (!$("pause").checked) { state.held = 0; $("held").textContent = 0; } });
  connect();
});
