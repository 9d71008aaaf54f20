// The panels' controls, built from the catalog: each panel asks for the commands of its group and
// for the commands playing the roles it has dedicated controls for (lib/catalog.js); rows, inputs,
// units, ranges and labels come from the field metadata (lib/fields.js). What the model lacks is
// disabled with the catalog's reason.
//
// `ui` = { catalog, run(op, args, okText), toast, showError, showReason(node, text, sections),
//          disable(node, reason), reads: [] (initial reads), onReport(item) }

import {
  allByRole, answerForms, axisFields, byRole, groupMissing, groupRows, reportsByItself, roleReason, roleSections,
} from "./catalog.js";
import { commandRow, el, fieldInputs, requestForm } from "./fields.js";

const $ = (id) => document.getElementById(id);
const cap = (text) => text.charAt(0).toUpperCase() + text.slice(1);

// Roles with their own controls on a panel (not repeated as generated rows).
const CAMERA_CONTROLS = ["photo", "recording", "sd_capacity", "zoom_control", "focus_control"];

// -- attitude and pointing ----------------------------------------------------------------------

export function buildAttitude(ui) {
  const cat = ui.catalog, m = cat.model;
  const has = byRole(cat, "attitude") != null;
  if (!has) {
    ui.showReason($("attitude-reason"), `No attitude on the ${m.name}: ${roleReason(cat, "attitude")}`,
      roleSections(cat, "attitude", "attitude_stream"));
    for (const id of ["yaw", "pitch", "roll"]) $(id).title = "this model reports no attitude";
  }
  if (!byRole(cat, "version")) {
    $("conn-version").textContent = "not available";
    $("conn-version").title = roleReason(cat, "version");
  }
  return has;
}

// The range an angle input accepts: the model's range, narrowed by every angle command's field
// range for that axis (the catalog's `axis` metadata).
function angleRange(cat, axis) {
  let [lo, hi] = cat.model[`${axis}_range_deg`];
  for (const spec of allByRole(cat, "angle")) {
    for (const f of axisFields(spec, axis)) {
      if (f.min != null) lo = Math.max(lo, f.min);
      if (f.max != null) hi = Math.min(hi, f.max);
    }
  }
  return [lo, hi];
}

// The fastest yaw rate the rate commands take (and the model allows).
function maxRate(cat) {
  const maxima = allByRole(cat, "rate").flatMap((s) => axisFields(s, "yaw")).map((f) => f.max).filter((v) => v != null);
  return Math.min(cat.model.max_rate_deg_s || 30, ...maxima);
}

// Returns { range: {yaw, pitch}, maxRate, rates: reason or null }.
export function buildPointing(ui) {
  const cat = ui.catalog, m = cat.model;
  const angles = allByRole(cat, "angle").length > 0;
  const rates = allByRole(cat, "rate").length > 0;
  const ptz = byRole(cat, "gimbal_control");
  const info = { range: { yaw: angleRange(cat, "yaw"), pitch: angleRange(cat, "pitch") }, maxRate: maxRate(cat), rates: null };
  if (!angles && !rates && !ptz) {
    const why = roleReason(cat, "gimbal_control");
    ui.showReason($("pointing-reason"), `The ${m.name} has no gimbal: ${why}`, roleSections(cat, "gimbal_control"));
    $("panel-pointing").classList.add("disabled");
    info.rates = why;
    for (const b of $("panel-pointing").querySelectorAll("button, input, select")) ui.disable(b, why);
    return info;
  }
  for (const axis of ["yaw", "pitch"]) {
    const [lo, hi] = info.range[axis];
    Object.assign($(`angle-${axis}`), { min: lo, max: hi, title: `${lo}..${hi}° on the ${m.name}` + (axis === "pitch" ? " (up positive)" : "") });
  }
  if (!angles) for (const id of ["btn-point", "angle-yaw", "angle-pitch"]) ui.disable($(id), roleReason(cat, "angle"));
  if (!rates) info.rates = roleReason(cat, "rate");
  if (!ptz) {
    for (const id of ["btn-center", "btn-follow", "btn-lock", "btn-calib"]) ui.disable($(id), roleReason(cat, "gimbal_control"));
    return info;
  }
  // every gimbal control code of this model's table (calibrations, mount, trims, nudges), each
  // sent only after a confirmation; "stop" has its own button
  const codes = (requestForm(ptz, "w")?.fields?.[0]?.values || []).filter((v) => v.name !== "stop");
  const sel = $("calib-select");
  for (const v of codes) sel.append(el("option", { value: v.name, text: cap(v.label || v.name), title: v.vendor_term || v.name }));
  sel.title = `${ptz.title}: the codes of the ${cat.dialect_label}`;
  if (!codes.length) ui.disable($("btn-calib"), `no gimbal codes in the ${cat.dialect_label}`);
  return info;
}

