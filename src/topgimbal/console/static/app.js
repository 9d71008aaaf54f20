// topgimbal console page. Plain ES modules, no build step.
// Data flow: /api/catalog (what the model supports, with field metadata) + /ws pushes
// (hello, attitude, status, traffic, error) -> DOM; user actions -> ops over /ws, each acked.
// The panels are built from the catalog's roles and groups (lib/panels.js, lib/catalog.js); the
// link state (LOST, read-only) is the server's (lib/link.js).

import { Conn, fetchJSON, withToken } from "./lib/conn.js";
import { drawHeading, drawHorizon, drawNoAttitude } from "./lib/gauges.js";
import { describeFields, el, formatFields } from "./lib/fields.js";
import { lockControls, showLink } from "./lib/link.js";
import { buildAttitude, buildBuilder, buildCamera, buildNetwork, buildPointing, buildRange, buildThermal, showReport } from "./lib/panels.js";
import { provide } from "./lib/bus.js";
import { startWhere } from "./lib/where.js";

const $ = (id) => document.getElementById(id);

const S = {
  catalog: null,
  model: null,
  attitude: null,
  attitudeDirty: false,
  attCount: 0,
  attRate: 0,
  target: null,        // commanded yaw (degrees) the camera acknowledged; null: none
  motionSeq: 0,        // bumped by every motion action, so a late ack cannot bring back a marker
  hasAttitude: false,
  traffic: [],
  trafficDirty: false,
  clockOffset: 0,
  recordingSince: null,
  recording: false,
  photos: 0,
  status: null,        // the newest status push (link state included)
  lockReason: null,    // why the camera's controls are disabled (link lost, read-only), or null
  range: { yaw: [-180, 180], pitch: [-90, 90] },
  maxRate: 0,
  ratesReason: null,   // why the model takes no rate commands, or null
};

// ---------------------------------------------------------------- messages and errors

function toast(text, kind = "info", ms = 7000) {
  const t = el("div", { class: `toast ${kind}`, role: kind === "error" ? "alert" : "status" },
    el("span", { class: "x", text: "×", onclick: () => t.remove() }), text);
  $("toasts").prepend(t);  // newest first: the strip's one visible line (style.css)
  $("toasts").scrollTop = 0;
  while ($("toasts").children.length > 5) $("toasts").lastChild.remove();
  setTimeout(() => t.remove(), ms);
}

function logError(text) {
  const log = $("error-log");
  if (log.firstElementChild?.classList.contains("muted")) log.innerHTML = "";
  log.prepend(el("li", { text: `${new Date().toLocaleTimeString()} ${text}` }));
  while (log.children.length > 20) log.lastChild.remove();
}

function showError(text) {
  toast(text, "error", 10000);
  logError(text);
}

// Run an op; an error always becomes a visible message. Resolves with the result (or undefined).
function run(op, args = {}, okText = null) {
  return conn.op(op, args).then(
    (result) => {
      if (okText) toast(okText, "ok", 2500);
      return result;
    },
    (err) => {
      showError(err.message || String(err));
      return undefined;
    },
  );
}

// Run an op and hand back the outcome either way (the error is shown too): {ok, result} or {ok: false, error}.
function attempt(op, args = {}) {
  return conn.op(op, args).then(
    (result) => ({ ok: true, result }),
    (err) => {
      showError(err.message || String(err));
      return { ok: false, error: err };
    },
  );
}

// ---------------------------------------------------------------- connection

const conn = new Conn({
  onState(state) {
    if (state !== "open") setPageLink(state === "closed" ? "disconnected" : "connecting");
  },
  onMessage(msg) {
    switch (msg.type) {
      case "hello": return onHello(msg);
      case "attitude":
        S.attitude = msg;
        S.attitudeDirty = true;
        S.attCount++;
        return;
      case "status": return onStatus(msg);
      case "traffic": return onTraffic(msg.items || []);
      case "error": return showError(msg.message);
      case "recovered": return toast(`${msg.source}: working again`, "ok", 3000);
    }
  },
});

// The page's own socket to the console server (not the camera's link): shown on the badge while
// it is not open; the camera's link comes with every status (applyLink).
function setPageLink(state) {
  const l = $("link");
  l.dataset.state = state;
  l.textContent = state;
  l.title = "the page's connection to the console server";
  $("conn-link").textContent = `${state} (${l.title})`;
}

