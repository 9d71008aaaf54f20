"""topgimbal.timeouts: a time-limited wait that never loses a cancellation, and a bounded stop."""

from __future__ import annotations

import asyncio
import logging
import sys

import pytest

from topgimbal.timeouts import STOP_ROUND_S, stop_tasks, within

pytestmark = pytest.mark.virtual


async def _cancelled_as_the_result_arrives(wait) -> str:  # type: ignore[no-untyped-def]
    """A task waits for a future; in one loop iteration the future gets its result and the task
    is cancelled (a reply and a close at once). What does the task see?"""
    loop = asyncio.get_running_loop()
    fut: asyncio.Future[int] = loop.create_future()

    async def waiter() -> str:
        try:
            await wait(fut, 10.0)
        except asyncio.CancelledError:
            return "cancelled"
        return "result: the cancellation was lost"

    task = asyncio.ensure_future(waiter())
    await asyncio.sleep(0)  # the task now waits
    fut.set_result(1)
    task.cancel()
    return await task


async def test_within_keeps_a_cancellation_that_comes_with_the_result() -> None:
    assert await _cancelled_as_the_result_arrives(within) == "cancelled"


@pytest.mark.skipif(sys.version_info >= (3, 12), reason="CPython 3.12 fixed asyncio.wait_for")
async def test_asyncio_wait_for_loses_it_here_which_is_why_within_exists() -> None:
    # the race `within` avoids, shown on this interpreter (CPython gh-86296)
    assert await _cancelled_as_the_result_arrives(asyncio.wait_for) == "result: the cancellation was lost"


async def test_within_times_out_and_cancels_what_it_waited_for() -> None:
    fut: asyncio.Future[int] = asyncio.get_running_loop().create_future()
    with pytest.raises(asyncio.TimeoutError):
        await within(fut, 0.5)
    assert fut.cancelled()
    assert await within(asyncio.sleep(0.1, result=7), 1.0) == 7
    assert await within(asyncio.sleep(0, result=8), None) == 8


async def test_stop_tasks_cancels_again_a_task_that_swallowed_its_cancellation(caplog) -> None:  # type: ignore[no-untyped-def]
    swallowed = []

    async def stubborn() -> None:
        while True:
            try:
                await asyncio.sleep(3600)
            except asyncio.CancelledError:
                if swallowed:
                    raise
                swallowed.append(True)  # the first cancellation is lost (as wait_for loses one)

    async def failing() -> None:
        raise ValueError("boom")

    tasks = [asyncio.ensure_future(stubborn()), asyncio.ensure_future(failing())]
    await asyncio.sleep(0)
    with caplog.at_level(logging.WARNING, logger="topgimbal"):
        left = await stop_tasks(tasks, "test")
    assert left == [] and swallowed == [True] and tasks[0].cancelled()
    assert "1 still running" in caplog.text and "stubborn" in caplog.text


async def test_stop_tasks_gives_up_on_a_task_that_never_stops_and_says_so(caplog) -> None:  # type: ignore[no-untyped-def]
    release = asyncio.Event()

    async def immortal() -> None:
        while not release.is_set():
            try:
                await asyncio.sleep(3600)
            except asyncio.CancelledError:
                pass  # swallowed until the test releases it

    t = asyncio.ensure_future(immortal())
    await asyncio.sleep(0)
    loop = asyncio.get_running_loop()
    start = loop.time()
    with caplog.at_level(logging.WARNING, logger="topgimbal"):
        left = await stop_tasks([t], "test")
    assert left == [t] and not t.done()
    assert loop.time() - start == pytest.approx(5 * STOP_ROUND_S, abs=0.01)  # virtual time: exact
    assert "did not stop after 5 cancellations" in caplog.text
    release.set()  # the test's own cleanup: now it may end
    t.cancel()
    await asyncio.wait({t})
