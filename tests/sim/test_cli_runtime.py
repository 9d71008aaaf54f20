"""`cli/runtime.py`: how `sim`, `proxy` and `mavlink` wait for SIGINT/SIGTERM or a time limit."""

from __future__ import annotations

import asyncio
import os
import signal

import pytest

from topgimbal.cli.runtime import stop_on_signals, wait_stopped

pytestmark = pytest.mark.virtual


async def test_a_time_limit_ends_the_wait() -> None:
    stop = stop_on_signals()
    await asyncio.wait_for(wait_stopped(stop, 0.01), 5)
    assert not stop.is_set()


async def test_sigterm_sets_the_stop_event() -> None:
    stop = stop_on_signals()
    os.kill(os.getpid(), signal.SIGTERM)  # caught by the loop's handler, not the default action
    await asyncio.wait_for(wait_stopped(stop), 5)
    assert stop.is_set()