// The camera's link state from a status push: badge, LOST banner, controls, gauges.
function applyLink(st) {
  if (st.feeds !== undefined) $("conn-feeds").textContent = st.feeds;  // what the host feeds the camera
  const reason = showLink(st, S.clockOffset);
  if (reason !== S.lockReason || reason) {
    const was = S.lockReason;
    S.lockReason = reason;
    if (S.catalog) lockControls(reason);   // the panels exist: (un)lock them now; main() does it otherwise
    if (!was && reason && st.link === "lost") showLost();
    $("panel-attitude").classList.toggle("lost", st.link === "lost");
    if (was && !reason) toast("Camera link back: frames arrive again", "ok", 4000);
  }
}

// The gauges while the link is lost: never the last attitude as if it were live.
function showLost() {
  if (!S.hasAttitude) return;
  S.attitude = null;
  drawNoAttitude($("horizon"), "link lost");
  drawNoAttitude($("heading"), "link lost", S.target);
  $("horizon").dataset.state = $("heading").dataset.state = "lost";
}

let helloResolve;
const helloSeen = new Promise((resolve) => { helloResolve = resolve; });

function onHello(msg) {
  $("camera-url").textContent = msg.url || "";
  document.body.dataset.mode = msg.mode || "camera";
  S.traffic = [];
  renderedKey = null;
  onTraffic(msg.traffic || []);
  S.trafficDirty = true;
  if (msg.status) onStatus(msg.status);
  showUnavailable(msg.unavailable || {});
  helloResolve(msg);
}

// What this camera's link does not carry (a camera reached through Zenoh: no frames, so no
// traffic and no pcap): said in the traffic panel, not shown as an error.
function showUnavailable(u) {
  const reason = $("traffic-reason");
  reason.hidden = !u.traffic;
  reason.textContent = u.traffic ? `Traffic unavailable for this camera: ${u.traffic}` : "";
  const pcapLink = $("traffic-pcap");
  if (u.pcap) {  // disabled, and seen to be (issue 35.6: it looked enabled for a Zenoh camera)
    pcapLink.removeAttribute("href");
    pcapLink.setAttribute("aria-disabled", "true");
    pcapLink.classList.add("disabled");
    pcapLink.tabIndex = -1;
    pcapLink.dataset.reason = pcapLink.title = `No pcap for this camera: ${u.pcap}`;
  } else if (pcapLink.dataset.reason) {  // this camera has one (a page reused for another camera)
    delete pcapLink.dataset.reason;
    pcapLink.removeAttribute("aria-disabled");
    pcapLink.classList.remove("disabled");
    pcapLink.removeAttribute("tabindex");
    pcapLink.title = "";
    pcapLink.href = withToken("api/traffic.pcap");
  }
}

const num = (v, d = 0) => (typeof v === "number" && Number.isFinite(v) ? v.toFixed(d) : "–");

function pick(obj, ...keys) {
  for (const k of keys) if (obj && obj[k] != null) return obj[k];
  return undefined;
}

function onStatus(st) {
  S.clockOffset = Date.now() / 1000 - st.now;
  S.status = st;
  applyLink(st);
  if (st.recorded && !$("traffic-pcap").dataset.reason) {
    const r = st.recorded;
    $("traffic-pcap").title = `Download what the console recorded as pcap (Wireshark, tshark): the newest ${r.frames} frames ` +
      `(${(r.bytes / 1024).toFixed(0)} KiB; it keeps at most ${r.max_frames} frames and ${(r.max_bytes / 1048576).toFixed(0)} MiB)`;
  }
  const stats = st.stats || {};
  $("frames-in").textContent = pick(stats, "frames_in", "rx_frames") ?? 0;
  $("frames-out").textContent = pick(stats, "frames_out", "tx_frames") ?? 0;
  $("conn-errors").textContent = `${pick(stats, "errors", "device_errors") ?? 0} from the camera · ${st.errors} in the console`;
  $("conn-timeouts").textContent = pick(stats, "timeouts") ?? 0;
  const rtt = pick(stats, "rtt_ms_last", "rtt_ms");
  const avg = pick(stats, "rtt_ms_avg", "rtt_ms_mean");
  $("conn-rtt").textContent = rtt == null ? "–" : `${num(rtt, 1)} ms` + (avg != null ? ` (avg ${num(avg, 1)} ms)` : "");
  const dl = $("conn-stats");
  dl.innerHTML = "";
  for (const [k, v] of Object.entries(stats)) {
    dl.append(el("dt", { text: k }), el("dd", { text: typeof v === "object" ? JSON.stringify(v) : String(v) }));
  }
  if (st.version != null) $("conn-version").textContent = formatVersion(st.version);
  // recording
  const rec = st.recording;
  if (rec != null) setRecording(!!rec, st.recording_since != null ? st.recording_since + S.clockOffset : null);
  if (st.sd !== undefined) showSD(st.sd);
}

