"""The client under the simulator's fault plans: the right answer or a clear error, measured.

Per plan, a C12 simulator (in this process, loopback UDP) and one client
(`connect(url, timeout_s=0.3, retries=2, dup_window_s=0.25)`, everything else default) run three workers for
--seconds: IPV write then read (a new address each time), TAS write then read (0..25 s in turn),
and photos. The simulator's own state is recorded after every frame it handles, so each outcome is
checked against the truth: a read must return a value the device held at some moment during the
call, a write must have been applied during it. Then a stream runs, the simulator is stopped, and
the time until the stream ends with LinkLostError is the time to detect a dead device.

Columns: requests made (reads + writes + photos), ok %, idempotent ok %, wrong values (must be 0),
photos asked / CAP frames the client sent / acknowledged / frames the device got (network copies
included) / photos the device took (its own counter), p50 / p99 latency of successful calls, and
the detection time.

    python bench/faults.py [--seconds 5] [--plans late,drop]
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import itertools
import logging
import time
from dataclasses import dataclass, field
from typing import Any

import topgimbal
from topgimbal.errors import LinkLostError, TopGimbalError
from topgimbal.sim import FaultPlan, Simulator

DEBUG = False
PLANS: dict[str, dict[str, Any]] = {
    "late": {"late_reply_s": 0.4, "late_reply_p": 0.3, "direction": "out"},
    "delay+jitter": {"delay_s": 0.05, "jitter_s": 0.3},
    "corrupt+truncate": {"corrupt": 0.2, "truncate": 0.1},
    "drop30": {"drop": 0.3},
    "dup+reorder": {"duplicate": 0.2, "reorder": 0.2},
    "silence": {"silence": ((1.5, 3.0),)},
    "everything": {
        "drop": 0.1,
        "duplicate": 0.1,
        "corrupt": 0.1,
        "truncate": 0.05,
        "reorder": 0.1,
        "delay_s": 0.02,
        "jitter_s": 0.1,
        "late_reply_s": 0.4,
        "late_reply_p": 0.2,
        "silence": ((2.0, 2.8),),
    },
}


@dataclass
class Op:
    kind: str  # read / write / photo
    key: str  # ip / tas / cap
    start: float
    end: float = 0.0
    ok: bool = False
    value: Any = None
    error: str = ""


@dataclass
class History:
    """What the device held, and since when (monotonic), per setting."""

    points: dict[str, list[tuple[float, Any]]] = field(default_factory=lambda: {"ip": [], "tas": []})

    def record(self, now: float, ip: str, tas: Any) -> None:
        for key, v in (("ip", ip), ("tas", tas)):
            seq = self.points[key]
            if not seq or seq[-1][1] != v:
                seq.append((now, v))

    def held(self, key: str, a: float, b: float) -> set[Any]:
        seq = self.points[key]
        out = {v for t, v in seq if a <= t <= b}
        before = [v for t, v in seq if t < a]
        if before:
            out.add(before[-1])
        return out


def pct(xs: list[float], p: float) -> float:
    s = sorted(xs)
    return s[min(len(s) - 1, round(p / 100 * (len(s) - 1)))] if s else float("nan")


async def run_plan(name: str, plan: dict[str, Any], seconds: float, seed: int) -> dict[str, Any]:
    sim = Simulator("C12", seed=seed, faults=FaultPlan(**plan))
    await sim.start(udp=[("127.0.0.1", 0)])
    history = History()
    device = sim.device
    original = device.handle
    cap_got = 0

    def handle(peer: Any, frame: Any) -> Any:
        nonlocal cap_got
        out = original(peer, frame)
        cap_got += frame.ident == "CAP"
        history.record(time.monotonic(), sim.network.ip, sim.settings["TAS"]["interval_s"])
        return out

    device.handle = handle  # type: ignore[method-assign]
    history.record(time.monotonic(), sim.network.ip, sim.settings["TAS"]["interval_s"])
    photos_before = sim.camera.photos_taken
    ops: list[Op] = []
    cap_sent = 0
    # dup_window_s: the simulator's reorder holds a packet (a copy too) up to 0.2 s
    async with topgimbal.connect(sim.url, model="C12", timeout_s=0.3, retries=2, dup_window_s=0.25) as cam:

        def count(direction: str, frame: Any, message: Any) -> None:
            nonlocal cap_sent
            if direction == "out" and frame.ident == "CAP":
                cap_sent += 1

        cam.on_traffic(count)
        end = time.monotonic() + seconds

        async def call(kind: str, key: str, coro: Any, value: Any = None, field: str = "") -> None:
            op = Op(kind, key, time.monotonic(), value=value)
            ops.append(op)
            try:
                result = await coro
            except TopGimbalError as exc:
                op.error = type(exc).__name__
                return
            finally:
                op.end = time.monotonic()
            op.ok = True
            if field:
                op.value = (result.fields or {}).get(field)

        async def setting(key: str, ident: str, field: str, values: Any) -> None:
            while time.monotonic() < end:
                v = next(values)
                await call("write", key, cam.request(ident, **{field: v}), v)
                await call("read", key, cam.request(ident, read=True), field=field)

        async def photos() -> None:
            while time.monotonic() < end:
                await call("photo", "cap", cam.photo())

        ips = (f"10.{i // 250 % 250}.{i % 250}.{1 + i % 200}" for i in itertools.count(seed * 1000))
        tas = itertools.cycle(range(26))
        await asyncio.gather(setting("ip", "IPV", "address", ips), setting("tas", "TAS", "interval_s", tas), photos())
        stats = cam.stats.as_dict()
        # A dead device: how long until a running stream says so.
        detect = float("nan")
        with contextlib.suppress(TopGimbalError):
            async with cam.attitude(rate_hz=20) as stream:
                await asyncio.wait_for(stream.__anext__(), 10)
                device.handle = lambda *a, **k: []  # type: ignore[method-assign]
                await sim.stop()
                t0 = time.monotonic()
                try:
                    async for _att in stream:
                        pass
                except LinkLostError:
                    detect = time.monotonic() - t0
    if sim.started:
        await sim.stop()
    wrong = 0
    for op in ops:
        if not op.ok or op.kind == "photo":
            continue
        if op.value not in history.held(op.key, op.start, op.end):
            wrong += 1
            if wrong <= 3 and DEBUG:
                print("WRONG", op, history.held(op.key, op.start, op.end), history.points[op.key][-5:])
    idem = [op for op in ops if op.kind != "photo"]
    photos = [op for op in ops if op.kind == "photo"]
    lat = [(op.end - op.start) * 1000 for op in ops if op.ok]
    return {
        "plan": name,
        "requests": len(ops),
        "ok_pct": 100 * sum(op.ok for op in ops) / max(1, len(ops)),
        "idem_ok_pct": 100 * sum(op.ok for op in idem) / max(1, len(idem)),
        "wrong": wrong,
        "photos": len(photos),
        "cap_sent": cap_sent,
        "acked": sum(op.ok for op in photos),
        "cap_got": cap_got,
        "taken": sim.camera.photos_taken - photos_before,
        "p50_ms": pct(lat, 50),
        "p99_ms": pct(lat, 99),
        "detect_s": detect,
        "late": stats["late_replies"],
        "deferred": stats["deferred"],
    }


async def main_async(args: argparse.Namespace) -> None:
    logging.getLogger("topgimbal").setLevel(logging.ERROR)  # link-lost warnings are expected here
    names = args.plans.split(",") if args.plans else list(PLANS)
    print(
        f"C12 simulator, loopback UDP, connect(timeout_s=0.3, retries=2, dup_window_s=0.25), {args.seconds:g} s per plan"
    )
    head = (
        f"{'plan':17s} {'reqs':>5s} {'ok%':>6s} {'idem%':>6s} {'wrong':>5s} "
        f"{'photos asked/sent/acked/got/taken':>34s} {'p50 ms':>8s} {'p99 ms':>8s} {'dead in':>8s}"
    )
    print(head)
    for i, name in enumerate(names):
        r = await run_plan(name, PLANS[name], args.seconds, seed=100 + i)
        photos = f"{r['photos']}/{r['cap_sent']}/{r['acked']}/{r['cap_got']}/{r['taken']}"
        print(
            f"{r['plan']:17s} {r['requests']:5d} {r['ok_pct']:6.1f} {r['idem_ok_pct']:6.1f} {r['wrong']:5d} "
            f"{photos:>34s} {r['p50_ms']:8.1f} {r['p99_ms']:8.1f} {r['detect_s']:7.2f}s",
            flush=True,
        )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seconds", type=float, default=5.0, help="per plan (default 5)")
    ap.add_argument("--plans", default="", help=f"comma-separated subset of {', '.join(PLANS)}")
    asyncio.run(main_async(ap.parse_args()))


if __name__ == "__main__":
    main()
