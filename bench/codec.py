"""Codec throughput, side by side in one run: parse + decode of a 200,000-frame mixed stream in C
(libtopgimbal), in Python with the C fast path, in pure Python, in pure Python as it was before the
C work (commit a995c83, extracted with `git archive` into a temporary directory), and public
Python parsers of the same protocol on the frames both understand.

    python bench/codec.py [--frames N] [--rounds R] [--original REV|none] [--public DIR]

CPU time (time.process_time), best of R rounds taken in turn (the machine is shared: the load
average is printed with the figures). Ratios are against a saturated 115200-baud 8N1 link and
against the other implementations. Prints figures; asserts nothing.

`--public DIR`: a scratch directory holding public parsers (never vendored into this repository),
laid out as PUBLIC below says; each is measured on single-frame datagrams of the frames it decodes.
"""

from __future__ import annotations

import argparse
import os
import random
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from topgimbal import _speedups
from topgimbal.protocol import Frame, FrameParser, any_decoder, get_dialect
from topgimbal.protocol.parser import PureFrameParser

ROOT = Path(__file__).resolve().parents[1]
LINK_BYTES_S = 115200 / 10  # 8N1: 10 bits per byte
ORIGINAL = "a995c83"  # main before the C work (round one's baseline: 181,637 frames/s on a quiet machine)

# The decode loop every pure-Python figure uses (ours now and the original): one FrameParser, each
# datagram fed, each frame decoded by the likelier dialect, as the benchmark always did.
DRIVER = """
import sys, time
from topgimbal.protocol import Frame, FrameParser, get_dialect
raw = open(sys.argv[1], "rb").read()
dgs, i = [], 0
while i < len(raw):
    n = int.from_bytes(raw[i:i + 2], "big"); dgs.append(raw[i + 2:i + 2 + n]); i += 2 + n
sky, top = get_dialect("skydroid"), get_dialect("topotek")
decode = sys.argv[2] == "decode"
parser = FrameParser(); n = 0
t0 = time.process_time()
for dg in dgs:
    for ev in parser.feed(dg):
        if type(ev) is Frame:
            n += 1
            if decode:
                (top if ev.src == "D" or ev.dst == "P" or ev.ident in ("GIA", "GPS") else sky).decode(ev)
print(n, time.process_time() - t0)
"""


def load() -> str:
    one, five, fifteen = os.getloadavg()
    return f"load average {one:.2f} {five:.2f} {fifteen:.2f} on {os.cpu_count()} CPUs"


def mixed_stream(n: int, seed: int = 1) -> list[bytes]:
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
    return datagrams


def write_stream(datagrams: list[bytes], path: Path) -> None:
    """Each datagram as a 2-byte big-endian length and its bytes (read by DRIVER and c/tests/bench.c)."""
    path.write_bytes(b"".join(len(d).to_bytes(2, "big") + d for d in datagrams))


def run_driver(src: Path, stream: Path, mode: str) -> float:
    """frames/s of DRIVER on the pure path of the package under `src` (CPU time in that process)."""
    env = dict(os.environ, PYTHONPATH=str(src), TOPGIMBAL_PURE="1")
    out = subprocess.run([sys.executable, "-c", DRIVER, str(stream), mode], env=env, capture_output=True, text=True)
    if out.returncode != 0:
        raise RuntimeError(out.stderr.strip()[-300:])
    n, dt = out.stdout.split()
    return int(n) / float(dt)


def original_tree(rev: str, into: Path) -> Path | None:
    """src/ of `rev`, extracted with git archive (None when this is not a git checkout)."""
    archive = subprocess.run(["git", "-C", str(ROOT), "archive", rev, "src"], capture_output=True)
    if archive.returncode != 0:
        return None
    subprocess.run(["tar", "-x", "-C", str(into)], input=archive.stdout, check=True)
    return into / "src"


def best_rate(fn: Callable[[], int], rounds: int) -> float:
    best = 0.0
    for _ in range(rounds):
        t0 = time.process_time()
        n = fn()
        best = max(best, n / (time.process_time() - t0))
    return best


def python_figures(datagrams: list[bytes], rounds: int) -> dict[str, float]:
    """Fast-path figures (in this process): per frame as the pure loop does it, and batched."""
    sky, top = get_dialect("skydroid"), get_dialect("topotek")
    any_dec = any_decoder()

    def per_frame() -> int:
        parser, n = FrameParser(), 0
        for dg in datagrams:
            for ev in parser.feed(dg):
                if type(ev) is Frame:
                    n += 1
                    (top if ev.src == "D" or ev.dst == "P" or ev.ident in ("GIA", "GPS") else sky).decode(ev)
        return n

    def batched() -> int:
        feed, n = FrameParser().feed_messages, 0
        for dg in datagrams:
            n += len(feed(dg, any_dec, final=True))
        return n

    def parse_only() -> int:
        feed, n = FrameParser().feed_datagram, 0
        for dg in datagrams:
            n += len(feed(dg))
        return n

    return {
        "parse only": best_rate(parse_only, rounds),
        "decode, frame by frame (the pure loop)": best_rate(per_frame, rounds),
        "decode, batched (feed_messages + any_decoder)": best_rate(batched, rounds),
    }