function formatVersion(v) {
  if (v == null) return "–";
  if (typeof v === "string") return v;
  if (v.fields) return Object.values(v.fields).join(" ");
  if (typeof v === "object") return Object.entries(v).map(([k, x]) => `${k} ${x}`).join(", ");
  return String(v);
}

// ---------------------------------------------------------------- attitude (rAF rendering)

function frame() {
  if (S.attitudeDirty && S.attitude && S.status?.link !== "lost") {
    S.attitudeDirty = false;
    const a = S.attitude;
    $("yaw").textContent = a.yaw.toFixed(2);
    $("pitch").textContent = a.pitch.toFixed(2);
    $("roll").textContent = a.roll.toFixed(2);
    drawHorizon($("horizon"), a.pitch, a.roll);
    drawHeading($("heading"), a.yaw, S.target);
    $("horizon").dataset.state = $("heading").dataset.state = "live";
  }
  if (S.trafficDirty) renderTraffic();
  if (S.recording && S.recordingSince != null) {
    $("rec-elapsed").textContent = clock(Date.now() / 1000 - S.recordingSince);
  }
  requestAnimationFrame(frame);
}

setInterval(() => {
  S.attRate = S.attCount;
  S.attCount = 0;
  $("conn-att-rate").textContent = `${S.attRate} Hz`;
  if (S.status?.link === "lost") showLink(S.status, S.clockOffset); // "... (12 s ago)" keeps counting
}, 1000);

function clock(s) {
  s = Math.max(0, Math.floor(s));
  const h = Math.floor(s / 3600), m = Math.floor((s % 3600) / 60), sec = s % 60;
  const mm = String(m).padStart(2, "0"), ss = String(sec).padStart(2, "0");
  return h ? `${h}:${mm}:${ss}` : `${mm}:${ss}`;
}

// ---------------------------------------------------------------- traffic

function onTraffic(items) {
  for (const it of items) {
    it.seq = ++trafficSeq;
    S.traffic.push(it);
    if (it.dir === "in" && it.fields && S.catalog) {
      showReport(S.catalog, it);
      rowHeard(it);
    }
  }
  if (S.traffic.length > 3000) S.traffic.splice(0, S.traffic.length - 3000);
  if (!$("traffic-pause").checked) S.trafficDirty = true;
}

function trafficMatches(it, q, dir, hideAtt) {
  if (dir !== "all" && it.dir !== dir) return false;
  if (hideAtt && (it.stream || it.poll)) return false;
  if (!q) return true;
  it.hay ??= `${it.id || ""} ${it.name || ""} ${it.frame} ${formatFields(it.fields)} ${meaningOf(it)}`.toLowerCase();
  const hay = it.hay;
  return q.split(/\s+/).every((w) => hay.includes(w));
}

// What a frame means, in English: "Thermal palette: White hot" (its raw fields are the tooltip).
function meaningOf(it) {
  if (it.error) return `⚠ ${it.error}`;
  const spec = S.catalog?.commands[it.id];
  if (!spec) return `${it.name || it.id || ""} ${formatFields(it.fields)}`.trim();
  const fields = it.fields && Object.keys(it.fields).length ? describeFields(spec, it.fields, { single: true }) : "";
  return fields ? `${spec.title}: ${fields}` : spec.title;
}

// What the camera said about a command that has a row (whoever asked: this page, another page, the
// video panel's wheel): an answer is shown as it is; a write's echo makes the row read the value
// back (an echo may carry a step such as "zoom in", not the value it led to).
function rowHeard(it) {
  const row = document.querySelector(`[data-cmd="${CSS.escape(it.id || "")}"]`);
  if (!row?.show) return;
  if (!it.echo) row.show(it.fields, { heard: true });
  else if (row.readBack) row.readBack();
  else row.show(it.fields, { heard: true, echo: true });
}

