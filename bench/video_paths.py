"""Glass-to-glass latency per video path, side by side in one run (issue 38).

    .venv/bin/python bench/video_paths.py [--seconds 15] [--skip-browser]
    .venv/bin/python bench/video.py --paths          # the same, from the video bench

One simulated C12 (`topgimbal sim --video`, 1280x720 at 30 fps, H.264) on loopback, and per path a
receiver that reads the simulator's burned-in wall-clock stamp from the pictures it shows:

- RTP: `topgimbal video relay` (no re-encoding) -> QGroundControl's GStreamer pipeline (udpsrc !
  rtpjitterbuffer ! rtph264depay ! avdec_h264), once with rtpjitterbuffer's default 200 ms latency
  and once with `latency=0`; the stamp is read as each decoded picture leaves the pipeline.
- Chromium via WebRTC and via MJPEG: `topgimbal console --url ... --video-url ...` and Debian's
  chromium; the page reads the stamp of the picture on screen every 250 ms (window.__videoLatency),
  so its figures include up to one frame period of display age (~17 ms on average at 30 fps).

Per path: median and p95 latency, pictures per second delivered, pictures lost (RTP: gaps in the
stamps; WebRTC: the video element's dropped frames; MJPEG: not measurable in the page), and the CPU
of the process that relays (% of one core: the relay process for RTP; the console for the others).
Figures are printed, not asserted: the machine is shared.
"""

from __future__ import annotations

import argparse
import itertools
import os
import re
import shutil
import statistics
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

from topgimbal.video.render import decode_stamp  # noqa: E402

EXE = [sys.executable, "-m", "topgimbal.cli.main"]
ENV = {**os.environ, "PYTHONPATH": str(ROOT / "src")}
GST = shutil.which("gst-launch-1.0") or "/usr/bin/gst-launch-1.0"
CHROMIUM = "/usr/bin/chromium"
FPS = 30.0
W, H = 1280, 720


def cpu_ticks(pid: int) -> float:
    """User + system CPU seconds of a process (and its waited-for children)."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return sum(int(x) for x in fields[11:15]) / os.sysconf("SC_CLK_TCK")


def p95(xs: list[float]) -> float:
    return float(np.percentile(xs, 95)) if xs else float("nan")


def row(name: str, lat: list[float], fps: float | None, lost: str, cpu: str) -> str:
    med = f"{statistics.median(lat):.0f}" if lat else "-"
    return f"| {name} | {med} | {p95(lat):.0f} | {len(lat)} | {'-' if fps is None else f'{fps:.1f}'} | {lost} | {cpu} |"


def start(cmd: list[str], pattern: str, lines: int = 12) -> tuple[subprocess.Popen[str], list[str]]:
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True, env=ENV)
    assert proc.stdout is not None
    seen = []
    for _ in range(lines):
        line = proc.stdout.readline().strip()
        seen.append(line)
        if re.search(pattern, line):
            return proc, seen
    proc.kill()
    raise RuntimeError(f"{cmd[3:5]}: no line matching {pattern!r} in {seen}")


def free_udp_port() -> int:
    import socket

    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def rtp_path(rtsp: str, seconds: float, jitter_latency_ms: int | None) -> tuple[list[float], float, int, float]:
    """(latencies ms, pictures/s, pictures lost, relay CPU %) through `video relay` + QGC's pipeline."""
    port = free_udp_port()
    relay, _ = start([*EXE, "video", "relay", "--from", rtsp, "--to", f"udp://127.0.0.1:{port}"], r"-> udp://")
    jb = ["rtpjitterbuffer"] + ([f"latency={jitter_latency_ms}"] if jitter_latency_ms is not None else [])
    gst = subprocess.Popen(
        [GST, "-q", "udpsrc", "address=127.0.0.1", f"port={port}",
         "caps=application/x-rtp,media=video,clock-rate=90000,encoding-name=H264", "!", *jb, "!", "rtph264depay",
         "!", "avdec_h264", "!", "videoconvert", "!", "video/x-raw,format=GRAY8", "!", "fdsink", "fd=1"],
        stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
    )  # fmt: skip
    assert gst.stdout is not None
    lat: list[float] = []
    stamps: list[int] = []
    try:
        time.sleep(0.5)
        # skip the join (up to one GOP) and the first second, then measure
        warm_end = time.time() + 2.0
        while time.time() < warm_end:
            gst.stdout.read(W * H)
        c0, t0 = cpu_ticks(relay.pid), time.time()
        end = t0 + seconds
        while time.time() < end:
            buf = gst.stdout.read(W * H)
            now_ms = time.time() * 1000
            if not buf or len(buf) < W * H:
                break
            st = decode_stamp(np.frombuffer(buf, np.uint8).reshape(H, W))
            if st is not None:
                lat.append(now_ms - st)
                stamps.append(st)
        c1, t1 = cpu_ticks(relay.pid), time.time()
    finally:
        gst.kill()
        gst.wait()
        relay.terminate()
        relay.wait(10)
    period = 1000.0 / FPS
    lost = sum(max(0, round((b - a) / period) - 1) for a, b in itertools.pairwise(stamps))
    return lat, len(stamps) / (t1 - t0), lost, 100.0 * (c1 - c0) / (t1 - t0)


