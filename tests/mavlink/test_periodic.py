"""The bridge parts' timer loop (mavlink/periodic.py), on virtual time: a step every period from
start() to close(), nothing after close(), and a failing step logged, not raised out of close()."""

from __future__ import annotations

import asyncio
import logging

import pytest

from topgimbal.clock import monotonic
from topgimbal.periodic import Periodic

pytestmark = pytest.mark.virtual


async def test_a_step_every_period_until_close() -> None:
    times: list[float] = []

    async def step() -> None:
        times.append(monotonic())

    start = monotonic()
    loop = Periodic(0.5, step, name="test")
    assert not loop.started
    loop.start()
    loop.start()  # a second start runs no second loop
    assert loop.started
    await asyncio.sleep(2.6)
    await loop.close()
    assert [round(t - start, 3) for t in times] == [0.5, 1.0, 1.5, 2.0, 2.5]
    await asyncio.sleep(2.0)
    assert len(times) == 5 and not loop.started
    await loop.close()  # closing again is harmless


async def test_a_failing_step_is_logged_and_close_returns(caplog: pytest.LogCaptureFixture) -> None:
    calls = 0

    async def step() -> None:
        nonlocal calls
        calls += 1
        raise RuntimeError("broken")

    loop = Periodic(1.0, step, name="the broken part")
    loop.start()
    await asyncio.sleep(3.5)
    with caplog.at_level(logging.ERROR, logger="topgimbal.mavlink"):
        await loop.close()
    assert calls == 1  # the error ended the loop
    assert [r.getMessage() for r in caplog.records] == ["the broken part stopped on an error"]


async def test_close_before_start_does_nothing() -> None:
    async def step() -> None:
        raise AssertionError("never")

    await Periodic(1.0, step, name="idle").close()
