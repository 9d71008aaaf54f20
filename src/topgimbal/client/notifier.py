"""Who hears what: subscribers to device frames, traffic hooks and link-state callbacks
(python-can's Notifier, aioesphomeapi's callback sets). Callbacks may be sync or async; one that
raises is logged and the others still run."""

from __future__ import annotations

import asyncio
import contextlib
import inspect
import logging
from collections.abc import Awaitable, Callable
from typing import TypeVar

from ..errors import FieldValueError, TopGimbalError
from ..protocol import Frame, Message

log = logging.getLogger("topgimbal.client")

MessageCallback = Callable[[Message], "Awaitable[None] | None"]
TrafficCallback = Callable[[str, Frame, "Message | None"], "Awaitable[None] | None"]
LinkCallback = Callable[[bool, str], "Awaitable[None] | None"]
C = TypeVar("C")

MAX_CALLBACKS = 1024  # per kind: a leak in the caller shows up as an error, not as memory growth


class Notifier:
    # Slots: each client has one, read per frame; 1,000 clients' worth must stay in cache (fleet).
    __slots__ = ("_link", "_subs", "_tasks", "_traffic")

    def __init__(self) -> None:
        self._subs: dict[str | None, list[MessageCallback]] = {}
        self._traffic: list[TrafficCallback] = []
        self._link: list[LinkCallback] = []
        self._tasks: set[asyncio.Task[object]] = set()

    @property
    def wants_traffic(self) -> bool:
        return bool(self._traffic)

    @property
    def wants_messages(self) -> bool:
        """Someone subscribed to messages (else `message` has nothing to do)."""
        return bool(self._subs)

    def subscribe(self, callback: MessageCallback, ident: str | None = None) -> Callable[[], None]:
        if not callable(callback):
            raise FieldValueError("callback", callback, "a function taking a Message")
        if ident is not None and not isinstance(ident, str):
            raise FieldValueError("ident", ident, "an identifier such as 'GAC', or None for every frame")
        key = ident.upper() if ident else None
        return self._add(self._subs.setdefault(key, []), callback)

    def on_traffic(self, callback: TrafficCallback) -> Callable[[], None]:
        if not callable(callback):
            raise FieldValueError("callback", callback, "a function taking (direction, frame, message)")
        return self._add(self._traffic, callback)

    def on_link_change(self, callback: LinkCallback) -> Callable[[], None]:
        if not callable(callback):
            raise FieldValueError("callback", callback, "a function taking (up, reason)")
        return self._add(self._link, callback)

    def _add(self, bucket: list[C], callback: C) -> Callable[[], None]:
        if len(bucket) >= MAX_CALLBACKS:
            raise TopGimbalError(f"{MAX_CALLBACKS} callbacks already registered here; unsubscribe old ones")
        bucket.append(callback)

        def remove() -> None:
            with contextlib.suppress(ValueError):
                bucket.remove(callback)

        return remove

    # -- delivery ------------------------------------------------------------------------------

    def message(self, message: Message) -> None:
        everyone, own = self._subs.get(None), self._subs.get(message.frame.ident)
        if everyone:
            for cb in list(everyone):
                self._call(cb, message)
        if own:
            for cb in list(own):
                self._call(cb, message)

    def traffic(self, direction: str, frame: Frame, message: Message | None) -> None:
        for cb in list(self._traffic):
            self._call(cb, direction, frame, message)

    def link(self, up: bool, reason: str) -> None:
        for cb in list(self._link):
            self._call(cb, up, reason)

    def _call(self, cb: Callable[..., object], *args: object) -> None:
        try:
            result = cb(*args)
        except Exception:
            log.exception("callback %r failed", cb)
            return
        if inspect.isawaitable(result):
            task = asyncio.ensure_future(result)
            self._tasks.add(task)
            task.add_done_callback(self._task_done)

    def _task_done(self, task: asyncio.Task[object]) -> None:
        self._tasks.discard(task)
        if not task.cancelled() and task.exception() is not None:
            log.error("async callback failed", exc_info=task.exception())

    def close(self) -> None:
        for task in list(self._tasks):
            task.cancel()
