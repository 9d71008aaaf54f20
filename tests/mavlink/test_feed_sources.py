"""Where each of the camera's feeds comes from (mavlink/feed_sources.py through AutopilotStreams):
the message in use, its sender, rate and age, or `none` and why, on a fake clock."""

from __future__ import annotations

import math
from typing import Any

import pytest
from pymavlink.dialects.v20 import common as ml

from topgimbal.autopilot.streams import AutopilotStreams
from topgimbal.clock import FakeClock
from topgimbal.mavlink import feed_sources
from topgimbal.mavlink.quaternion import from_euler_deg

pytestmark = pytest.mark.virtual

GIMBAL = 154
LAT, LON = 47.397742, 8.545594


class Comp:
    """The gimbal component the requests go out on: what was sent."""

    def __init__(self) -> None:
        self.sent: list[Any] = []

    def send(self, m: Any) -> None:
        self.sent.append(m)


def stamped(m: Any, sysid: int = 1, compid: int = 1) -> Any:
    """The message as heard from `sysid/compid` (packing gives it the header the bridge reads)."""
    m.pack(ml.MAVLink(None, srcSystem=sysid, srcComponent=compid))
    return m


def gpi(lat: float = LAT, lon: float = LON, hdg: int = 9000) -> Any:
    return ml.MAVLink_global_position_int_message(0, int(lat * 1e7), int(lon * 1e7), 500_000, 20_000, 0, 0, 0, hdg)


def state(q: list[float] | None = None) -> Any:
    q = list(from_euler_deg(1.0, 2.0, 90.0)) if q is None else q
    return ml.MAVLink_autopilot_state_for_gimbal_device_message(GIMBAL, 1, 0, q, 0, 0, 0, 0, 0, 0, 0, 0, 0)


def attitude(yaw: float = 1.0) -> Any:
    return ml.MAVLink_attitude_message(0, 0.01, 0.02, yaw, 0, 0, 0)


def heartbeat() -> Any:
    return ml.MAVLink_heartbeat_message(2, 3, 0, 0, 4, 3)  # a quadrotor, autopilot type 3


def system_time(usec: int = 1_700_000_000_000_000) -> Any:
    return ml.MAVLink_system_time_message(usec, 0)


def make() -> tuple[AutopilotStreams, FakeClock, Comp]:
    clock = FakeClock(100.0)
    comp = Comp()
    return AutopilotStreams(comp, 1, {GIMBAL, 100, 101}, clock=clock), clock, comp  # type: ignore[arg-type]


def feed_for(s: AutopilotStreams, clock: FakeClock, make_msg: Any, hz: float, seconds: float, compid: int = 1) -> None:
    for _ in range(round(seconds * hz)):
        s.on_message(stamped(make_msg(), compid=compid))
        clock.advance(1.0 / hz)


def test_nothing_heard_every_feed_says_no_autopilot() -> None:
    s, _, _ = make()
    feeds = s.feeds()
    assert set(feeds) == {"position", "attitude", "heading", "time"}
    for v in feeds.values():
        assert v["message"] is None and v["source"] is None and v["rate_hz"] is None and v["age_s"] is None
        assert "no autopilot heard on the MAVLink links" in v["none"]


def test_each_feed_names_its_message_sender_rate_and_age() -> None:
    s, clock, _ = make()
    s.on_message(stamped(heartbeat()))
    for _ in range(20):  # 2 s: position and attitude at 10 Hz, the time at 1 Hz
        s.on_message(stamped(gpi()))
        s.on_message(stamped(state()))
        if _ % 10 == 0:
            s.on_message(stamped(system_time()))
        clock.advance(0.1)
    feeds = s.feeds()
    assert feeds["position"] == {"message": "GLOBAL_POSITION_INT", "source": "1/1", "rate_hz": 10.0,
                                 "age_s": 0.1, "none": None}  # fmt: skip
    assert feeds["attitude"]["message"] == "AUTOPILOT_STATE_FOR_GIMBAL_DEVICE" and feeds["attitude"]["rate_hz"] == 10.0
    assert feeds["heading"]["message"] == "AUTOPILOT_STATE_FOR_GIMBAL_DEVICE"  # preferred to the position's hdg
    assert feeds["time"]["message"] == "SYSTEM_TIME" and feeds["time"]["rate_hz"] == 1.0
    assert feeds["time"]["age_s"] == 1.0  # heard at 0 s and 1 s of 2


