// The console's video panel (topgimbal.video.webconsole): the camera's pictures through the
// server's MJPEG relay, an attitude/zoom/recording overlay, click to point, drag a box to track,
// wheel to zoom, thermal as picture-in-picture or side by side, the stream's state when it drops,
// and the glass-to-glass latency read from the timestamp the simulator burns into its pictures.
// A click moves the page's commanded-yaw marker like Point does (lib/bus.js); tracking started by a
// box shows its state and has a Stop (the catalog's tracking command with a `stop` action).
import { consoleReady } from "./bus.js";
import { byRole } from "./catalog.js";
import { requestForm } from "./fields.js";
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

// One picture with its own state line and its own yaw/pitch/zoom overlay (in side by side each
// picture carries its overlay; in picture-in-picture the inset's is hidden).
// The picture's box has the stream's shape from the start (`size`, from /api/video): the panel keeps
// its height when the first picture comes, so nothing below it moves under the operator's pointer.
function view(lens, size) {
  const img = el("img", { alt: `${lens} video`, "data-testid": `video-${lens}`, draggable: "false" });
  if (Array.isArray(size) && size[0] > 0 && size[1] > 0) img.style.aspectRatio = `${size[0]} / ${size[1]}`;
  const state = el("div", { class: "vstate", "data-testid": `video-state-${lens}` }, "connecting…");
  const box = el("div", { class: "vbox", hidden: "" });
  const overlay = el("div", { class: "voverlay", "data-testid": `video-overlay-${lens}` }, "");
  const wrap = el("div", { class: `vview ${lens}`, "data-lens": lens }, img, overlay, state, box);
  return { lens, img, state, box, overlay, wrap, pictures: -1, still: 0, shown: false };
}

const cap = (t) => t.charAt(0).toUpperCase() + t.slice(1);

// The relay's error without the URL it repeats ("cannot open URL: [Errno 111] Connection refused: 'URL'").
function shortError(error, url) {
  let e = String(error || "");
  if (url) e = e.split(`'${url}'`).join("").split(url).join("");
  e = e.replace(/\[Errno \d+\]\s*/g, "").replace(/^cannot open\s*:\s*/, "").replace(/[:\s]+$/, "");
  return e;
}

// The message for a lens that has never shown a picture: which URL, why, and how to give another.
function noVideoText(lensInfo) {
  const why = shortError(lensInfo.error, lensInfo.url) || "nothing came";
  return `${cap(lensInfo.lens)}: no video from ${lensInfo.url || "the camera"} (${why}); retrying. ` +
    `Elsewhere? Start the console with --video-url ${lensInfo.lens}=rtsp://HOST:PORT/PATH or --video-port PORT.`;
}

