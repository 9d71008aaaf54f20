"""Fleet benchmark: N simulated cameras (one simulator process) served by one `topgimbal zenoh`
process to a subscriber in a third process (this one, eclipse-zenoh directly). Figures, no
assertions:

- attitude messages delivered per second (all cameras) against the nominal N x rate, what the
  cameras sent in the same window (the machine's UDP OutDatagrams: a simulator process that falls
  behind shows here, not as the server's loss), and the loss between server and subscriber (gaps
  in each camera's `seq`). A window's count also moves with the queue before the server (a queue
  200 ms deeper at the end than at the start is 1 % fewer samples counted in 20 s);
- latency from the camera's send to the subscriber (p50 / p99), the wait in the server's receive
  queue included: one of the N cameras, `probe`, is simulated in a process of its own,
  sweeping its yaw at 7 deg/s between -80 and +80 deg (its range is +-90: turning one way it would
  sit at the stop after 13 s, every sample the same yaw) so that each of its samples has its own
  yaw; a yaw sent twice within AMBIGUOUS_S (the turns) is not used; each GAC datagram it sends is
  stamped (wall clock) as it leaves, and its sample is found again at the subscriber by that yaw.
  The probe's samples are not in the delivery figures (nominal: the other N-1 cameras'). The same
  samples are split at the server's stamp `t` (below): `camera_to_server_ms` (the kernel's queue,
  the server's read and its client) and `probe_server_to_subscriber_ms_p99` (the batch's wait,
  Zenoh, and this process's subscriber thread, which shares its cores with the simulators);
- latency p50 / p99 from the camera's frame reaching the server's client (the `t` stamped on
  arrival there) to the subscriber's callback. That clock starts when the server READS a datagram:
  the time it waited before, in the server's UDP receive queue, is not in it. So the queue is
  sampled too (/proc/net/udp, the server's own sockets, every 0.2 s): its bytes, the datagrams
  they hold (bytes / the kernel's per-datagram charge, measured here on a socket of this process)
  and the milliseconds that is at the nominal rate, and the datagrams the kernel dropped from it.
  An overloaded server shows a full queue, a few hundred ms long, while its latency p99 stays low;
- a command's round trip p50 / p99 to camera 0 (`version()`, a VER query, which the attitude
  stream does not answer): through Zenoh (query on
  topgimbal/cam0/call/version -> the server's client -> camera -> reply) and direct (an SDK
  client on the camera's UDP port from this process);
- CPU seconds per wall second of the server process and of the simulator process, per camera;
- why a queue stood: `server_off_core_while_queued_ms`, the time the serving loop did not run while
  more than 10 ms of traffic waited for it (in each 0.2 s sample that began and ended that deep,
  the wall time less the loop thread's CPU; with worker processes, their loops summed), and each
  core's `steal_ms`, the time the hypervisor ran someone else. A queue that grows while the loop
  runs flat out is the server's cost; one that grows while the loop is off its core is the
  machine's (or a lock the loop waits on).

The window opens on a steady state, not on the start: after every camera is heard, it waits until
the server's receive queue has stayed under WARM_QUEUE_MS (at the nominal rate) in every sample for
WARM_STEADY_S (at most WARM_MAX_S; `warmup_s` says how long from the server's start, `steady`
whether it got there). The start (1,000 clients connecting, their first collection) leaves a queue
that one run measured at 138 ms on its first half-second, and it is not what a fleet does.

`--pin` puts the server (and its Zenoh threads) on half of the cores, and everything else (the
simulators, the probe, this process and its subscriber) on the other half, as when the cameras are
other machines: the server is not preempted by its own load generator. Unpinned, the scheduler
decides; both are worth printing (`placement` says which ran).

    python bench/fleet.py --cameras 10,100 --rate-hz 50 --seconds 10
    python bench/fleet.py --cameras 1000 --rate-hz 50 --batched     # the batch key, topgimbal/@attitude/*
    python bench/fleet.py --cameras 250 --batched --own-sockets      # one UDP socket per camera, as before
    python bench/fleet.py --cameras 1000 --batched --pin             # the server on its own core(s)

Loopback only (tcp/127.0.0.1, scouting off). On a shared, loaded machine the figures say what this
machine could do at that moment: the script prints the load average next to them."""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import json
import math
import os
import signal
import socket
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