// -- camera -------------------------------------------------------------------------------------

export function buildCamera(ui) {
  const cat = ui.catalog;
  const missing = ["photo", "recording"].filter((r) => !byRole(cat, r));
  if (missing.length) {
    ui.showReason($("camera-reason"), missing.map((r) => roleReason(cat, r)).join("; "), roleSections(cat, ...missing));
  }
  if (!byRole(cat, "photo")) ui.disable($("btn-photo"), roleReason(cat, "photo"));
  if (!byRole(cat, "recording")) ui.disable($("btn-record"), roleReason(cat, "recording"));
  // zoom and focus buttons: the command playing the role, if its action table has the button's action
  const zoom = zoomPlan(cat);
  for (const b of document.querySelectorAll("[data-hold-role], [data-once-role]")) {
    const role = b.dataset.holdRole || b.dataset.onceRole;
    if (role === "zoom_control" && zoom.kind !== "optical") {
      zoomButton(ui, b, zoom);
      continue;
    }
    const spec = byRole(cat, role);
    const value = requestForm(spec, "w")?.fields?.[0]?.values?.find((v) => v.name === b.dataset.action);
    if (!spec) ui.disable(b, roleReason(cat, role));
    else if (!value) ui.disable(b, `${spec.title} has no ${b.dataset.action} on the ${cat.model.name}`);
    else {
      b.dataset.id = spec.id;
      b.title = `${value.label} (${spec.id} ${value.name})`;
    }
  }
  $("zoom-note").textContent = zoom.note;
  $("zoom-note").title = zoom.tip || "";
  // the rows show the camera's current settings: those read without arguments are read when
  // shown (the lens rows on load, the folded image and video settings when unfolded)
  const rows = (box, specs) => {
    const reads = [];
    for (const spec of specs) {
      const row = commandRow(ui, spec.id);
      box.append(row);
      if (row.readBack) reads.push(row.read);
    }
    return reads;
  };
  ui.reads.push(...rows($("lens-settings"), groupRows(cat, "lens", CAMERA_CONTROLS)));
  const more = groupRows(cat, "camera", CAMERA_CONTROLS);
  const moreReads = rows($("camera-settings"), more);
  $("camera-more").addEventListener("toggle", () => {
    if ($("camera-more").open && !$("camera-more").dataset.read) {
      $("camera-more").dataset.read = "1";
      for (const read of moreReads) read();
    }
  });
  $("camera-more").hidden = !more.length;
  $("camera-more-summary").textContent = `${cat.groups.camera.replace(/^./, (c) => c.toUpperCase())} (${more.length})`;
  if (!byRole(cat, "sd_capacity")) {
    $("sd").textContent = "not available";
    $("sd").title = roleReason(cat, "sd_capacity");
  }
}

// What "- wide / + tele" can do on this model, from the catalog and the model profile: run the
// zoom motor (an optical zoom), step the digital zoom (a fixed lens with a digital zoom whose table
// has steps, e.g. the C12), or nothing (a fixed lens without one: the motor command would be
// acknowledged and change nothing, so the buttons are disabled with that reason).
function zoomPlan(cat) {
  const m = cat.model, motor = byRole(cat, "zoom_control");
  if (motor && m.optical_zoom_max > 1) {
    return { kind: "optical", note: `optical zoom 1..${m.optical_zoom_max}×: hold to zoom` };
  }
  const fixed = `the ${m.name}'s lens is fixed (no optical zoom)`;
  const digital = byRole(cat, "digital_zoom");
  const field = (requestForm(digital, "w")?.fields || []).find((f) => f.kind === "enum");
  const steps = field && ["zoom_in", "zoom_out"].every((a) => field.values.some((v) => v.name === a));
  if (digital && steps) {
    return { kind: "digital", spec: digital, field: field.name, note: `${cap(fixed)}: each click is one digital zoom step (1..${m.digital_zoom_max}×)`,
             tip: `${digital.title} (${digital.id})` };
  }
  const reason = motor
    ? `${fixed} and it has no stepped digital zoom: the zoom command would be acknowledged and change nothing`
    : roleReason(cat, "zoom_control");
  return { kind: "none", reason, note: `${cap(reason)}.` };
}

