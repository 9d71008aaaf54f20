"""Codec throughput: decode (parse + named fields) and encode on a mixed stream, against the frame
rate of a saturated 115200-baud 8N1 link (11 520 bytes/s). Target: decode >= 300x that link rate.

Run: `python bench/codec.py [--frames N]`. Prints figures; asserts nothing."""

from __future__ import annotations

import argparse
import random
import subprocess
import tempfile
import time
from pathlib import Path

from topgimbal import _speedups
from topgimbal.protocol import Diagnostic, Frame, FrameParser, Message, get_dialect

LINK_BYTES_S = 115200 / 10  # 8N1: 10 bits per byte


def mixed_stream(n: int, seed: int = 1) -> tuple[list[bytes], list[tuple[str, str, dict]]]:  # type: ignore[type-arg]
    """Datagrams of 1..3 frames from both dialects (attitude answers dominate, as on a real link)."""
    rnd = random.Random(seed)
    sky, top = get_dialect("skydroid"), get_dialect("topotek")
    req = sky.encode("GAC", read=True)
    makers = [
        (6, lambda: sky.response(req, yaw_deg=rnd.uniform(-90, 90), pitch_deg=rnd.uniform(-90, 90), roll_deg=0)),
        (
            3,
            lambda: top.notification(
                "GIA",
                src="G",
                dst="U",
                rw="r",
                yaw_deg=rnd.uniform(-150, 150),
                pitch_deg=rnd.uniform(-90, 90),
                roll_deg=rnd.uniform(-5, 5),
            ),
        ),
        (2, lambda: sky.encode("GAY", yaw_deg=rnd.uniform(-90, 90), speed_deg_s=5).swapped()),
        (1, lambda: top.notification("ZMP", src="M", dst="P", magnification_x=12.3, zoom_pos=rnd.randint(-500, 500))),
        (1, lambda: top.notification("LRF", src="E", dst="P", distance_m=rnd.uniform(5, 1500))),
        (1, lambda: sky.response(sky.encode("SDC", read=True), remaining_mb=rnd.randint(0, 60000), total_mb=61000)),
        (1, lambda: top.encode("GPS", heading_deg=10, lon_deg=113.5, lat_deg=22.5, alt_m=100)),
        (1, lambda: top.response(top.encode("REC", action="start"), state="started", file_index=rnd.randint(0, 9999))),
    ]
    weights = [w for w, _ in makers]
    frames: list[Frame] = [rnd.choices(makers, weights)[0][1]() for _ in range(n)]
    datagrams: list[bytes] = []
    i = 0
    while i < len(frames):
        k = rnd.randint(1, 3)
        sep = b"\r\n" if rnd.random() < 0.2 else b""
        datagrams.append(b"".join(f.to_bytes() + sep for f in frames[i : i + k]))
        i += k
    encode_jobs = [
        ("skydroid", "GAY", {"yaw_deg": -50.0, "speed_deg_s": 5.0}),
        ("skydroid", "GSM", {"yaw_rate_deg_s": 3.0, "pitch_rate_deg_s": -2.0}),
        ("topotek", "YPR", {"yaw_rate_deg_s": 10, "pitch_rate_deg_s": -20, "roll_rate_deg_s": 0}),
        ("topotek", "GIP", {"pitch_deg": -45.0}),
        ("skydroid", "REC", {"action": "start"}),
        ("topotek", "UAV", {"yaw_deg": 90, "pitch_deg": -5, "roll_deg": 1, "speed_m_s": 3, "path_angle_deg": 0}),
    ]
    return datagrams, encode_jobs


class FastFrameParser(FrameParser):
    """FrameParser with the C scan dropped in (as protocol/parser.py will adopt it)."""