from topgimbal.fleet.batch import DEFAULT_BATCH_S

CLK_TCK = os.sysconf("SC_CLK_TCK")


def pct(xs: list[float], p: float) -> float:
    if not xs:
        return float("nan")
    xs = sorted(xs)
    return xs[min(len(xs) - 1, int(p / 100 * len(xs)))]


def cpu_s(pid: int, tid: int | None = None) -> float:
    where = f"/proc/{pid}/stat" if tid is None else f"/proc/{pid}/task/{tid}/stat"
    fields = Path(where).read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / CLK_TCK  # utime + stime


def children(pid: int) -> list[int]:
    out: list[int] = []
    for task in Path(f"/proc/{pid}/task").iterdir():
        with contextlib.suppress(OSError):
            out += [int(c) for c in (task / "children").read_text().split()]
    return out


def tree_cpu_s(pid: int) -> float:
    """A process and its children (`topgimbal zenoh`'s worker processes): all serving CPU."""
    total = 0.0
    for p in [pid, *children(pid)]:
        with contextlib.suppress(OSError):
            total += cpu_s(p)
    return total


def main_thread_cpu_s(pid: int) -> float:
    """The Python threads' CPU (the event loops: every camera's client); the rest is Zenoh's. With
    worker processes, theirs: the parent then is a Zenoh router and its Python thread sleeps."""
    total = 0.0
    for p in [pid, *children(pid)]:
        with contextlib.suppress(OSError):
            total += cpu_s(p, p)
    return total


def socket_inodes(pids: list[int]) -> set[int]:
    """The socket inodes of these processes' open files."""
    out: set[int] = set()
    for pid in pids:
        with contextlib.suppress(OSError):
            for fd in Path(f"/proc/{pid}/fd").iterdir():
                with contextlib.suppress(OSError):
                    link = os.readlink(fd)
                    if link.startswith("socket:["):
                        out.add(int(link[8:-1]))
    return out


def udp_queues(inodes: set[int]) -> tuple[int, int]:
    """(bytes waiting in the receive queues, datagrams dropped from them) of these UDP sockets,
    as /proc/net/udp and udp6 say (rx_queue is the kernel's charge: the skbs' truesize)."""
    queued = drops = 0
    for table in ("/proc/net/udp", "/proc/net/udp6"):
        with contextlib.suppress(OSError):
            for line in Path(table).read_text().splitlines()[1:]:
                f = line.split()
                if len(f) >= 13 and int(f[9]) in inodes:
                    queued += int(f[4].split(":")[1], 16)
                    drops += int(f[12])
    return queued, drops


def udp_out_datagrams() -> int:
    """UDP datagrams this machine has sent (/proc/net/snmp, every process): over the window, what
    the simulators sent (the server's few commands aside), so a shortfall of the cameras shows
    apart from one of the server. Linux only; -1 elsewhere."""
    with contextlib.suppress(OSError, ValueError, IndexError):
        head, values = [
            line.split() for line in Path("/proc/net/snmp").read_text().splitlines() if line.startswith("Udp:")
        ][:2]
        return int(values[head.index("OutDatagrams")])
    return -1


