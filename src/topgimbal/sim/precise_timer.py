"""A wake-up at a precise time for a simulator's streams: a Linux timerfd on the event loop.

asyncio sleeps in epoll_wait, whose timeout is whole milliseconds, and the selector rounds it up:
a `call_at` timer fires up to 1 ms late. A simulator streaming at 100 Hz therefore woke 1 ms early
(TIMER_EARLY_S) and sent what fell due within that margin, so frames left anywhere in the last
millisecond before their time: gaps between frames off by up to ~1.9 ms (p99 1.8 ms at the
receiver, measured with a blocking reader, bench/latency.py). A timerfd expires at a nanosecond
time and wakes epoll as any readable fd does: frames leave at their due time plus the wake-up.

Used only where the loop's clock reads CLOCK_MONOTONIC (`clock.reads_system_monotonic`); a loop
with a time of its own (a virtual-time test loop, looptime) or a system without timerfd keeps
`call_at`, and so does a fleet's SharedTimer (one timer for many simulators, already batched).
`make()` says which: a PreciseTimer or None.
"""

from __future__ import annotations

import asyncio
import ctypes
import logging
import os
import sys
from collections.abc import Callable

from ..clock import loop_clock, reads_system_monotonic

log = logging.getLogger("topgimbal.sim")

CLOCK_MONOTONIC = 1  # Linux's clockid_t for it
TFD_TIMER_ABSTIME = 1
# The early margin that goes with it (Device.tick): frames due within it leave now. A timerfd
# fires at its time (the kernel's timer slack is 50 us); the margin only keeps a frame due a hair
# after the wake-up (float rounding between two reads of the clock) from costing a second wake.
PRECISE_EARLY_S = 0.0002


class _Timespec(ctypes.Structure):
    _fields_ = [("tv_sec", ctypes.c_long), ("tv_nsec", ctypes.c_long)]


class _Itimerspec(ctypes.Structure):
    _fields_ = [("it_interval", _Timespec), ("it_value", _Timespec)]


class _TimerFdApi:
    """timerfd_create / timerfd_settime: the os module's (Python 3.13+) or libc's through ctypes."""

    def __init__(self) -> None:
        self._libc: ctypes.CDLL | None = None
        if not hasattr(os, "timerfd_create"):
            libc = ctypes.CDLL(None, use_errno=True)
            libc.timerfd_create.argtypes = [ctypes.c_int, ctypes.c_int]
            libc.timerfd_create.restype = ctypes.c_int
            libc.timerfd_settime.argtypes = [ctypes.c_int, ctypes.c_int, ctypes.POINTER(_Itimerspec), ctypes.c_void_p]
            libc.timerfd_settime.restype = ctypes.c_int
            self._libc = libc

    def create(self) -> int:
        flags = os.O_NONBLOCK | os.O_CLOEXEC  # TFD_NONBLOCK / TFD_CLOEXEC have these values
        if self._libc is None:
            return int(os.timerfd_create(CLOCK_MONOTONIC, flags=flags))  # type: ignore[attr-defined,unused-ignore]
        fd = int(self._libc.timerfd_create(CLOCK_MONOTONIC, flags))
        if fd < 0:
            err = ctypes.get_errno()
            raise OSError(err, os.strerror(err))
        return fd

    def set_abs(self, fd: int, when_s: float) -> None:
        """Expire once at CLOCK_MONOTONIC `when_s`; 0 disarms."""
        if self._libc is None:
            os.timerfd_settime(fd, flags=TFD_TIMER_ABSTIME if when_s else 0, initial=when_s)  # type: ignore[attr-defined,unused-ignore]
            return
        sec = int(when_s)
        spec = _Itimerspec(_Timespec(0, 0), _Timespec(sec, int((when_s - sec) * 1e9)))
        if self._libc.timerfd_settime(fd, TFD_TIMER_ABSTIME if when_s else 0, ctypes.byref(spec), None) != 0:
            err = ctypes.get_errno()
            raise OSError(err, os.strerror(err))


_API: _TimerFdApi | None = None


class PreciseTimer:
    """One pending wake-up at a time (`arm` replaces it), `cancel()` as a TimerHandle's, on the
    loop that made it. `callback` runs on the loop, as a reader callback."""

    def __init__(self, loop: asyncio.AbstractEventLoop, callback: Callable[[], None], api: _TimerFdApi) -> None:
        self._loop = loop
        self._callback = callback
        self._api = api
        self._fd = api.create()
        self.armed = False
        self.now = loop_clock(loop)  # the loop's time, which is CLOCK_MONOTONIC's here (make())
        loop.add_reader(self._fd, self._expired)

    def arm(self, when_s: float) -> None:
        """Call back at CLOCK_MONOTONIC time `when_s` (at once if it has passed)."""
        self._api.set_abs(self._fd, max(when_s, 1e-9))  # 0 would disarm
        self.armed = True

    def cancel(self) -> None:
        if self.armed and self._fd >= 0:
            self._api.set_abs(self._fd, 0.0)
            self._drain()
        self.armed = False

    def close(self) -> None:
        if self._fd < 0:
            return
        self.armed = False
        if not self._loop.is_closed():
            self._loop.remove_reader(self._fd)
        os.close(self._fd)
        self._fd = -1

    def _drain(self) -> bool:
        try:
            os.read(self._fd, 8)  # the expiry count; reading it re-arms readiness
            return True
        except (BlockingIOError, InterruptedError):
            return False

    def _expired(self) -> None:
        if not self._drain() or not self.armed:
            return  # cancelled or re-armed after it expired: nothing is due from this expiry
        self.armed = False
        self._callback()


def make(loop: asyncio.AbstractEventLoop, callback: Callable[[], None]) -> PreciseTimer | None:
    """A PreciseTimer on `loop`, or None where one cannot stand for `call_at` (see the module)."""
    global _API
    if not sys.platform.startswith("linux") or not reads_system_monotonic(loop):
        return None
    try:
        if _API is None:
            _API = _TimerFdApi()
        return PreciseTimer(loop, callback, _API)
    except (OSError, AttributeError, NotImplementedError) as exc:  # no timerfd here: call_at it is
        log.debug("no timerfd (%s): stream frames keep the selector's millisecond timers", exc)
        return None
