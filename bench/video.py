"""Video figures: CPU cost of the simulated streams, encoder choices, the simulator's event-loop
timing while video runs, and glass-to-glass latency (RTSP to a Python decoder, and through the
console's relay to chromium). Figures are printed, not asserted (the machine is shared).

    .venv/bin/python bench/video.py [--seconds 8] [--skip-browser]
    .venv/bin/python bench/video.py --paths [--seconds 15]   # latency per path: RTP, WebRTC, MJPEG

CPU is this process's user+system time over a window while one receiver (Debian's ffmpeg, in
another process, not counted) reads the stream; 100 % = one core. "At the full rate" scales the
CPU per delivered picture to the nominal frame rate (a busy machine delivers fewer pictures).
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import resource
import shutil
import statistics
import subprocess
import sys
import time
from typing import Any

import av
import numpy as np

from topgimbal.sim import Simulator
from topgimbal.video.encode import Encoder, yuv420_frame
from topgimbal.video.render import Renderer
from topgimbal.video.simvideo import SimVideo, VideoOptions
from topgimbal.video.snapshot import SceneState


def load() -> str:
    """The 1, 5 and 15 minute load averages (the figures depend on how busy the machine is)."""
    return " / ".join(f"{x:.2f}" for x in os.getloadavg())


def cpu_s() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def reader(url: str, seconds: float) -> subprocess.Popen[bytes]:
    return subprocess.Popen(
        ["ffmpeg", "-v", "error", "-rtsp_transport", "tcp", "-i", url, "-t", str(seconds), "-f", "null", "-"],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )


async def stream_cost(
    model: str, lenses: list[str], size: tuple[int, int], fps: float, codec: str, seconds: float
) -> dict[str, Any]:
    sim = Simulator(model)
    await sim.start(udp=[("127.0.0.1", 0)])
    video = await SimVideo(sim, VideoOptions(port=0, fps=fps, size=size, codec=codec)).start()
    procs = [reader(video.urls[lens], seconds + 3) for lens in lenses]
    await asyncio.sleep(2.0)  # receivers connected, encoders warm
    lags: list[float] = []
    stop = time.monotonic() + seconds
    c0, frames0 = cpu_s(), [w.frames for w in video._workers]
    while time.monotonic() < stop:  # the simulator's loop: how late does a 10 ms sleep wake?
        t = time.monotonic()
        await asyncio.sleep(0.01)
        lags.append((time.monotonic() - t - 0.01) * 1000)
    workers = list(video._workers)
    c1, frames1 = cpu_s(), [w.frames for w in workers]
    await video.stop()
    await sim.stop()
    for p in procs:
        p.wait(10)
    got = {w.spec.lens: (b - a) / seconds for w, a, b in zip(workers, frames0, frames1, strict=True)}
    delivered = sum(b - a for a, b in zip(frames0, frames1, strict=True))
    return {
        "cpu_pct": (c1 - c0) / seconds * 100,
        # CPU per delivered picture x the nominal rate: what the streams cost at full rate, also
        # on a machine so busy that this process does not get the CPU to deliver it.
        "cpu_pct_nominal": (c1 - c0) / max(1, delivered) * fps * len(lenses) * 100,
        "fps": {k: round(v, 1) for k, v in got.items() if k in lenses},
        "loop_lag_ms_p50": statistics.median(lags),
        "loop_lag_ms_p99": sorted(lags)[int(len(lags) * 0.99)],
    }


def encoder_figures(n: int = 60) -> list[str]:
    out = []
    states = [
        SceneState("C12", 20 + i * 0.5, -5, 0, 1, 1, "white_hot", True, False, 0, "stopped", 1e9 + i, i)
        for i in range(n)
    ]

    def per_picture(fn: Any) -> float:
        fn(0)
        t0 = cpu_s()
        for i in range(n):
            fn(i)
        return (cpu_s() - t0) / n * 1000

    def interleaved(*fns: Any) -> list[float]:
        """CPU ms per call of each function, calls alternating (a busy machine slows all alike)."""
        spent = [0.0] * len(fns)
        for i in range(n):
            for k, fn in enumerate(fns):
                t0 = time.thread_time()
                fn(i)
                spent[k] += time.thread_time() - t0
        return [x / n * 1000 for x in spent]

    rgb, ycc = Renderer("visible", 1280, 720, 62.0), Renderer("visible", 1280, 720, 62.0, mode="YCbCr")
    rgb_pics = [rgb.render(st) for st in states]
    ycc_pics = [ycc.render(st) for st in states]
    r_rgb, r_ycc, c_rgb, c_ycc = interleaved(
        lambda i: rgb.render(states[i]),
        lambda i: ycc.render(states[i]),
        lambda i: av.VideoFrame.from_ndarray(np.asarray(rgb_pics[i]), format="rgb24").reformat(format="yuv420p"),
        lambda i: yuv420_frame(ycc_pics[i]),
    )
    out.append(
        f"render 1280x720 (numpy + Pillow): RGB {r_rgb:.1f} ms/picture, straight into Y'CbCr {r_ycc:.1f} ms/picture"
    )
    out.append(
        f"to the encoder's yuv420p: from RGB (PyAV/FFmpeg swscale) {c_rgb:.1f} ms/picture, "
        f"from Y'CbCr (Y copied, chroma averaged 2x2) {c_ycc:.1f} ms/picture"
    )
    out.append(
        f"render + conversion: RGB path {r_rgb + c_rgb:.1f} ms, Y'CbCr path {r_ycc + c_ycc:.1f} ms per picture "
        f"(= {(r_rgb + c_rgb - r_ycc - c_ycc) * 3:.0f} % of a core saved at 30 fps)"
    )
    frames = [yuv420_frame(p) for p in ycc_pics]
    for codec in ("h264", "h265"):
        e = Encoder(codec, 1280, 720, 30)
        sizes: list[int] = []

        def enc(i: int, e: Encoder = e, sizes: list[int] = sizes) -> None:
            f = frames[i]
            f.pts = i * 3000
            sizes.extend(len(bytes(p)) for p in e._ctx.encode(f))

        ms = per_picture(enc)
        out.append(
            f"PyAV {codec} 1280x720 (encoder only): {ms:.1f} ms/picture = {ms * 3:.0f} % of a core at 30 fps, "
            f"{sum(sizes) * 8 * 30 / max(1, len(sizes)) / 1000:.0f} kbit/s"
        )
    gst = (
        "import gi,resource;gi.require_version('Gst','1.0');from gi.repository import Gst;Gst.init(None)\n"
        "def run(d):\n r0=resource.getrusage(0);p=Gst.parse_launch(d);p.set_state(Gst.State.PLAYING)\n"
        " p.get_bus().timed_pop_filtered(60*Gst.SECOND,Gst.MessageType.EOS|Gst.MessageType.ERROR);p.set_state(Gst.State.NULL)\n"
        " r1=resource.getrusage(0);return r1.ru_utime+r1.ru_stime-r0.ru_utime-r0.ru_stime\n"
        "s='videotestsrc num-buffers=300 pattern=ball ! video/x-raw,width=1280,height=720,framerate=30/1,format=I420'\n"
        "b=run(s+' ! fakesink');e=run(s+' ! x264enc tune=zerolatency speed-preset=ultrafast bitrate=4000 threads=1 ! fakesink')\n"
        "print(f'{(e-b)/300*1000:.1f}')\n"
    )
    if shutil.which("/usr/bin/python3"):
        r2 = subprocess.run(["/usr/bin/python3", "-c", gst], capture_output=True, text=True, timeout=120)
        if r2.returncode == 0:
            out.append(
                f"GStreamer x264enc 1280x720 (test pattern, I420 in, Debian python): {r2.stdout.strip()} ms/picture"
            )
        else:
            out.append(f"GStreamer: not measured ({r2.stderr.strip().splitlines()[-1:]})")
    return out


READER = """
import json, sys, time
from topgimbal.video.frames import frames
from topgimbal.video.render import decode_stamp
lat, end = [], time.time() + float(sys.argv[2])
for pic in frames(sys.argv[1], format="rgb24"):
    stamp = decode_stamp(pic)
    if stamp is not None:
        lat.append(time.time() * 1000 - stamp)
    if time.time() > end:
        break
