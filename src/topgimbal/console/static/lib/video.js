// The console's video panel (topgimbal.video.webconsole): the camera's pictures through the
// server's MJPEG relay, an attitude/zoom/recording overlay, click to point, drag a box to track,
// wheel to zoom, thermal as picture-in-picture or side by side, the stream's state when it drops,
// and the glass-to-glass latency read from the timestamp the simulator burns into its pictures.
import { fetchJSON, token, withToken } from "./conn.js";

const STAMP_CELLS = 80, STAMP_BITS = 48;   // as topgimbal/video/render.py draws them
const panel = document.getElementById("panel-video");
const latencies = [];                      // ms, newest last (bench/video.py reads it)
window.__videoLatency = latencies;

function post(path, body) {
  const headers = { "Content-Type": "application/json" };
  if (token) headers["X-Topgimbal-Token"] = token;
  return fetch(withToken(path), { method: "POST", headers, body: JSON.stringify(body) })
    .then(async (r) => ({ ok: r.ok, body: await r.json().catch(() => ({})) }));
}

function el(tag, attrs = {}, ...kids) {
  const e = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs)) e.setAttribute(k, v);
  e.append(...kids);
  return e;
}

function view(lens) {
  const img = el("img", { alt: `${lens} video`, "data-testid": `video-${lens}`, draggable: "false" });
  const state = el("div", { class: "vstate", "data-testid": `video-state-${lens}` }, "connecting…");
  const box = el("div", { class: "vbox", hidden: "" });
  const wrap = el("div", { class: `vview ${lens}`, "data-lens": lens }, img, state, box);
  return { lens, img, state, box, wrap, pictures: -1, still: 0 };
}

function decodeStamp(ctx, w, h) {
  const cell = w / STAMP_CELLS, y = h - 1.5 * cell;
  const level = (i) => {
    const d = ctx.getImageData(Math.floor(cell + (i + 0.5) * cell) - 1, Math.floor(y) - 1, 3, 3).data;
    let s = 0;
    for (let k = 0; k < d.length; k += 4) s += (d[k] + d[k + 1] + d[k + 2]) / 3;
    return s / (d.length / 4);
  };
  if (!(level(0) > 160 && level(1) < 96)) return null;
  let v = 0;
  for (let i = 0; i < STAMP_BITS; i++) v = v * 2 + (level(2 + i) > 128 ? 1 : 0);
  return v;
}