def bench_encode(n: int) -> float:
    sky, top = get_dialect("skydroid"), get_dialect("topotek")
    jobs = [
        (sky, "GAY", {"yaw_deg": -50.0, "speed_deg_s": 5.0}),
        (sky, "GSM", {"yaw_rate_deg_s": 3.0, "pitch_rate_deg_s": -2.0}),
        (top, "YPR", {"yaw_rate_deg_s": 10, "pitch_rate_deg_s": -20, "roll_rate_deg_s": 0}),
        (top, "GIP", {"pitch_deg": -45.0}),
        (sky, "REC", {"action": "start"}),
        (top, "UAV", {"yaw_deg": 90, "pitch_deg": -5, "roll_deg": 1, "speed_m_s": 3, "path_angle_deg": 0}),
    ]
    t0 = time.process_time()
    for i in range(n):
        d, ident, values = jobs[i % len(jobs)]
        d.encode(ident, **values).to_bytes()
    return n / (time.process_time() - t0)


def c_figures(stream: Path) -> list[str]:
    """libtopgimbal's own figures (c/tests/bench.c, gcc -O2, CPU time) on the same stream."""
    r = subprocess.run(["make", "-s", "-C", str(ROOT / "c"), "build/bench"], capture_output=True, text=True)
    if r.returncode != 0:
        return [f"C benchmark not built: {r.stderr.strip()[:200]}"]
    out = subprocess.run([str(ROOT / "c" / "build" / "bench"), str(stream)], capture_output=True, text=True)
    return out.stdout.strip().splitlines()


# -- public parsers (measured from a scratch directory, never vendored) ---------------------------

# (who, directory under --public, import, call, which frames it decodes)
PUBLIC = [
    (
        "CinarSamet/skydroid-c12-toolkit@82a4a6b protocol.parse_gac_packet",
        "cinar",
        "skydroid_c12.protocol",
        lambda mod: mod.parse_gac_packet,
        "skydroid GAC",
    ),
    (
        "alireza787b/PixEagle@b20cc4e GimbalInterface._parse_gimbal_packet",
        "pixeagle/src",
        "classes.gimbal_interface",
        lambda mod: _pixeagle(mod),
        "topotek GAC",
    ),
    (
        "QGC fork (DhakshaGroundControl) skydroid_camera_simulator.parse",
        "qgcfork",
        "skydroid_camera_simulator",
        lambda mod: mod.parse,
        "#TP commands",
    ),
    (
        "TOP module parse_tp_frame (repository not identified)",
        "tpframes",
        "top_frames",
        lambda mod: mod.parse_tp_frame,
        "skydroid GAC",
    ),
]


def _pixeagle(mod: Any) -> Callable[[bytes], Any]:
    import logging

    logging.disable(logging.CRITICAL)  # its parser logs at debug level on every packet
    gi = mod.GimbalInterface()
    # as its listener loop does with each datagram
    return lambda dg: gi._parse_gimbal_packet(dg.decode("utf-8", errors="replace").strip())


def frame_set(kind: str, n: int) -> tuple[list[bytes], Any]:
    """Single-frame datagrams of one kind, and the dialect they belong to."""
    rnd = random.Random(2)
    sky, top = get_dialect("skydroid"), get_dialect("topotek")
    if kind == "skydroid GAC":
        req = sky.encode("GAC", read=True)
        make = lambda: sky.response(req, yaw_deg=rnd.uniform(-90, 90), pitch_deg=rnd.uniform(-90, 90), roll_deg=0)  # noqa: E731
        return [make().to_bytes() for _ in range(n)], sky
    if kind == "topotek GAC":
        req = top.encode("GAC", read=True, dst="G")
        make = lambda: top.response(  # noqa: E731
            req, yaw_deg=rnd.uniform(-150, 150), pitch_deg=rnd.uniform(-90, 90), roll_deg=rnd.uniform(-5, 5)
        )
        return [make().to_bytes() for _ in range(n)], top
    actions = [("PTZ", {"action": "up"}), ("PTZ", {"action": "stop"}), ("REC", {"action": "start"})]
    return [sky.encode(a, **v).to_bytes() for a, v in (rnd.choice(actions) for _ in range(n))], sky