print(json.dumps(lat))
"""


async def rtsp_latency(seconds: float) -> list[float]:
    """Burned-in capture time -> decoded by the SDK's frames() in another process."""
    sim = Simulator("C12")
    await sim.start(udp=[("127.0.0.1", 0)])
    video = await SimVideo(sim, VideoOptions(port=0)).start()
    proc = await asyncio.create_subprocess_exec(
        sys.executable, "-c", READER, video.urls["visible"], str(seconds), stdout=asyncio.subprocess.PIPE
    )
    out, _ = await proc.communicate()
    await video.stop()
    await sim.stop()
    return [float(x) for x in json.loads(out or b"[]")][5:]


def browser_latency(seconds: float) -> tuple[list[float], float]:
    """Burned-in time -> shown in chromium through the console (the page decodes the stamp)."""
    sys.path.insert(0, "tests")
    from playwright.sync_api import sync_playwright

    from console.conftest import CHROMIUM, LAUNCH_ARGS, BackgroundConsole

    with BackgroundConsole("C12") as bg, sync_playwright() as p:
        b = p.chromium.launch(executable_path=CHROMIUM, headless=True, args=LAUNCH_ARGS)
        page = b.new_page(viewport={"width": 1400, "height": 1000})
        page.goto(bg.url)
        page.wait_for_function("window.__videoLatency && window.__videoLatency.length > 4", timeout=20_000)
        c0 = cpu_s()
        page.wait_for_timeout(seconds * 1000)
        cpu = (cpu_s() - c0) / seconds * 100
        lat = page.evaluate("window.__videoLatency.slice()")
        b.close()
    return lat, cpu


