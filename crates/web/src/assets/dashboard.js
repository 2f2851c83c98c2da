// buslab's live dashboard: applies the server's deltas (docs/web.md) to the page. Plain DOM,
// no library; text from the bus goes in as text, never as markup.
"use strict";

const MAX_LOG_LINES = 500;
const MAX_HISTORY = 1200;
const $ = (id) => document.getElementById(id);

const state = {
  rows: new Map(),      // ID -> <tr>
  load: [],             // {t, percent, frames}
  history: new Map(),   // node number -> [{t, tec, rec, state}]
  names: new Map(),     // node number -> name
  held: 0,
  source: null,
};

function text(tag, value, cls) {
  const el = document.createElement(tag);
  el.textContent = value;
  if (cls) el.className = cls;
  return el;
}

function connect() {
  if (state.source) state.source.close();
  const filter = $("filter").value.trim();
  const url = "/api/events" + (filter ? "?filter=" + encodeURIComponent(filter) : "");
  $("filtererror").textContent = "";
  const source = new EventSource(url);
  state.source = source;
  source.addEventListener("update", (e) => apply(JSON.parse(e.data)));
  source.onopen = () => { $("link").textContent = "live"; };
  source.onerror = () => {
    $("link").textContent = "reconnecting";
    if (filter) {
      // A bad filter is refused with 400: say why.
      fetch(url).then((r) => r.ok ? null : r.text()).then((why) => {
        if (why) { $("filtererror").textContent = why; source.close(); }
      }).catch(() => {});
    }
  };
}

function apply(d) {
  if (d.full) {
    state.rows.clear();
    $("ids").tBodies[0].replaceChildren();
    state.load = [];
    state.history.clear();
    $("log").replaceChildren();
  }
  $("frames").textContent = d.frames;
  $("fps").textContent = d.frames_per_s;
  $("bitrate").textContent = d.bitrate ? d.bitrate + " bit/s" : "unknown";
  $("lost").textContent = d.lost;
  if (d.bus_failure) $("link").textContent = "bus stopped: " + d.bus_failure;
  for (const row of d.ids) applyRow(row);
  for (const s of d.load) state.load.push(s);
  state.load = state.load.slice(-120);
  const last = state.load[state.load.length - 1];
  if (last) $("load").textContent = last.percent == null ? "unknown" : last.percent.toFixed(1) + " %";
  drawLoad();
  applyNodes(d.nodes);
  appendLog(d.log, d.log_skipped);
  if (d.devices) applyDevices(d.devices);
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

function applyNodes(nodes) {
  const body = $("nodes").tBodies[0];
  body.replaceChildren();
  const select = $("histnode");
  const chosen = select.value;
  for (const n of nodes) {
    state.names.set(n.number, n.name);
    const h = state.history.get(n.number) || [];
    for (const s of n.history) h.push(s);
    state.history.set(n.number, h.slice(-MAX_HISTORY));
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

function appendLog(entries, skipped) {
  if ($("pause").checked) {
    state.held += entries.length + skipped;
    $("held").textContent = state.held;
    return;
  }
  const log = $("log");
  const atBottom = log.scrollTop + log.clientHeight >= log.scrollHeight - 4;
  if (skipped) log.appendChild(text("div", "… " + skipped + " frames not shown (too many at once)"));
  for (const e of entries) log.appendChild(text("div", e.time.toFixed(6) + "  " + e.frame));
  while (log.childNodes.length > MAX_LOG_LINES) log.removeChild(log.firstChild);
  if (atBottom) log.scrollTop = log.scrollHeight;
}

const SVG = "http://www.w3.org/2000/svg";
function svg(tag, attrs, content) {
  const el = document.createElementNS(SVG, tag);
  for (const [k, v] of Object.entries(attrs)) el.setAttribute(k, v);
  if (content != null) el.textContent = content;
  return el;
}

// A line chart like the server's: 600 x 160, y from 0 to top, rules at given heights.
function chart(el, series, top, unit, rules) {
  const W = 600, H = 160;
  const xs = series.flatMap((s) => s.points.map((p) => p[0]));
  const x0 = Math.min(...xs), x1 = Math.max(...xs);
  const span = Math.max(x1 - x0, 1e-9);
  const px = (x) => ((x - x0) / span) * W;
  const py = (y) => H - Math.min(Math.max(y / top, 0), 1) * H;
  const parts = [svg("rect", { x: 0, y: 0, width: W, height: H, class: "frame" })];
  for (const [y, label] of rules) {
    parts.push(svg("line", { class: "rule", x1: 0, x2: W, y1: py(y), y2: py(y) }));
    parts.push(svg("text", { x: 4, y: py(y) - 2 }, label));
  }
  parts.push(svg("text", { x: -38, y: 10 }, top.toFixed(0)), svg("text", { x: -38, y: H }, "0"));
  if (xs.length) {
    const digits = span < 10 ? 1 : 0;
    parts.push(svg("text", { x: 0, y: H + 16 }, x0.toFixed(digits) + " s"));
    parts.push(svg("text", { x: W - 40, y: H + 16 }, x1.toFixed(digits) + " s"));
  }
  parts.push(svg("text", { x: 200, y: H + 16 }, unit));
  for (const s of series) {
    const pts = s.points.map((p) => px(p[0]).toFixed(1) + "," + py(p[1]).toFixed(1)).join(" ");
    parts.push(svg("polyline", { class: s.name, points: pts }));
  }
  el.replaceChildren(...parts);
}

function drawLoad() {
  const known = state.load.every((s) => s.percent != null);
  const points = state.load.map((s) => [s.t, known ? s.percent : s.frames]);
  const top = known ? 100 : Math.max(1, ...points.map((p) => p[1]));
  chart($("loadchart"), [{ name: "load", points }], top, known ? "% load" : "frames/s", []);
}

function drawHistory() {
  const h = state.history.get(Number($("histnode").value)) || [];
  chart($("tecchart"), [
    { name: "tec", points: h.map((s) => [s.t, s.tec]) },
    { name: "rec", points: h.map((s) => [s.t, s.rec]) },
  ], 256, "TEC (red), REC (blue)", [[96, "warning 96"], [128, "passive 128"]]);
}

async function write(path, body) {
  const result = $("result");
  result.textContent = "…";
  try {
    const r = await fetch(path, {
      method: "POST",
      headers: { "Content-Type": "application/json", "X-Buslab-Token": $("token").value.trim() },
      body: JSON.stringify(body),
    });
    const answer = await r.text();
    result.textContent = (r.ok ? "done: " : "refused (" + r.status + "): ") + answer;
  } catch (e) {
    result.textContent = "failed: " + e;
  }
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
  // The token may come in the address's fragment (never sent to the server): #token=...
  const m = location.hash.match(/token=([A-Za-z0-9._-]+)/);
  if (m) $("token").value = m[1];
  fetch("/api/state?n=0").then((r) => r.json()).then((s) => {
    $("channel").textContent = s.channel;
    $("writable").textContent = s.writable ? "(needs the server's token)" : "(this server is read-only)";
  }).catch(() => {});
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
  $("applyfilter").addEventListener("click", connect);
  $("filter").addEventListener("keydown", (e) => { if (e.key === "Enter") connect(); });
  $("clear").addEventListener("click", () => { $("log").replaceChildren(); state.held = 0; $("held").textContent = 0; });
  $("pause").addEventListener("change", () => { if (!$("pause").checked) { state.held = 0; $("held").textContent = 0; } });
  connect();
});
