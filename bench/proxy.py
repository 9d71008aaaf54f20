"""What the proxy costs: added latency, loss and CPU on loopback UDP, in both of its modes.

The proxy runs in its own process exactly as a user runs it, between this client and a UDP echo
"camera" (another process, with a 4 MiB receive buffer so the echo is never what drops frames):
  full   `topgimbal proxy --json --pcap --log` (its output to /dev/null): decoding, printing,
         capturing and logging every frame (in its watcher process);
  bare   `topgimbal proxy --quiet`: forwarding (and counting frames) alone.
For each mode it prints
  1. round trip one frame at a time, alternating direct-to-echo and through-the-proxy samples
     (--ping-rate pairs/s): p50/p99 of each and what the proxy adds;
  2. a stream at --rate frames/s (each echoed, so twice that many cross the proxy) for --seconds,
     direct and through the proxy: frames lost (target 0), round-trip p50/p99 and what the proxy
     adds at that rate (target: p99 <= 1 ms), what it wrote (pcap packets, log lines) and the CPU
     time its forwarding process and its watcher process used per frame crossing it.
Each frame crosses the proxy twice per round trip, so the added figures are for both crossings.
The machine's load average is printed with every figure: on a machine shared with other work the
p99 figures measure the scheduler as much as the proxy (the CPU per frame much less so).

    python bench/proxy.py [--mode both|full|bare] [--pings 2000] [--ping-rate 200] [--rate 1000] [--seconds 10]
"""

from __future__ import annotations

import argparse
import os
import re
import socket
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from latency import Peer, pct  # a sibling script (bench/ is not a package)

from topgimbal.protocol import make_frame
from topgimbal.wire import CaptureRecord, read_capture

ECHO_CODE = """
import socket
s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4 << 20)
s.bind(("127.0.0.1", 0))
print("udp://127.0.0.1:%d" % s.getsockname()[1], flush=True)
while True:
    data, addr = s.recvfrom(2048)
    s.sendto(data, addr)
"""
TICKS_S = os.sysconf("SC_CLK_TCK")


def load() -> str:
    """The load average, and a warning when the machine is busy with other work."""
    one, five, _ = os.getloadavg()
    busy = "  [machine loaded: other work competes for the CPUs]" if one > 0.75 * (os.cpu_count() or 1) else ""
    return f"load {one:.2f} {five:.2f}{busy}"


def frame(seq: int) -> bytes:
    """An attitude answer whose data is the sequence number (unique, decodable)."""
    return make_frame("GAC", f"{seq % (1 << 48):012X}", src="G", dst="U", rw="r", header="#tp").to_bytes()


class ProxyProcess:
    def __init__(self, to_port: int, pcap: Path, log: Path, bare: bool = False) -> None:
        argv = [sys.executable, "-m", "topgimbal.cli.main", "proxy", "--listen", "udp://127.0.0.1:0"]
        argv += ["--to", f"udp://127.0.0.1:{to_port}"]
        argv += ["--quiet"] if bare else ["--json", "--pcap", str(pcap), "--log", str(log)]
        self.proc = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        assert self.proc.stderr is not None
        line = self.proc.stderr.readline()
        m = re.search(r"udp://127\.0\.0\.1:(\d+)", line)
        if not m:
            self.proc.kill()
            raise RuntimeError(f"the proxy did not start: {line!r}")
        self.port = int(m.group(1))

    def cpu_s(self) -> tuple[float, float]:
        """CPU time (user + system) used so far by the forwarding process and by its watcher
        process (the child that decodes, prints and writes; 0 when there is none)."""

        def used(pid: int) -> float:
            fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
            return (int(fields[11]) + int(fields[12])) / TICKS_S

        pid = self.proc.pid
        children = Path(f"/proc/{pid}/task/{pid}/children").read_text().split()
        return used(pid), sum(used(int(c)) for c in children)

    def stop(self) -> str:
        self.proc.terminate()
        _, err = self.proc.communicate(timeout=10)
        return err.strip()


def connected(port: int) -> socket.socket:
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.connect(("127.0.0.1", port))
    s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 20)
    s.settimeout(1.0)
    return s


def ping_pong(
    direct: socket.socket, proxied: socket.socket, n: int, rate: float = 0.0
) -> tuple[list[float], list[float]]:
    """n round trips each way, alternating, `rate` pairs per second (0: back to back)."""
    a: list[float] = []
    b: list[float] = []
    start = time.perf_counter()
    for i in range(n):
        if rate:
            time.sleep(max(0.0, start + i / rate - time.perf_counter()))
        for sock, out in ((direct, a), (proxied, b)):
            data = frame(i)
            t0 = time.perf_counter()
            sock.send(data)
            while sock.recv(2048) != data:  # a late echo of an earlier frame is skipped
                pass
            out.append(time.perf_counter() - t0)
    return a, b


