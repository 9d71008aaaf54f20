"""Console figures for issue 17 item 3 and issue 12: how long after a camera goes quiet the page is
told LOST, how soon after it returns the page is told up, and what the pcap download costs.

    python bench/console_link.py [--rounds 3]

Loss and return are timed at a WebSocket page, with the in-process simulator stopped and started
again on its UDP port: a C12 (attitude stream) and a C13 (no stream: the console's link check)."""

from __future__ import annotations

import argparse
import asyncio
import statistics
import time
from typing import Any

import aiohttp

from topgimbal.console import ConsoleServer
from topgimbal.console.capture import MAX_FRAMES, Recorder, link_for, pcap
from topgimbal.protocol import get_model


async def _until(ws: aiohttp.ClientWebSocketResponse, state: str, timeout: float = 30.0) -> float:
    start = time.perf_counter()
    while time.perf_counter() - start < timeout:
        msg: dict[str, Any] = await ws.receive_json(timeout=timeout)
        if msg.get("type") == "status" and msg.get("link") == state:
            return time.perf_counter() - start
    raise TimeoutError(state)


async def loss_and_return(model: str, rounds: int) -> tuple[list[float], list[float]]:
    lost, back = [], []
    async with ConsoleServer(sim_model=model, port=0) as srv, aiohttp.ClientSession() as http:
        assert srv.sim is not None
        port = srv.sim.addresses["udp"][0][1]
        ws = await http.ws_connect(srv.base_url + "ws")
        await _until(ws, "up")
        for _ in range(rounds):
            await asyncio.sleep(1.0)
            await srv.sim.stop()
            lost.append(await _until(ws, "lost"))
            await asyncio.sleep(1.0)
            await srv.sim.start(udp=[("127.0.0.1", port)])
            back.append(await _until(ws, "up"))
    return lost, back


def pcap_cost() -> tuple[float, int, float]:
    _, model = get_model("C12")
    rec = Recorder()
    frame = b"#tpDU6rGAC0000FF9C001E42"  # a GAC answer's size
    t0 = time.perf_counter()
    for i in range(MAX_FRAMES * 2):
        rec.add(1.7e9 + i * 0.02, "in" if i % 2 else "out", frame)
    add_us = (time.perf_counter() - t0) / (MAX_FRAMES * 2) * 1e6
    t0 = time.perf_counter()
    data = pcap(rec.frames(), link_for("udp://127.0.0.1:5000", model))
    return time.perf_counter() - t0, len(data), add_us


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--rounds", type=int, default=3)
    args = ap.parse_args()
    for model in ("C12", "C13"):
        lost, back = asyncio.run(loss_and_return(model, args.rounds))
        print(
            f"{model}: LOST {statistics.median(lost):.2f} s after the camera stopped "
            f"(min {min(lost):.2f}, max {max(lost):.2f}); up {statistics.median(back):.2f} s after it returned "
            f"(max {max(back):.2f}); {args.rounds} rounds"
        )
    seconds, size, add_us = pcap_cost()
    print(
        f"recorder: {add_us:.2f} us per frame recorded; pcap of {MAX_FRAMES} frames: {size} bytes in {seconds * 1000:.0f} ms"
    )


if __name__ == "__main__":
    main()