const MAX_ROWS = 300;
let trafficSeq = 0;      // sequence number of the newest item received
let renderedSeq = 0;     // ... and of the newest item considered for the pane
let renderedKey = null;  // the filter the pane was built with

function trafficRow(it) {
  const cls = `tr ${it.dir}${it.error ? " err" : ""}${S.catalog?.commands[it.id]?.role === "error" ? " ere" : ""}${it.poll ? " poll" : ""}`;
  const t = new Date(it.t * 1000);
  const ts = t.toLocaleTimeString([], { hour12: false }) + "." + String(t.getMilliseconds()).padStart(3, "0");
  const meaning = meaningOf(it);
  const raw = `${it.id || ""} ${it.name || ""} ${formatFields(it.fields)}`.trim();
  return el("div", { class: cls, "data-id": it.id || "", "data-dir": it.dir },
    el("span", { class: "t", text: ts }),
    el("span", { class: "d", text: it.dir === "in" ? "◀" : "▶", title: it.dir === "in" ? "from the camera" : "to the camera" }),
    el("span", { class: "f", text: it.frame, title: it.frame }),
    el("span", { class: "m", text: meaning, title: `${meaning}\n${raw}`, "data-raw": raw }));
}

// Appends only what is new (a 50 Hz attitude stream shown in the pane stays cheap); rebuilds
// when the filter changes or the history was cleared.
function renderTraffic() {
  S.trafficDirty = false;
  const box = $("traffic");
  const atBottom = box.scrollTop + box.clientHeight >= box.scrollHeight - 20;
  const q = $("traffic-filter").value.trim().toLowerCase();
  const dir = $("traffic-dir").value;
  const hideAtt = $("traffic-hide-att").checked;
  const key = `${q}\u0000${dir}\u0000${hideAtt}`;
  const rows = [];
  const full = key !== renderedKey;
  for (let i = S.traffic.length - 1; i >= 0 && rows.length < MAX_ROWS; i--) {
    const it = S.traffic[i];
    if (!full && it.seq <= renderedSeq) break;
    if (trafficMatches(it, q, dir, hideAtt)) rows.push(it);
  }
  rows.reverse();
  const frag = document.createDocumentFragment();
  for (const it of rows) frag.append(trafficRow(it));
  if (full) box.replaceChildren(frag);
  else box.append(frag);
  while (box.childElementCount > MAX_ROWS) box.firstElementChild.remove();
  renderedKey = key;
  renderedSeq = trafficSeq;
  if (atBottom) box.scrollTop = box.scrollHeight;
}

for (const id of ["traffic-filter", "traffic-dir", "traffic-hide-att"]) {
  $(id).addEventListener("input", () => { S.trafficDirty = true; });
}
$("traffic-pause").addEventListener("change", () => { S.trafficDirty = true; });
$("traffic-clear").addEventListener("click", () => { S.traffic = []; renderedKey = null; S.trafficDirty = true; });

// A command's answer in the builder's result line: English labels, raw fields as tooltip.
function showAnswer(prefix, m) {
  const node = $("cmd-result");
  if (!m || !m.id) {
    node.textContent = `${prefix}no reply (none expected)`;
    node.title = "";
    return;
  }
  const spec = S.catalog.commands[m.id];
  const text = m.fields ? describeFields(spec, m.fields, { single: true }) : m.error || "ok";
  node.textContent = `${prefix}${spec?.title || m.id}: ${text || "ok"}`;
  node.title = `${m.id} ${formatFields(m.fields)}`;
  node.dataset.raw = formatFields(m.fields);
}

// Raw frame: the server appends the checksum when it is missing (protocol code lives there).
$("btn-raw").addEventListener("click", async () => {
  const text = $("raw-input").value.trim();
  if (!text) return showError("type a frame first, e.g. #TPUD2rVER00");
  const reply = await run("raw", { frame: text });
  if (reply !== undefined) showAnswer(`sent ${reply.sent} → `, reply);
});
$("raw-input").addEventListener("keydown", (e) => { if (e.key === "Enter") $("btn-raw").click(); });

// ---------------------------------------------------------------- building the panels from the catalog

// A visible reason (no vendor section numbers in the text: they are in its tooltip).
function showReason(node, text, sections = "") {
  node.hidden = false;
  node.textContent = text;
  node.title = sections;
}

