"""The simulator under abuse (issue 9): RSS, CPU and a well-behaved client's latency.

A `topgimbal sim` process (C12, UDP and TCP on 127.0.0.1) is abused by a separate process while a
well-behaved UDP client asks `GAC` (attitude query) 20 times a second and times each answer (1 s
timeout). Scenarios (each --seconds long, after a quiet reference period):

- udp-dead:   every --wave-s, 300 UDP sockets subscribe to 100 Hz attitude and close at once.
- udp-silent: 300 UDP sockets subscribe to 100 Hz attitude, stay open, never read, and renew
              their subscription every 10 s.
- tcp-noread: 4 TCP clients (4 KiB receive buffers) subscribe to 100 Hz attitude and send queries
              as fast as the simulator takes them (up to 10,000 a second each), never read, and
              reconnect when dropped.

Printed per scenario: the simulator's RSS (before, after 10 s, at the end, growth from 10 s to the
end), its CPU share, the good client's p50/p95/p99 and timeouts, and how many lines the simulator
logged. `--src DIR` runs the simulator from another checkout's `src` (a before/after comparison in
one run: `git archive main src | tar -x -C /tmp/base` then `--src /tmp/base/src`).

    .venv/bin/python bench/abuse.py [--seconds 60] [--scenario udp-dead,udp-silent,tcp-noread]
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import os
import re
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

from topgimbal.protocol import get_dialect

LOOP = "127.0.0.1"
D = get_dialect("skydroid")
GAA_100 = D.encode("GAA", rate_hz=100).to_bytes()
GAC_QUERY = D.encode("GAC", read=True).to_bytes()
TICK_S = os.sysconf("SC_CLK_TCK")


def pct(values: list[float], p: float) -> float:
    s = sorted(values)
    return s[min(len(s) - 1, round(p / 100 * (len(s) - 1)))] if s else float("nan")


# -- the simulator under test ----------------------------------------------------------------------


class Sim:
    def __init__(self, src: str | None) -> None:
        env = dict(os.environ)
        if src:
            env["PYTHONPATH"] = src
        argv = [sys.executable, "-m", "topgimbal.cli.main", "sim", "--model", "C12"]
        argv += ["--udp", f"{LOOP}:0", "--tcp", f"{LOOP}:0"]
        self.proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
        assert self.proc.stdout is not None and self.proc.stderr is not None
        self.udp = self.tcp = 0
        while not (self.udp and self.tcp):
            line = self.proc.stdout.readline()
            if not line:
                raise RuntimeError(f"the simulator did not start: {self.proc.stderr.read()}")
            m = re.match(r"(udp|tcp)://[0-9.]+:([0-9]+)", line)
            if m:
                setattr(self, m.group(1), int(m.group(2)))
        self.log_lines: list[str] = []
        threading.Thread(target=self._drain, daemon=True).start()

    def _drain(self) -> None:
        assert self.proc.stderr is not None
        for line in self.proc.stderr:
            self.log_lines.append(line.rstrip())

    def rss_mb(self) -> float:
        with open(f"/proc/{self.proc.pid}/status") as f:
            for line in f:
                if line.startswith("VmRSS:"):
                    return int(line.split()[1]) / 1024
        return float("nan")

    def cpu_s(self) -> float:
        with open(f"/proc/{self.proc.pid}/stat") as f:
            fields = f.read().rsplit(")", 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / TICK_S

    def stop(self) -> None:
        self.proc.terminate()
        try:
            self.proc.wait(10)
        except subprocess.TimeoutExpired:
            self.proc.kill()


# -- the well-behaved client -----------------------------------------------------------------------


class GoodClient:
    """Asks GAC at 20 Hz over UDP and records each round trip (a timeout counts as 1 s)."""

    def __init__(self, port: int) -> None:
        self.port = port
        self.samples: list[tuple[float, float, bool]] = []  # (time sent, round trip s, answered)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        s.bind((LOOP, 0))
        s.settimeout(0.05)
        while not self._stop.is_set():
            t0 = time.monotonic()
            s.sendto(GAC_QUERY, (LOOP, self.port))
            answered = False
            while time.monotonic() - t0 < 1.0:
                try:
                    data = s.recv(2048)
                except TimeoutError:
                    continue
                if b"GAC" in data:
                    answered = True
                    break
            rtt = time.monotonic() - t0
            self.samples.append((t0, rtt, answered))
            time.sleep(max(0.0, 0.05 - rtt))
        s.close()

    def between(self, t0: float, t1: float) -> tuple[list[float], int]:
        rows = [(rtt, ok) for t, rtt, ok in self.samples if t0 <= t < t1]
        return [rtt for rtt, _ in rows], sum(1 for _, ok in rows if not ok)

    def stop(self) -> None:
        self._stop.set()
        self._thread.join(3)


# -- abusers (run in their own process) ------------------------------------------------------------


def udp_dead(udp: int, tcp: int, seconds: float, wave_s: float) -> None:
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        t0 = time.monotonic()
        socks = []
        for _ in range(300):
            s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            s.bind((LOOP, 0))
            s.sendto(GAA_100, (LOOP, udp))
            socks.append(s)
        time.sleep(0.05)
        for s in socks:
            s.close()
        time.sleep(max(0.0, min(wave_s - (time.monotonic() - t0), end - time.monotonic())))


def udp_silent(udp: int, tcp: int, seconds: float, wave_s: float) -> None:
    socks = []
    for _ in range(300):
        s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
        s.bind((LOOP, 0))
        socks.append(s)
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        for s in socks:
            s.sendto(GAA_100, (LOOP, udp))
        time.sleep(min(10.0, max(0.0, end - time.monotonic())))
    for s in socks:
        s.close()


def tcp_noread(udp: int, tcp: int, seconds: float, wave_s: float) -> None:
    def connect() -> socket.socket | None:
        s = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
        try:
            s.connect((LOOP, tcp))
            s.setblocking(False)
            s.send(GAA_100)
        except OSError:
            s.close()
            return None
        return s

    conns: list[socket.socket | None] = [connect() for _ in range(4)]
    end = time.monotonic() + seconds
    burst = GAC_QUERY * 100
    while time.monotonic() < end:
        for i, s in enumerate(conns):
            if s is None:
                conns[i] = connect()
                continue
            try:
                s.send(burst)
            except BlockingIOError:
                pass  # the simulator reads slower than this: fine
            except OSError:
                s.close()
                conns[i] = connect()  # dropped by the simulator: come back
        time.sleep(0.01)
    for s in conns:
        if s is not None:
            s.close()


SCENARIOS = {"udp-dead": udp_dead, "udp-silent": udp_silent, "tcp-noread": tcp_noread}


# -- one run ---------------------------------------------------------------------------------------


def run(name: str, src: str | None, seconds: float, quiet_s: float, wave_s: float) -> dict[str, Any]:
    sim = Sim(src)
    good = GoodClient(sim.udp)
    try:
        time.sleep(quiet_s)
        t_quiet = time.monotonic() - quiet_s
        rss0, cpu0, t0 = sim.rss_mb(), sim.cpu_s(), time.monotonic()
        abuser = mp.get_context("fork").Process(target=SCENARIOS[name], args=(sim.udp, sim.tcp, seconds, wave_s))
        abuser.start()
        rss = []
        while abuser.is_alive() and time.monotonic() - t0 < seconds + 5:
            time.sleep(1.0)
            rss.append((time.monotonic() - t0, sim.rss_mb()))
        abuser.join(5)
        t1, cpu1 = time.monotonic(), sim.cpu_s()
        at10 = next((r for t, r in rss if t >= 10), rss[-1][1])
        quiet, _ = good.between(t_quiet, t0)
        during, timeouts = good.between(t0, t1)
        return {
            "rss0": rss0,
            "rss10": at10,
            "rss_end": rss[-1][1],
            "rss_max": max(r for _, r in rss),
            "growth": (rss[-1][1] - at10) / at10,
            "cpu": (cpu1 - cpu0) / (t1 - t0),
            "quiet_p95": pct(quiet, 95),
            "p50": pct(during, 50),
            "p95": pct(during, 95),
            "p99": pct(during, 99),
            "n": len(during),
            "timeouts": timeouts,
            "log_lines": len(sim.log_lines) - 1,  # less the banner
        }
    finally:
        good.stop()
        sim.stop()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seconds", type=float, default=60.0, help="abuse per scenario, s (default 60)")
    ap.add_argument("--quiet", type=float, default=5.0, help="reference period before the abuse, s (default 5)")
    ap.add_argument("--wave-s", type=float, default=10.0, help="udp-dead: seconds between waves (default 10)")
    ap.add_argument("--scenario", default=",".join(SCENARIOS), help="comma-separated (default: all)")
    ap.add_argument("--src", help="run the simulator from this src directory (default: the installed one)")
    a = ap.parse_args()
    label = a.src or str(Path(__file__).resolve().parent.parent / "src")
    print(f"bench/abuse.py: simulator from {label}; {a.seconds:g} s per scenario; good client: GAC query at 20 Hz")
    for name in a.scenario.split(","):
        r = run(name, a.src, a.seconds, a.quiet, a.wave_s)
        flat = "flat" if abs(r["growth"]) <= 0.10 else "GROWS"
        print(
            f"  {name:10s} RSS {r['rss0']:5.1f} -> {r['rss10']:5.1f} (10 s) -> {r['rss_end']:5.1f} MB (end), "
            f"max {r['rss_max']:5.1f}, growth {100 * r['growth']:+5.1f} % {flat}; simulator CPU {100 * r['cpu']:5.1f} %",
            flush=True,
        )
        print(
            f"  {'':10s} good client p50 {1000 * r['p50']:6.2f} ms, p95 {1000 * r['p95']:7.2f} ms, "
            f"p99 {1000 * r['p99']:7.2f} ms, {r['timeouts']} timeouts of {r['n']} "
            f"(quiet p95 {1000 * r['quiet_p95']:.2f} ms); simulator log lines {r['log_lines']}",
            flush=True,
        )


if __name__ == "__main__":
    main()