def stream(sock: socket.socket, n: int, rate: float, base: int) -> tuple[int, list[float], float]:
    """Send n frames paced at `rate`; returns (frames echoed back, round trips, achieved rate)."""
    sent: dict[bytes, float] = {}
    rtts: list[float] = []
    done = threading.Event()

    def receive() -> None:
        idle_until = None
        while len(rtts) < n:
            try:
                data = sock.recv(2048)
            except TimeoutError:
                if done.is_set() and idle_until is not None and time.perf_counter() > idle_until:
                    return
                if done.is_set() and idle_until is None:
                    idle_until = time.perf_counter() + 2.0
                continue
            t = time.perf_counter()
            t0 = sent.pop(data, None)
            if t0 is not None:
                rtts.append(t - t0)

    rx = threading.Thread(target=receive)
    rx.start()
    frames = [frame(base + i) for i in range(n)]
    start = time.perf_counter()
    for i, data in enumerate(frames):
        due = start + i / rate
        while (wait := due - time.perf_counter()) > 0:
            time.sleep(wait if wait > 0.0005 else 0)
        sent[data] = time.perf_counter()
        sock.send(data)
    elapsed = time.perf_counter() - start
    done.set()
    rx.join()
    return len(rtts), rtts, (n - 1) / elapsed if elapsed else 0.0


def run(mode: str, echo_port: int, args: argparse.Namespace) -> None:
    ms = 1000.0
    bare = mode == "bare"
    tmp = Path(tempfile.mkdtemp(prefix="topgimbal-bench-proxy-"))
    proxy = ProxyProcess(echo_port, tmp / "bench.pcap", tmp / "bench.jsonl", bare)
    direct, proxied = connected(echo_port), connected(proxy.port)
    what = "forwarding only: --quiet" if bare else "--json to /dev/null, --pcap and --log on"
    print(f"mode {mode} ({what})")
    n = int(args.rate * args.seconds)
    try:
        ping_pong(direct, proxied, 100)  # warm-up
        a, b = ping_pong(direct, proxied, args.pings, args.ping_rate)
        print(
            f"  round trip, one frame at a time, {args.pings} each (alternating, {args.ping_rate:g} pairs/s); {load()}"
        )
        print(f"    {'':22s} {'p50 ms':>8s} {'p99 ms':>8s} {'mean ms':>8s}")
        for name, xs in (("direct to the echo", a), ("through the proxy", b)):
            print(f"    {name:22s} {pct(xs, 50) * ms:8.3f} {pct(xs, 99) * ms:8.3f} {statistics.fmean(xs) * ms:8.3f}")
        print(
            f"    added by the proxy: p50 {(pct(b, 50) - pct(a, 50)) * ms:.3f} ms, "
            f"p99 {(pct(b, 99) - pct(a, 99)) * ms:.3f} ms (target p99 <= 1 ms)"
        )
        print(f"  stream at {args.rate:g} frames/s for {args.seconds:g} s ({n} frames each way)")
        runs = []
        cpu = (0.0, 0.0)
        for name, sock, base in (
            ("direct to the echo", direct, 10_000_000),
            ("through the proxy", proxied, 20_000_000),
        ):
            before = proxy.cpu_s()
            got, rtts, achieved = stream(sock, n, args.rate, base)
            after = proxy.cpu_s()
            cpu = (after[0] - before[0], after[1] - before[1])
            runs.append((got, rtts))
            print(
                f"    {name:22s} sent {n} at {achieved:.1f}/s, echoed back {got}, lost {n - got}"
                f" (target 0); round trip p50 {pct(rtts, 50) * ms:.3f} ms, p99 {pct(rtts, 99) * ms:.3f} ms; {load()}"
            )
        (_, direct_rtts), (got, proxy_rtts) = runs
        print(
            f"    added by the proxy at {args.rate:g} frames/s: p50 {(pct(proxy_rtts, 50) - pct(direct_rtts, 50)) * ms:.3f} ms, "
            f"p99 {(pct(proxy_rtts, 99) - pct(direct_rtts, 99)) * ms:.3f} ms (target p99 <= 1 ms), "
            f"lost {n - got} (target 0)"
        )
        crossings = n + got
        print(
            f"    CPU for {crossings} frame crossings: forwarding process {cpu[0]:.2f} s"
            f" ({cpu[0] / crossings * 1e6:.0f} us per frame), watcher process {cpu[1]:.2f} s"
            f" ({cpu[1] / crossings * 1e6:.0f} us per frame)"
        )
    finally:
        direct.close()
        proxied.close()
        stats = proxy.stop()
    if not bare:
        packets = sum(1 for r in read_capture(tmp / "bench.pcap") if isinstance(r, CaptureRecord))
        lines = len((tmp / "bench.jsonl").read_text().splitlines()) - 1
        expected = 2 * (100 + args.pings) + n + runs[1][0]
        print(f"    the proxy wrote {packets} pcap packets and {lines} log lines (expected {expected} each)")
    print(f"    {stats.splitlines()[-1] if stats else ''}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--mode", choices=["both", "full", "bare"], default="both")
    ap.add_argument("--pings", type=int, default=2000)
    ap.add_argument("--ping-rate", type=float, default=200.0, help="round-trip pairs per second (0: flat out)")
    ap.add_argument("--rate", type=float, default=1000.0, help="frames per second (default 1000)")
    ap.add_argument("--seconds", type=float, default=10.0)
    ap.add_argument("--bare", action="store_true", help="the same as --mode bare")
    args = ap.parse_args()
    modes = ["bare"] if args.bare else (["full", "bare"] if args.mode == "both" else [args.mode])
    print(f"proxy in its own process, UDP echo camera, loopback, {os.cpu_count()} CPUs; {load()}")
    echo = Peer([sys.executable, "-c", ECHO_CODE])
    try:
        for mode in modes:
            run(mode, echo.port, args)
    finally:
        echo.stop()


if __name__ == "__main__":
    main()
