"""LinkMonitor's next deadline is never one already past: a timer re-armed for a ping the keeper
did not send (a request in flight is a probe already) was a busy loop in real time and one that
never ended on a virtual-time loop."""

from __future__ import annotations

import pytest

from topgimbal.client.link import LinkMonitor
from topgimbal.clock import FakeClock

pytestmark = pytest.mark.virtual


def test_an_overdue_ping_that_was_not_sent_is_not_a_deadline() -> None:
    clock = FakeClock(100.0)
    link = LinkMonitor(clock=clock, timeout_s=3.0, ping_after_s=1.0)
    link.expect(True)
    assert link.next_deadline() == 101.0  # the ping, then the timeout
    clock.advance(1.0)  # the ping is due; the keeper does not send it (busy)
    deadline = link.next_deadline()
    assert deadline is not None and deadline > clock()
    assert deadline == 103.0  # the link's timeout is still watched


def test_a_ping_sent_moves_the_next_one_on() -> None:
    clock = FakeClock(0.0)
    link = LinkMonitor(clock=clock, timeout_s=3.0, ping_after_s=1.0)
    link.expect(True)
    clock.advance(1.0)
    link.pinged()
    assert link.next_deadline() == 2.0
    clock.advance(3.0)
    assert link.check() is not None and not link.up
    assert link.next_deadline() is None or link.next_deadline() > clock()  # down: nothing overdue to wake for
