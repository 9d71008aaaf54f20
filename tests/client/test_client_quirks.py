"""The client copes with each model's quirks by itself, from the profile (no user flags), against
in-memory devices (no sockets): closed-loop pointing where angle commands are ignored (C11) or
nothing moves (detected), repeated stops (C13), no echo awaited where none comes (C13), host feeds
(C11: TIM, FAE + FAI), destinations and frame sizes (C11), the G-class header (C13), concurrent
stops, and the UDP stream lease renewal."""

from __future__ import annotations

import asyncio
import dataclasses
import datetime

import pytest

import topgimbal
from topgimbal.errors import FieldValueError, UnsupportedError
from topgimbal.protocol import get_model

pytestmark = pytest.mark.virtual


def overshoot(history, start: float, target: float, index: int) -> float:
    """How far past `target` an axis went, coming from `start` (degrees, 0 if never)."""
    sign = 1.0 if target > start else -1.0
    return max([0.0, *((p[index] - target) * sign for p in history)])


# -- pointing by rates -----------------------------------------------------------------------------


async def test_c11_points_by_closing_the_loop_over_rates(kinematic):
    dev = kinematic("C11")
    async with topgimbal.connect(dev.url, model="C11", timeout_s=0.5, host_feeds=False) as cam:
        att = await cam.point(40, -30)
        assert abs(att.yaw_deg - 40) <= 0.5 and abs(att.pitch_deg + 30) <= 0.5
        await asyncio.sleep(0.2)  # the gimbal has stopped where the answer said
        assert abs(dev.pos["yaw"] - 40) <= 0.5 and abs(dev.pos["pitch"] + 30) <= 0.5
        assert dev.vel == {"yaw": 0.0, "pitch": 0.0}
        att = await cam.point(-20, 5)  # and back the other way
        assert abs(att.yaw_deg + 20) <= 0.5 and abs(att.pitch_deg - 5) <= 0.5
    sent = {f.ident for f in dev.received}
    assert not sent & {"GAM", "GAY", "GAP", "GSM"}  # never what the C11 ignores
    assert {"GSY", "GSP"} <= sent
    assert overshoot(dev.history, 0.0, 40.0, 1) <= 1.0 and overshoot(dev.history, 0.0, -30.0, 2) <= 1.0


async def test_angle_commands_that_move_nothing_switch_pointing_to_rates(kinematic):
    dev = kinematic("C12", ignore_angles=True)  # firmware that echoes GAM and does nothing
    async with topgimbal.connect(dev.url, model="C12", timeout_s=0.5, check_model=False) as cam:
        await cam.attitude_stream(20)
        att = await cam.point(10, -8)
        assert abs(att.yaw_deg - 10) <= 0.5 and abs(att.pitch_deg + 8) <= 0.5
        assert cam.angles_ignored  # remembered: the next point() goes straight to rates
        dev.received.clear()
        await cam.point(0, 0)
        assert not any(f.ident == "GAM" for f in dev.received)
    assert overshoot(dev.history, 0.0, 10.0, 1) <= 1.0


async def test_angle_commands_that_work_are_used(kinematic):
    dev = kinematic("C12")
    async with topgimbal.connect(dev.url, model="C12", timeout_s=0.5, check_model=False) as cam:
        att = await cam.point(5, -5)
        assert abs(att.yaw_deg - 5) <= 0.5 and not cam.angles_ignored
    assert any(f.ident == "GAM" for f in dev.received) and not any(f.ident == "GSY" for f in dev.received)


async def test_c11_rates_go_one_axis_per_frame_and_angles_say_use_point(kinematic):
    dev = kinematic("C11")
    async with topgimbal.connect(dev.url, model="C11", timeout_s=0.5, host_feeds=False, check_model=False) as cam:
        await cam.rates(10, -5)
        assert [f.ident for f in dev.received[-2:]] == ["GSY", "GSP"]
        await asyncio.sleep(0.3)
        assert dev.pos["yaw"] > 1 and dev.pos["pitch"] < -0.5  # signs: the C11's GSY is inverted on the wire
        await cam.stop()
        assert dev.rate == {"yaw": 0.0, "pitch": 0.0}
        with pytest.raises(UnsupportedError, match="point"):
            await cam.set_angles(10, 10)