function zoomButton(ui, b, zoom) {
  if (zoom.kind === "none") return ui.disable(b, zoom.reason);
  b.dataset.stepId = zoom.spec.id;
  b.title = `one digital zoom step (${zoom.spec.id} ${b.dataset.action}): ${zoom.note}`;
  b.addEventListener("click", async () => {
    await ui.run("request", { id: zoom.spec.id, values: { [zoom.field]: b.dataset.action } });
    document.querySelector(`[data-cmd="${CSS.escape(zoom.spec.id)}"]`)?.readBack?.(); // the level the camera reached, in its row
  });
}

// -- thermal ------------------------------------------------------------------------------------

export function buildThermal(ui) {
  const cat = ui.catalog, m = cat.model;
  if (!m.thermal) ui.showReason($("thermal-reason"), `The ${m.name} (${m.title}) has no thermal camera.`, "");
  for (const spec of groupRows(cat, "thermal")) {
    const row = commandRow(ui, spec.id);
    $("thermal-settings").append(row);
    const read = requestForm(spec, "r");
    if (row.read && !(read.fields || []).length) ui.reads.push(row.read); // show the camera's values
  }
  // what the dialect has and this model lacks, with the reason
  const missing = groupMissing(cat, "thermal");
  for (const c of missing) $("thermal-unsupported").append(commandRow(ui, c.id));
  if (missing.length) {
    $("thermal-missing").hidden = false;
    const n = missing.length;
    $("thermal-missing-summary").textContent = `${n} thermal setting${n > 1 ? "s" : ""} not available on the ${m.name} (why)`;
  }
}

// -- laser range and target ---------------------------------------------------------------------

export function buildRange(ui) {
  const cat = ui.catalog, m = cat.model, box = $("range-buttons");
  const spec = byRole(cat, "range");
  if (!spec) {
    ui.showReason($("range-reason"), `The ${m.name} has no laser rangefinder: ${roleReason(cat, "range")}.`, roleSections(cat, "range"));
    $("range-distance").textContent = "not available";
  } else {
    if (requestForm(spec, "r") && !(requestForm(spec, "r").fields || []).length) {
      box.append(el("button", { "data-testid": "btn-range-single", text: "Measure", title: `${spec.title} (${spec.id} query)`,
        onclick: async () => {
          const msg = await ui.run("request", { id: spec.id, read: true });
          if (msg?.fields) ui.onReport({ id: spec.id, fields: msg.fields });
        } }));
    }
    const write = requestForm(spec, "w");
    const actions = write?.fields?.length === 1 && write.fields[0].kind === "enum" ? write.fields[0] : null;
    for (const v of actions?.values || []) {
      box.append(el("button", { "data-testid": `btn-range-${v.name}`, text: cap(v.label || v.name), title: `${spec.id} ${v.name}`,
        onclick: () => ui.run("request", { id: spec.id, values: { [actions.name]: v.name } }) }));
    }
    if (write && !actions) $("range-settings").append(commandRow(ui, spec.id));
  }
  for (const s of groupRows(cat, "position")) $("vehicle-settings").append(commandRow(ui, s.id));
  if (!$("vehicle-settings").children.length) $("vehicle-box").hidden = true;
  if (!reportsByItself(byRole(cat, "latitude"))) {
    $("target-lat").textContent = $("target-lon").textContent = "not reported by this model";
  }
  $("btn-copy-target").onclick = () => copyTarget($("btn-copy-target"));
}

// The target as one "lat, lon" text, once both halves have come (the camera's target solution).
const target = { lat: null, lon: null };

function showTarget() {
  if (target.lat == null || target.lon == null) return;
  const text = `${target.lat.toFixed(7)}, ${target.lon.toFixed(7)}`;
  $("target-pos").textContent = text;
  $("btn-copy-target").disabled = false;
}

// Copy to the clipboard; where the page may not (plain HTTP on another host), the older
// select-and-copy path. The button says what happened, and keeps what it copied in data-copied.
async function copyTarget(button) {
  const text = $("target-pos").textContent;
  let ok = false;
  try {
    await navigator.clipboard.writeText(text);
    ok = true;
  } catch {
    const area = el("textarea", { text });
    document.body.append(area);
    area.value = text;
    area.select();
    try { ok = document.execCommand("copy"); } catch { ok = false; }
    area.remove();
  }
  button.dataset.copied = ok ? text : "";
  button.textContent = ok ? "Copied" : "Copy failed: select the text";
  setTimeout(() => { button.textContent = "Copy"; }, 2000);
}

