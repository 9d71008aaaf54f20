"""Device commands that watch or record a session: `monitor` (a live view), `log` (the traffic as
JSONL, and with `--pcap` as a capture Wireshark opens, written by `topgimbal.wire`), `replay`."""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import json
import time
from collections.abc import Callable
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from rich.table import Table

from ..client import AsyncClient, TrafficLog, read_log
from ..errors import RequestTimeoutError, TopGimbalError
from ..protocol import Frame, Message
from .device_output import plain as _plain

Register = Callable[..., argparse.ArgumentParser]


async def _first_attitude(cam: AsyncClient, rate_hz: float) -> None:
    """Start the stream and wait (briefly) for its first sample, so the first screen shows it."""
    await cam.attitude_stream(rate_hz)
    with contextlib.suppress(RequestTimeoutError):
        await cam.wait_attitude(timeout_s=max(1.0, 3.0 / rate_hz))


def _monitor_table(cam: AsyncClient) -> Table:
    from rich.table import Table

    table = Table(title=f"{cam.model.name} at {cam.url}", show_header=True, expand=False)
    table.add_column("what")
    table.add_column("value")
    att = cam.state.attitude
    if att is not None:
        table.add_row("yaw / pitch / roll", f"{att.yaw_deg:8.2f}  {att.pitch_deg:8.2f}  {att.roll_deg:8.2f}")
        table.add_row("attitude age", f"{(time.monotonic() - att.t) * 1000:.0f} ms")
    else:
        table.add_row("attitude", "-")
    for name in ("zoom", "recording", "sd", "range_m", "mode", "version"):
        s = getattr(cam.state, name)
        table.add_row(name, "-" if s is None else str(_plain(s.value)))
    st = cam.stats
    table.add_row("frames in / out", f"{st.frames_in} / {st.frames_out}")
    table.add_row("timeouts / retries / late", f"{st.timeouts} / {st.retries} / {st.late_replies}")
    table.add_row("rtt last / avg", f"{st.rtt_ms_last or 0:.2f} / {st.rtt_ms_avg or 0:.2f} ms")
    table.add_row("connected", str(st.connected))
    return table


async def _monitor(cam: AsyncClient, args: argparse.Namespace) -> int:
    """A live view; `--count N` renders N frames and exits (for scripts and tests)."""
    from rich.console import Console
    from rich.live import Live

    await _first_attitude(cam, args.rate)
    with contextlib.suppress(TopGimbalError):
        await cam.recording()
    with contextlib.suppress(TopGimbalError):
        await cam.sd_card()
    console = Console(force_terminal=None if not args.json else False)
    frames = 0
    interval = 1.0 / max(args.fps, 0.1)
    if args.json:
        while not args.count or frames < args.count:
            await asyncio.sleep(interval)
            print(json.dumps({"state": cam.state.as_dict(), "link": cam.stats.as_dict()}, default=str), flush=True)
            frames += 1
        return 0
    with Live(_monitor_table(cam), console=console, refresh_per_second=args.fps, transient=False) as live:
        while not args.count or frames < args.count:
            await asyncio.sleep(interval)
            live.update(_monitor_table(cam))
            frames += 1
    return 0


async def _log(cam: AsyncClient, args: argparse.Namespace) -> dict[str, object]:
    """Record the traffic (with the attitude stream on, if asked) to a JSONL file."""
    log = TrafficLog(args.file, url=cam.url, model=cam.model.name, dialect=cam.dialect.name)
    count = 0

    def record(direction: str, frame: Frame, message: Message | None) -> None:
        nonlocal count
        log.record(direction, frame, message)
        count += 1

    cam.on_traffic(record)
    try:
        if args.stream:
            await cam.attitude_stream(args.stream)
        await asyncio.sleep(args.seconds)
        if args.stream:
            await cam.stop_attitude_stream()
    finally:
        log.close()
    if args.stream and cam.stats.frames_in == 0:
        raise TopGimbalError(f"nothing came from the device in {args.seconds:g} s; {args.file} holds no answers")
    out: dict[str, object] = {"file": args.file, "frames": count}
    if args.pcap:
        from ..wire.export import log_to_pcap  # the one pcap writer (topgimbal.wire)

        report = log_to_pcap(args.file, args.pcap)
        out.update(pcap=args.pcap, pcap_frames=report.frames, pcap_problems=len(report.problems))
    return out


async def _replay(cam: AsyncClient, args: argparse.Namespace) -> dict[str, object]:
    """Send the host -> device frames of a log again, with their original spacing."""
    records = [r for r in read_log(args.file) if r.direction == "out"]
    sent = replies = 0
    start = time.monotonic()
    t0 = records[0].mono if records else 0.0
    for r in records:
        if not args.fast:
            delay = (r.mono - t0) / args.speed - (time.monotonic() - start)
            if delay > 0:
                await asyncio.sleep(delay)
        try:
            reply = await cam.send_raw(r.frame, wait_reply=not args.no_wait)
        except TopGimbalError as exc:
            if not args.json:
                print(f"{r.frame.text()} -> {exc}")
            sent += 1
            continue
        sent += 1
        if reply is not None:
            replies += 1
            if not args.json:
                print(f"{r.frame.text()} -> {reply.frame.text()}")
    if sent and not replies and not args.no_wait:
        raise TopGimbalError(f"replay: the device answered none of the {sent} frames sent")
    return {"file": args.file, "sent": sent, "replies": replies}


def register(sub: argparse._SubParsersAction, command: Register) -> None:  # type: ignore[type-arg]
    p = command(sub, "monitor", _monitor, "live view of attitude, camera state and link statistics")
    p.add_argument("--rate", type=float, default=20.0, help="attitude stream rate in Hz (default 20)")
    p.add_argument("--fps", type=float, default=5.0, help="screen refreshes per second (default 5)")
    p.add_argument("--count", type=int, default=0, help="render N frames and exit")

    p = command(sub, "log", _log, "record the traffic to a JSONL file (and a pcap with --pcap)")
    p.add_argument("file")
    p.add_argument(
        "--pcap",
        metavar="FILE",
        help="also write what was recorded as a capture for Wireshark (pcapng if FILE ends in .pcapng); "
        "`topgimbal pcap from-log LOG -o FILE` converts any log later",
    )
    p.add_argument("--seconds", type=float, default=10.0)
    p.add_argument("--stream", type=float, default=0.0, metavar="HZ", help="turn the attitude stream on while logging")

    p = command(sub, "replay", _replay, "send the host -> device frames of a JSONL log again")
    p.add_argument("file")
    p.add_argument("--speed", type=float, default=1.0, help="time scale (2 = twice as fast)")
    p.add_argument("--fast", action="store_true", help="ignore the original timing")
    p.add_argument("--no-wait", action="store_true", help="do not wait for replies")