def bench_parse(datagrams: list[bytes], decode: bool, fast: bool = False) -> tuple[float, int]:
    sky, top = get_dialect("skydroid"), get_dialect("topotek")
    parser = FastFrameParser() if fast else FrameParser()
    dec_sky, dec_top = sky.decode, top.decode
    if fast:  # the C decoders, with the pure ones as their fallback
        dec_sky = _speedups.make_decoder(sky, Message, sky.decode)
        dec_top = _speedups.make_decoder(top, Message, top.decode)
    n = 0
    t0 = time.perf_counter()
    for dg in datagrams:
        for ev in parser.feed(dg):
            if type(ev) is Frame:
                n += 1
                if decode:
                    (dec_top if ev.src == "D" or ev.dst == "P" or ev.ident in ("GIA", "GPS") else dec_sky)(ev)
    return time.perf_counter() - t0, n


def bench_encode(jobs: list[tuple[str, str, dict]], n: int) -> float:  # type: ignore[type-arg]
    dialects = {name: get_dialect(name) for name in ("skydroid", "topotek")}
    prepared = [(dialects[d], ident, values) for d, ident, values in jobs]
    t0 = time.perf_counter()
    for i in range(n):
        d, ident, values = prepared[i % len(prepared)]
        d.encode(ident, **values).to_bytes()
    return time.perf_counter() - t0


def bench_c(datagrams: list[bytes]) -> list[str]:
    """libtopgimbal's own figures (c/tests/bench.c, gcc -O2) on the same stream."""
    root = Path(__file__).resolve().parents[1]
    exe = root / "c" / "build" / "bench"
    r = subprocess.run(["make", "-s", "-C", str(root / "c"), "build/bench"], capture_output=True, text=True)
    if r.returncode != 0:
        return [f"C benchmark not built: {r.stderr.strip()[:200]}"]
    with tempfile.NamedTemporaryFile(suffix=".stream") as f:
        f.write(b"".join(len(d).to_bytes(2, "big") + d for d in datagrams))
        f.flush()
        out = subprocess.run([str(exe), f.name], capture_output=True, text=True, check=True).stdout
    return out.strip().splitlines()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--frames", type=int, default=200_000)
    args = ap.parse_args()
    datagrams, jobs = mixed_stream(args.frames)
    total_bytes = sum(len(d) for d in datagrams)
    avg = total_bytes / args.frames
    link_fps = LINK_BYTES_S / avg
    print(f"mixed stream: {args.frames} frames in {len(datagrams)} datagrams, {avg:.1f} bytes/frame on average")
    print(f"saturated 115200-baud link: {link_fps:,.0f} frames/s")
    best: dict[str, float] = {}
    fast_scan = _speedups.make_scan(Frame, Diagnostic, _speedups.scan_flags(FrameParser))
    if fast_scan is not None:
        FastFrameParser._scan = fast_scan  # type: ignore[method-assign]
    else:
        print(f"Python fast path not in use: {_speedups.status()}")
    for _ in range(3):  # best of three: the machine is shared
        for label, decode in (("parse only", False), ("decode (parse + fields)", True)):
            dt, n = bench_parse(datagrams, decode)
            assert n == args.frames, (n, args.frames)
            best[label] = max(best.get(label, 0.0), n / dt)
        if fast_scan is not None:
            for label, decode in (("fast path: parse only", False), ("fast path: decode (parse + fields)", True)):
                dt, n = bench_parse(datagrams, decode, fast=True)
                assert n == args.frames, (n, args.frames)
                best[label] = max(best.get(label, 0.0), n / dt)
        dt = bench_encode(jobs, args.frames // 2)
        best["encode (typed fields -> bytes)"] = max(
            best.get("encode (typed fields -> bytes)", 0.0), (args.frames // 2) / dt
        )
    for label, fps in best.items():
        print(f"{label:<36} {fps:>12,.0f} frames/s  = {fps / link_fps:6.0f}x the link")
    for line in bench_c(datagrams):
        print(line)
    ratio = best["decode (parse + fields)"] / link_fps
    print(f"decode target >= 300x the link: {'met' if ratio >= 300 else 'NOT met'} ({ratio:.0f}x)")


if __name__ == "__main__":
    main()
