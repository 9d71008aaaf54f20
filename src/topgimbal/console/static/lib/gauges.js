// Artificial horizon and heading dial on canvases. Pure drawing: called from requestAnimationFrame.

function setup(canvas) {
  const dpr = window.devicePixelRatio || 1;
  const w = canvas.clientWidth || canvas.width;
  const h = canvas.clientHeight || canvas.height;
  if (canvas.width !== Math.round(w * dpr)) {
    canvas.width = Math.round(w * dpr);
    canvas.height = Math.round(h * dpr);
  }
  const ctx = canvas.getContext("2d");
  ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
  return { ctx, w, h };
}

const rad = (d) => (d * Math.PI) / 180;

// A filled dot (the path stays current).
function dot(ctx, x, y, radius, color) {
  ctx.fillStyle = color;
  ctx.beginPath();
  ctx.arc(x, y, radius, 0, 2 * Math.PI);
  ctx.fill();
}

// The commanded yaw: a green dot on the rim of the heading dial.
function drawTarget(ctx, cx, cy, r, target) {
  if (target == null || !Number.isFinite(target)) return;
  const tt = rad(target - 90);
  dot(ctx, cx + (r - 8) * Math.cos(tt), cy + (r - 8) * Math.sin(tt), 4, "#3ccf7a");
}

export function drawHorizon(canvas, pitch, roll) {
  const { ctx, w, h } = setup(canvas);
  const r = Math.min(w, h) / 2 - 2;
  const cx = w / 2, cy = h / 2;
  const pxPerDeg = r / 45;
  ctx.clearRect(0, 0, w, h);
  ctx.save();
  ctx.beginPath();
  ctx.arc(cx, cy, r, 0, 2 * Math.PI);
  ctx.clip();
  ctx.translate(cx, cy);
  ctx.rotate(rad(-(roll || 0)));
  const off = (pitch || 0) * pxPerDeg;
  ctx.fillStyle = "#2f6fa8";
  ctx.fillRect(-2 * r, -3 * r + off, 4 * r, 3 * r);
  ctx.fillStyle = "#7a5530";
  ctx.fillRect(-2 * r, off, 4 * r, 3 * r);
  ctx.strokeStyle = "#fff";
  ctx.lineWidth = 2;
  ctx.beginPath();
  ctx.moveTo(-2 * r, off);
  ctx.lineTo(2 * r, off);
  ctx.stroke();
  // pitch ladder every 10 degrees
  ctx.lineWidth = 1;
  ctx.fillStyle = "#fff";
  ctx.font = "10px system-ui, sans-serif";
  ctx.textAlign = "left";
  ctx.textBaseline = "middle";
  for (let d = -90; d <= 90; d += 10) {
    if (d === 0) continue;
    const y = off - d * pxPerDeg;
    if (Math.abs(y) > r) continue;
    const half = d % 20 === 0 ? 28 : 16;
    ctx.beginPath();
    ctx.moveTo(-half, y);
    ctx.lineTo(half, y);
    ctx.stroke();
    if (d % 20 === 0) ctx.fillText(String(d), half + 4, y);
  }
  ctx.restore();
  // fixed aircraft symbol and roll pointer
  ctx.strokeStyle = "#ffd34d";
  ctx.lineWidth = 3;
  ctx.beginPath();
  ctx.moveTo(cx - 50, cy); ctx.lineTo(cx - 16, cy); ctx.lineTo(cx - 8, cy + 8);
  ctx.moveTo(cx + 50, cy); ctx.lineTo(cx + 16, cy); ctx.lineTo(cx + 8, cy + 8);
  ctx.stroke();
  dot(ctx, cx, cy, 3, "#ffd34d");
  ctx.strokeStyle = "#ffffff55";
  ctx.lineWidth = 2;
  ctx.beginPath();
  ctx.arc(cx, cy, r - 1, 0, 2 * Math.PI);
  ctx.stroke();
  // roll scale ticks
  ctx.strokeStyle = "#fff";
  ctx.lineWidth = 1.5;
  for (const a of [-60, -45, -30, -20, -10, 0, 10, 20, 30, 45, 60]) {
    const t = rad(a - 90);
    const l = a % 30 === 0 ? 12 : 7;
    ctx.beginPath();
    ctx.moveTo(cx + (r - 2) * Math.cos(t), cy + (r - 2) * Math.sin(t));
    ctx.lineTo(cx + (r - 2 - l) * Math.cos(t), cy + (r - 2 - l) * Math.sin(t));
    ctx.stroke();
  }
  const t = rad(-(roll || 0) - 90);
  ctx.fillStyle = "#ffd34d";
  ctx.beginPath();
  ctx.moveTo(cx + (r - 16) * Math.cos(t), cy + (r - 16) * Math.sin(t));
  ctx.lineTo(cx + (r - 28) * Math.cos(t - 0.07), cy + (r - 28) * Math.sin(t - 0.07));
  ctx.lineTo(cx + (r - 28) * Math.cos(t + 0.07), cy + (r - 28) * Math.sin(t + 0.07));
  ctx.fill();
}

