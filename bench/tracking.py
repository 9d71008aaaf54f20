"""Tracking figures, scored on the simulator's truth (sim/truth.py). Printed, not asserted.

    .venv/bin/python bench/tracking.py [--seconds 8] [--latency-ms 150] [--skip-camera]

1. Companion loop (topgimbal.track) on a C10 (no tracker of its own): a target crosses at
   10 deg/s, hidden for 0.5 s half way; the simulator's pictures (640x360, 25 fps) reach the loop
   `--latency-ms` after they were taken. Figures: RMS and largest angle between the optical axis
   and the target while it is visible (after a 1 s pull-in), and the time from the end of the
   occlusion to the first detection. The same run with ArduPilot's companion example law (P only
   on raw pixel offsets, no latency term) side by side, and the PI loop without latency
   compensation (the picture's arrival time taken as its capture time).
2. The simulated camera's own tracker (SIP) through the MAVLink bridge, 275 streamed at 10 Hz:
   the box's distance from the true target (fractions of the picture) while tracking, and the
   time from the camera losing the target to the first 275 with status ERROR.
"""

from __future__ import annotations

import argparse
import asyncio
import math
import os
import statistics
import time
from typing import Any

import numpy as np

from topgimbal import connect
from topgimbal.sim import Simulator
from topgimbal.sim.targets import parse_spec
from topgimbal.sim.truth import truth_record
from topgimbal.track import CompanionTracker, Picture, TrackConfig
from topgimbal.track.loop import capture_time
from topgimbal.video.lens import stream_for
from topgimbal.video.render import Renderer, decode_stamp
from topgimbal.video.snapshot import capture

SIZE = (640, 360)
FPS = 25.0


def angle_between(az1: float, el1: float, az2: float, el2: float) -> float:
    a1, e1, a2, e2 = (math.radians(v) for v in (az1, el1, az2, el2))
    c = math.sin(e1) * math.sin(e2) + math.cos(e1) * math.cos(e2) * math.cos(a1 - a2)
    return math.degrees(math.acos(max(-1.0, min(1.0, c))))


async def sim_pictures(sim: Simulator, latency_s: float, stamped: bool) -> Any:
    """The simulator's pictures, rendered in a thread, delivered `latency_s` after capture."""
    spec = stream_for(sim.model, "visible")
    renderer = Renderer("visible", SIZE[0], SIZE[1], spec.hfov_deg)
    queue: asyncio.Queue[tuple[float, Any]] = asyncio.Queue()
    loop = asyncio.get_running_loop()

    def render(state: Any) -> Any:
        return np.asarray(renderer.render(state))

    async def produce() -> None:
        n = 0
        next_t = loop.time()
        while True:
            state = capture(sim.device, frame=n)
            taken = loop.time()
            image = await asyncio.to_thread(render, state)
            await queue.put((taken + latency_s, image))
            n += 1
            next_t += 1.0 / FPS
            await asyncio.sleep(max(0.0, next_t - loop.time()))

    task = asyncio.ensure_future(produce())
    try:
        while True:
            due, image = await queue.get()
            await asyncio.sleep(max(0.0, due - loop.time()))
            stamp = decode_stamp(image) if stamped else None
            yield Picture(image, capture_time(loop.time(), time.time(), stamp, 0.0))
    finally:
        task.cancel()


async def companion_run(law: str, latency_s: float, seconds: float, compensate: bool = True) -> dict[str, Any]:
    sim = Simulator("C10")
    await sim.start(udp=[("127.0.0.1", 0)])
    try:
        async with connect(sim.url, model="C10") as cam:
            dev = sim.device
            t0 = dev.now - dev.state.camera.booted_at
            hide0 = t0 + seconds / 2
            dev.state.targets = (
                parse_spec(
                    f"bearing={-3 - 10 * t0:.4f},elevation=4,speed=10,size=2,contrast=0.9,"
                    f"hide={hide0:.4f}-{hide0 + 0.5:.4f}"
                ),
            )
            tr = truth_record(dev)["targets"][0]
            box = (tr["x"] - 0.04, tr["y"] - 0.07, 0.08, 0.14)
            tracker = CompanionTracker(cam, TrackConfig(box=box, law=law, kind="kcf"))
            seen: list[tuple[float, bool]] = []
            tracker.on_picture = lambda pic, b: seen.append((pic.t, b is not None))
            errors: list[tuple[float, float, bool]] = []
            dbg: list[Any] = []

            async def score() -> None:
                while True:
                    r = truth_record(dev)
                    tg = r["targets"][0]
                    dbg.append(
                        (round(r["yaw_deg"] - tg["bearing_deg"], 2), round(r["pitch_deg"] - tg["elevation_deg"], 2))
                    )
                    errors.append(
                        (
                            r["t"],
                            angle_between(r["yaw_deg"], r["pitch_deg"], tg["bearing_deg"], tg["elevation_deg"]),
                            tg["visible"],
                        )
                    )
                    await asyncio.sleep(0.02)

            scorer = asyncio.ensure_future(score())
            loop = asyncio.get_running_loop()
            start_mono = loop.time()
            report = await tracker.run(sim_pictures(sim, latency_s, stamped=compensate), duration_s=seconds)
            scorer.cancel()
    finally:
        await sim.stop()
    if os.environ.get("TRACK_DEBUG"):
        for i in range(0, len(errors), 10):
            t, e, v = errors[i]
            print(f"  t={t - t0:5.2f} err={e:6.2f} visible={v} {dbg[i] if i < len(dbg) else ''}")
    visible = [e for t, e, v in errors if v and t - t0 > 1.0]
    # occlusion end, in this process's monotonic time: device time and loop time share the clock
    hide_end_mono = start_mono + (hide0 + 0.5 - t0)
    back = [t for t, ok in seen if ok and t >= hide_end_mono]
    return {
        "law": law + ("" if compensate else " (no latency comp.)"),
        "rms_deg": math.sqrt(statistics.fmean(e * e for e in visible)) if visible else float("nan"),
        "max_deg": max(visible) if visible else float("nan"),
        "reacquired_s": (back[0] - hide_end_mono) if back else float("nan"),
        "pictures": report.pictures,
        "detections": report.detections,
        "final": report.state,
    }


