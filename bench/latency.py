"""Client latency and telemetry figures against the simulator on loopback UDP.

Prints: request round-trip p50/p99 (AsyncClient.request to the simulator) next to a bare UDP
echo and a bare query to the simulator measured in the same run (target: client p99 within 1.5x of
the echo; the bare query shows how much of that the simulator itself takes), then the attitude
stream at 100 Hz for --seconds (rate error, p99 jitter, loss; targets < 0.5 %, < 2 ms, 0).

`--compare DIR` also measures the client from another source tree (e.g. `git archive main src |
tar -x -C /tmp/main`, then `--compare /tmp/main/src`) against the same simulator, alternating
the two in rounds so that both see the same machine load: before/after in one run.

    python bench/latency.py [--requests 2000] [--seconds 60] [--model C12] [--pin] [--compare DIR]
"""

from __future__ import annotations

import argparse
import asyncio
import itertools
import json
import os
import re
import statistics
import subprocess
import sys
import time

import topgimbal

ROUNDS = 10


def pct(values: list[float], p: float) -> float:
    s = sorted(values)
    return s[min(len(s) - 1, round(p / 100 * (len(s) - 1)))]


ECHO_CODE = """
import socket, sys
s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
s.bind(("127.0.0.1", 0))
print("udp://127.0.0.1:%d" % s.getsockname()[1], flush=True)
while True:
    data, addr = s.recvfrom(2048)
    s.sendto(data, addr)
"""


# The same echo woken by an event loop (epoll, as the simulator is): what any asyncio device pays
# over a blocked recvfrom before it runs a line of its own.
ASYNC_ECHO_CODE = """
import asyncio, socket
async def main():
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.bind(("127.0.0.1", 0))
    s.setblocking(False)
    print("udp://127.0.0.1:%d" % s.getsockname()[1], flush=True)
    def readable():
        while True:
            try:
                data, addr = s.recvfrom(2048)
            except BlockingIOError:
                return
            s.sendto(data, addr)
    asyncio.get_running_loop().add_reader(s.fileno(), readable)
    await asyncio.Event().wait()
asyncio.run(main())
"""


class Peer:
    """A process printing its udp:// URL (the device is another process, as in real life: no GIL
    shared with the client being measured)."""

    def __init__(self, argv: list[str], cpu: int | None = None) -> None:
        pin = None if cpu is None else (lambda: os.sched_setaffinity(0, {cpu}))
        self.proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, preexec_fn=pin)
        assert self.proc.stdout is not None
        for _ in range(10):
            line = self.proc.stdout.readline()
            m = re.search(r"udp://[0-9.]+:[0-9]+", line)
            if m:
                self.url = m.group(0)
                self.port = int(self.url.rsplit(":", 1)[1])
                return
        self.stop()
        raise RuntimeError(f"{argv[:4]} did not print a udp:// URL")

    def stop(self) -> None:
        self.proc.terminate()
        self.proc.wait(5)


async def echo_rtts(port: int, n: int, payload: bytes) -> list[float]:
    loop = asyncio.get_running_loop()
    waiter: list[asyncio.Future[bytes]] = []

    class Client(asyncio.DatagramProtocol):
        def datagram_received(self, data: bytes, addr: tuple) -> None:  # type: ignore[type-arg]
            if waiter and not waiter[0].done():
                waiter[0].set_result(data)

    t, _ = await loop.create_datagram_endpoint(Client, remote_addr=("127.0.0.1", port))
    out = []
    for _ in range(n):
        fut = loop.create_future()
        waiter[:] = [fut]
        t0 = time.perf_counter()
        t.sendto(payload)
        await asyncio.wait_for(fut, 1.0)
        out.append(time.perf_counter() - t0)
    t.close()
    return out


async def client_rtts(url: str, model: str, n: int) -> tuple[list[float], int]:
    out = []
    # No pacing: the simulator takes commands back to back (its command_pacing quirk is off), and
    # the round trip, not the C12's 40 ms gap between commands, is what is measured here.
    async with topgimbal.connect(url, model=model, timeout_s=1.0, min_command_gap_s=0) as cam:
        for _ in range(50):  # warm-up
            await cam.request("GAC", read=True)
        for _ in range(n):
            t0 = time.perf_counter()
            await cam.request("GAC", read=True)
            out.append(time.perf_counter() - t0)
        return out, cam.stats.timeouts


