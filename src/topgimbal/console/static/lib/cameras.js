// Several cameras: the switcher in the top bar and the overview grid, from GET /api/cameras
// (polled at the interval the server gives, 0.25 s). The page of a camera is /cam/NAME/ (its API
// and socket are relative to it); "/" is the first camera. A console of one camera answers
// {"several": false}: then neither shows and the page stops asking.
import { fetchJSON, withToken } from "./conn.js";

const $ = (id) => document.getElementById(id);
const here = location.pathname.match(/^\/cam\/([^/]+)\/?$/);
const current = here ? decodeURIComponent(here[1]) : null;
const pageOf = (name) => withToken(`/cam/${encodeURIComponent(name)}/`);
const deg = (v) => (typeof v === "number" && Number.isFinite(v) ? `${v.toFixed(1)}°` : "–");

function el(tag, attrs = {}, text = "") {
  const e = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs)) e.setAttribute(k, v);
  if (text) e.textContent = text;
  return e;
}

// The tiles are made once per camera and updated in place: the grid is polled every 0.25 s, and a
// tile made anew each time ate clicks (the press on one button, the release on its successor: no
// click at all; seen on a loaded machine, and a person's click lasts about 0.1 s).
const tiles = new Map();  // camera name -> { button, signature }

function tileFor(name) {
  let entry = tiles.get(name);
  if (!entry) {
    const t = el("button", { class: "camtile", type: "button", "data-testid": `cam-tile-${name}`, "data-camera": name });
    t.addEventListener("click", () => { if (t.getAttribute("aria-current") !== "true") location.href = pageOf(name); });
    entry = { button: t, signature: "" };
    tiles.set(name, entry);
  }
  return entry;
}

function tile(c, selected) {
  const entry = tileFor(c.name);
  const t = entry.button;
  t.setAttribute("data-link", c.link);
  t.setAttribute("aria-current", selected ? "true" : "false");
  const signature = JSON.stringify(c);
  if (signature === entry.signature) return t;
  entry.signature = signature;
  const parts = [el("span", { class: "cname" }, c.name), el("span", { class: "cmodel muted" }, `${c.model} · ${c.source}`)];
  const link = el("span", { class: "clink", "data-state": c.link, "data-testid": `cam-link-${c.name}` },
    c.link === "lost" ? `LOST: ${c.link_reason || "no reason given"}` : c.link);
  if (c.link_reason) link.title = c.link_reason;
  parts.push(link);
  const a = c.attitude;
  parts.push(el("span", { class: "catt", "data-testid": `cam-att-${c.name}`, "data-yaw": a ? String(a.yaw) : "" },
    a ? `yaw ${deg(a.yaw)} pitch ${deg(a.pitch)} roll ${deg(a.roll)}` : (c.has_attitude ? "waiting for attitude" : "no attitude")));
  const rec = c.recording === true ? "● recording" : c.recording === false ? "not recording" : "recording: –";
  parts.push(el("span", { class: "crec", "data-rec": c.recording ? "1" : "0", "data-testid": `cam-rec-${c.name}` }, rec));
  for (const [what, why] of Object.entries(c.unavailable || {})) {
    parts.push(el("span", { class: "cnote", title: why, "data-testid": `cam-unavailable-${c.name}-${what}` }, `${what}: unavailable`));
  }
  morph(t, parts);
  return t;
}

// The tile's parts updated in place when they are the same kinds of element: its text changes with
// every attitude sample, and a press on a span that is replaced before the release is no click on
// the tile (the press and the release then have no common target in the page; seen beside two busy
// loops, where a click's press and release can straddle a poll).
function morph(parent, parts) {
  const old = [...parent.children];
  const alike = old.length === parts.length && parts.every((p, i) => old[i].tagName === p.tagName && old[i].className === p.className);
  if (!alike) {
    parent.replaceChildren(...parts);
    return;
  }
  parts.forEach((p, i) => {
    const o = old[i];
    if (o.textContent !== p.textContent) o.textContent = p.textContent;
    for (const a of o.getAttributeNames()) if (!p.hasAttribute(a)) o.removeAttribute(a);
    for (const a of p.getAttributeNames()) if (o.getAttribute(a) !== p.getAttribute(a)) o.setAttribute(a, p.getAttribute(a));
  });
}

function render(body) {
  const cams = body.cameras || [];
  const selected = current ?? cams[0]?.name;
  $("panel-cameras").hidden = false;
  $("camera-switch").hidden = false;
  $("cameras-count").textContent = `${cams.length} of at most ${body.max_cameras}`;
  for (const name of [...tiles.keys()]) if (!cams.some((c) => c.name === name)) tiles.delete(name);
  const grid = $("camera-grid");
  const wanted = cams.length ? cams.map((c) => tile(c, c.name === selected))
    : [el("p", { class: "muted" }, "no camera yet: waiting for cameras served on Zenoh")];
  // the same buttons in the same order: left where they are (moving one would drop a press on it)
  const same = wanted.length === grid.children.length && wanted.every((t, i) => grid.children[i] === t);
  if (!same) grid.replaceChildren(...wanted);
  const sel = $("camera-select");
  const names = cams.map((c) => c.name).join("\n");
  if (sel.dataset.names !== names) {
    sel.dataset.names = names;
    sel.replaceChildren(...cams.map((c) => el("option", { value: c.name }, `${c.name} (${c.model})`)));
  }
  if (selected != null && sel.value !== selected) sel.value = selected;
  document.body.dataset.camera = selected ?? "";
}

async function poll() {
  let body;
  try {
    body = await fetchJSON("/api/cameras");
  } catch (err) {
    setTimeout(poll, 2000);  // the console is restarting or gone: the link badge says so
    return;
  }
  if (!body.several) return;  // one camera: no switcher, no grid
  render(body);
  setTimeout(poll, Math.max(100, (body.interval_s || 0.25) * 1000));
}

$("camera-select").addEventListener("change", (e) => {
  const name = e.target.value;
  if (name && name !== (current ?? document.body.dataset.camera)) location.href = pageOf(name);
});

poll();
