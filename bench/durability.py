"""The cost of durable acknowledgements (`topgimbal sim --state FILE`) on write latency.

A simulator process (C12, UDP, 127.0.0.1) with and without --state; a client sends `IPV` writes
(a persistent setting: with --state each reply waits for the file's fsync) and times each reply:
back to back (as fast as replies come), paced at 100 Hz, and with 4 writes in flight (the group
commit shares one fsync between them). Printed: p50/p99/max per case and writes per second, and
the file system the state file is on (fsync costs what the disk under it costs).

    .venv/bin/python bench/durability.py [--writes 1000] [--dir DIR]
"""

from __future__ import annotations

import argparse
import re
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from topgimbal.protocol import get_dialect

LOOP = "127.0.0.1"
D = get_dialect("skydroid")


def write(i: int) -> bytes:
    return D.encode("IPV", address=f"10.{(i >> 16) & 255}.{(i >> 8) & 255}.{i & 255}").to_bytes()


def pct(values: list[float], p: float) -> float:
    s = sorted(values)
    return s[min(len(s) - 1, round(p / 100 * (len(s) - 1)))]


class Sim:
    def __init__(self, state: Path | None) -> None:
        argv = [sys.executable, "-m", "topgimbal.cli.main", "sim", "--model", "C12", "--udp", f"{LOOP}:0"]
        if state is not None:
            argv += ["--state", str(state)]
        self.proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
        assert self.proc.stdout is not None
        m = re.match(r"udp://[0-9.]+:([0-9]+)", self.proc.stdout.readline())
        assert m, "the simulator did not print its URL"
        self.port = int(m.group(1))

    def stop(self) -> None:
        self.proc.terminate()
        self.proc.wait(10)


def measure(port: int, n: int, period_s: float, window: int) -> tuple[list[float], float]:
    """Send n writes, at most `window` in flight, one every period_s (0: as fast as possible)."""
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.bind((LOOP, 0))
    s.settimeout(5)
    sent_at: dict[bytes, float] = {}
    rtts: list[float] = []
    i = 0
    t_start = time.monotonic()
    next_at = t_start
    while len(rtts) < n:
        now = time.monotonic()
        can_send = i < n and len(sent_at) < window
        if can_send and now >= next_at:
            i += 1
            frame = write(i)
            sent_at[frame[7:-2]] = now  # identifier + data: the echo carries the same
            s.sendto(frame, (LOOP, port))
            next_at = next_at + period_s if period_s else now
            continue
        s.settimeout(next_at - now if can_send else 5.0)
        try:
            data = s.recv(2048)
        except TimeoutError:
            continue
        t0 = sent_at.pop(data[7:-2], None)
        if t0 is not None:
            rtts.append(time.monotonic() - t0)
    elapsed = time.monotonic() - t_start
    s.close()
    return rtts, n / elapsed


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--writes", type=int, default=1000, help="writes per case (default 1000)")
    ap.add_argument("--dir", help="directory of the state file (default: a temporary directory)")
    a = ap.parse_args()
    where = Path(a.dir) if a.dir else Path(tempfile.mkdtemp(prefix="topgimbal-durability-"))
    fs = subprocess.run(["stat", "-f", "-c", "%T", str(where)], capture_output=True, text=True).stdout.strip()
    print(f"bench/durability.py: {a.writes} IPV writes per case; state file in {where} ({fs or 'file system unknown'})")
    cases = [("back to back", 0.0, 1), ("100 Hz", 0.01, 1), ("4 in flight", 0.0, 4)]
    for label, state in (("without --state", None), ("with --state", where / "cam.json")):
        sim = Sim(state)
        try:
            measure(sim.port, 50, 0.0, 1)  # warm up
            for case, period, window in cases:
                rtts, rate = measure(sim.port, a.writes, period, window)
                print(
                    f"  {label:16s} {case:13s} p50 {1000 * pct(rtts, 50):6.3f} ms, p99 {1000 * pct(rtts, 99):7.3f} ms, "
                    f"max {1000 * max(rtts):7.2f} ms, {rate:7.0f} writes/s",
                    flush=True,
                )
        finally:
            sim.stop()


if __name__ == "__main__":
    main()