// Tracking, from the catalog: what stops it (the tracking command whose action table has `stop`)
// and what reads its state (a readable tracking command whose answer has an enum `state`).
function trackingPlan(cat) {
  const starts = byRole(cat, "tracking_target") || byRole(cat, "tracking_box");
  let stop = null;
  for (const role of ["tracking", "tracking_confirm"]) {
    const spec = byRole(cat, role);
    const field = (requestForm(spec, "w")?.fields || []).find((f) => f.kind === "enum" && f.values.some((v) => v.name === "stop"));
    if (spec && field) { stop = { spec, field: field.name }; break; }
  }
  const q = byRole(cat, "tracking");
  const answer = (q?.forms || []).find((f) => f.rw === "r" && f.direction === "response");
  const stateField = (answer?.fields || []).find((f) => f.kind === "enum" && f.name === "state");
  const query = q && requestForm(q, "r") && stateField ? { spec: q, field: stateField } : null;
  return { starts, stop, query };
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
  // body[data-video] says the panel is decided ("none" or "shown"): the page's layout above the
  // controls is final from then on (the panel sits above them), which is what a test waits for
  try { info = await fetchJSON("api/video"); } catch { document.body.dataset.video = "none"; return; }   // no video extra: no panel
  panel.hidden = false;
  const views = Object.fromEntries(info.lenses.map((l) => [l.lens, view(l.lens, l.size)]));
  const stage = el("div", { class: "vstage pip", "data-testid": "video-stage" });
  const latency = el("span", { class: "vlatency", "data-testid": "video-latency" }, "");
  const lensNames = Object.keys(views);
  let main = lensNames[0];
  const layout = () => {
    stage.replaceChildren(...lensNames.map((n) => views[n].wrap));
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
  const tracking = el("span", { class: "vtracking", "data-testid": "video-tracking" }, "");
  const trackStop = el("button", { type: "button", "data-testid": "btn-track-stop", hidden: "" }, "Stop tracking");
  tools.append(tracking, trackStop, latency);
  const hint = el("p", { class: "muted small", "data-testid": "video-hint" }, "click: point there · drag: track the box · wheel: zoom");
  // the path's line is there, one line high, before the panel counts as shown: its text came later
  // and took a line of its own then, which moved every control below under a held pointer (a level
  // drag on the pad became a pitch rate)
  const pathLabel = el("span", { class: "vpath muted small", "data-testid": "video-path" }, "video: starting…");
  tools.append(pathLabel);
  panel.append(stage, tools, hint);
  layout();
  document.body.dataset.video = "shown";
  const track = { views, tracking, trackStop, hint, plan: null };
  consoleReady.then((api) => setUpTracking(api, track));
  const showPaths = () => {
    pathLabel.textContent = "video: " + lensNames.map((n) => `${n} ${views[n].path === "webrtc"
      ? "WebRTC (H.264 as the camera sends it)" : "MJPEG (the server's relay)"}`).join(" · ");
    pathLabel.title = pathLabel.textContent;   // the whole text where the line cuts it
  };
  const byLens = Object.fromEntries(info.lenses.map((l) => [l.lens, l]));
  for (const v of Object.values(views)) {
    v.path = "mjpeg";
    playWebRtc(v, byLens[v.lens], track, showPaths).then((ok) => { if (!ok) playMjpeg(v, track); showPaths(); });
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
      const now = await fetchJSON("api/video");
      let nopic = false;
      for (const info of now.lenses) {
        const v = views[info.lens]; if (!v) continue;
        // a lens played over WebRTC: its state is the WebRTC reader's, not the idle relay's
        const l = v.path === "webrtc" && info.webrtc?.state ? { ...info, ...info.webrtc } : info;
        const moving = l.pictures !== v.pictures; v.pictures = l.pictures;
        v.still = moving ? 0 : v.still + 1;
        let text = "", state = l.state;
        // a lens that failed before any picture gets its message row; one still connecting keeps its
        // picture's box (with "connecting…" over it): the normal start moves nothing on the page.
        // A lens that has shown a picture keeps its box when its stream is lost (the relay's count
        // starts again and a reloaded <img> has no size yet, but the panel must not jump).
        v.shown ||= l.pictures > 0 || v.img.naturalWidth > 0;
        const never = !v.shown && l.state === "reconnecting";
        if (never && l.state === "reconnecting") { text = noVideoText(l); state = "novideo"; }
        else if (l.state === "reconnecting") {
          const why = shortError(l.error, l.url);
          text = `stream lost: reconnecting…${why ? ` (${why})` : ""}`;
        }
        else if (l.state === "connecting") text = "connecting…";
        else if (l.state === "playing" && v.still >= 4) { text = "stream stalled"; state = "stalled"; }
        v.state.textContent = text; v.state.hidden = !text; v.wrap.dataset.state = state;
        v.wrap.classList.toggle("nopic", never);
        nopic ||= never;
      }
      // a lens without any picture: one message per lens, one under the other (no inset on top)
      stage.classList.toggle("nopic", nopic);
      const a = now.attitude, parts = [];
      if (a) parts.push(`yaw ${a.yaw_deg.toFixed(1)}°  pitch ${a.pitch_deg.toFixed(1)}°  roll ${a.roll_deg.toFixed(1)}°`);
      parts.push(`zoom ${now.zoom_x.toFixed(1)}×`);
      if (now.recording) parts.push("● REC");
      for (const v of Object.values(views)) {
        v.overlay.textContent = parts.join("   ");
        v.overlay.classList.toggle("rec", !!now.recording);
      }
    } catch { /* the link pane says why */ }
    setTimeout(poll, 500);
  };
  poll();
}

