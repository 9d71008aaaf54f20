"""Device commands that watch or record a session: `monitor` (a live view), `log` (the traffic as
JSONL, and with `--pcap` as a capture Wireshark opens, written by `topgimbal.wire`), `replay`."""

from __future__ import annotations

import argparse
import contextlib
import copy
import sys
from collections.abc import Callable
from typing import TYPE_CHECKING

from ..client.jsonable import dumps
from ..clock import monotonic

if TYPE_CHECKING:
    from rich.table import Table

    from ..client import AsyncClient, LogRecord
    from ..wire.export import ExportReport

from ..errors import RequestTimeoutError, TopGimbalError
from ..protocol import Frame, Message
from .args import COUNT, HZ, input_file, number, writable_output
from .device_output import plain as _plain
from .device_output import text as _text

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
        table.add_row("attitude age", f"{(monotonic() - att.t) * 1000:.0f} ms")
    else:
        table.add_row("attitude", "-")
    for name in ("zoom", "recording", "sd", "range_m", "mode", "version"):
        s = getattr(cam.state, name)
        table.add_row(name, "-" if s is None else _cell(_plain(s.value)))
    st = cam.stats
    table.add_row("frames in / out", f"{st.frames_in} / {st.frames_out}")
    table.add_row("timeouts / retries / late", f"{st.timeouts} / {st.retries} / {st.late_replies}")
    table.add_row("rtt last / avg", f"{st.rtt_ms_last or 0:.2f} / {st.rtt_ms_avg or 0:.2f} ms")
    table.add_row("connected", str(st.connected))
    return table


def _cell(value: object) -> str:
    """A state value as the table shows it: a record (the SD card) as `name: value` pairs, never a
    Python dict; `-` for nothing."""
    if isinstance(value, dict):
        return ", ".join(f"{k}: {_text(k, v)}" for k, v in value.items()) or "-"
    return _text("", value)


async def _monitor(cam: AsyncClient, args: argparse.Namespace) -> int:
    """A live view; `--count N` renders N frames and exits (for scripts and tests)."""
    import asyncio  # here, not at the top: `topgimbal --help` does not load asyncio (cli/main.py)

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
            print(dumps({"state": cam.state, "link": cam.stats}), flush=True)
            frames += 1
        return 0
    with Live(_monitor_table(cam), console=console, refresh_per_second=args.fps, transient=False) as live:
        while not args.count or frames < args.count:
            await asyncio.sleep(interval)
            live.update(_monitor_table(cam))
            frames += 1
    return 0


async def _log(cam: AsyncClient, args: argparse.Namespace) -> dict[str, object]:
    """Record the traffic (with the attitude stream on, if asked) to a JSONL file. A failure or
    Ctrl-C keeps what was recorded and says so (with --pcap, the capture of it is still written)."""
    import asyncio

    if args.pcap:  # find out now, not after --seconds of recording
        writable_output(args.pcap)
    from ..client.traffic import TrafficLog

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
    except asyncio.CancelledError:  # Ctrl-C: what was recorded is the point of the command
        log.close()
        print(f"topgimbal: log interrupted: {_kept(args, count, 'Ctrl-C')}", file=sys.stderr, flush=True)
        raise
    except TopGimbalError as exc:
        log.close()
        kept = copy.copy(exc)  # the same kind of error (a timeout stays one), saying what is left
        kept.args = (f"{exc}; {_kept(args, count, 'the error')}",)
        raise kept from None
    finally:
        log.close()
    if args.stream and cam.stats.frames_in == 0:
        raise TopGimbalError(f"nothing came from the device in {args.seconds:g} s; {args.file} holds no answers")
    out: dict[str, object] = {"file": args.file, "frames": count}
    if args.pcap:
        report = _log_pcap(args)
        out.update(pcap=args.pcap, pcap_frames=report.frames, pcap_problems=len(report.problems))
    return out


def _log_pcap(args: argparse.Namespace) -> ExportReport:
    from ..wire.export import log_to_pcap  # the one pcap writer (topgimbal.wire)

    return log_to_pcap(args.file, args.pcap)


def _kept(args: argparse.Namespace, count: int, before: str) -> str:
    """What a stopped `log` left behind, for its error line."""
    kept = f"{args.file} keeps the {count} frames recorded before {before}"
    if args.pcap and count:
        try:
            kept += f", and {args.pcap} their capture ({_log_pcap(args).frames} frames)"
        except (TopGimbalError, OSError) as exc:
            kept += f" (no capture written: {exc})"
    return kept


async def _replay(cam: AsyncClient, args: argparse.Namespace) -> dict[str, object]:
    """Send the host -> device frames of a log again, with their original spacing."""
    import asyncio

    records = _records(input_file(args.file, "traffic log"))
    sent = replies = 0
    start = monotonic()
    t0 = records[0].mono if records else 0.0
    for r in records:
        if not args.fast:
            delay = (r.mono - t0) / args.speed - (monotonic() - start)
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


def _records(path: str) -> list[LogRecord]:
    """The host -> device records of a traffic log; a file that holds none (or is not a log at all)
    is an error naming it, not a replay that sends nothing and succeeds."""
    try:
        from ..client.traffic import read_log

        records = [r for r in read_log(path) if r.direction == "out"]
    except UnicodeDecodeError as exc:
        raise TopGimbalError(f"{path} is not a traffic log: not UTF-8 text (byte {exc.start})") from None
    except (TypeError, AttributeError, ValueError) as exc:  # a JSON line that is not a record object
        raise TopGimbalError(f"{path} is not a traffic log: a line is not a record ({exc})") from None
    if not records:
        raise TopGimbalError(
            f"{path} holds no host -> device frames to replay (a traffic log has one JSON object per line "
            "with 'dir' and 'raw'; write one with `topgimbal log FILE`)"
        )
    return records


def register(sub: argparse._SubParsersAction, command: Register) -> None:
    p = command(sub, "monitor", _monitor, "live view of attitude, camera state and link statistics")
    p.add_argument("--rate", type=HZ, default=20.0, help="attitude stream rate in Hz (default 20)")
    p.add_argument(
        "--fps",
        type=number(low=0.1, high=60, what="a refresh rate"),
        default=5.0,
        help="screen refreshes per second (0.1..60, default 5)",
    )
    p.add_argument("--count", type=COUNT, default=0, help="render N frames and exit (default 0: until Ctrl-C)")

    p = command(sub, "log", _log, "record the traffic to a JSONL file (and a pcap with --pcap)")
    p.add_argument("file")
    p.add_argument(
        "--pcap",
        metavar="FILE",
        help="also write what was recorded as a capture for Wireshark (pcapng if FILE ends in .pcapng); "
        "`topgimbal pcap from-log LOG -o FILE` converts any log later",
    )
    p.add_argument(
        "--seconds", type=number(low=0, low_open=True, what="a duration"), default=10.0, help="how long (default 10)"
    )
    p.add_argument(
        "--stream",
        type=number(low=0, what="a rate in Hz"),
        default=0.0,
        metavar="HZ",
        help="turn the attitude stream on while logging (default 0: off)",
    )

    p = command(sub, "replay", _replay, "send the host -> device frames of a JSONL log again")
    p.add_argument("file")
    p.add_argument(
        "--speed",
        type=number(low=0, low_open=True, what="a time scale"),
        default=1.0,
        help="time scale (2 = twice as fast)",
    )
    p.add_argument("--fast", action="store_true", help="ignore the original timing")
    p.add_argument("--no-wait", action="store_true", help="do not wait for replies")
