// Where the vehicle and the target are (issue 41.9): the console's `api/where` (console/where.py),
// asked once a second. The vehicle's fix comes from a bridge or the SDK's feeds, or from what the
// simulated camera was fed; the target is where the camera's axis meets the ground from it.

import { fetchJSON } from "./conn.js";

const $ = (id) => document.getElementById(id);
const POLL_MS = 1000;

function place(node, p, text) {
  node.textContent = text;
  node.dataset.lat = p ? String(p.lat_deg) : "";
  node.dataset.lon = p ? String(p.lon_deg) : "";
}

const SOURCES = { feeds: "fed by this console's client", autopilot: "the autopilot's", camera: "fed to the camera" };

export function show(w) {
  const v = w.vehicle, t = w.target;
  if (v) {
    const heading = v.heading_deg == null ? "no heading" : `heading ${v.heading_deg.toFixed(1)}°`;
    place($("where-vehicle"), v, `${v.lat_deg.toFixed(7)}, ${v.lon_deg.toFixed(7)} · ${v.alt_m.toFixed(1)} m · ${heading} (${SOURCES[v.source] || v.source})`);
  } else {
    place($("where-vehicle"), null, w.why || "–");
  }
  if (t) {
    place($("where-target"), t, `${t.lat_deg.toFixed(7)}, ${t.lon_deg.toFixed(7)} · ${t.range_m.toFixed(0)} m away`);
    $("where-target").title = `${t.source}: ±${t.error_m.toFixed(0)} m (1 sigma), bearing ${t.bearing_deg.toFixed(1)}°`;
  } else {
    place($("where-target"), null, v ? (w.why || "–") : "–");
    $("where-target").title = "";
  }
}

export function startWhere() {
  const tick = async () => {
    try {
      show(await fetchJSON("api/where"));
    } catch {
      // the link panel already says when the console cannot be reached; keep the last values
    }
  };
  tick();
  return setInterval(tick, POLL_MS);
}
