"""A link that is down keeps a deadline for its next ping even when the last one was still in flight
when the next fell due (a ping's timeout is as long as the ping period): without it nothing woke
the keeper again, and a silent device that came back without sending on its own (a camera that
rebooted, a SIP that ignores a C12's stream request) was never pinged again."""

from __future__ import annotations

import pytest

from topgimbal.client.link import LinkMonitor
from topgimbal.clock import FakeClock

pytestmark = pytest.mark.virtual


def test_a_down_link_with_an_overdue_ping_looks_again_one_period_on() -> None:
    clock = FakeClock(0.0)
    link = LinkMonitor(clock=clock, timeout_s=3.0, ping_after_s=1.0)
    link.expect(True)
    clock.advance(3.0)
    assert link.check() is not None and not link.up
    link.pinged()  # at 3.0: its answer is awaited until 4.0
    assert link.next_deadline() == 4.0
    clock.advance(1.0)  # due again, but the keeper is still waiting for the first: not taken
    assert link.ping_due()
    assert link.next_deadline() == 5.0  # neither None (never woken again) nor now (a busy loop)


def test_an_up_link_still_waits_for_its_timeout_only() -> None:
    clock = FakeClock(100.0)
    link = LinkMonitor(clock=clock, timeout_s=3.0, ping_after_s=1.0)
    link.expect(True)
    clock.advance(1.0)  # the ping is due; the keeper does not send it (busy)
    assert link.next_deadline() == 103.0
