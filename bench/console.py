"""Console figures: what the message limits cost, and the server's memory under pages that stop
reading. Everything on loopback, against an in-process simulator.

Prints: parse_message time for a typical op, for the largest accepted message and for a refused
deeply nested one; then, with the console in its own process, its RSS before, during and after
--pages raw-socket pages that send status ops for --seconds and never read a reply (each is paced
to 100 ops/s and cut off at its queue limit), and a good page's round-trip p50/p95 meanwhile.

    python bench/console.py [--pages 10] [--seconds 30]
"""

from __future__ import annotations

import argparse
import asyncio
import base64
import json
import os
import socket
import statistics
import struct
import subprocess
import sys
import time
import timeit

import aiohttp

from topgimbal.console.limits import MAX_MESSAGE_BYTES, MessageError, parse_message


def per_call_us(fn: object, n: int) -> float:
    return timeit.timeit(fn, number=n) / n * 1e6  # type: ignore[arg-type]


def bench_parse() -> None:
    typical = json.dumps({"op": "point", "ref": 17, "yaw": 12.5, "pitch": -30})
    largest = json.dumps({"op": "raw", "ref": 1, "frame": "x" * (MAX_MESSAGE_BYTES - 40)})
    deep = "[" * 30_000 + "]" * 30_000

    def refused() -> None:
        try:
            parse_message(deep)
        except MessageError:
            pass

    print(
        f"parse_message, typical op ({len(typical)} B):      {per_call_us(lambda: parse_message(typical), 20000):8.1f} us"
    )
    print(
        f"parse_message, largest accepted ({len(largest)} B): {per_call_us(lambda: parse_message(largest), 2000):8.1f} us"
    )
    print(f"parse_message, 30000-deep refused ({len(deep)} B): {per_call_us(refused, 200):8.1f} us")
    print(f"json.loads of the same typical op:               {per_call_us(lambda: json.loads(typical), 20000):8.1f} us")


def masked(text: str) -> bytes:
    payload = text.encode()
    mask = os.urandom(4)
    n = len(payload)
    head = bytes([0x81]) + (bytes([0x80 | n]) if n < 126 else bytes([0x80 | 126]) + struct.pack("!H", n))
    return head + mask + bytes(b ^ mask[i % 4] for i, b in enumerate(payload))


def stuck_page(port: int, deadline: float) -> tuple[int, str]:
    """A page that keeps sending status ops and never reads (in its own thread, blocking
    socket); returns how many it sent and how it ended."""
    sock = socket.create_connection(("127.0.0.1", port))
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    key = base64.b64encode(os.urandom(16)).decode()
    sock.sendall(
        (
            f"GET /ws HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
            f"Sec-WebSocket-Key: {key}\r\nSec-WebSocket-Version: 13\r\n\r\n"
        ).encode()
    )
    frame = masked(json.dumps({"op": "status", "ref": 0}))
    sent = 0
    sock.settimeout(max(0.1, deadline - time.monotonic()))
    try:
        while time.monotonic() < deadline:
            sock.sendall(frame * 20)
            sent += 20
        return sent, "still open at the deadline"
    except TimeoutError:
        return sent, "still open at the deadline"
    except OSError as exc:
        return sent, f"cut off by the console ({type(exc).__name__})"
    finally:
        sock.close()


async def good_page_rtts(base: str, seconds: float) -> list[float]:
    rtts: list[float] = []
    async with aiohttp.ClientSession() as http, http.ws_connect(base + "ws") as ws:
        end = time.monotonic() + seconds
        ref = 0
        while time.monotonic() < end:
            ref += 1
            t0 = time.perf_counter()
            await ws.send_json({"op": "version", "ref": ref})
            while True:
                msg = await ws.receive_json(timeout=30)
                if msg.get("ref") == ref:
                    break
            rtts.append((time.perf_counter() - t0) * 1000)
            await asyncio.sleep(0.02)
    return rtts


def rss_of(pid: int) -> float:
    with open(f"/proc/{pid}/status", encoding="ascii") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024
    return float("nan")


async def bench_stuck(pages: int, seconds: float) -> None:
    """The console in its own process (as `topgimbal console --sim C12`), abused from here."""
    proc = subprocess.Popen(
        [sys.executable, "-m", "topgimbal.cli.main", "console", "--sim", "C12", "--port", "0"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert proc.stdout is not None
        url = ""
        while not url:
            line = proc.stdout.readline()
            if not line:
                raise RuntimeError(f"the console did not start: {proc.stderr.read() if proc.stderr else ''}")
            if line.startswith("open "):
                url = line.split()[1]
        port = int(url.rsplit(":", 1)[1].strip("/"))
        await asyncio.sleep(1.0)
        before = rss_of(proc.pid)
        calm = await good_page_rtts(url, 3.0)
        deadline = time.monotonic() + seconds
        loop = asyncio.get_running_loop()
        abusers = [loop.run_in_executor(None, stuck_page, port, deadline) for _ in range(pages)]
        rtts_task = asyncio.create_task(good_page_rtts(url, seconds))
        peak = before
        while not all(a.done() for a in abusers):
            peak = max(peak, rss_of(proc.pid))
            await asyncio.sleep(0.2)
        results = [a.result() for a in abusers]
        rtts = await rtts_task
        await asyncio.sleep(0.5)
        after = rss_of(proc.pid)
    finally:
        proc.terminate()
        proc.wait(10)
    ends = {how: sum(1 for _, h in results if h == how) for _, how in results}
    print(
        f"{pages} pages that send status ops and never read, {seconds:.0f} s: "
        f"{statistics.mean(n for n, _ in results):.0f} ops sent each on average; "
        + ", ".join(f"{n} {how}" for how, n in ends.items())
    )
    print(f"console RSS: {before:.1f} MB before, {peak:.1f} MB peak, {after:.1f} MB after")
    q = statistics.quantiles
    print(f"good page round trip (version query), calm:  p50 {q(calm, n=20)[9]:.2f} ms, p95 {q(calm, n=20)[18]:.2f} ms")
    print(f"good page round trip (version query), abuse: p50 {q(rtts, n=20)[9]:.2f} ms, p95 {q(rtts, n=20)[18]:.2f} ms")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0] if __doc__ else None)
    ap.add_argument("--pages", type=int, default=10)
    ap.add_argument("--seconds", type=float, default=30.0)
    args = ap.parse_args()
    bench_parse()
    asyncio.run(bench_stuck(args.pages, args.seconds))


if __name__ == "__main__":
    main()
