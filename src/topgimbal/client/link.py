"""Whether the device is there, from what arrives. No I/O; an injected clock.

UDP has no connection: the link is *up* while frames come and goes *down* when nothing has come
for `timeout_s` while something was expected (a request in flight, a stream on). A byte stream
(TCP, serial) goes down the moment it closes. A frame from the device brings the link back up. While something is
expected and the line is quiet for `ping_after_s`, the client asks the device something harmless, so
that a stalled stream is told apart from a dead device and a returning device is noticed."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

Clock = Callable[[], float]


@dataclass(frozen=True)
class LinkEvent:
    up: bool
    reason: str
    at: float  # clock time of the transition


class LinkMonitor:
    # Slots: one per client, written per frame (a fleet server's 1,000 should stay in cache).
    __slots__ = (
        "_expecting",
        "_last_ping",
        "_quiet_since",
        "clock",
        "last_in",
        "ping_after_s",
        "reason",
        "timeout_s",
        "up",
    )  # fmt: skip

    def __init__(self, *, clock: Clock, timeout_s: float = 3.0, ping_after_s: float = 1.0) -> None:
        self.clock = clock
        self.timeout_s = timeout_s
        self.ping_after_s = ping_after_s
        now = clock()
        self.up = True
        self.reason = ""
        self.last_in: float | None = None
        self._quiet_since = now  # silence is measured from the later of the last frame and demand
        self._expecting = False
        self._last_ping = -1e18

    # -- inputs ---------------------------------------------------------------------------------

    def on_frame(self, now: float | None = None) -> LinkEvent | None:
        if now is None:
            now = self.clock()
        self.last_in = now
        self._quiet_since = now
        if not self.up:
            self.up, self.reason = True, ""
            return LinkEvent(True, "frames arrive again", now)
        return None

    def on_closed(self, reason: str) -> LinkEvent | None:
        if not self.up:
            self.reason = reason
            return None
        now = self.clock()
        self.up, self.reason = False, reason
        return LinkEvent(False, reason, now)

    def on_opened(self) -> LinkEvent | None:
        now = self.clock()
        self._quiet_since = now
        if not self.up:
            self.up, self.reason = True, ""
            return LinkEvent(True, "reconnected", now)
        return None

    def expect(self, expecting: bool) -> None:
        """Something is (or no longer is) waiting for the device."""
        if expecting and not self._expecting:
            self._quiet_since = max(self._quiet_since, self.clock())
        self._expecting = expecting

    def pinged(self) -> None:
        self._last_ping = self.clock()

    # -- outputs --------------------------------------------------------------------------------

    def silent_for(self) -> float:
        """Seconds since the last frame (or since the client started listening)."""
        return self.clock() - (self.last_in if self.last_in is not None else self._quiet_since)

    def check(self) -> LinkEvent | None:
        """The `down` transition, when it is due now."""
        now = self.clock()
        if self.up and self._expecting and now - self._quiet_since >= self.timeout_s:
            self.up = False
            heard = (
                f"nothing heard from the device for {now - self.last_in:.1f} s"
                if self.last_in is not None
                else f"the device has not answered at all in {now - self._quiet_since:.1f} s"
            )
            self.reason = heard
            return LinkEvent(False, heard, now)
        return None

    def ping_due(self) -> bool:
        now = self.clock()
        if not self._expecting or now - self._last_ping < self.ping_after_s:
            return False
        return now - self._quiet_since >= self.ping_after_s

    def next_deadline(self) -> float | None:
        if not self._expecting:
            return None
        ping: float | None = max(self._quiet_since, self._last_ping) + self.ping_after_s
        if ping is not None and ping <= self.clock():
            # Overdue and not taken (a request in flight is a probe already, or nothing streams):
            # not a deadline to wake for again. Waking for it re-armed a timer in the past, a busy
            # loop in real time and one that never ends on a virtual-time loop.
            ping = None
        if self.up:
            timeout_at = self._quiet_since + self.timeout_s
            return timeout_at if ping is None else min(timeout_at, ping)
        if ping is None:
            # Down, and the ping overdue and not taken (the last one still in flight when it was
            # due: a ping's timeout is as long as ping_after_s): look again one period on. With no
            # deadline at all, nothing woke the keeper again and a silent device that came back
            # without sending on its own (a SIP, a camera that rebooted) was never pinged again.
            ping = self.clock() + self.ping_after_s
        return ping