def datagram_charge(size: int = 24, count: int = 64) -> float:
    """The bytes a receive queue is charged per small datagram on this kernel (measured: send
    `count` datagrams of `size` bytes, a C12 GAC sample's, to an unread socket, read its rx_queue)."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as rx, socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as tx:
        rx.bind(("127.0.0.1", 0))
        for _ in range(count):
            tx.sendto(b"x" * size, rx.getsockname())
        time.sleep(0.05)
        queued, _ = udp_queues({os.fstat(rx.fileno()).st_ino})
    return queued / count if queued else float("nan")


def steal_s() -> dict[str, float]:
    """Each core's time the hypervisor gave to someone else (/proc/stat's steal), in seconds."""
    out: dict[str, float] = {}
    for line in Path("/proc/stat").read_text().splitlines():
        f = line.split()
        if f and f[0].startswith("cpu") and f[0] != "cpu" and len(f) > 8:
            out[f[0]] = int(f[8]) / CLK_TCK
    return out


class QueueSampler(threading.Thread):
    """The server's UDP receive queues every `every_s`, until stopped; and how long the serving loop
    did not run while datagrams waited: an interval that began and ended with more than
    `waiting_bytes` queued, less the main thread's CPU in it (a loop that is neither running nor
    draining is blocked or descheduled: a lock, the GIL, another process, the hypervisor)."""

    def __init__(self, pid: int, every_s: float = 0.2, waiting_bytes: int = 0) -> None:
        super().__init__(daemon=True)
        self.pid, self.every_s, self.waiting_bytes = pid, every_s, waiting_bytes
        self.inodes = socket_inodes([pid, *children(pid)])
        self.samples: list[int] = []
        self.drops0 = self.drops1 = udp_queues(self.inodes)[1]
        self.halt = threading.Event()
        self.not_running_s = 0.0  # waiting, and the loop off its core
        self.worst_not_running_s = 0.0  # the same, in the worst interval

    def run(self) -> None:
        prev = (time.monotonic(), main_thread_cpu_s(self.pid), udp_queues(self.inodes)[0])
        while not self.halt.wait(self.every_s):
            queued, self.drops1 = udp_queues(self.inodes)
            self.samples.append(queued)
            now = (time.monotonic(), main_thread_cpu_s(self.pid), queued)
            if prev[2] > self.waiting_bytes and queued > self.waiting_bytes:
                off = max(0.0, (now[0] - prev[0]) - (now[1] - prev[1]))
                self.not_running_s += off
                self.worst_not_running_s = max(self.worst_not_running_s, off)
            prev = now


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


# -- the simulator fleet (a child process) ---------------------------------------------------------


# -- the run ---------------------------------------------------------------------------------------


WARM_QUEUE_MS = 2.0  # the server's receive queue counts as drained under this (at the nominal rate)
WARM_STEADY_S = 2.0  # ... in every sample (every 0.1 s) for this long
WARM_MAX_S = 60.0  # then the window opens anyway, with steady: no


def placement(pin: bool) -> tuple[set[int] | None, set[int] | None, str]:
    """(the server's cores, the load generator's cores, a description); None: the scheduler's."""
    if not pin:
        return None, None, "unpinned (the scheduler places every process)"
    cpus = sorted(os.sched_getaffinity(0))
    if len(cpus) < 2:
        raise SystemExit("--pin needs two cores")
    half = len(cpus) // 2
    server, rest = set(cpus[:half]), set(cpus[half:])
    return (
        server,
        rest,
        f"pinned: server on cpu {','.join(map(str, sorted(server)))}, cameras and subscriber on {','.join(map(str, sorted(rest)))}",
    )


async def steady(server_pid: int, nominal_per_s: float) -> tuple[float, bool]:
    """Wait until the server's receive queue has been drained for WARM_STEADY_S (see the module
    docstring); (seconds waited, whether it got there)."""
    inodes = socket_inodes([server_pid, *children(server_pid)])
    limit = WARM_QUEUE_MS / 1000 * nominal_per_s * datagram_charge()
    t0 = time.monotonic()
    calm_since: float | None = None
    while (now := time.monotonic()) - t0 < WARM_MAX_S:
        if udp_queues(inodes)[0] > limit:
            calm_since = None
        elif calm_since is None:
            calm_since = now
        elif now - calm_since >= WARM_STEADY_S:
            return now - t0, True
        await asyncio.sleep(0.1)
    return time.monotonic() - t0, False


