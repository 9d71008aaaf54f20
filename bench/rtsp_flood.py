"""RTSP fairness figures (issue 27): what one client's PLAY flood does to another viewer.

    .venv/bin/python bench/rtsp_flood.py [--seconds 6] [--model C12]

A passive viewer plays the simulator's first stream over TCP (interleaved) and counts the bytes
and keyframes it receives per second, first alone, then while a second client sends PLAY on its
own session as fast as the answers come, then while it cycles SETUP / PLAY / TEARDOWN. Before
the fix every PLAY forced a keyframe for every viewer. Figures are printed, not asserted.
"""

from __future__ import annotations

import argparse
import asyncio
import os
import resource
import time
from typing import Any

from topgimbal.sim import Simulator
from topgimbal.video.simvideo import SimVideo, VideoOptions


def cpu_s() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


class Rtsp:
    """A minimal RTSP client over one TCP connection (answers and interleaved frames)."""

    def __init__(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter, url: str) -> None:
        self.reader, self.writer, self.url = reader, writer, url
        self.cseq = 0
        self.bytes = 0
        self.keyframes = 0
        self.answers: asyncio.Queue[tuple[int, dict[str, str]]] = asyncio.Queue()
        self.task = asyncio.ensure_future(self._read())

    @classmethod
    async def open(cls, url: str) -> Rtsp:
        host, port = url.split("//")[1].split("/")[0].rsplit(":", 1)
        r, w = await asyncio.open_connection(host.strip("[]"), int(port))
        return cls(r, w, url)

    async def _read(self) -> None:
        while True:
            first = await self.reader.readexactly(1)
            if first == b"$":
                head = await self.reader.readexactly(3)
                data = await self.reader.readexactly(int.from_bytes(head[1:3], "big"))
                self.bytes += 4 + len(data)
                if len(data) > 13:
                    nal = data[12] & 0x1F
                    # H.264 IDR: a single NAL (5), or the first fragment (FU-A 28, start bit) of one.
                    if nal == 5 or (nal == 28 and data[13] & 0x80 and data[13] & 0x1F == 5):
                        self.keyframes += 1
                continue
            head = first + await self.reader.readuntil(b"\r\n\r\n")
            lines = head.decode().split("\r\n")
            headers = {k.strip().lower(): v.strip() for k, _, v in (x.partition(":") for x in lines[1:] if x)}
            n = int(headers.get("content-length", "0"))
            if n:
                await self.reader.readexactly(n)
            self.answers.put_nowait((int(lines[0].split()[1]), headers))

    async def ask(self, method: str, **headers: str) -> tuple[int, dict[str, str]]:
        self.cseq += 1
        lines = [f"{method} {self.url} RTSP/1.0", f"CSeq: {self.cseq}"]
        lines += [f"{k.replace('_', '-')}: {v}" for k, v in headers.items()]
        self.writer.write(("\r\n".join(lines) + "\r\n\r\n").encode())
        return await asyncio.wait_for(self.answers.get(), 10)

    async def play(self, channels: str = "0-1") -> str:
        code, h = await self.ask("SETUP", Transport=f"RTP/AVP/TCP;unicast;interleaved={channels}")
        assert code == 200, code
        sid = h["session"].split(";")[0]
        assert (await self.ask("PLAY", Session=sid))[0] == 200
        return sid

    def close(self) -> None:
        self.task.cancel()
        self.writer.close()


async def play_flood(url: str, stop: asyncio.Event, counter: list[int]) -> None:
    c = await Rtsp.open(url)
    try:
        sid = await c.play("2-3")
        while not stop.is_set():
            await c.ask("PLAY", Session=sid)
            counter[0] += 1
    finally:
        c.close()


async def cycle_flood(url: str, stop: asyncio.Event, counter: list[int]) -> None:
    c = await Rtsp.open(url)
    try:
        while not stop.is_set():
            sid = await c.play("2-3")
            await c.ask("TEARDOWN", Session=sid)
            counter[0] += 1
    finally:
        c.close()


async def window(viewer: Rtsp, video: SimVideo, seconds: float, flood: Any, url: str) -> dict[str, float]:
    stop = asyncio.Event()
    counter = [0]
    task = asyncio.ensure_future(flood(url, stop, counter)) if flood else None
    stream = next(iter(video.streams.values()))
    b0, k0, c0, t0 = viewer.bytes, viewer.keyframes, cpu_s(), time.monotonic()
    a0 = getattr(stream, "keyframes_asked", None)
    await asyncio.sleep(seconds)
    dt = time.monotonic() - t0
    out = {
        "kB_s": (viewer.bytes - b0) / dt / 1000,
        "keyframes_s": (viewer.keyframes - k0) / dt,
        "cpu_pct": (cpu_s() - c0) / dt * 100,
        "requests_s": counter[0] / dt,
        "asked_s": float("nan") if a0 is None else (stream.keyframes_asked - a0) / dt,
    }
    stop.set()
    if task is not None:
        await task
    return out


async def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=6.0)
    ap.add_argument("--model", default="C12")
    args = ap.parse_args()
    sim = Simulator(args.model)
    await sim.start(udp=[("127.0.0.1", 0)])
    video = await SimVideo(sim, VideoOptions(port=0)).start()
    url = next(iter(video.urls.values()))
    print(f"RTSP PLAY flood, {args.model} {url}, {args.seconds:g} s windows, load {os.getloadavg()[0]:.2f}")
    viewer = await Rtsp.open(url)
    try:
        await viewer.play()
        await asyncio.sleep(2.0)  # settle: the first keyframe and the encoder's start
        rows = [
            ("alone", await window(viewer, video, args.seconds, None, url)),
            ("PLAY flood", await window(viewer, video, args.seconds, play_flood, url)),
            ("SETUP/PLAY/TEARDOWN", await window(viewer, video, args.seconds, cycle_flood, url)),
        ]
    finally:
        viewer.close()
        await video.stop()
        await sim.stop()
    base = rows[0][1]["kB_s"]
    print(f"{'other client':<22}{'viewer kB/s':>12}{'x alone':>9}{'keyframes/s':>13}{'asked/s':>9}"
          f"{'flood req/s':>13}{'CPU %':>7}")  # fmt: skip
    for name, r in rows:
        print(f"{name:<22}{r['kB_s']:>12.0f}{r['kB_s'] / base:>9.2f}{r['keyframes_s']:>13.2f}{r['asked_s']:>9.2f}"
              f"{r['requests_s']:>13.0f}{r['cpu_pct']:>7.0f}")  # fmt: skip


if __name__ == "__main__":
    asyncio.run(main())