function disable(node, reason) {
  node.disabled = true;
  node.title = reason;
  node.dataset.reason = reason;
}

// What the panel builders get (lib/panels.js).
const ui = {
  get catalog() { return S.catalog; },
  run, attempt, toast, showError, showReason, disable,
  reads: [],
  onReport: (it) => showReport(S.catalog, it),
};

// The problem with an angle input's value (null when fine); marks the input.
function checkAngle(axis) {
  const input = $(`angle-${axis}`);
  const text = input.value.trim();
  const [lo, hi] = S.range[axis];
  let problem = null;
  if (text !== "") {
    const v = Number(text);
    if (!Number.isFinite(v)) problem = `${axis} ${JSON.stringify(text)} is not a number`;
    else if (v < lo || v > hi) problem = `${axis} ${v}° is outside the ${S.model.name}'s range ${lo}..${hi}°`;
  }
  input.setAttribute("aria-invalid", problem ? "true" : "false");
  input.title = problem || `${lo}..${hi}° on the ${S.model.name}`;
  return problem;
}
for (const axis of ["yaw", "pitch"]) $(`angle-${axis}`).addEventListener("input", () => checkAngle(axis));

// ---------------------------------------------------------------- camera actions

function setRecording(on, sinceLocal) {
  S.recording = on;
  const b = $("btn-record");
  b.dataset.state = on ? "recording" : "idle";
  b.querySelector(".label").textContent = on ? "Stop recording" : "Record";
  const e = $("rec-elapsed");
  e.classList.toggle("on", on);
  if (on) {
    if (S.recordingSince == null) S.recordingSince = sinceLocal ?? Date.now() / 1000;
    else if (sinceLocal != null) S.recordingSince = sinceLocal;
  } else {
    S.recordingSince = null;
  }
}

$("btn-photo").addEventListener("click", async () => {
  const r = await run("photo");
  if (r !== undefined) {
    S.photos++;
    const idx = r?.fields?.file_index != null ? ` (file ${r.fields.file_index})` : "";
    $("photo-status").textContent = `photo taken at ${new Date().toLocaleTimeString()}${idx} — ${S.photos} this session`;
    $("photo-status").dataset.count = String(S.photos);
    toast("Photo taken", "ok", 2500);
  }
});

$("btn-record").addEventListener("click", async () => {
  const start = !S.recording;
  const r = await run("record", { action: start ? "start" : "stop" });
  if (r !== undefined) {
    S.recordingSince = null;
    setRecording(start, null);
    if (!start) $("rec-elapsed").textContent = "00:00";
    toast(start ? "Recording started" : "Recording stopped", "ok", 2500);
  }
});

// hold-to-move buttons (zoom, focus): action while pressed, stop on release
// (their command is the one playing `data-hold-role` / `data-once-role`, set by buildCamera)
for (const b of document.querySelectorAll("[data-hold-role]")) {
  let held = false;
  const release = () => {
    if (!held) return;
    held = false;
    b.classList.remove("held");
    run("request", { id: b.dataset.id, values: { action: "stop" } });
  };
  b.addEventListener("pointerdown", (e) => {
    if (b.disabled || !b.dataset.id) return; // a digital zoom step is a click (lib/panels.js)
    held = true;
    b.setPointerCapture?.(e.pointerId);
    b.classList.add("held");
    run("request", { id: b.dataset.id, values: { action: b.dataset.action } });
  });
  b.addEventListener("pointerup", release);
  b.addEventListener("pointercancel", release);
  b.addEventListener("lostpointercapture", release);
}
for (const b of document.querySelectorAll("[data-once-role]")) {
  b.addEventListener("click", () => run("request", { id: b.dataset.id, values: { action: b.dataset.action } }, `${b.textContent} sent`));
}

function showSD(sd) {
  const fill = $("sd-fill");
  if (!sd) return;
  if (!sd.present) {
    $("sd").textContent = "no card";
    fill.style.width = "0";
    return;
  }
  const rem = sd.remaining_mb, tot = sd.total_mb;
  $("sd").textContent = `${rem} / ${tot} MB free`;
  const pct = tot ? Math.max(0, Math.min(100, (100 * rem) / tot)) : 0;
  fill.style.width = `${pct}%`;
  fill.style.background = pct < 10 ? "var(--bad)" : pct < 25 ? "var(--warn)" : "var(--ok)";
}

// ---------------------------------------------------------------- pointing actions