PROBE = "probe"  # the camera whose every send is stamped (module docstring)
PROBE_KEYS = frozenset({PROBE, f"topgimbal/{PROBE}/attitude"})  # its name in a batch, its own key
PROBE_YAW_DPS = 7.0  # 0.14 deg between samples at 50 Hz, 0.01 deg on the wire: each yaw its own
PROBE_TURN_DEG = 80.0  # it sweeps -80..+80 (a C12's yaw stops at +-90): 23 s each way
AMBIGUOUS_S = 5.0  # a yaw sent twice within this long (at the turns) matches no send


class Probe:
    """A C12 simulated in this process whose GAC datagrams are stamped as they leave: the wall times
    of the sends of each yaw (rounded to 0.01 deg, the wire's resolution)."""

    def __init__(self) -> None:
        self.sent: list[tuple[float, bytes]] = []
        self.sim: Any = None

    async def start(self) -> str:
        from topgimbal.sim import Simulator

        self.sim = sim = await Simulator(model="C12", seed=4242).start(udp=[("127.0.0.1", 0)])
        (server,) = sim._udp  # the one UDP endpoint just opened
        send = server.sendto

        def stamped(data: bytes, peer: Any) -> None:
            if b"GAC" in data:
                self.sent.append((time.time(), data))
            send(data, peer)

        server.sendto = stamped
        return str(sim.endpoints[0][1])

    def sent_at(self) -> dict[float, list[float]]:
        from topgimbal.protocol import FrameParser, get_model

        dialect, _ = get_model("C12")
        out: dict[float, list[float]] = {}
        parser = FrameParser()
        for t, data in self.sent:
            for item in parser.feed_datagram(data):
                fields = getattr(dialect.decode(item), "fields", None) if hasattr(item, "ident") else None
                if fields and "yaw_deg" in fields:
                    out.setdefault(round(fields["yaw_deg"], 2), []).append(t)
        return out

    async def stop(self) -> None:
        if self.sim is not None:
            await self.sim.stop()


async def probe_child(out: str) -> None:
    """`--probe-child FILE`: the probe camera in its own process (not beside the subscriber, whose
    thread it would slow): prints its URL, turns, and at a line on stdin writes its sends' times by
    yaw to FILE."""
    from topgimbal import connect

    probe = Probe()
    url = await probe.start()
    try:
        async with connect(url, model="C12") as turning:  # its own client: the stream is the server's
            await turning.rates(yaw_deg_s=PROBE_YAW_DPS)
            print(url, flush=True)
            sweep = asyncio.ensure_future(probe_sweep(turning, probe.sim.gimbal.yaw_axis))
            await asyncio.get_running_loop().run_in_executor(None, sys.stdin.readline)
            sweep.cancel()
        Path(out).write_text(json.dumps(sorted(probe.sent_at().items())))
    finally:
        await probe.stop()


async def probe_sweep(turning: Any, yaw: Any) -> None:
    """Turn back at +-PROBE_TURN_DEG (read from the probe's own simulated gimbal, `yaw`)."""
    direction = 1.0
    while True:
        await asyncio.sleep(0.05)
        if yaw.pos * direction >= PROBE_TURN_DEG:
            direction = -direction
            await turning.rates(yaw_deg_s=direction * PROBE_YAW_DPS)


