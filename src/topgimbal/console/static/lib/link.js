// The camera link as the page shows it: the badge, the LOST banner and the controls that need the
// camera. The state comes from the server (the client's own link-loss detection, pushed at once on
// a change): the page keeps no timer of its own that could disagree with it.
//
// While the link is lost (or the console only watches a proxy) every control that would send to
// the camera is disabled with the reason in its tooltip; controls marked `data-local` (the traffic
// pane's filters, the pcap download) stay usable. Controls disabled for another reason (the model
// lacks the command) keep that reason.

const LOCK = "lockedBy";

function controls() {
  return [...document.querySelectorAll("main button, main input, main select, main textarea")].filter(
    (n) => !n.closest("[data-local]") && !n.closest("#panel-video") && !n.closest("#panel-connection"));
}

// Disable (reason given) or re-enable (null) what needs the camera; idempotent.
export function lockControls(reason) {
  for (const n of controls()) {
    if (reason) {
      if (n.disabled && !n.dataset[LOCK]) continue; // disabled for its own reason (unsupported)
      if (!n.dataset[LOCK] && n.hasAttribute("title")) n.dataset.titleBefore = n.title;
      n.dataset[LOCK] = "link";
      n.disabled = true;
      n.title = reason;
    } else if (n.dataset[LOCK]) {
      n.disabled = false;
      if ("titleBefore" in n.dataset) n.title = n.dataset.titleBefore;
      else n.removeAttribute("title");
      delete n.dataset[LOCK];
      delete n.dataset.titleBefore;
    }
  }
  const pad = document.getElementById("pad");
  if (reason) pad.dataset.locked = reason;
  else delete pad.dataset.locked;
  document.body.dataset.locked = reason ? "1" : "";
}

const hms = (t) => new Date(t * 1000).toLocaleTimeString([], { hour12: false });

function ago(seconds) {
  const s = Math.max(0, Math.round(seconds));
  return s < 90 ? `${s} s` : s < 5400 ? `${Math.round(s / 60)} min` : `${(s / 3600).toFixed(1)} h`;
}

// The banner's text for a lost link: what is lost, since when, why.
export function lostText(st, clockOffset = 0) {
  const now = Date.now() / 1000 - clockOffset;
  const heard = st.last_in != null
    ? `no frame from the camera since ${hms(st.last_in + clockOffset)} (${ago(now - st.last_in)} ago)`
    : "the camera has not answered at all";
  const declared = st.lost_since != null ? `; lost at ${hms(st.lost_since + clockOffset)}` : "";
  return `Camera link LOST: ${heard}${declared}${st.link_reason ? ` (${st.link_reason})` : ""}.`;
}

// The badge and the banner for a status; returns the lock reason (or null).
export function showLink(st, clockOffset = 0) {
  const badge = document.getElementById("link");
  const banner = document.getElementById("link-banner");
  const state = st.link;
  badge.dataset.state = state;
  let reason = null;
  if (state === "lost") {
    const text = lostText(st, clockOffset);
    badge.textContent = "LOST";
    badge.title = text;
    banner.hidden = false;
    banner.dataset.state = "lost";
    banner.querySelector(".text").textContent = text;
    reason = `${text} Controls that need the camera are disabled until frames arrive again.`;
  } else if (state === "watching") {
    badge.textContent = "watching";
    badge.title = st.readonly || "";
    banner.hidden = false;
    banner.dataset.state = "watching";
    const clients = (st.proxy?.clients || []).map((c) => c.client).join(", ") || "no client yet";
    banner.querySelector(".text").textContent =
      `Read-only: ${st.readonly}. Clients seen: ${clients}.`;
    reason = `Read-only: ${st.readonly}`;
  } else {
    badge.textContent = state;
    const age = st.last_in_age_s;
    badge.title = age == null ? "no frame yet" : `last frame ${age.toFixed(1)} s ago`;
    banner.hidden = true;
    banner.dataset.state = state;
  }
  const since = state === "lost" && st.lost_since != null ? ` since ${hms(st.lost_since + clockOffset)}` : "";
  const why = state === "lost" ? st.link_reason : badge.title;
  document.getElementById("conn-link").textContent = `${badge.textContent}${since}${why ? ` (${why})` : ""}`;
  return reason;
}