// The commanded-yaw marker on the heading dial shows only what the camera acknowledged: set on
// the ack of Point (or Center), cleared by Stop, rates (pad, keys) and any failed motion op.
function setTarget(yaw) {
  S.target = yaw;
  $("heading").dataset.target = yaw == null ? "" : String(yaw);
  S.attitudeDirty = true;
  if (!S.attitude && S.hasAttitude) drawNoAttitude($("heading"), "waiting for attitude", S.target);
}

// A motion op: the marker follows its outcome, unless another motion action came since.
function motion(op, args, okText, targetOnAck) {
  const seq = ++S.motionSeq;
  if (targetOnAck === undefined) setTarget(null);
  return conn.op(op, args).then(
    (result) => {
      if (seq === S.motionSeq && targetOnAck !== undefined) setTarget(targetOnAck);
      if (okText) toast(okText, "ok", 2500);
      return result;
    },
    (err) => {
      if (seq === S.motionSeq) setTarget(null);
      showError(err.message || String(err));
      return undefined;
    },
  );
}

function pointFromInputs() {
  const problems = ["yaw", "pitch"].map(checkAngle).filter(Boolean);
  if (problems.length) {
    ++S.motionSeq;
    setTarget(null);
    return showError(`${problems.join("; ")}: not sent`);
  }
  const yaw = $("angle-yaw").value.trim(), pitch = $("angle-pitch").value.trim();
  const args = {};
  if (yaw !== "") args.yaw = Number(yaw);
  if (pitch !== "") args.pitch = Number(pitch);
  if (args.yaw == null && args.pitch == null) return showError("type a yaw and/or a pitch angle first");
  // a pitch-only command keeps the acknowledged yaw marker as it is
  return motion("point", args, null, args.yaw ?? S.target);
}
$("btn-point").addEventListener("click", pointFromInputs);
for (const id of ["angle-yaw", "angle-pitch"]) {
  $(id).addEventListener("keydown", (e) => { if (e.key === "Enter") pointFromInputs(); });
}
$("btn-center").addEventListener("click", () => motion("center", {}, "Centering", 0));
$("btn-stop").addEventListener("click", () => motion("stop", {}, "Stopped"));
$("btn-follow").addEventListener("click", () => run("mode", { mode: "follow" }, "Follow mode"));
$("btn-lock").addEventListener("click", () => run("mode", { mode: "lock" }, "Lock mode"));
$("btn-calib").addEventListener("click", () => {
  const sel = $("calib-select");
  const label = sel.selectedOptions[0]?.textContent || sel.value;
  const text = `Send "${label}" to the ${S.model.name}?\n\nThe gimbal may move or re-orient its axes on its own ` +
    "(calibrations, mount orientation, trims): keep it level and still until it finishes.";
  if (!window.confirm(text)) return toast(`${label}: cancelled`);
  return run("ptz", { action: sel.value }, `${label} sent`);
});

// rates: drag pad and arrow keys
let rateSent = { yaw: 0, pitch: 0 };
let rateWanted = { yaw: 0, pitch: 0 };
let rateTimer = null;

function wantRates(yaw, pitch) {
  rateWanted = { yaw: Math.round(yaw * 10) / 10, pitch: Math.round(pitch * 10) / 10 };
  $("rate-readout").textContent = `rate ${rateWanted.yaw} / ${rateWanted.pitch} °/s`;
  if (!rateTimer) {
    flushRates();
    rateTimer = setInterval(flushRates, 120);
  }
}

function flushRates() {
  if (rateWanted.yaw === rateSent.yaw && rateWanted.pitch === rateSent.pitch) return;
  rateSent = { ...rateWanted };
  motion("rates", rateSent);
}

function stopRates() {
  clearInterval(rateTimer);
  rateTimer = null;
  rateWanted = rateSent = { yaw: 0, pitch: 0 };
  $("rate-readout").textContent = "rate 0 / 0 °/s";
  motion("stop", {});
}

const pad = $("pad"), knob = $("pad-knob");
let padActive = false;

function padMove(e) {
  const r = pad.getBoundingClientRect();
  let x = ((e.clientX - r.left) / r.width) * 2 - 1;
  let y = ((e.clientY - r.top) / r.height) * 2 - 1;
  x = Math.max(-1, Math.min(1, x));
  y = Math.max(-1, Math.min(1, y));
  knob.style.left = `${((x + 1) / 2) * 100}%`;
  knob.style.top = `${((y + 1) / 2) * 100}%`;
  const dead = (v) => (Math.abs(v) < 0.08 ? 0 : v);
  wantRates(dead(x) * S.maxRate, -dead(y) * S.maxRate); // up on the pad = pitch up
}