def summary(xs: list[float]) -> str:
    if not xs:
        return "no samples"
    s = sorted(xs)
    return f"median {statistics.median(s):.0f} ms, p90 {s[int(len(s) * 0.9)]:.0f} ms, max {s[-1]:.0f} ms ({len(s)} samples)"


async def stream_figures(seconds: float) -> None:
    print("== simulated streams: CPU of the simulator process while one ffmpeg reads each stream")
    cases = [
        ("C12", ["visible"], (1280, 720), 30.0, "h264"),
        ("C12", ["visible", "thermal"], (1280, 720), 30.0, "h264"),
        ("C12", ["visible"], (1280, 720), 15.0, "h264"),
        ("C12", ["visible"], (640, 360), 30.0, "h264"),
        ("C12", ["visible"], (1920, 1080), 30.0, "h264"),
        ("SIP", ["visible"], (1280, 720), 30.0, "h265"),
    ]
    for model, lenses, size, fps, codec in cases:
        r = await stream_cost(model, lenses, size, fps, codec, seconds)
        print(
            f"  {model} {'+'.join(lenses):15s} {size[0]}x{size[1]}@{fps:g} {codec}: {r['cpu_pct']:.0f} % of a core "
            f"({r['cpu_pct_nominal']:.0f} % at the full rate), "
            f"delivered fps {r['fps']}, sim loop lag p50 {r['loop_lag_ms_p50']:.2f} ms p99 {r['loop_lag_ms_p99']:.2f} ms"
            f" (load {load()})"
        )


async def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=8.0)
    ap.add_argument("--skip-browser", action="store_true")
    ap.add_argument("--skip-encoders", action="store_true")
    ap.add_argument("--latency-only", action="store_true", help="only the glass-to-glass figures")
    ap.add_argument(
        "--quiet-load", type=float, default=None, metavar="L",
        help="before the latency figures, wait (at most --quiet-wait-s) for the 1-minute load average to fall below L",
    )  # fmt: skip
    ap.add_argument("--quiet-wait-s", type=float, default=600.0)
    ap.add_argument("--paths", action="store_true",
                    help="glass-to-glass per path side by side: RTP to QGC's pipeline, Chromium via WebRTC and "
                    "via MJPEG (bench/video_paths.py)")  # fmt: skip
    args = ap.parse_args()
    if args.paths:
        import runpy

        sys.argv = [sys.argv[0], "--seconds", str(args.seconds)] + (["--skip-browser"] if args.skip_browser else [])
        path = os.path.join(os.path.dirname(os.path.abspath(__file__)), "video_paths.py")
        # in a thread with no event loop: video_paths uses Playwright's sync API, which refuses to
        # run inside a running loop (this main() is a coroutine)
        await asyncio.get_running_loop().run_in_executor(None, lambda: runpy.run_path(path, run_name="__main__"))
        return
    print(f"load average at the start: {load()}")
    if not args.skip_encoders and not args.latency_only:
        print("== encoders (one core, this machine)")
        for line in encoder_figures():
            print("  " + line)
    if not args.latency_only:
        await stream_figures(args.seconds)
    if args.quiet_load is not None:
        end = time.monotonic() + args.quiet_wait_s
        while os.getloadavg()[0] >= args.quiet_load and time.monotonic() < end:
            await asyncio.sleep(5)
    print(f"== glass-to-glass latency (burned-in wall-clock time vs. the clock when shown); load {load()}")
    print("  RTSP -> PyAV decoder (the SDK's frames()):", summary(await rtsp_latency(args.seconds)))
    if not args.skip_browser:
        lat, cpu = await asyncio.get_running_loop().run_in_executor(None, browser_latency, args.seconds)
        print("  RTSP -> console relay (MJPEG) -> chromium <img>:", summary(lat))
        print(f"  console process (simulator + video + relay) while the page plays both lenses: {cpu:.0f} % of a core")
    print(f"  load average at the end: {load()}")


if __name__ == "__main__":
    asyncio.run(main())