def test_attitude_falls_back_to_attitude_when_the_gimbal_state_stops() -> None:
    s, clock, _ = make()
    feed_for(s, clock, state, 50, 1.0)
    feed_for(s, clock, lambda: attitude(), 4, 1.0 + feed_sources.STALE_S)  # the state went quiet meanwhile
    feeds = s.feeds()
    assert feeds["attitude"]["message"] == "ATTITUDE" and feeds["attitude"]["source"] == "1/1"
    assert feeds["attitude"]["rate_hz"] == 4.0


def test_heading_from_the_position_when_no_attitude_comes() -> None:
    s, clock, _ = make()
    s.on_message(stamped(heartbeat()))
    feed_for(s, clock, gpi, 5, 1.0)
    feeds = s.feeds()
    assert feeds["heading"]["message"] == "GLOBAL_POSITION_INT"
    assert feeds["attitude"]["none"] == "no AUTOPILOT_STATE_FOR_GIMBAL_DEVICE or ATTITUDE from the autopilot 1/1"


def test_a_message_without_its_value_is_no_source_and_says_why() -> None:
    s, clock, _ = make()
    for _ in range(5):
        s.on_message(stamped(gpi(0.0, 0.0, hdg=65535)))  # before the first fix
        s.on_message(stamped(system_time(0)))  # no GPS time yet
        s.on_message(stamped(state([math.nan] * 4)))
        clock.advance(0.1)
    feeds = s.feeds()
    assert feeds["position"]["none"] == "GLOBAL_POSITION_INT from 1/1: no GPS fix yet (lat, lon 0, 0)"
    assert feeds["time"]["none"] == "SYSTEM_TIME from 1/1: no GPS time yet (time_unix_usec 0)"
    assert feeds["attitude"]["none"] == "AUTOPILOT_STATE_FOR_GIMBAL_DEVICE from 1/1: no attitude in it (q NaN or zero)"
    assert feeds["heading"]["message"] is None
    s.on_message(stamped(gpi()))  # the fix comes
    assert s.feeds()["position"]["source"] == "1/1"


def test_a_feed_that_stopped_says_when_it_was_last_heard() -> None:
    s, clock, _ = make()
    feed_for(s, clock, gpi, 10, 1.0)
    clock.advance(feed_sources.STALE_S + 1.0)
    assert s.feeds()["position"]["none"] == "GLOBAL_POSITION_INT from 1/1 last heard 4.1 s ago"


def test_asked_and_not_answered_or_not_asked() -> None:
    s, clock, comp = make()
    s.on_message(stamped(heartbeat()))
    assert s.feeds()["time"]["none"] == "no SYSTEM_TIME from the autopilot 1/1, not asked (--no-request-streams)"
    s.check()
    clock.advance(6.0)
    s.check()
    assert len([m for m in comp.sent if m.get_type() == "COMMAND_LONG" and m.param1 == 2]) == 2
    assert s.feeds()["time"]["none"] == "no SYSTEM_TIME from the autopilot 1/1, asked 2 times"
    assert s.feeds()["position"]["none"] == "no GLOBAL_POSITION_INT from the autopilot 1/1, asked 2 times"


def test_our_own_components_and_other_systems_are_not_sources() -> None:
    s, clock, _ = make()
    feed_for(s, clock, gpi, 10, 1.0, compid=GIMBAL)  # our own echo
    s.on_message(stamped(gpi(), sysid=2))  # another vehicle
    s.on_message(stamped(gpi(), sysid=255, compid=190))  # a ground station
    assert s.feeds()["position"]["message"] is None and not s.sources.heard


def test_another_sender_restarts_the_rate_and_the_record_is_bounded() -> None:
    s, clock, _ = make()
    feed_for(s, clock, gpi, 10, 3.0)
    heard = s.sources.heard["GLOBAL_POSITION_INT"]
    assert len(heard.arrivals) == feed_sources.RATE_SAMPLES
    feed_for(s, clock, gpi, 2, 2.0, compid=2)  # a companion computer takes over
    v = s.feeds()["position"]
    assert v["source"] == "1/2" and v["rate_hz"] == 2.0
    assert len(s.sources.heard) == 1