async function start() {
  let info;
  try { info = await fetchJSON("/api/video"); } catch { return; }   // no video extra: no panel
  panel.hidden = false;
  const views = Object.fromEntries(info.lenses.map((l) => [l.lens, view(l.lens)]));
  const stage = el("div", { class: "vstage pip", "data-testid": "video-stage" });
  const overlay = el("div", { class: "voverlay", "data-testid": "video-overlay" }, "");
  const latency = el("span", { class: "vlatency", "data-testid": "video-latency" }, "");
  const lensNames = Object.keys(views);
  let main = lensNames[0];
  const layout = () => {
    stage.replaceChildren(...lensNames.map((n) => views[n].wrap), overlay);
    for (const n of lensNames) views[n].wrap.classList.toggle("main", n === main);
  };
  const tools = el("div", { class: "vtools" });
  if (lensNames.length > 1) {
    const swap = el("button", { type: "button", "data-testid": "video-swap" }, "swap");
    swap.onclick = () => { main = lensNames.find((n) => n !== main); layout(); };
    const mode = el("button", { type: "button", "data-testid": "video-layout" }, "side by side");
    mode.onclick = () => {
      const pip = stage.classList.toggle("pip");
      stage.classList.toggle("side", !pip);
      mode.textContent = pip ? "side by side" : "picture in picture";
    };
    tools.append(swap, mode);
  }
  tools.append(latency);
  panel.append(stage, tools,
    el("p", { class: "muted small" }, "click: point there · drag: track the box · wheel: zoom"));
  layout();
  for (const v of Object.values(views)) {
    v.img.src = withToken(`/video/${v.lens}.mjpg`);
    v.img.addEventListener("error", () => {           // the relay went away: try again
      v.state.textContent = "no video: reconnecting…"; v.wrap.dataset.state = "lost";
      setTimeout(() => { v.img.src = withToken(`/video/${v.lens}.mjpg?t=${Date.now()}`); }, 1000);
    });
    attachPointer(v);
  }
  const canvas = document.createElement("canvas");
  const ctx = canvas.getContext("2d", { willReadFrequently: true });
  setInterval(() => {                                 // glass-to-glass from the burned-in time
    const img = views[lensNames[0]].img;
    if (!img.naturalWidth) return;
    canvas.width = img.naturalWidth; canvas.height = img.naturalHeight;
    ctx.drawImage(img, 0, 0);
    const stamp = decodeStamp(ctx, canvas.width, canvas.height);
    if (stamp === null) { latency.textContent = ""; return; }
    const ms = (Date.now() % 2 ** STAMP_BITS) - stamp;
    latencies.push(ms); if (latencies.length > 100) latencies.shift();
    latency.textContent = `glass-to-glass ${ms} ms`;
  }, 250);
  const poll = async () => {
    try {
      const now = await fetchJSON("/api/video");
      for (const l of now.lenses) {
        const v = views[l.lens]; if (!v) continue;
        const moving = l.pictures !== v.pictures; v.pictures = l.pictures;
        v.still = moving ? 0 : v.still + 1;
        let text = "", state = l.state;
        if (l.state === "reconnecting") text = `stream lost: reconnecting… (${l.error || ""})`;
        else if (l.state === "connecting") text = "connecting…";
        else if (l.state === "playing" && v.still >= 4) { text = "stream stalled"; state = "stalled"; }
        v.state.textContent = text; v.state.hidden = !text; v.wrap.dataset.state = state;
      }
      const a = now.attitude, parts = [];
      if (a) parts.push(`yaw ${a.yaw_deg.toFixed(1)}°  pitch ${a.pitch_deg.toFixed(1)}°  roll ${a.roll_deg.toFixed(1)}°`);
      parts.push(`zoom ${now.zoom_x.toFixed(1)}×`);
      if (now.recording) parts.push("● REC");
      overlay.textContent = parts.join("   ");
      overlay.classList.toggle("rec", !!now.recording);
    } catch { /* the link pane says why */ }
    setTimeout(poll, 500);
  };
  poll();
}

function attachPointer(v) {
  let down = null;
  const frac = (e) => {
    const r = v.img.getBoundingClientRect();
    return [Math.min(1, Math.max(0, (e.clientX - r.left) / r.width)), Math.min(1, Math.max(0, (e.clientY - r.top) / r.height))];
  };
  v.img.addEventListener("mousedown", (e) => { e.preventDefault(); down = { x: e.clientX, y: e.clientY, f: frac(e) }; });
  v.img.addEventListener("mousemove", (e) => {
    if (!down) return;
    const r = v.img.getBoundingClientRect(), [x0, y0] = down.f, [x1, y1] = frac(e);
    Object.assign(v.box.style, {
      left: `${Math.min(x0, x1) * r.width}px`, top: `${Math.min(y0, y1) * r.height}px`,
      width: `${Math.abs(x1 - x0) * r.width}px`, height: `${Math.abs(y1 - y0) * r.height}px`,
    });
    v.box.hidden = Math.hypot(e.clientX - down.x, e.clientY - down.y) < 6;
  });
  window.addEventListener("mouseup", async (e) => {
    if (!down) return;
    const start = down; down = null;
    const [x1, y1] = frac(e);
    if (Math.hypot(e.clientX - start.x, e.clientY - start.y) < 6) {
      const r = await post("/api/video/point", { lens: v.lens, x: x1, y: y1 });
      v.wrap.dataset.last = r.ok ? `point ${r.body.yaw_deg} ${r.body.pitch_deg}` : `error ${r.body.message}`;
    } else {
      const [x0, y0] = start.f;
      const r = await post("/api/video/track", { lens: v.lens, x0, y0, x1, y1 });
      v.wrap.dataset.last = r.ok ? "tracking" : `error ${r.body.message}`;
      setTimeout(() => { v.box.hidden = true; }, r.ok ? 1500 : 300);
    }
  });
  let lastWheel = 0;
  v.img.addEventListener("wheel", (e) => {
    e.preventDefault();
    const now = Date.now(); if (now - lastWheel < 250) return; lastWheel = now;
    post("/api/video/zoom", { direction: e.deltaY < 0 ? "in" : "out" });
  }, { passive: false });
}

start();