// A cleared canvas with a filled disc (its path left current, for the rim's stroke).
function disc(canvas, fill) {
  const { ctx, w, h } = setup(canvas);
  const r = Math.min(w, h) / 2 - 2;
  const cx = w / 2, cy = h / 2;
  ctx.clearRect(0, 0, w, h);
  dot(ctx, cx, cy, r, fill);
  return { ctx, r, cx, cy };
}

export function drawHeading(canvas, yaw, target) {
  const { ctx, r, cx, cy } = disc(canvas, "#111a23");
  ctx.strokeStyle = "#ffffff55";
  ctx.lineWidth = 2;
  ctx.stroke();
  // dial: 0 at the top = gimbal straight ahead (yaw relative to the mount), clockwise positive
  ctx.font = "11px system-ui, sans-serif";
  ctx.textAlign = "center";
  ctx.textBaseline = "middle";
  for (let a = -180; a < 180; a += 10) {
    const t = rad(a - 90);
    const major = a % 30 === 0;
    ctx.strokeStyle = major ? "#dde6ee" : "#6b7c8d";
    ctx.lineWidth = major ? 2 : 1;
    ctx.beginPath();
    ctx.moveTo(cx + (r - 3) * Math.cos(t), cy + (r - 3) * Math.sin(t));
    ctx.lineTo(cx + (r - (major ? 14 : 9)) * Math.cos(t), cy + (r - (major ? 14 : 9)) * Math.sin(t));
    ctx.stroke();
    if (a % 90 === 0) {
      ctx.fillStyle = "#8697a8";
      const label = a === 0 ? "0" : a === 180 || a === -180 ? "180" : String(a);
      ctx.fillText(label, cx + (r - 26) * Math.cos(t), cy + (r - 26) * Math.sin(t));
    }
  }
  drawTarget(ctx, cx, cy, r, target);
  const t = rad((yaw || 0) - 90);
  ctx.strokeStyle = "#3fa7ff";
  ctx.lineWidth = 4;
  ctx.lineCap = "round";
  ctx.beginPath();
  ctx.moveTo(cx - 14 * Math.cos(t), cy - 14 * Math.sin(t));
  ctx.lineTo(cx + (r - 34) * Math.cos(t), cy + (r - 34) * Math.sin(t));
  ctx.stroke();
  dot(ctx, cx, cy, 5, "#3fa7ff");
  ctx.fillStyle = "#dde6ee";
  ctx.font = "600 15px system-ui, sans-serif";
  ctx.fillText(`${(yaw || 0).toFixed(1)}°`, cx, cy + r * 0.45);
}

// A dial without data: grey, with the reason in the middle (never a level horizon or a heading
// of 0 that looks live). A commanded yaw, if any, is still marked.
export function drawNoAttitude(canvas, text, target = null) {
  const { ctx, r, cx, cy } = disc(canvas, "#151b22");
  ctx.setLineDash([4, 6]);
  ctx.strokeStyle = "#ffffff33";
  ctx.lineWidth = 2;
  ctx.stroke();
  ctx.setLineDash([]);
  drawTarget(ctx, cx, cy, r, target);
  ctx.fillStyle = "#8697a8";
  ctx.font = "600 14px system-ui, sans-serif";
  ctx.textAlign = "center";
  ctx.textBaseline = "middle";
  ctx.fillText(text, cx, cy);
}
