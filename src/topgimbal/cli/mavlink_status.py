"""`topgimbal mavlink --status SECONDS [--json]`: where the bridge's feeds to the camera come from.

The bridge is a long-running process and the autopilot is only heard on its MAVLink links, so its
own output is where an operator looks (`topgimbal info` talks to the camera, not to a bridge). Every
SECONDS, and once more when it stops, it prints for each camera where its position, vehicle
attitude, heading and UTC time come from (message, system/component, rate, age) or `none` and why,
and what the camera link feeds the camera (Bridge.info()); with --json, one JSON object per line."""

from __future__ import annotations

import argparse
import asyncio
import contextlib
from collections.abc import Awaitable, Sequence
from typing import Any, Protocol

from ..client.jsonable import dumps

MIN_STATUS_S = 0.5  # --status below this would flood a terminal


class HasInfo(Protocol):
    def info(self) -> dict[str, Any]: ...


def status_seconds(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        v = float("nan")
    if not MIN_STATUS_S <= v <= 3600:
        raise argparse.ArgumentTypeError(f"{text!r}: expected {MIN_STATUS_S:g}..3600 seconds")
    return v


def add_status_arguments(p: argparse.ArgumentParser, *, json: bool = True, needs: str = "") -> None:
    """--status (and --json unless `json` is False); `needs`: the option it goes with, for the help."""
    p.add_argument("--status", type=status_seconds, default=None, metavar="SECONDS",
                   help=f"{needs}every SECONDS (and at the end) print where the camera's feeds come from: the position, "
                   "vehicle attitude, heading and time (autopilot message, system/component, rate, age, or why none)")  # fmt: skip
    if json:
        p.add_argument("--json", action="store_true", help="print the start and the --status lines as JSON, one a line")


def bound_links(node: Any, addresses: Sequence[tuple[str, int] | None]) -> list[dict[str, str | None]]:
    """Each MAVLink link as given and the address it got (port 0 resolved), for the start line."""
    return [{"link": str(link), "address": f"{a[0]}:{a[1]}" if a else None}
            for link, a in zip(node.links, addresses, strict=True)]  # fmt: skip


def links_text(links: list[dict[str, str | None]]) -> str:
    return ", ".join(f"{x['link']} ({x['address']})" if x["address"] else str(x["link"]) for x in links)


def feed_line(feed: str, v: dict[str, Any]) -> str:
    """`position  GLOBAL_POSITION_INT from 1/1, 10.0 Hz, 0.05 s ago` or `time  none: why`."""
    if v.get("none"):
        return f"{feed:<9} none: {v['none']}"
    rate = f"{v['rate_hz']:g} Hz" if v.get("rate_hz") is not None else "rate not known yet"
    return f"{feed:<9} {v['message']} from {v['source']}, {rate}, {v['age_s']:g} s ago"


def status_lines(name: str, info: dict[str, Any]) -> list[str]:
    lines = [f"feeds of {name}:"]
    lines += [f"  {feed_line(feed, v)}" for feed, v in info.get("feeds", {}).items()]
    lines.append(f"  sent to the camera: {info.get('camera_feeds', 'nothing')}")
    return lines


def print_status(named: Sequence[tuple[str, HasInfo]], as_json: bool) -> None:
    for name, bridge in named:
        info = bridge.info()
        if as_json:
            print(dumps({"status": name, **info}), flush=True)
        else:
            print("\n".join(status_lines(name, info)), flush=True)


async def status_loop(named: Sequence[tuple[str, HasInfo]], every_s: float, as_json: bool) -> None:
    while True:
        await asyncio.sleep(every_s)
        print_status(named, as_json)


async def serve_with_status(
    named: Sequence[tuple[str, HasInfo]], args: argparse.Namespace, wait: Awaitable[None]
) -> None:
    """Await `wait` (the bridge's run until a signal or --seconds), printing the status every
    --status seconds and once at the end."""
    every_s = getattr(args, "status", None)
    if every_s is None:
        await wait
        return
    as_json = bool(getattr(args, "json", False))
    task = asyncio.ensure_future(status_loop(named, every_s, as_json))
    try:
        await wait
    finally:
        task.cancel()
        with contextlib.suppress(asyncio.CancelledError):
            await task
        print_status(named, as_json)