pad.addEventListener("pointerdown", (e) => {
  const why = pad.dataset.locked || S.ratesReason;
  if (why) return showError(why);
  padActive = true;
  pad.setPointerCapture(e.pointerId);
  pad.classList.add("active");
  ++S.motionSeq;
  setTarget(null);
  padMove(e);
});
pad.addEventListener("pointermove", (e) => { if (padActive) padMove(e); });
const padEnd = () => {
  if (!padActive) return;
  padActive = false;
  pad.classList.remove("active");
  knob.style.left = knob.style.top = "50%";
  stopRates();
};
pad.addEventListener("pointerup", padEnd);
pad.addEventListener("pointercancel", padEnd);

const keys = new Set();
const KEYDIR = { ArrowLeft: [-1, 0], ArrowRight: [1, 0], ArrowUp: [0, 1], ArrowDown: [0, -1] };

function keyRates() {
  let x = 0, y = 0;
  for (const k of keys) { x += KEYDIR[k][0]; y += KEYDIR[k][1]; }
  return [x * S.maxRate * 0.5, y * S.maxRate * 0.5];
}

document.addEventListener("keydown", (e) => {
  if (!(e.key in KEYDIR) || !S.catalog || pad.dataset.locked || S.ratesReason) return;
  if (e.target.closest && e.target.closest("input, select, textarea")) return;
  e.preventDefault();
  if (keys.has(e.key)) return;
  keys.add(e.key);
  wantRates(...keyRates());
});
document.addEventListener("keyup", (e) => {
  if (!keys.delete(e.key)) return;
  if (keys.size) wantRates(...keyRates());
  else stopRates();
});
window.addEventListener("blur", () => { if (keys.size) { keys.clear(); stopRates(); } });

// ---------------------------------------------------------------- start



async function main() {
  try {
    S.catalog = await fetchJSON("api/catalog");
  } catch (err) {
    showError(`Could not load the command catalog: ${err.message}`);
    return;
  }
  S.model = S.catalog.model;
  if (!$("traffic-pcap").dataset.reason) $("traffic-pcap").href = withToken("api/traffic.pcap");
  document.title = `${S.model.name} · topgimbal console`;
  $("model-name").textContent = `${S.model.name} · ${S.catalog.dialect}`;
  $("conn-model").textContent = S.model.title;
  $("conn-dialect").textContent = S.catalog.dialect_label;
  $("conn-dialect").title = S.catalog.dialect_title;
  S.hasAttitude = buildAttitude(ui);
  const pointing = buildPointing(ui);
  Object.assign(S, { range: pointing.range, maxRate: pointing.maxRate, ratesReason: pointing.rates });
  buildCamera(ui);
  buildThermal(ui);
  buildRange(ui);
  startWhere();
  buildNetwork(ui);
  buildBuilder(ui, showAnswer);
  // never a level horizon and a heading of 0 as if live: say what is missing until samples come
  const text = S.hasAttitude ? "waiting for attitude" : "no attitude";
  const state = S.hasAttitude ? "waiting" : "none";
  drawNoAttitude($("horizon"), text);
  drawNoAttitude($("heading"), text);
  $("horizon").dataset.state = $("heading").dataset.state = state;
  // show the camera's current settings (once the socket is up and the camera is there: a read
  // of a lost or watched camera only fails); ready for automation afterwards
  const hello = await helloSeen;
  if (S.lockReason) {
    lockControls(S.lockReason);
    if (S.status?.link === "lost") showLost();
  } else if (hello.mode !== "watch") {
    await Promise.all(ui.reads.map((read) => read()));
  }
  provide({
    catalog: S.catalog, run, attempt, showError,
    motionStart() { const seq = ++S.motionSeq; setTarget(null); return seq; },
    motionEnd(seq, yaw) { if (seq === S.motionSeq) setTarget(yaw); },
    refresh(ident) { document.querySelector(`[data-cmd="${CSS.escape(ident)}"]`)?.readBack?.(); },
  });
  document.body.dataset.ready = "1";
  requestAnimationFrame(frame);
}

main();
