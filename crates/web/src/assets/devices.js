// The bench's device panels on the live dashboard (docs/web.md): SLIO boards, the ZELLE cell,
// the CPU196 board. Uses dashboard.js's helpers ($, text, svg, chart, write). A value on a
// panel is what the device told: an LED clicked stays as it was (marked pending) until the
// SLIO's answer comes back over the bus. A board's switches and potentiometer are the
// bench's: a click changes them on the board at once, and the SLIO's pins are read again.
"use strict";

const LED_PINS = [7, 8, 9, 11, 12];

// The board's switches and potentiometer as the bench has them, asked once per panel (a
// write: only with the token; the answer comes back in the live updates).
function askBench(slio) {
  const token = $("token").value.trim();
  if (!token) return;
  fetch("/api/slio", {
    method: "POST",
    headers: { "Content-Type": "application/json", "X-Buslab-Token": token },
    body: JSON.stringify({ action: "board", slio }),
  }).catch(() => {});
}

function button(label, onClick, cls) {
  const b = text("button", label, cls);
  b.type = "button";
  b.addEventListener("click", onClick);
  return b;
}

function box(title, id) {
  const d = document.createElement("div");
  d.className = "device";
  d.id = id;
  d.appendChild(text("h3", title));
  return d;
}

function volts(a) {
  return a == null ? "-" : a.code + " (" + a.volts.toFixed(3) + " V)";
}

function slioBox(s) {
  const d = box("SLIO " + s.slio + " (" + s.command_id + "/" + s.reply_id + ")", "slio-" + s.slio);
  const leds = document.createElement("p");
  leds.className = "leds";
  leds.appendChild(document.createTextNode("LEDs "));
  for (const pin of LED_PINS) {
    const b = button("●", () => {
      const on = b.dataset.on === "1";
      write("/api/slio", { action: "output", slio: s.slio, pin, on: !on });
    }, "led");
    b.dataset.pin = pin;
    b.title = "P" + pin + ": click to switch (shown once the SLIO confirms)";
    leds.appendChild(b);
  }
  d.appendChild(leds);
  const table = document.createElement("table");
  table.className = "kv";
  const bench = document.createElement("p");
  bench.className = "bench";
  bench.appendChild(document.createTextNode("switches "));
  for (const k of [0, 1, 2, 3]) {
    const b = button("S" + k, () => {
      write("/api/slio", { action: "switch", slio: s.slio, switch: k, on: b.dataset.on !== "1" });
    }, "switch");
    b.dataset.switch = k;
    b.title = "input switch " + k + " (P" + k + "): click to flip it on the board";
    bench.appendChild(b);
  }
  const pot = document.createElement("input");
  pot.type = "number"; pot.min = 0; pot.max = 5; pot.step = 0.1; pot.value = 2.5; pot.size = 4;
  pot.className = "pot";
  bench.append(text("span", " potentiometer "), pot, text("span", " V "),
    button("turn", () => write("/api/slio", { action: "pot", slio: s.slio, volts: Number(pot.value) }), "pot"));
  d.appendChild(bench);
  for (const [key, label] of [["switches", "switches P0..P3 (SLIO)"], ["bench", "board (bench)"], ["adc1", "ADC1 (P5)"],
    ["adc2", "ADC2 (P6, pot.)"], ["dpm1", "DPM1 (P10)"], ["dpm2", "DPM2 (P4)"],
    ["outputs", "DATA_OUTPUT"], ["status", "status"], ["replies", "frames from it"]]) {
    const tr = document.createElement("tr");
    tr.appendChild(text("th", label));
    const td = text("td", "-");
    td.dataset.key = key;
    tr.appendChild(td);
    table.appendChild(tr);
  }
  d.appendChild(table);
  const controls = document.createElement("p");
  controls.append(
    button("convert ADC1", () => write("/api/slio", { action: "convert", slio: s.slio, input: 1 }), "adc1"),
    button("convert ADC2", () => write("/api/slio", { action: "convert", slio: s.slio, input: 2 }), "adc2"),
    button("read", () => write("/api/slio", { action: "read", slio: s.slio }), "read"),
  );
  d.appendChild(controls);
  const dpm = document.createElement("p");
  const duty = document.createElement("input");
  duty.type = "number"; duty.min = 0; duty.max = 1023; duty.value = 512; duty.size = 5;
  dpm.append(text("span", "duty "), duty,
    button("DPM1", () => write("/api/slio", { action: "dpm", slio: s.slio, output: 1, duty: Number(duty.value) })),
    button("DPM2", () => write("/api/slio", { action: "dpm", slio: s.slio, output: 2, duty: Number(duty.value) })));
  d.appendChild(dpm);
  askBench(s.slio);
  return d;
}