// MJPEG: the server's relay (decodes and JPEG-encodes); plays any codec in any browser.
function playMjpeg(v, track) {
  v.path = "mjpeg";
  v.img.src = withToken(`video/${v.lens}.mjpg`);
  v.img.addEventListener("error", () => {           // the relay went away: try again
    v.state.textContent = "no video: reconnecting…"; v.wrap.dataset.state = "lost";
    setTimeout(() => { v.img.src = withToken(`video/${v.lens}.mjpg?t=${Date.now()}`); }, 1000);
  });
  attachPointer(v, track);
}

// WebRTC through the console's WHEP endpoint (the camera's H.264 packets, no re-encoding: the
// lowest latency). Resolves false (and the caller plays MJPEG) when the browser has no WebRTC,
// the console has none (no aiortc), the stream is not H.264, the places are taken, or no picture
// comes within WEBRTC_WAIT_MS; a connection lost later switches the lens to MJPEG. `?video=mjpeg`
// in the page's URL skips it.
const WEBRTC_WAIT_MS = 8000;
async function playWebRtc(v, lensInfo, track, changed) {
  if (!window.RTCPeerConnection || !lensInfo?.webrtc) return false;
  if (new URLSearchParams(location.search).get("video") === "mjpeg") return false;
  if (lensInfo.webrtc.codec && lensInfo.webrtc.codec !== "h264") return false;
  // asked first, so a lens that cannot play over WebRTC costs no failed request
  const ready = await fetchJSON(`video/${v.lens}/whep`).catch(() => null);
  if (!ready?.ready) return false;
  const pc = new RTCPeerConnection({ iceServers: [] });
  let session = null;
  const end = () => {
    pc.close();
    if (session) fetch(withToken(session), { method: "DELETE", headers: token ? { "X-Topgimbal-Token": token } : {} }).catch(() => {});
    session = null;
  };
  try {
    pc.addTransceiver("video", { direction: "recvonly" });
    const video = el("video", { "data-testid": `video-${v.lens}`, "data-path": "webrtc", playsinline: "" });
    video.muted = true; video.autoplay = true;
    // answers like an <img>, so what reads the picture's size (latency, scripts) works on both
    Object.defineProperty(video, "naturalWidth", { get: () => video.videoWidth });
    Object.defineProperty(video, "naturalHeight", { get: () => video.videoHeight });
    pc.ontrack = (e) => {
      // a live picture to steer by: ask for the smallest playout delay the browser allows
      if ("playoutDelayHint" in e.receiver) e.receiver.playoutDelayHint = 0;
      if ("jitterBufferTarget" in e.receiver) e.receiver.jitterBufferTarget = 0;
      video.srcObject = e.streams[0] || new MediaStream([e.track]);
    };
    await pc.setLocalDescription(await pc.createOffer());
    const headers = { "Content-Type": "application/sdp" };
    if (token) headers["X-Topgimbal-Token"] = token;
    // the offer as created, without waiting for candidates: the console answers with the one
    // address this page reached it on, and learns the browser's from its connectivity checks
    const r = await fetch(withToken(`video/${v.lens}/whep`), { method: "POST", headers, body: pc.localDescription.sdp });
    if (r.status !== 201) { pc.close(); return false; }
    session = r.headers.get("Location");            // the session's path: DELETE ends it
    await pc.setRemoteDescription({ type: "answer", sdp: await r.text() });
    const shown = await new Promise((res) => {
      const t = setTimeout(() => res(false), WEBRTC_WAIT_MS);
      video.addEventListener("loadeddata", () => { clearTimeout(t); res(true); }, { once: true });
    });
    if (!shown) { end(); return false; }
    v.wrap.replaceChild(video, v.img);
    const img = v.img;
    v.img = video; v.path = "webrtc";
    attachPointer(v, track);
    pc.onconnectionstatechange = () => {
      if (pc.connectionState !== "failed" && pc.connectionState !== "closed") return;
      end();
      if (v.img !== video) return;
      v.wrap.replaceChild(img, video); v.img = img;   // the connection is gone: the relay's pictures
      playMjpeg(v, track); changed();
    };
    window.addEventListener("pagehide", end);
    return true;
  } catch {
    end();
    return false;
  }
}