def probe_latencies(
    sent: dict[float, list[float]], heard: list[tuple[float, float, float]]
) -> tuple[list[float], list[float], int, int]:
    """Send-to-subscriber seconds of the probe's samples heard, each matched with the latest send
    of its yaw before it was heard; the send-to-server part of each (the server stamps `t` when it
    reads the datagram, so the rest is its batch, Zenoh and this subscriber's thread); how many were
    not found; how many were ambiguous (another send of that yaw within AMBIGUOUS_S before the
    latest: at the sweep's turns, or a probe that stopped)."""
    lat: list[float] = []
    to_server: list[float] = []
    missing = ambiguous = 0
    for yaw, now, stamp in heard:
        before = sorted(t for t in sent.get(round(yaw, 2), ()) if t <= now)
        if not before:
            missing += 1
        elif len(before) > 1 and before[-1] - before[-2] < AMBIGUOUS_S:
            ambiguous += 1
        else:
            lat.append(now - before[-1])
            to_server.append(stamp - before[-1])
    return lat, to_server, missing, ambiguous


class Subscriber:
    """Counts attitude samples per camera, seq gaps and latency, in Zenoh's callback thread."""

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.counting = False
        self.count = 0
        self.lost = 0
        self.repeated = 0  # a seq not above the last one: a copy or a reordering
        self.last_seq: dict[str, int] = {}
        self.latency: list[float] = []
        self.puts = 0  # batch puts heard (--batched)
        # (yaw_deg, when heard, the server's stamp `t`) of the probe camera's samples
        self.probe: list[tuple[float, float, float]] = []

    def __call__(self, sample: Any) -> None:
        now = time.time()
        d = json.loads(sample.payload.to_bytes())
        with self.lock:
            self._one(str(sample.key_expr), d, now)

    def batch(self, sample: Any) -> None:
        """A put on the batch key (`--batched`): a JSON array of samples, each with its camera's name.
        `_one`'s work written out over the array: this thread shares a core with the simulators
        under --pin, and what it takes from them comes back as bursts at the server."""
        now = time.time()
        rows = json.loads(sample.payload.to_bytes())
        with self.lock:
            self.puts += 1
            counting, last, lat, probe = self.counting, self.last_seq, self.latency, self.probe
            count = lost = repeated = 0
            for d in rows:
                k = d["name"]
                if k in PROBE_KEYS:
                    if counting:
                        probe.append((d["yaw_deg"], now, d["t"]))
                    continue
                seq = d["seq"]
                prev = last.get(k)
                last[k] = seq
                if not counting:
                    continue
                count += 1
                if prev is not None:
                    if seq > prev + 1:
                        lost += seq - prev - 1
                    elif seq <= prev:
                        repeated += 1
                lat.append(now - d["t"])
            self.count += count
            self.lost += lost
            self.repeated += repeated

    def _one(self, k: str, d: dict[str, Any], now: float) -> None:
        if k in PROBE_KEYS:
            if self.counting:
                self.probe.append((d["yaw_deg"], now, d["t"]))
            return
        prev = self.last_seq.get(k)
        self.last_seq[k] = d["seq"]
        if not self.counting:
            return
        self.count += 1
        if prev is not None and d["seq"] > prev + 1:
            self.lost += d["seq"] - prev - 1
        elif prev is not None and d["seq"] <= prev:
            self.repeated += 1
        self.latency.append(now - d["t"])