def public_figures(base: Path, rounds: int) -> list[str]:
    lines = []
    for who, sub, module, get_call, kind in PUBLIC:
        path = base / sub
        if not path.is_dir():
            lines.append(f"  {who}: not found under {base}")
            continue
        sys.path.insert(0, str(path))
        try:
            call = get_call(__import__(module, fromlist=["_"]))
        except Exception as exc:
            lines.append(f"  {who}: cannot load ({exc!r})")
            continue
        finally:
            sys.path.remove(str(path))
        datagrams, dialect = frame_set(kind, 20_000)
        understood = sum(call(dg) is not None for dg in datagrams[:200])

        def theirs(call: Callable[[bytes], Any] = call, dgs: list[bytes] = datagrams) -> int:
            for dg in dgs:
                call(dg)
            return len(dgs)

        def ours(parser_cls: type[FrameParser], decode: Any, dgs: list[bytes] = datagrams) -> int:
            # timed like theirs: one call per datagram, the result dropped (what each call yields
            # is checked on the first 200 below, outside the timing)
            feed = parser_cls().feed_messages
            for dg in dgs:
                feed(dg, decode, final=True)
            return len(dgs)

        for parser_cls, decode in ((PureFrameParser, dialect._decode_py), (FrameParser, dialect.decode)):
            sample = [m for dg in datagrams[:200] for m in parser_cls().feed_messages(dg, decode, final=True)]
            if len(sample) != 200 or any(m.fields is None for m in sample):
                raise SystemExit(f"{who}: our {parser_cls.__name__} did not decode every frame of the set")

        rate: dict[str, float] = {}
        for _ in range(rounds):  # in turn, so load changes hit all three alike
            for label, fn in (
                ("theirs", theirs),
                ("pure", lambda d=dialect: ours(PureFrameParser, d._decode_py)),
                ("fast", lambda d=dialect: ours(FrameParser, d.decode)),
            ):
                rate[label] = max(rate.get(label, 0.0), best_rate(fn, 1))
        lines.append(f"  {who}")
        lines.append(f"    on {kind} frames, one per datagram ({understood}/200 decoded by it)")
        lines.append(f"    theirs {rate['theirs']:>12,.0f} frames/s")
        lines.append(
            f"    ours, pure Python {rate['pure']:>12,.0f} frames/s = {rate['pure'] / rate['theirs']:5.2f}x theirs"
        )
        if _speedups.enabled():
            lines.append(
                f"    ours, fast path   {rate['fast']:>12,.0f} frames/s = {rate['fast'] / rate['theirs']:5.2f}x theirs"
            )
    return lines


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--frames", type=int, default=200_000)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--original", default=ORIGINAL, help="git revision to compare the pure path with ('none': skip)")
    ap.add_argument("--public", type=Path, help="scratch directory of public parsers (see PUBLIC)")
    args = ap.parse_args()
    datagrams = mixed_stream(args.frames)
    total = sum(len(d) for d in datagrams)
    link_fps = LINK_BYTES_S / (total / args.frames)
    print(
        f"mixed stream: {args.frames:,} frames in {len(datagrams):,} datagrams, {total / args.frames:.1f} bytes/frame"
    )
    print(f"saturated 115200-baud link: {link_fps:,.0f} frames/s")
    print(f"fast path: {_speedups.status()}; {load()} (CPU time, best of {args.rounds})")
    with tempfile.TemporaryDirectory(prefix="topgimbal-bench-") as tmp:
        stream = Path(tmp) / "stream.bin"
        write_stream(datagrams, stream)
        orig_src = None if args.original == "none" else original_tree(args.original, Path(tmp))
        figures: dict[str, float] = {}
        for _ in range(args.rounds):  # in turn: the same load for each
            for label, src, mode in (
                ("pure Python: parse only", ROOT / "src", "parse"),
                ("pure Python: decode", ROOT / "src", "decode"),
                (f"pure Python {args.original} (original): decode", orig_src, "decode"),
            ):
                if src is not None:
                    figures[label] = max(figures.get(label, 0.0), run_driver(src, stream, mode))
        if _speedups.enabled():
            for label, fps in python_figures(datagrams, args.rounds).items():
                figures[f"fast path: {label}"] = fps
        figures["encode (typed fields -> bytes)"] = max(bench_encode(args.frames // 4) for _ in range(args.rounds))
        c_lines = c_figures(stream)
    print(f"\n{'':54} {'frames/s':>12}  {'x link':>7}")
    for label, fps in figures.items():
        print(f"{label:<54} {fps:>12,.0f}  {fps / link_fps:>7.0f}")
    for line in c_lines:
        print(line)
    print(f"({load()})")
    pure = figures["pure Python: decode"]
    orig = figures.get(f"pure Python {args.original} (original): decode")
    batched = figures.get("fast path: decode, batched (feed_messages + any_decoder)")
    c_decode = next((float(x.split()[-6]) for x in c_lines if x.startswith("C parse + decode (datagrams)")), None)
    print("\ntargets (issue 11):")
    if c_decode is not None:
        print(f"  C parse + decode >= 8M frames/s: {'met' if c_decode >= 8e6 else 'NOT met'} ({c_decode:,.0f})")
    if batched is not None:
        print(f"  Python fast path decode >= 1M frames/s: {'met' if batched >= 1e6 else 'NOT met'} ({batched:,.0f})")
    if orig:
        ratio = pure / orig
        print(f"  pure Python decode >= 1.5x the original: {'met' if ratio >= 1.5 else 'NOT met'} ({ratio:.2f}x)")
    if args.public:
        print(f"\npublic Python parsers (from {args.public}; {load()}):")
        for line in public_figures(args.public, args.rounds):
            print(line)


if __name__ == "__main__":
    main()