# -- stops, echoes ------------------------------------------------------------------------------------


async def test_c13_stops_three_times_and_waits_for_no_echo(fake):
    fake.dialect, fake.model = get_model("C13")
    url = fake.start_memory()
    fake.handler = lambda f: None if f.ident in fake.model.no_echo else fake.default(f)  # never echoes motion
    async with topgimbal.connect(url, model="C13", timeout_s=0.3, check_model=False) as cam:
        await cam.rates(5, 0)  # returns at once: no echo is awaited where none comes
        await cam.set_angles(10, -10)
        await cam.stop()
        assert cam.stats.timeouts == 0
        await asyncio.sleep(0.05)  # let the in-memory link deliver what was sent without waiting
    ptz = [f for f in fake.received if f.ident == "PTZ"]
    gsm = [
        f
        for f in fake.received
        if f.ident == "GSM" and f.data == fake.dialect.encode("GSM", yaw_rate_deg_s=0, pitch_rate_deg_s=0).data
    ]
    assert len(ptz) == 3 and len(gsm) == 3  # the profile's stop_repeats


async def test_other_models_stop_once_and_await_the_echo(fake):
    url = fake.start_memory()
    async with topgimbal.connect(url, model="C12", timeout_s=0.3, check_model=False) as cam:
        await cam.stop()
        assert cam.stop_repeats == 1 and cam.stats.replies == 2
    assert [f.ident for f in fake.received] == ["GSM", "PTZ"]


async def test_two_concurrent_stops_both_succeed(fake):
    url = fake.start_memory()
    async with topgimbal.connect(url, model="C13", timeout_s=0.3, check_model=False, echo_motion=True) as cam:
        await asyncio.gather(cam.stop(), cam.stop(), cam.stop())
        await asyncio.gather(cam.stop(), cam.rates(1, 1), cam.stop())
        assert cam.stats.timeouts == 0 and cam.stats.errors == 0


async def test_c13_long_gimbal_frames_use_the_upper_case_header(fake):
    fake.dialect, fake.model = get_model("C13")
    url = fake.start_memory()
    async with topgimbal.connect(url, model="C13", timeout_s=0.3, check_model=False) as cam:
        await cam.set_angles(10, -10)
        await asyncio.sleep(0.05)
    gam = next(f for f in fake.received if f.ident == "GAM")
    assert gam.header == "#TP" and len(gam.data) > 2


# -- C11: destinations, frame size, host feeds ----------------------------------------------------------


async def test_c11_digital_zoom_goes_to_m_and_frames_fit_its_size_limit(fake):
    fake.dialect, fake.model = get_model("C11")
    url = fake.start_memory()
    async with topgimbal.connect(url, model="C11", timeout_s=0.3, check_model=False, host_feeds=False) as cam:
        await cam.digital_zoom(2)
        assert fake.received[-1].ident == "DZM" and fake.received[-1].dst == "M"
    # Every C11 form fits its 28 bytes; a profile with a tighter limit refuses longer frames before sending.
    tight = dataclasses.replace(get_model("C11")[1], max_frame_bytes=16)
    async with topgimbal.connect(url, model=tight, timeout_s=0.3, check_model=False, host_feeds=False) as cam:
        sent = len(fake.received)
        with pytest.raises(FieldValueError, match="16 bytes"):
            await cam.vehicle_attitude(1, 2, 3)  # FAI: 12 data characters, 24 bytes in all
        assert len(fake.received) == sent


