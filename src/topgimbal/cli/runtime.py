"""Running a server subcommand until a signal (or a time limit) stops it."""

from __future__ import annotations

import asyncio
import contextlib
import signal
import sys
from collections.abc import Coroutine
from typing import Any

from ..timeouts import within


def stop_on_signals() -> asyncio.Event:
    """An event that SIGINT or SIGTERM sets, from now on. Off the main thread the loop cannot
    catch signals: then only a time limit (or cancellation) ends a wait on it."""
    stop = asyncio.Event()
    loop = asyncio.get_running_loop()
    for sig in (signal.SIGINT, signal.SIGTERM):
        with contextlib.suppress(NotImplementedError, RuntimeError):
            loop.add_signal_handler(sig, stop.set)
    return stop


async def wait_stopped(stop: asyncio.Event, seconds: float | None = None) -> None:
    """Wait for `stop`, or `seconds` when given, whichever comes first."""
    if seconds is None:
        await stop.wait()
        return
    with contextlib.suppress(asyncio.TimeoutError):
        await within(stop.wait(), seconds)


def run_server(main: Coroutine[Any, Any, None]) -> int:
    """Run a server command's `main` to its end: 0, also after a Ctrl-C that came before its
    signal handlers were installed (then "stopped" on stderr, not a traceback)."""
    try:
        asyncio.run(main)
    except KeyboardInterrupt:
        print("stopped", file=sys.stderr)
    return 0