LAUNCH_ARGS = ["--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run", "--disable-background-networking",
               "--disable-component-update", "--disable-sync", "--allow-loopback-in-peer-connection",
               "--disable-features=WebRtcHideLocalIpsWithMdns",
               "--autoplay-policy=no-user-gesture-required"]  # fmt: skip


def browser_path(page_url: str, console_pid: int, seconds: float, mjpeg: bool) -> tuple[list[float], Any, str, float]:
    from playwright.sync_api import sync_playwright

    with sync_playwright() as p:
        b = p.chromium.launch(executable_path=CHROMIUM, headless=True, args=LAUNCH_ARGS)
        try:
            page = b.new_context(viewport={"width": 1400, "height": 1100}).new_page()
            url = page_url + (("&" if "?" in page_url else "?") + "video=mjpeg" if mjpeg else "")
            page.goto(url)
            want = "visible MJPEG" if mjpeg else "visible WebRTC"
            page.wait_for_function(
                f"(document.querySelector('[data-testid=video-path]')?.textContent || '').includes('{want}')",
                timeout=60_000,
            )
            page.wait_for_timeout(2000)
            page.evaluate("window.__videoLatency.length = 0")
            q0 = page.evaluate("document.querySelector('[data-testid=video-visible]').getVideoPlaybackQuality?.() "
                               "&& [performance.now(), document.querySelector('[data-testid=video-visible]')"
                               ".getVideoPlaybackQuality().totalVideoFrames, document.querySelector("
                               "'[data-testid=video-visible]').getVideoPlaybackQuality().droppedVideoFrames]")  # fmt: skip
            c0, t0 = cpu_ticks(console_pid), time.time()
            page.wait_for_timeout(seconds * 1000)
            c1, t1 = cpu_ticks(console_pid), time.time()
            lat = [float(x) for x in page.evaluate("window.__videoLatency.slice()")]
            q1 = page.evaluate("document.querySelector('[data-testid=video-visible]').getVideoPlaybackQuality?.() "
                               "&& [performance.now(), document.querySelector('[data-testid=video-visible]')"
                               ".getVideoPlaybackQuality().totalVideoFrames, document.querySelector("
                               "'[data-testid=video-visible]').getVideoPlaybackQuality().droppedVideoFrames]")  # fmt: skip
        finally:
            b.close()
    fps = lost = None
    if q0 and q1:
        fps = (q1[1] - q0[1]) / ((q1[0] - q0[0]) / 1000)
        lost = int(q1[2] - q0[2])
    return lat, fps, "n/a" if lost is None else str(lost), 100.0 * (c1 - c0) / (t1 - t0)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=15.0, help="measuring window per path (default 15)")
    ap.add_argument("--skip-browser", action="store_true", help="only the RTP paths")
    args = ap.parse_args()
    print(f"load average {' / '.join(f'{x:.2f}' for x in os.getloadavg())}, {os.cpu_count()} CPUs")
    sim, lines = start([*EXE, "sim", "--model", "C12", "--udp", "127.0.0.1:0", "--video", "--video-port", "0"],
                       r"/stream=2$")  # fmt: skip
    udp = next(x for x in lines if x.startswith("udp://"))
    rtsp = {"visible": next(x for x in lines if x.endswith("/stream=1")),
            "thermal": next(x for x in lines if x.endswith("/stream=2"))}  # fmt: skip
    rows = []
    try:
        for jb in (None, 0):
            lat, fps, lost, cpu = rtp_path(rtsp["visible"], args.seconds, jb)
            name = "RTP: video relay -> QGC pipeline, " + ("jitterbuffer default (200 ms)" if jb is None
                                                         else "rtpjitterbuffer latency=0")  # fmt: skip
            rows.append(row(name, lat, fps, str(lost), f"relay {cpu:.1f} %"))
            print(rows[-1], flush=True)
        if not args.skip_browser:
            console, out = start([*EXE, "console", "--url", udp, "--model", "C12", "--port", "0",
                                  "--video-url", f"visible={rtsp['visible']}", "--video-url",
                                  f"thermal={rtsp['thermal']}"], r"^open http")  # fmt: skip
            page_url = next(x for x in out if x.startswith("open "))[5:]
            try:
                for mjpeg in (False, True):
                    lat, fps, lost, cpu = browser_path(page_url, console.pid, args.seconds, mjpeg)
                    name = (
                        "Chromium via MJPEG (console relay)" if mjpeg else "Chromium via WebRTC (WHEP, no re-encoding)"
                    )
                    rows.append(row(name, lat, fps, lost, f"console {cpu:.1f} %"))
                    print(rows[-1], flush=True)
            finally:
                console.terminate()
                console.wait(20)
    finally:
        sim.terminate()
        sim.wait(20)
    print()
    print("| path | median ms | p95 ms | readings | pictures/s | lost | CPU (one core = 100 %) |")
    print("|---|---|---|---|---|---|---|")
    print("\n".join(rows))
    print(f"\nload average after: {' / '.join(f'{x:.2f}' for x in os.getloadavg())}")


if __name__ == "__main__":
    main()
