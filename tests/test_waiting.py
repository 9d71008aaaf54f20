"""tests/waiting.py: a wait returns the value it waited for, and one that runs out says what it
waited for, its bound and the last values it saw (on looptime's loop: the bound costs no time)."""

from __future__ import annotations

import itertools

import pytest

from waiting import WaitTimeoutError, near, until, until_blocking

pytestmark = pytest.mark.virtual


async def test_until_returns_the_first_value_that_holds() -> None:
    counter = itertools.count()
    assert await until("the third read", lambda: next(counter), lambda v: v >= 3, bound_s=5) == 3


async def test_a_wait_that_runs_out_shows_the_last_values_seen() -> None:
    readings = iter([11.0, 11.2, 11.4, 11.45] + [11.4987] * 1000)
    with pytest.raises(WaitTimeoutError) as failed:
        await near("the yaw", lambda: next(readings), 12.0, margin=0.5, bound_s=1.0)
    message = str(failed.value)
    assert message.startswith("the yaw within 0.5 of 12: not within 1 s")
    # distinct values only, oldest first, the last one the value it stopped at
    assert message.endswith("11.0, 11.2, 11.4, 11.45, 11.4987")


async def test_near_returns_the_value_inside_the_margin() -> None:
    readings = iter([0.0, 5.0, 11.6, 11.9])
    assert await near("the yaw", lambda: next(readings), 12.0, margin=0.5, bound_s=5) == 11.6


def test_until_blocking_says_what_it_waited_for() -> None:
    with pytest.raises(WaitTimeoutError, match=r"the page: not within 0.1 s; .*'loading'"):
        until_blocking("the page", lambda: "loading", lambda v: v == "ready", bound_s=0.1, every_s=0.01)
    assert until_blocking("the page", lambda: "ready", bound_s=0.1) == "ready"