async def camera_tracker_run(seconds: float) -> dict[str, Any]:
    from pymavlink.dialects.v20 import common as ml

    from topgimbal.mavlink import Bridge, BridgeConfig

    sim = Simulator("SIP")
    await sim.start(udp=[("127.0.0.1", 0)])
    bridge = Bridge(BridgeConfig(url=sim.url, model="SIP", endpoints=["udpin:127.0.0.1:0"]))
    await bridge.start()
    got: list[tuple[Any, dict[str, Any]]] = []
    truth: list[dict[str, Any]] = []
    mav = ml.MAVLink(None, srcSystem=255, srcComponent=190)
    parser = ml.MAVLink(None)
    loop = asyncio.get_running_loop()
    dev = sim.device

    class P(asyncio.DatagramProtocol):
        def datagram_received(self, data: bytes, addr: Any) -> None:
            for m in parser.parse_buffer(data) or []:
                if m.get_type() == "CAMERA_TRACKING_IMAGE_STATUS":
                    got.append((m, truth_record(dev)))

    transport, _ = await loop.create_datagram_endpoint(P, remote_addr=("127.0.0.1", bridge.addresses[0][1]))

    def send(msg: Any) -> None:
        transport.sendto(msg.pack(mav))
        mav.seq = (mav.seq + 1) % 256

    try:
        send(ml.MAVLink_heartbeat_message(6, 8, 0, 0, 4, 3))
        await asyncio.sleep(1.5)  # the bridge finds the camera, the attitude stream starts
        t0 = dev.now - dev.state.camera.booted_at
        hide0 = t0 + seconds - 2.0
        dev.state.targets = (
            parse_spec(f"bearing={5 - 10 * t0:.4f},elevation=-3,speed=10,hide={hide0:.4f}-{hide0 + 60:.4f}"),
        )
        tr = truth_record(dev)["targets"][0]
        x, y = tr["x"], tr["y"]
        send(ml.MAVLink_command_long_message(1, 100, 2005, 0, x - 0.03, y - 0.05, x + 0.03, y + 0.05, 0, 0, 0))
        send(ml.MAVLink_command_long_message(1, 100, 511, 0, 275, 100_000, 0, 0, 0, 0, 0))
        end = loop.time() + seconds
        while loop.time() < end:
            truth.append(truth_record(dev))
            await asyncio.sleep(0.02)
    finally:
        transport.close()
        await bridge.close()
        await sim.stop()
    active = [(m, t) for m, t in got if m.tracking_status == 1 and t["tracking"] == "tracking" and t["t"] - t0 > 1.0]
    dist = [math.hypot((m.rec_top_x + m.rec_bottom_x) / 2 - t["targets"][0]["x"],
                       (m.rec_top_y + m.rec_bottom_y) / 2 - t["targets"][0]["y"]) for m, t in active]  # fmt: skip
    lost_t = next((r["t"] for r in truth if r["tracking"] == "lost"), None)
    err_t = next((t["t"] for m, t in got if m.tracking_status == 2), None)
    return {
        "statuses": len(got),
        "box_rms_frac": math.sqrt(statistics.fmean(d * d for d in dist)) if dist else float("nan"),
        "box_max_frac": max(dist) if dist else float("nan"),
        "error_after_loss_s": (err_t - lost_t) if lost_t is not None and err_t is not None else float("nan"),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seconds", type=float, default=8.0)
    ap.add_argument("--latency-ms", type=float, default=150.0)
    ap.add_argument("--repeat", type=int, default=1, help="runs of each law (the figures vary with the load)")
    ap.add_argument("--skip-camera", action="store_true", help="only the companion loop")
    ap.add_argument("--skip-companion", action="store_true", help="only the camera's own tracker")
    a = ap.parse_args()
    print(f"load average {' / '.join(f'{x:.2f}' for x in os.getloadavg())}")
    if not a.skip_companion:
        lat = a.latency_ms / 1000.0
        print(
            f"companion loop, C10, target at 10 deg/s, 0.5 s occlusion, {a.latency_ms:g} ms video latency, {a.seconds:g} s"
        )
        print(f"{'law':28} {'RMS deg':>8} {'max deg':>8} {'reacq. s':>9} {'pictures':>9} {'found':>6}  final")
        for law, comp in [(law, comp) for law, comp in (("pi", True), ("pixel-p", True), ("pi", False))
                          for _ in range(a.repeat)]:  # fmt: skip
            r = asyncio.run(companion_run(law, lat, a.seconds, compensate=comp))
            print(f"{r['law']:28} {r['rms_deg']:8.3f} {r['max_deg']:8.3f} {r['reacquired_s']:9.2f} "
                  f"{r['pictures']:9d} {r['detections']:6d}  {r['final']}")  # fmt: skip
    if not a.skip_camera:
        r = asyncio.run(camera_tracker_run(a.seconds))
        print("camera's own tracker (SIP) through the bridge, 275 at 10 Hz")
        print(f"  statuses {r['statuses']}, box distance from the truth: RMS {r['box_rms_frac'] * 100:.2f} % "
              f"max {r['box_max_frac'] * 100:.2f} % of the picture; ERROR {r['error_after_loss_s']:.2f} s after the loss")  # fmt: skip


if __name__ == "__main__":
    main()
