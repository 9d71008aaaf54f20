"""TCP reassembly of hostile captures (`wire.tcpstream.TcpStream`): the time to reassemble one
direction whose segments arrive in the worst orders a capture can hold.

- reversed: one-byte segments, last first, then the first one (everything waits, then drains).
- holes:    one-byte segments with a missing byte before each, skipped at the end of the capture.

Each ordering is run for a few sizes up to MAX_PENDING one-byte segments (the most that can wait);
the time should grow in proportion (a list scan per segment made it quadratic: 32,000 reversed
segments took 90 s before). Prints seconds and microseconds per segment, with the load average.

    .venv/bin/python bench/reassembly.py [--sizes 8192,65536,262144]
"""

from __future__ import annotations

import argparse
import os
import time

from topgimbal.wire.packets import TCP_SYN
from topgimbal.wire.tcpstream import MAX_PENDING, TcpStream


def run(order: str, n: int) -> float:
    stream = TcpStream(max_pending=max(MAX_PENDING, n))
    stream.add(0, TCP_SYN, b"")
    start = time.perf_counter()
    if order == "reversed":
        for i in range(n, 0, -1):
            stream.add(1 + i, 0, b"x")
        got = stream.add(1, 0, b"x")
    else:
        for i in range(n):
            stream.add(2 + 2 * i, 0, b"x")
        got = stream.finish()
    elapsed = time.perf_counter() - start
    assert sum(len(d.data) for d in got) == (n + 1 if order == "reversed" else n)
    return elapsed


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--sizes", default=f"8192,65536,{MAX_PENDING}", help="segment counts, comma-separated")
    args = parser.parse_args()
    print(f"load average {os.getloadavg()[0]:.2f}")
    for order in ("reversed", "holes"):
        for n in (int(x) for x in args.sizes.split(",")):
            s = run(order, n)
            print(f"{order:9s} {n:7d} segments  {s:7.3f} s  {s / n * 1e6:6.2f} us/segment")


if __name__ == "__main__":
    main()
