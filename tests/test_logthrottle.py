"""logthrottle.ThrottledLog: one line per kind per period, the next one counting what was left out
(the simulator's servers, the proxy, the MAVLink bridge, the media server and RTSP streams)."""

from __future__ import annotations

import logging

import pytest

from topgimbal.logthrottle import MAX_KINDS, ThrottledLog

pytestmark = pytest.mark.virtual


def test_allow_says_when_to_log_and_how_many_were_left_out() -> None:
    now = [0.0]
    throttle = ThrottledLog(logging.getLogger("test"), 10.0, lambda: now[0])
    assert throttle.allow("busy") == 0
    assert [throttle.allow("busy") for _ in range(3)] == [None, None, None]
    assert throttle.allow("other") == 0  # each kind has its own period
    now[0] = 9.9
    assert throttle.allow("busy") is None
    now[0] = 10.0
    assert throttle.allow("busy") == 4
    assert throttle.allow("busy") is None


def test_warning_appends_the_count_left_out(caplog: pytest.LogCaptureFixture) -> None:
    now = [0.0]
    throttle = ThrottledLog(logging.getLogger("test.throttle"), 5.0, lambda: now[0])
    with caplog.at_level(logging.WARNING, logger="test.throttle"):
        assert throttle.warning("full", "full: %d", 1)
        assert not throttle.warning("full", "full: %d", 2)
        assert not throttle.warning("full", "full: %d", 3)
        now[0] = 5.0
        assert throttle.warning("full", "full: %d", 4)
    assert [r.getMessage() for r in caplog.records] == ["full: 1", "full: 4 (2 more like it not logged)"]


def test_kinds_are_bounded_and_a_forgotten_kind_starts_afresh() -> None:
    now = [0.0]
    throttle = ThrottledLog(logging.getLogger("test"), 10.0, lambda: now[0])
    assert throttle.allow("k0") == 0
    assert throttle.allow("k0") is None  # counted for k0
    for i in range(1, MAX_KINDS + 1):
        throttle.allow(f"k{i}")
    assert len(throttle._last) == MAX_KINDS and "k0" not in throttle._last and "k0" not in throttle._left_out
    assert throttle.allow("k0") == 0  # logged at once, with no stale count