// What the camera reports by itself or answers, shown where it belongs: a distance (a range
// answer's field in metres), a target position (latitude / longitude reports).
export function showReport(cat, it) {
  const spec = cat.commands[it.id];
  if (!spec || !it.fields || it.echo) return;
  const form = answerForms(spec).find((f) => (f.fields || []).length && f.fields.every((x) => x.name in it.fields));
  if (!form) return;
  const f = form.fields[0], v = it.fields[f.name];
  if (spec.role === "range" && f.unit === "m") {
    $("range-distance").textContent = v == null ? "no echo (out of range)" : `${v.toFixed(1)} m`;
  } else if ((spec.role === "latitude" || spec.role === "longitude") && typeof v === "number") {
    $(spec.role === "latitude" ? "target-lat" : "target-lon").textContent = `${v.toFixed(6)}°`;
    target[spec.role === "latitude" ? "lat" : "lon"] = v;
    showTarget();
  }
}

// -- network ------------------------------------------------------------------------------------

// The network group's address settings (a write of one IPv4 field), in catalog order.
function addressCommands(cat) {
  return groupRows(cat, "network").filter((s) => {
    const f = requestForm(s, "w")?.fields || [];
    return f.length === 1 && f[0].kind === "ipv4" && requestForm(s, "r");
  });
}

export function buildNetwork(ui) {
  const cat = ui.catalog, box = $("network-fields");
  const have = addressCommands(cat);
  ui.net = { specs: have, values: {} };
  if (!have.length) {
    const why = roleReason(cat, "ip_address");
    ui.showReason($("network-reason"), why, roleSections(cat, "ip_address"));
    ui.disable($("btn-net-read"), why);
    ui.disable($("btn-net-write"), why);
    return;
  }
  for (const s of have) {
    box.append(el("label", { for: `net-${s.id}`, text: s.title, title: `${s.id} — ${s.section}` }),
      el("input", { id: `net-${s.id}`, "data-testid": `net-${s.id}`, type: "text", placeholder: "read first", spellcheck: "false" }));
  }
  $("btn-net-read").addEventListener("click", () => readNetwork(ui));
  $("btn-net-write").addEventListener("click", () => writeNetwork(ui));
}

const addressField = (spec) => requestForm(spec, "w").fields[0].name;

async function readNetwork(ui) {
  for (const s of ui.net.specs) {
    const m = await ui.run("request", { id: s.id, read: true });
    const v = m?.fields?.[addressField(s)];
    if (v != null) {
      ui.net.values[s.id] = v;
      $(`net-${s.id}`).value = v;
    }
  }
}

async function writeNetwork(ui) {
  const changes = ui.net.specs.map((s) => [s, $(`net-${s.id}`).value.trim()]).filter(([s, v]) => v && v !== ui.net.values[s.id]);
  if (!changes.length) return ui.toast("Nothing to write: read the settings and change a value first.");
  const list = changes.map(([s, v]) => `${s.title}: ${v}`).join("\n");
  const ip = changes.find(([s]) => s.role === "ip_address");
  const warning = ip
    ? `The camera's address will change to ${ip[1]}. This console will lose contact with the camera; restart it with the new address.`
    : "The camera's network configuration (and so its address) will change; this console may lose contact with it.";
  if (!window.confirm(`Write these network settings?\n\n${list}\n\n${warning}`)) return ui.toast("Network settings not written.");
  for (const [s, v] of changes) {
    const r = await ui.run("request", { id: s.id, values: { [addressField(s)]: v } }, `${s.title} written`);
    if (r !== undefined) ui.net.values[s.id] = v;
  }
}

// -- command builder ----------------------------------------------------------------------------

export function buildBuilder(ui, showAnswer) {
  const cat = ui.catalog, sel = $("cmd-select");
  const specs = Object.values(cat.commands).filter((c) => requestForm(c, "w") || requestForm(c, "r"))
    .sort((a, b) => a.id.localeCompare(b.id));
  for (const c of specs) sel.append(el("option", { value: c.id, text: `${c.id} — ${c.title}` }));
  let inputs = null;
  const refresh = () => {
    const spec = cat.commands[sel.value];
    const rwSel = $("cmd-rw");
    for (const o of rwSel.options) o.disabled = !requestForm(spec, o.value);
    if (!requestForm(spec, rwSel.value)) rwSel.value = requestForm(spec, "w") ? "w" : "r";
    inputs = fieldInputs(requestForm(spec, rwSel.value)?.fields || [], { prefix: "cmd-" });
    $("cmd-fields").replaceChildren(inputs.node);
  };
  sel.addEventListener("change", refresh);
  $("cmd-rw").addEventListener("change", refresh);
  $("btn-cmd-send").addEventListener("click", async () => {
    const read = $("cmd-rw").value === "r";
    const m = await ui.run("request", { id: sel.value, read, values: inputs.get() });
    if (m !== undefined) showAnswer("", m);
  });
  const version = byRole(cat, "version");
  if (version) sel.value = version.id;
  refresh();
}