async def run(n: int, rate_hz: float, seconds: float, calls: int, workers: int = 0,
              batched: bool = False, own_sockets: bool = False, pin: bool = False,
              batch_ms: float | None = None) -> dict[str, Any]:  # fmt: skip
    import zenoh

    from topgimbal import connect

    server_cpus, load_cpus, where = placement(pin)
    if load_cpus is not None:  # this process, and what it starts from now on (but the server)
        os.sched_setaffinity(0, load_cpus)
    started = time.monotonic()
    tmp = Path(tempfile.mkdtemp(prefix="fleet-bench-"))
    m = max(1, n - 1)  # the simulator process's cameras; the n-th is the probe (n cameras served in all)
    sims = await asyncio.create_subprocess_exec(
        sys.executable, "-m", "topgimbal.cli.main", "sim", "--model", "C12", "--fleet", str(m), "--udp", "127.0.0.1:0",
        stdout=asyncio.subprocess.PIPE,
    )  # fmt: skip
    server: asyncio.subprocess.Process | None = None
    session: Any = None
    probe: asyncio.subprocess.Process | None = None
    try:
        assert sims.stdout is not None
        urls = [(await asyncio.wait_for(sims.stdout.readline(), 300)).decode().strip() for _ in range(m)]
        cams = tmp / "cameras"
        suffix = "?socket=own" if own_sockets else ""  # the server's default: one shared socket
        probe = await asyncio.create_subprocess_exec(
            sys.executable, __file__, "--probe-child", str(tmp / "probe.json"),
            stdin=asyncio.subprocess.PIPE, stdout=asyncio.subprocess.PIPE,
        )  # fmt: skip
        assert probe.stdout is not None
        probe_url = (await asyncio.wait_for(probe.stdout.readline(), 60)).decode().strip()
        lines = [f"cam{i}={u}{suffix},C12" for i, u in enumerate(urls)] + [f"{PROBE}={probe_url}{suffix},C12"]
        cams.write_text("\n".join(lines))
        port = free_port()
        server = await asyncio.create_subprocess_exec(
            sys.executable, "-m", "topgimbal.cli.main", "zenoh", "--cameras", str(cams),
            "--listen", f"tcp/127.0.0.1:{port}", "--rate-hz", str(rate_hz), "--workers", str(workers),
            *([] if batch_ms is None else ["--batch-ms", str(batch_ms)]),
            stdout=asyncio.subprocess.PIPE,
            preexec_fn=None if server_cpus is None else (lambda: os.sched_setaffinity(0, server_cpus)),
        )  # fmt: skip
        assert server.stdout is not None
        await asyncio.wait_for(server.stdout.readline(), 600)
        conf = zenoh.Config()
        for k, v in (("mode", "client"), ("scouting/multicast/enabled", False), ("scouting/gossip/enabled", False),
                     ("connect/endpoints", [f"tcp/127.0.0.1:{port}"])):  # fmt: skip
            conf.insert_json5(k, json.dumps(v))
        session = zenoh.open(conf)
        sub = Subscriber()
        if batched:  # every camera's samples together (docs/fleet.md, the batch key)
            zsub = session.declare_subscriber("topgimbal/@attitude/*", sub.batch)
        else:
            zsub = session.declare_subscriber("topgimbal/*/attitude", sub)
        # warm up: every camera streaming
        for _ in range(600):
            if len(sub.last_seq) >= m:
                break
            await asyncio.sleep(0.1)
        _, settled = await steady(server.pid, n * rate_hz)
        warmup_s = time.monotonic() - started
        cpu0 = (tree_cpu_s(server.pid), cpu_s(sims.pid), main_thread_cpu_s(server.pid))
        # "waiting": more than 10 ms of the cameras' traffic queued (a loop that keeps up has less)
        charge0 = datagram_charge()
        waiting = int(0.010 * n * rate_hz * charge0) if math.isfinite(charge0) else 0
        queues = QueueSampler(server.pid, waiting_bytes=waiting)
        steal0 = steal_s()
        out0 = udp_out_datagrams()
        t0 = time.monotonic()
        with sub.lock:
            sub.counting = True
        queues.start()
        await asyncio.sleep(seconds)
        with sub.lock:
            sub.counting = False
            count, lost, repeated, lat, puts = sub.count, sub.lost, sub.repeated, list(sub.latency), sub.puts
            heard = list(sub.probe)
        queues.halt.set()
        steal1 = steal_s()
        wall = time.monotonic() - t0
        # less the probe's 50 a second (a small excess when it also answered its turning client)
        sent = udp_out_datagrams() - out0 - int(rate_hz * wall) if out0 >= 0 else -1
        cpu1 = (tree_cpu_s(server.pid), cpu_s(sims.pid), main_thread_cpu_s(server.pid))
        streaming = len(sub.last_seq)

        # command round trips: through Zenoh, then direct
        zrtt: list[float] = []
        zfail: list[str] = []
        for _ in range(calls):
            key = "topgimbal/cam0/call/version"  # the camera the direct client asks too
            t = time.perf_counter()
            replies = await asyncio.to_thread(lambda k=key: list(session.get(k, payload="{}", timeout=10)))
            body = json.loads(replies[0].ok.payload.to_bytes()) if replies and replies[0].ok is not None else None
            if body and body["ok"]:
                zrtt.append(time.perf_counter() - t)
            else:
                zfail.append(str(body)[:160] if body else "no reply")
        drtt: list[float] = []
        async with connect(urls[0], model="C12") as cam:
            for _ in range(calls):
                t = time.perf_counter()
                with contextlib.suppress(Exception):
                    await cam.version()
                    drtt.append(time.perf_counter() - t)
        zsub.undeclare()
        assert probe.stdin is not None
        probe.stdin.write(b"stop\n")
        await probe.stdin.drain()
        await asyncio.wait_for(probe.wait(), 60)
        sent_at = {yaw: ts for yaw, ts in json.loads((tmp / "probe.json").read_text())}
        e2e, to_server, unmatched, ambiguous = probe_latencies(sent_at, heard)
        charge = datagram_charge()
        qms = [1000 * q / charge / (n * rate_hz) for q in queues.samples]  # a datagram's wait, at the nominal rate
        kernel_drops = (queues.drops1 - queues.drops0) % 2**32
        return {
            "cameras": n, "workers": workers or "auto", "placement": where,
            "batch_ms": batch_ms if batch_ms is not None else f"{DEFAULT_BATCH_S * 1000:g} (the server's default)",
            "warmup_s": round(warmup_s, 1), "steady": "yes" if settled else f"no (queue above {WARM_QUEUE_MS:g} ms after {WARM_MAX_S:g} s)", "subscribed": "batch key" if batched else "per-camera keys",
            "udp_sockets": "one per camera" if own_sockets else "shared",
            "batch_puts_per_s": round(puts / wall, 1), "rate_hz": rate_hz, "seconds": round(wall, 2), "streaming": streaming,
            "delivered_per_s": round(count / wall, 1), "nominal_per_s": m * rate_hz,
            "of_nominal_pct": round(100 * count / wall / (m * rate_hz), 1),
            "cameras_sent_of_nominal_pct": round(100 * sent / wall / (m * rate_hz), 1) if sent >= 0 else "n/a",
            "lost_server_to_subscriber_pct": round(100 * lost / max(1, count + lost), 3),
            "repeated_or_reordered": repeated,
            "camera_to_subscriber_ms_p50": round(pct(e2e, 50) * 1000, 2), "camera_to_subscriber_ms_p99": round(pct(e2e, 99) * 1000, 2),
            "camera_to_subscriber_ms_max": round(max(e2e, default=float("nan")) * 1000, 2),
            # the same samples split at the server's stamp: where the tail is
            "camera_to_server_ms_p50": round(pct(to_server, 50) * 1000, 2), "camera_to_server_ms_p99": round(pct(to_server, 99) * 1000, 2),
            "probe_server_to_subscriber_ms_p99": round(pct([a - b for a, b in zip(e2e, to_server, strict=True)], 99) * 1000, 2),
            "probe_samples": f"{len(e2e)} matched, {unmatched} not, {ambiguous} ambiguous",
            "latency_ms_p50": round(pct(lat, 50) * 1000, 2), "latency_ms_p99": round(pct(lat, 99) * 1000, 2),
            "server_udp_queue_kib_p50": round(pct(queues.samples, 50) / 1024), "server_udp_queue_kib_max": round(max(queues.samples, default=0) / 1024),
            "server_udp_queue_ms_p50": round(pct(qms, 50), 1), "server_udp_queue_ms_max": round(max(qms, default=0.0), 1),
            "kernel_bytes_per_datagram": round(charge),
            "kernel_dropped_in_window": kernel_drops, "kernel_dropped_pct": round(100 * kernel_drops / (n * rate_hz * wall), 2),
            "cmd_rtt_ms_zenoh_p50": round(pct(zrtt, 50) * 1000, 2), "cmd_rtt_ms_zenoh_p99": round(pct(zrtt, 99) * 1000, 2),
            "cmd_rtt_ms_direct_p50": round(pct(drtt, 50) * 1000, 2), "cmd_rtt_ms_direct_p99": round(pct(drtt, 99) * 1000, 2),
            "calls_ok": f"{len(zrtt)}/{calls} zenoh, {len(drtt)}/{calls} direct",
            "zenoh_call_failures": sorted(set(zfail))[:3],
            "server_cpu_pct": round(100 * (cpu1[0] - cpu0[0]) / wall, 1),
            "server_cpu_pct_per_camera": round(100 * (cpu1[0] - cpu0[0]) / wall / n, 2),
            "server_event_loop_cpu_pct": round(100 * (cpu1[2] - cpu0[2]) / wall, 1),
            "server_cpu_us_per_sample": round(1e6 * (cpu1[0] - cpu0[0]) / max(1, count + len(heard)), 1),
            "sim_cpu_pct": round(100 * (cpu1[1] - cpu0[1]) / wall, 1),
            "server_off_core_while_queued_ms": f"{1000 * queues.not_running_s:.0f} (worst 0.2 s: {1000 * queues.worst_not_running_s:.0f})",
            "steal_ms": ", ".join(f"{c} {1000 * (steal1.get(c, 0.0) - v):.0f}" for c, v in steal0.items()),
        }  # fmt: skip
    finally:
        if session is not None:
            session.close()
        for p in (server, sims, probe):
            if p is not None and p.returncode is None:
                p.send_signal(signal.SIGINT if p is server else signal.SIGTERM)
                try:
                    await asyncio.wait_for(p.wait(), 30)
                except asyncio.TimeoutError:
                    p.kill()
                    await p.wait()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cameras", default="10,100", help="camera counts to run, comma-separated (default 10,100)")
    ap.add_argument("--rate-hz", type=float, default=50.0)
    ap.add_argument("--seconds", type=float, default=10.0, help="measuring window per run")
    ap.add_argument("--calls", type=int, default=200, help="command round trips per path")
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--workers", type=int, default=0, help="topgimbal zenoh --workers (default 0: automatic)")
    ap.add_argument("--batched", action="store_true",
                    help="subscribe to the batch key topgimbal/@attitude/* instead of topgimbal/*/attitude")  # fmt: skip
    ap.add_argument(
        "--own-sockets",
        action="store_true",
        help="one UDP socket per camera (?socket=own) instead of the server's shared socket",
    )
    ap.add_argument("--batch-ms", type=float, default=None,
                    help="topgimbal zenoh --batch-ms (default: the server's, DEFAULT_BATCH_S)")  # fmt: skip
    ap.add_argument("--pin", action="store_true",
                    help="the server on half of the cores, the simulators, probe and subscriber on the rest")  # fmt: skip
    ap.add_argument("--probe-child", metavar="FILE", help=argparse.SUPPRESS)  # the probe's own process
    args = ap.parse_args()
    if args.probe_child:
        asyncio.run(probe_child(args.probe_child))
        return
    print(f"cores {os.cpu_count()}, load average before: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    for n in (int(x) for x in args.cameras.split(",")):
        r = asyncio.run(
            run(
                n,
                args.rate_hz,
                args.seconds,
                args.calls,
                args.workers,
                args.batched,
                args.own_sockets,
                args.pin,
                args.batch_ms,
            )
        )
        r["load_after"] = round(os.getloadavg()[0], 2)
        if args.json:
            print(json.dumps(r))
        else:
            print(f"\n{n} cameras at {args.rate_hz:g} Hz ({r['streaming']} streaming), {r['seconds']} s:")
            for k, v in r.items():
                print(f"  {k:34} {v}")


if __name__ == "__main__":
    main()