CLIENT_CODE = """
import asyncio, json, sys, time, topgimbal
def connect(url, model):
    try:
        return topgimbal.connect(url, model=model, timeout_s=1.0, min_command_gap_s=0)
    except TypeError:  # a tree from before pacing
        return topgimbal.connect(url, model=model, timeout_s=1.0)
async def main(url, model, n):
    out = []
    async with connect(url, model) as cam:
        for _ in range(50):
            await cam.request("GAC", read=True)
        for _ in range(n):
            t0 = time.perf_counter()
            await cam.request("GAC", read=True)
            out.append(time.perf_counter() - t0)
    print(json.dumps(out))
asyncio.run(main(sys.argv[1], sys.argv[2], int(sys.argv[3])))
"""


def client_process_rtts(src: str, url: str, model: str, n: int) -> list[float]:
    """The client from source tree `src`, in its own process (so two trees never mix)."""
    env = dict(os.environ, PYTHONPATH=src)
    out = subprocess.run(
        [sys.executable, "-c", CLIENT_CODE, url, model, str(n)], env=env, capture_output=True, text=True, check=True
    )
    return list(json.loads(out.stdout))


def compare(url: str, model: str, n: int, other: str) -> None:
    here = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "src")
    runs: dict[str, list[float]] = {"this tree": [], other: []}
    for _ in range(4):  # alternate, so that both see the same load
        for name, src in (("this tree", here), (other, other)):
            runs[name] += client_process_rtts(src, url, model, n // 4)
    print(f"client round trip, this tree vs {other} (same simulator, alternating rounds)")
    for name, xs in runs.items():
        print(f"  {name:34s} p50 {pct(xs, 50) * 1000:7.3f} ms  p99 {pct(xs, 99) * 1000:7.3f} ms")


async def attitude_run(url: str, model: str, seconds: float, rate_hz: float) -> dict[str, float]:
    arrivals: list[float] = []
    async with topgimbal.connect(url, model=model, timeout_s=1.0) as cam:
        cam.subscribe(lambda m: arrivals.append(time.perf_counter()), "GAC")
        await cam.attitude_stream(rate_hz)
        await asyncio.sleep(0.5)  # settle
        arrivals.clear()
        t0 = time.perf_counter()
        await asyncio.sleep(seconds)
        t1 = time.perf_counter()
        await cam.stop_attitude_stream()
    inside = [t for t in arrivals if t0 <= t <= t1]
    period = 1.0 / rate_hz
    gaps = [b - a for a, b in itertools.pairwise(inside)]
    rate = (len(inside) - 1) / (inside[-1] - inside[0]) if len(inside) > 1 else 0.0
    jitter = [abs(g - period) for g in gaps]
    # GAC frames carry no sequence number: loss is counted against the expected number of samples;
    # "bunched" counts samples that came less than half a period after the previous one.
    lost = max(0, round((inside[-1] - inside[0]) * rate_hz) + 1 - len(inside)) if inside else 0
    bunched = sum(1 for g in gaps if g < period / 2)
    return {
        "samples": len(inside),
        "expected": seconds * rate_hz,
        "rate_hz": rate,
        "rate_error_pct": abs(rate - rate_hz) / rate_hz * 100,
        "jitter_p50_ms": pct(jitter, 50) * 1000 if jitter else 0.0,
        "jitter_p99_ms": pct(jitter, 99) * 1000 if jitter else 0.0,
        "lost": lost,
        "bunched": bunched,
    }


async def raw_rtts(port: int, n: int, payload: bytes) -> list[float]:
    """Bare UDP to the simulator, no client: what the simulator itself costs."""
    return await echo_rtts(port, n, payload)


def placement(pin: bool) -> tuple[int | None, str]:
    """Where the peers run: anywhere (the scheduler decides), or `--pin`: this process on one core
    and every peer on another, so that each round trip crosses cores the same way. Free, a
    blocked recvfrom (the bare echo) is woken on the sender's core and an epoll wait (the
    simulator, the asyncio echo) usually is not: measured here, a bare echo on the same core as
    its client answered in 0.033 ms p50, on another core in 0.071 ms. Pinned, that difference is
    out of the comparison; free is what an unpinned user gets."""
    if not pin:
        return None, "free placement"
    cpus = sorted(os.sched_getaffinity(0))
    if len(cpus) < 2:
        raise SystemExit("--pin needs two cores")
    os.sched_setaffinity(0, {cpus[0]})
    return cpus[1], f"pinned: client on cpu {cpus[0]}, echoes and simulator on cpu {cpus[1]}"


async def main_async(args: argparse.Namespace) -> None:
    cpu, where = placement(args.pin)
    echo = Peer([sys.executable, "-c", ECHO_CODE], cpu)
    aecho = Peer([sys.executable, "-c", ASYNC_ECHO_CODE], cpu)
    sim = Peer([sys.executable, "-m", "topgimbal.cli.main", "sim", "--model", args.model, "--udp", "127.0.0.1:0"], cpu)
    try:
        query = b"#TPUG2rGAC0032"
        await echo_rtts(echo.port, 50, query)  # warm-up
        await raw_rtts(sim.port, 50, query)
        # In turn, ROUNDS times, so that a change of machine load hits all three alike (one after
        # the other, a busy spell during one of them alone decides the p99 ratio).
        e: list[float] = []
        ae: list[float] = []
        raw: list[float] = []
        c: list[float] = []
        timeouts = 0
        per_round = max(1, args.requests // ROUNDS)
        for _ in range(ROUNDS):
            e += await echo_rtts(echo.port, per_round, query)
            ae += await echo_rtts(aecho.port, per_round, query)
            raw += await raw_rtts(sim.port, per_round, query)
            got, lost = await client_rtts(sim.url, args.model, per_round)
            c += got
            timeouts += lost
        ms = 1000.0
        print(
            f"round trip over loopback UDP, {len(c)} requests each in {ROUNDS} alternating rounds "
            f"({args.model} simulator, own process; {where}; load average {' '.join(f'{x:.2f}' for x in os.getloadavg())})"
        )
        print(f"  {'':34s} {'p50 ms':>8s} {'p99 ms':>8s} {'mean ms':>8s}")
        for name, xs in (
            ("bare UDP echo", e),
            ("asyncio UDP echo (epoll-woken)", ae),
            ("bare UDP GAC query -> sim", raw),
            ("client.request(GAC) -> sim", c),
        ):
            print(f"  {name:34s} {pct(xs, 50) * ms:8.3f} {pct(xs, 99) * ms:8.3f} {statistics.fmean(xs) * ms:8.3f}")
        print(f"  p99 ratio client/echo: {pct(c, 99) / pct(e, 99):.2f}x (target <= 1.5x in each run)")
        print(
            f"  p99 ratio asyncio echo/echo: {pct(ae, 99) / pct(e, 99):.2f}x, p50 {pct(ae, 50) / pct(e, 50):.2f}x "
            "(an event loop's wake-up alone, before any device code)"
        )
        print(
            f"  client's own share: p50 {(pct(c, 50) - pct(raw, 50)) * ms:.3f} ms, "
            f"p99 {(pct(c, 99) - pct(raw, 99)) * ms:.3f} ms over the bare query"
        )
        print(
            f"  p99 ratio client/bare-sim (client overhead only): {pct(c, 99) / pct(raw, 99):.2f}x  timeouts: {timeouts}"
        )
        if args.compare:
            await asyncio.to_thread(compare, sim.url, args.model, args.requests, args.compare)
        r = await attitude_run(sim.url, args.model, args.seconds, args.rate)
        print(f"attitude stream at {args.rate:g} Hz for {args.seconds:g} s")
        print(
            f"  samples {r['samples']} (expected {r['expected']:.0f}), rate {r['rate_hz']:.3f} Hz, "
            f"rate error {r['rate_error_pct']:.3f} % (target < 0.5 %)"
        )
        print(
            f"  jitter p50 {r['jitter_p50_ms']:.3f} ms, p99 {r['jitter_p99_ms']:.3f} ms (target < 2 ms), "
            f"lost {r['lost']} (target 0), bunched {r['bunched']}"
        )
    finally:
        sim.stop()
        aecho.stop()
        echo.stop()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--requests", type=int, default=2000)
    ap.add_argument("--seconds", type=float, default=60.0, help="attitude stream duration (default 60)")
    ap.add_argument("--rate", type=float, default=100.0)
    ap.add_argument("--model", default="C12", help="a SkyDroid model (rate-controlled stream)")
    ap.add_argument("--pin", action="store_true", help="client on one core, every peer on another (see placement())")
    ap.add_argument("--compare", metavar="DIR", help="also measure the client of another source tree (its src/)")
    asyncio.run(main_async(ap.parse_args()))


if __name__ == "__main__":
    main()