async def test_c11_gets_its_clock_and_the_vehicle_attitude_without_being_asked(fake):
    fake.dialect, fake.model = get_model("C11")
    url = fake.start_memory()
    async with topgimbal.connect(url, model="C11", timeout_s=0.3, check_model=False) as cam:
        for _ in range(100):
            if any(f.ident == "TIM" for f in fake.received):
                break
            await asyncio.sleep(0.02)
        tim = fake.dialect.decode(next(f for f in fake.received if f.ident == "TIM")).fields["time"]
        now = datetime.datetime.now(datetime.timezone.utc).replace(tzinfo=None)
        assert abs((tim - now).total_seconds()) < 5  # UTC, now
        assert not any(f.ident in ("FAE", "FAI") for f in fake.received)  # no attitude given yet
        await cam.vehicle_attitude(yaw_deg=90, pitch_deg=5, roll_deg=-2)
        for _ in range(100):
            if sum(f.ident == "FAI" for f in fake.received) >= 3:
                break
            await asyncio.sleep(0.02)
        idents = [f.ident for f in fake.received if f.ident in ("FAE", "FAI")]
        assert idents[0] == "FAE" and idents.count("FAE") == 1 and idents.count("FAI") >= 3
        fai = fake.dialect.decode(next(f for f in fake.received if f.ident == "FAI")).fields
        assert (fai["yaw_deg"], fai["pitch_deg"], fai["roll_deg"]) == (90.0, 5.0, -2.0)
        assert cam.feeds.sent["FAI"] >= 3 and cam.stats.late_replies == 0  # their echoes are not "late"


async def test_host_feeds_can_be_turned_off_and_other_models_have_none(fake):
    fake.dialect, fake.model = get_model("C11")
    url = fake.start_memory()
    async with topgimbal.connect(url, model="C11", timeout_s=0.3, check_model=False, host_feeds=False) as cam:
        await asyncio.sleep(1.2)
        await cam.vehicle_attitude(0, 0, 0)  # sent once, acknowledged
    assert [f.ident for f in fake.received] == ["FAI"]
    other = type(fake)("C12")
    url = other.start_memory()
    async with topgimbal.connect(url, model="C12", timeout_s=0.3, check_model=False) as cam:
        await asyncio.sleep(1.2)
    assert other.received == []
    await other.stop()


# -- the stream's UDP lease ----------------------------------------------------------------------------


async def test_a_running_stream_renews_its_request(fake):
    url = fake.start_memory()
    async with topgimbal.connect(url, model="C12", timeout_s=0.3, check_model=False, stream_renew_s=0.2) as cam:
        async with cam.attitude(20) as stream:
            async for _ in stream:
                if cam.streams.renewals >= 2:
                    break
        gaa = [f for f in fake.received if f.ident == "GAA"]
        assert len(gaa) >= 4 and gaa[-1].data == b"00"  # on, renewed twice (or more), off


@pytest.mark.loopback
@pytest.mark.parametrize("renew_s, forgotten", [(0.3, False), (None, True)], ids=["renewed", "not-renewed"])
async def test_a_long_udp_stream_outlives_the_simulators_peer_lease(renew_s, forgotten):
    """The simulator forgets a UDP peer it has not heard from for a lease (1.5 s here, 60 s by
    default, like NAT and firewalls); the client's periodic stream request keeps it known."""
    from topgimbal.sim import Simulator
    from topgimbal.sim.servers import Limits

    sim = Simulator("C12", limits=Limits(udp_lease_s=1.5))
    await sim.start(udp=[("127.0.0.1", 0)])
    try:
        async with topgimbal.connect(sim.url, model="C12", timeout_s=0.3, stream_renew_s=renew_s) as cam:
            got = 0
            async with cam.attitude(20) as stream:
                async for _ in stream:
                    got += 1
                    if got >= 80:  # 4 s at 20 Hz: more than two leases
                        break
            assert (cam.streams.renewals >= 5) is not forgotten
        assert (sim.server_counts["udp_forgotten_lease"] > 0) is forgotten
    finally:
        await sim.stop()