function attachPointer(v, track) {
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
    const api = await Promise.race([consoleReady, Promise.resolve(null)]);
    const seq = api?.motionStart();                 // the marker follows what the camera acknowledges
    if (Math.hypot(e.clientX - start.x, e.clientY - start.y) < 6) {
      const r = await post("api/video/point", { lens: v.lens, x: x1, y: y1 });
      v.wrap.dataset.last = r.ok ? `point ${r.body.yaw_deg} ${r.body.pitch_deg}` : `error ${r.body.message}`;
      if (r.ok) api?.motionEnd(seq, r.body.yaw_deg);
      else api?.showError(`Point at the picture: ${r.body.message || "refused"}`);
    } else {
      const [x0, y0] = start.f;
      const r = await post("api/video/track", { lens: v.lens, x0, y0, x1, y1 });
      v.wrap.dataset.last = r.ok ? "tracking" : `error ${r.body.message}`;
      // The box the user drew stays up while the camera tracks (setUpTracking hides it after).
      if (!r.ok) setTimeout(() => { v.box.hidden = true; }, 300);
      else track.box = v.box;
      if (r.ok) track.started?.((r.body.requests || []).map((q) => q.id).join(", "));
      else api?.showError(`Tracking: ${r.body.message || "refused"}`);
    }
  });
  let lastWheel = 0;
  v.img.addEventListener("wheel", (e) => {
    e.preventDefault();
    const now = Date.now(); if (now - lastWheel < 250) return; lastWheel = now;
    post("api/video/zoom", { direction: e.deltaY < 0 ? "in" : "out" });
  }, { passive: false });
}

// Tracking state (what the camera acknowledged or answered) and its Stop.
function setUpTracking(api, track) {
  const plan = trackingPlan(api.catalog);
  const name = api.catalog.model.name;
  if (!plan.starts) {
    track.hint.textContent = `click: point there · wheel: zoom · the ${name} does not track targets`;
    return;
  }
  let poll = null, seen = false;
  const show = (text, on, state) => {
    track.tracking.textContent = text;
    track.tracking.dataset.state = state || (on ? "tracking" : "stopped");
    track.trackStop.hidden = !on;
    if (!on || state === "lost") {
      clearInterval(poll); poll = null;
      if (track.box) track.box.hidden = true;
    }
  };
  const readState = async (fallback, on) => {
    if (!plan.query) return show(fallback, on);
    const m = await api.run("request", { id: plan.query.spec.id, read: true });
    const value = m?.fields?.[plan.query.field.name];
    if (value == null) return show(fallback, on);
    const label = plan.query.field.values.find((x) => x.name === value)?.label || value;
    // A camera that was tracking and is waiting again without a stop lost its target
    // (docs/errata.md E41): said as such, not as "waiting".
    if (seen && on && value !== "tracking" && value !== "stopped") {
      return show(`tracking: lost (the camera's state: ${label.toLowerCase()})`, true, "lost");
    }
    seen = seen || value === "tracking";
    show(`tracking: ${label.toLowerCase()} (the camera's state)`, value !== "stopped");
  };
  track.started = (ids) => {
    seen = false;
    readState(`tracking: on (the camera acknowledged ${ids})`, true);
    // While tracking, ask the camera once a second so a lost target shows.
    clearInterval(poll);
    if (plan.query) poll = setInterval(() => readState("", true), 1000);
  };
  if (!plan.stop) {
    track.trackStop.disabled = true;
    track.trackStop.title = `the ${name} has no command that stops tracking`;
  } else {
    track.trackStop.title = `${plan.stop.spec.title} (${plan.stop.spec.id} stop)`;
  }
  track.trackStop.onclick = async () => {
    const r = await api.attempt("request", { id: plan.stop.spec.id, values: { [plan.stop.field]: "stop" } });
    if (r.ok) readState(`tracking: stopped (the camera acknowledged ${plan.stop.spec.id} stop)`, false);
    else show(`tracking: stop refused: ${r.error.message}`, true);
  };
}

start();