function applySlio(d, s) {
  for (const led of s.leds) {
    const b = d.querySelector('button.led[data-pin="' + led.pin + '"]');
    b.dataset.on = led.on ? "1" : "0";
    b.className = "led" + (led.on ? " on" : "") + (led.pending ? " pending" : "");
    b.dataset.pending = led.pending ? "1" : "0";
  }
  const set = (key, v) => { d.querySelector('td[data-key="' + key + '"]').textContent = v; };
  // A switch shows the board's position when the bench told it, else what the SLIO read.
  const positions = s.bench ? s.bench.switches : s.switches;
  for (const b of d.querySelectorAll("button.switch")) {
    const on = positions ? positions[Number(b.dataset.switch)] : false;
    b.dataset.on = on ? "1" : "0";
    b.textContent = "S" + b.dataset.switch + (positions ? (on ? " on" : " off") : "");
  }
  set("switches", s.switches ? s.switches.map((x) => (x ? "1" : "0")).join(" ") : "-");
  set("bench", s.bench ? "switches " + s.bench.switches.map((x) => (x ? "1" : "0")).join(" ") +
    ", potentiometer " + s.bench.potentiometer.toFixed(3) + " V" : "-");
  set("adc1", volts(s.adc[0]));
  set("adc2", volts(s.adc[1]));
  set("dpm1", volts(s.dpm[0]));
  set("dpm2", volts(s.dpm[1]));
  set("outputs", s.outputs == null ? "-" : s.outputs.toString(16).toUpperCase().padStart(4, "0"));
  set("status", s.status || (s.heard ? "-" : "not heard yet"));
  set("replies", s.replies);
}

function zelleBox() {
  const d = box("ZELLE cell", "zelle");
  d.append(text("p", "", "state"),
    button("measure ch1+ch2", () => write("/api/zelle", {
      action: "measure", channels: [1, 2], interval_ms: 10, cycles: 50, chunks: 10 }), "measure"),
    button("stop", () => write("/api/zelle", { action: "stop" }), "stop"),
    button("read RAM", () => write("/api/zelle", { action: "ram", len: 256 }), "ram"));
  const plot = svg("svg", { class: "chart", viewBox: "-40 -10 650 190", width: 480, height: 150 });
  d.appendChild(plot);
  d.appendChild(text("pre", "", "ram"));
  return d;
}

function applyZelle(d, z) {
  d.querySelector(".state").textContent = "on " + z.port + ": " + (z.busy || "idle") +
    (z.runs ? ", " + z.chunks + " blocks measured" : "") +
    (z.missing ? ", " + z.missing + " readings missing" : "") + (z.error ? " — " + z.error : "");
  // Each measured block its own piece: between two the cell measured nothing (it was read).
  const series = z.series.map((blocks, k) => ({ name: "ch" + (k % 4 + 1), pieces: blocks }));
  chart(d.querySelector("svg"), series, 5, "volts over the seconds of the run (channel " +
    z.channels.join(", ") + "; gaps: the cell was read back)", [], "V");
  d.querySelector("pre.ram").textContent = z.ram || "(read RAM, or measure: the data area from 0800h)";
}

function cpuBox() {
  const d = box("CPU196 board", "cpu196");
  d.append(text("p", "", "state"), text("pre", "", "identity"),
    button("start (bank 0, set 0)", () => write("/api/cpu196", { action: "start", bank: 0, config: 0 }), "start"),
    button("stop", () => write("/api/cpu196", { action: "stop" }), "stop"),
    button("identify", () => write("/api/cpu196", { action: "identify" }), "identify"));
  d.appendChild(svg("svg", { class: "chart", viewBox: "-40 -10 650 190", width: 480, height: 150 }));
  d.appendChild(text("pre", "", "thread"));
  return d;
}

function applyCpu(d, c) {
  d.querySelector(".state").textContent = "on " + c.port + ": " +
    (c.running ? "streaming " + c.running + ", " + c.samples + " samples" : c.busy ? "busy" : "idle") +
    (c.error ? " — " + c.error : "");
  d.querySelector("pre.identity").textContent = c.identity || "(identity not read yet)";
  const series = c.series.slice(0, 4).map(([name, points], k) => ({ name: "ch" + (k + 1), points }));
  chart(d.querySelector("svg"), series, 5, "A/D stream, volts: " + c.series.slice(0, 4).map((s) => s[0]).join(", "), []);
  const t = d.querySelector("pre.thread");
  t.textContent = c.text || "(THREAD text appears while the board runs)";
  t.scrollTop = t.scrollHeight;
}

function applyDevices(v) {
  const section = $("devices");
  section.hidden = false;
  const panels = $("panels");
  for (const s of v.slio) {
    let d = $("slio-" + s.slio);
    if (!d) { d = slioBox(s); panels.appendChild(d); }
    applySlio(d, s);
  }
  if (v.zelle) {
    let d = $("zelle");
    if (!d) { d = zelleBox(); panels.appendChild(d); }
    applyZelle(d, v.zelle);
  }
  if (v.cpu196) {
    let d = $("cpu196");
    if (!d) { d = cpuBox(); panels.appendChild(d); }
    applyCpu(d, v.cpu196);
  }
}
