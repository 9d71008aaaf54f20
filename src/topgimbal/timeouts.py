"""Waiting with a time limit, and stopping tasks, without losing a cancellation.

`asyncio.wait_for` before CPython 3.12 swallows a cancellation that arrives in the same loop
iteration as the awaited result (CPython gh-86296): it returns the result instead of raising
`CancelledError`, and a task looping around it (a bridge's rangefinder loop, a heartbeat) goes on
for ever after it was cancelled. That hung `topgimbal mavlink --seconds 1` in its close, now and
then, on a loaded machine. `within()` is the same wait without the race, and the only one the
package uses (an architecture test forbids `asyncio.wait_for` in src/). `stop_tasks()` cancels and
waits with a bound, so a task that swallows its cancellation anyway (a library's) is cancelled
again, logged, and never holds a close for ever.

A shared leaf: every layer that waits may import it; it imports nothing of topgimbal's."""

from __future__ import annotations

import asyncio
import logging
import sys
from collections.abc import Awaitable, Iterable
from typing import Any, TypeVar

T = TypeVar("T")

log = logging.getLogger("topgimbal")

STOP_ROUND_S = 1.0  # stop_tasks: how long each round waits before cancelling again
STOP_ROUNDS = 5  # ... and how many rounds before it gives up on a task (logged)


async def within(aw: Awaitable[T], timeout_s: float | None) -> T:
    """`await aw`, raising `asyncio.TimeoutError` after `timeout_s` (None: no limit); `aw` is
    cancelled on timeout, as with `asyncio.wait_for`. A cancellation of the caller always
    propagates, even when `aw` completed in the same loop iteration."""
    if timeout_s is None:
        return await aw
    if sys.version_info >= (3, 11):
        # asyncio.timeout turns only its own cancellation into TimeoutError (it counts them with
        # Task.uncancel): a cancel from outside stays a CancelledError.
        async with asyncio.timeout(timeout_s):
            return await aw
    return await _within_310(aw, timeout_s)  # pragma: no cover - CPython 3.10


async def _within_310(aw: Awaitable[T], timeout_s: float) -> T:  # pragma: no cover - CPython 3.10
    inner = asyncio.ensure_future(aw)
    try:
        done, _ = await asyncio.wait({inner}, timeout=timeout_s)
    except BaseException:  # cancelled from outside: take the inner operation with us, re-raise
        inner.cancel()
        raise
    if done:
        return inner.result()
    inner.cancel()
    await asyncio.wait({inner})
    raise asyncio.TimeoutError()


async def stop_tasks(tasks: Iterable[asyncio.Future[Any]], what: str = "task") -> list[asyncio.Future[Any]]:
    """Cancel `tasks` and wait until they are done: every STOP_ROUND_S the ones still running are
    cancelled again (a task that swallowed its cancellation gets another one), and after
    STOP_ROUNDS rounds the ones left are logged and given up on, so a close always returns.
    Their exceptions are consumed. Returns the tasks left running (normally none)."""
    tasks = list(tasks)
    pending = {t for t in tasks if not t.done()}
    for round_no in range(STOP_ROUNDS):
        if not pending:
            break
        for t in pending:
            t.cancel()
        _, pending = await asyncio.wait(pending, timeout=STOP_ROUND_S)
        if pending and round_no == 0:
            log.warning("%s: %d still running %.0f s after it was cancelled (cancelling again): %s",
                        what, len(pending), STOP_ROUND_S, ", ".join(_name(t) for t in pending))  # fmt: skip
    for t in tasks:
        if t.done() and not t.cancelled():
            t.exception()  # consumed: a task's failure at close is not "never retrieved"
    if pending:
        log.error("%s: %d did not stop after %d cancellations; left running: %s",
                  what, len(pending), STOP_ROUNDS, ", ".join(_name(t) for t in pending))  # fmt: skip
    return list(pending)


def _name(t: asyncio.Future[Any]) -> str:
    coro = t.get_coro() if isinstance(t, asyncio.Task) else None
    return getattr(coro, "__qualname__", None) or repr(t)
