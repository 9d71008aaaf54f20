"""Geotags with ArduPilot's defaults (issue 32, item 3): the bridge asks the autopilot on its own
link for GLOBAL_POSITION_INT and SYSTEM_TIME, says what is fed and warns when it goes stale, never
publishes 0, 0 as a position, and stamps a photo with the position at the shutter (interpolated
between fixes, carried forward at the velocity), not the last fix heard."""

from __future__ import annotations

import asyncio
import itertools
import logging
import math
from typing import Any

import pytest
from pymavlink.dialects.v20 import common as ml

from topgimbal.clock import monotonic, wall_time
from topgimbal.mavlink import autopilot_streams

from .conftest import Peer, eventually
from .virtual import MemPeer, in_virtual_time

pytestmark = pytest.mark.external

CAMERA = 100
LAT0, LON0 = 47.397742, 8.545594
SPEED_M_S = 10.0  # north
METRES_PER_DEG = math.pi / 180 * 6371008.8


async def captured(peer: Peer, index: int) -> Any:
    def find() -> Any:
        return next(
            (m for m in peer.messages if m.get_type() == "CAMERA_IMAGE_CAPTURED" and m.image_index == index), None
        )

    await eventually(lambda: find() is not None, 5, f"CAMERA_IMAGE_CAPTURED {index}")
    return find()


def _interval_requests(peer: Peer, msgid: int) -> list[Any]:
    return [m for m in peer.messages if m.get_type() == "COMMAND_LONG" and m.command == 511 and m.param1 == msgid]


async def test_the_bridge_asks_the_autopilot_for_what_photos_need(
    rig_factory: Any, caplog: Any, monkeypatch: Any
) -> None:
    monkeypatch.setattr(autopilot_streams, "RETRY_S", 1.0)
    caplog.set_level(logging.INFO, logger="topgimbal.mavlink")
    r = await rig_factory("C12", role="device")
    autopilot = await Peer(sysid=1, compid=1).connect(r.bridge.addresses[0][1])
    gcs = r.peer  # a ground station (MAV_AUTOPILOT_INVALID): nothing is asked of it
    try:
        autopilot.send(ml.MAVLink_heartbeat_message(2, 3, 0, 0, 4, 3))  # a quadrotor, ArduPilot
        await eventually(lambda: bool(_interval_requests(autopilot, 33)) and bool(_interval_requests(autopilot, 2)),
                         5, "SET_MESSAGE_INTERVAL for GLOBAL_POSITION_INT and SYSTEM_TIME")  # fmt: skip
        assert all(m.target_system == 1 and m.target_component == 1 for m in _interval_requests(autopilot, 33))
        assert _interval_requests(autopilot, 33)[0].param2 == 100_000  # 10 Hz
        assert any(m.get_type() == "REQUEST_DATA_STREAM" and m.req_stream_id == 6 for m in autopilot.messages)
        assert r.bridge.streams.status()["GLOBAL_POSITION_INT"]["age_s"] is None
        # the autopilot answers: the position is fed, nothing more is asked for it
        for i in range(15):
            autopilot.send(ml.MAVLink_global_position_int_message(i * 100, int(LAT0 * 1e7), int(LON0 * 1e7),
                                                                  500_000, 20_000, 0, 0, 0, 9000))  # fmt: skip
            await asyncio.sleep(0.1)
        asked = len(_interval_requests(autopilot, 33))
        status = r.bridge.streams.status()["GLOBAL_POSITION_INT"]
        assert status["source"] == "1/1" and status["age_s"] is not None and status["age_s"] < 1 and not status["stale"]
        assert any("GLOBAL_POSITION_INT from 1/1" in rec.getMessage() for rec in caplog.records)
        info = r.bridge.info()
        assert info["autopilot"]["GLOBAL_POSITION_INT"]["source"] == "1/1" and isinstance(info["camera_feeds"], str)
        # it stops: a warning, and the bridge asks again
        await eventually(lambda: len(_interval_requests(autopilot, 33)) > asked, 6, "asked again once stale")
        assert any(
            rec.levelno == logging.WARNING and "no GLOBAL_POSITION_INT" in rec.getMessage() for rec in caplog.records
        )
        assert not [m for m in gcs.messages if m.get_type() == "COMMAND_LONG" and m.target_system == 255]
    finally:
        autopilot.close()


@pytest.mark.virtual
@in_virtual_time  # a closed loop on the clock (a vehicle at 10 m/s): on a loaded machine real time
# put the camera's own tag 2.8 m off; in virtual time the product's timing is what is measured
@pytest.mark.parametrize(
    ("boot_clock", "late_s"),
    [(False, 0.0),  # time_boot_ms a message counter: the fixes are dated by their arrival
     (True, 0.25)],  # a slow, queueing link (PX4's payload link): each fix 10-250 ms late, dated by its time_boot_ms
)  # fmt: skip
async def test_a_photo_carries_the_position_at_the_shutter_and_the_autopilots_time(
    vrig_maker: Any, boot_clock: bool, late_s: float
) -> None:
    r = await vrig_maker("C12", role="device")
    autopilot = await MemPeer(sysid=1, compid=1).join(r.link)
    shutters: list[float] = []
    fed: list[float | None] = []  # the latitude the camera itself was fed at its shutter (its EXIF)
    state = r.sim.device.state

    def on_capture(event: str, index: int) -> None:
        shutters.append(monotonic())
        fed.append(state.position.lat_deg)

    state.capture_listeners.append(on_capture)
    # the autopilot's clock: a day ahead of ours, so a photo dated by our clock would show it; it
    # runs on the (virtual) clock the product measures intervals with
    t0 = monotonic()
    utc0 = wall_time() + 86400.0

    def autopilot_utc(t: float) -> float:
        return utc0 + (t - t0)

    def north_m(t: float) -> float:
        return SPEED_M_S * (t - t0)

    async def fly() -> None:
        i = 0
        while True:  # GLOBAL_POSITION_INT at 5 Hz, flying north at 10 m/s; SYSTEM_TIME at 1 Hz
            now = monotonic()
            lat = LAT0 + north_m(now) / METRES_PER_DEG
            boot_ms = round((now - t0 + 100.0) * 1000) if boot_clock else i
            fix = ml.MAVLink_global_position_int_message(boot_ms, round(lat * 1e7), round(LON0 * 1e7), 500_000,
                                                         20_000, int(SPEED_M_S * 100), 0, 0, 0)  # fmt: skip
            if late_s:  # a different delay each (the quickest 10 ms): what the bridge cannot tell by arrival
                asyncio.get_running_loop().call_later(0.01 + (i * 7 % 10) / 9 * (late_s - 0.01), autopilot.send, fix)
            else:
                autopilot.send(fix)
            if i % 5 == 0:
                autopilot.send(ml.MAVLink_system_time_message(int(autopilot_utc(now) * 1e6), i))
            i += 1
            await asyncio.sleep(0.2)

    task = asyncio.ensure_future(fly())
    try:
        # (the bridge trusts an autopilot's time_boot_ms once it has kept time for a second)
        await asyncio.sleep(3.0 if boot_clock else 1.0)
        for n in range(3):
            await asyncio.sleep(0.13 * n)  # between fixes, not on them
            ack = await r.peer.ack(CAMERA, ml.MAV_CMD_IMAGE_START_CAPTURE, 0, 0, 1, n + 1)
            assert ack.result == ml.MAV_RESULT_ACCEPTED
            got = await captured(r.peer, n)
            shutter = shutters[-1]
            error_m = abs((got.lat / 1e7 - LAT0) * METRES_PER_DEG - north_m(shutter))
            time_error_s = abs(got.time_utc / 1e6 - autopilot_utc(shutter))
            own = fed[-1]
            own_m = abs((own - LAT0) * METRES_PER_DEG - north_m(shutter)) if own is not None else math.nan
            print(f"photo {n}: position error {error_m:.2f} m, time error {time_error_s:.3f} s; "
                  f"the camera's own tag {own_m:.2f} m")  # fmt: skip
            assert error_m < 1.0, f"photo {n}: {error_m:.2f} m from where the vehicle was at the shutter"
            assert time_error_s < 1.0, f"photo {n}: dated {time_error_s:.2f} s off the autopilot's UTC"
            assert abs(got.lon / 1e7 - LON0) < 1e-6 and got.relative_alt == 20_000
            # the camera's own tag (its EXIF): fed a position for the shutter right before the photo
            # (within 2 m: the frames paced ahead of the photo vary by +-50 ms, 0.5 m at 10 m/s; was 3-5.8 m)
            assert own_m < 2.0, f"photo {n}: the camera tagged it {own_m:.2f} m off"
    finally:
        task.cancel()
        autopilot.close()


async def test_no_fix_is_never_published_as_0_0(rig_factory: Any) -> None:
    r = await rig_factory("C12", role="device")
    autopilot = await Peer(sysid=1, compid=1).connect(r.bridge.addresses[0][1])
    try:
        for _ in range(3):  # what an autopilot sends before its first fix
            autopilot.send(ml.MAVLink_global_position_int_message(0, 0, 0, 0, 0, 0, 0, 0, 65535))
        await asyncio.sleep(0.2)
        ack = await r.peer.ack(CAMERA, ml.MAV_CMD_IMAGE_START_CAPTURE, 0, 0, 1, 1)
        assert ack.result == ml.MAV_RESULT_ACCEPTED
        got = await captured(r.peer, 0)
        assert (got.lat, got.lon, got.alt) == (2**31 - 1, 2**31 - 1, 2**31 - 1)
        assert r.bridge.feed.sample().fix is None
    finally:
        autopilot.close()


@pytest.mark.virtual
@in_virtual_time
async def test_virtual_the_autopilot_is_asked_again_on_the_products_schedule(vrig_maker: Any, caplog: Any) -> None:
    """The same in virtual time with the product's own timers (CHECK_S 1 s, RETRY_S 5 s, not
    shortened): unanswered, the request is repeated exactly every RETRY_S; answered, never; the
    stream stopped, a warning once it is stale_s old and the request again at the next check."""
    caplog.set_level(logging.INFO, logger="topgimbal.mavlink")
    # the camera's attitude slower than by default: a minute of it costs real CPU even in virtual time
    vrig = await vrig_maker("C12", role="device", stream_hz=5.0, attitude_hz=1.0)
    autopilot = await MemPeer(sysid=1, compid=1).join(vrig.link)
    asked_at: list[float] = []
    inner = autopilot._got

    def got(m: Any) -> None:
        if m.get_type() == "COMMAND_LONG" and m.command == 511 and m.param1 == 33:
            asked_at.append(monotonic())
            # acked as autopilots do (one that acks nothing is asked ever more rarely: test_px4_links)
            autopilot.send(ml.MAVLink_command_ack_message(511, 0, 0, 0, m.get_srcSystem(), m.get_srcComponent()))
        inner(m)

    autopilot._got = got  # type: ignore[method-assign]
    position = next(w for w in autopilot_streams.WANTED if w.name == "GLOBAL_POSITION_INT")
    try:
        t0 = monotonic()
        autopilot.send(ml.MAVLink_heartbeat_message(2, 3, 0, 0, 4, 3))  # a quadrotor, ArduPilot
        await asyncio.sleep(30.0)
        assert asked_at and asked_at[0] - t0 <= autopilot_streams.CHECK_S + 0.01
        gaps = [b - a for a, b in itertools.pairwise(asked_at)]
        assert gaps == pytest.approx([autopilot_streams.RETRY_S] * len(gaps), abs=0.01), asked_at
        assert len(asked_at) == 1 + int((30.0 - (asked_at[0] - t0)) // autopilot_streams.RETRY_S)
        # answered at 10 Hz for 20 s: not asked again
        n = len(asked_at)
        for i in range(200):
            autopilot.send(ml.MAVLink_global_position_int_message(i * 100, int(LAT0 * 1e7), int(LON0 * 1e7),
                                                                  500_000, 20_000, 0, 0, 0, 9000))  # fmt: skip
            await asyncio.sleep(0.1)
        assert len(asked_at) == n
        status = vrig.bridge.streams.status()["GLOBAL_POSITION_INT"]
        assert status["source"] == "1/1" and status["age_s"] <= 0.1 and not status["stale"]
        last_fix = monotonic() - 0.1
        await asyncio.sleep(10.0)  # it stops
        # stale once older than stale_s (2 s), asked again at the first check after that
        assert len(asked_at) > n
        assert position.stale_s < asked_at[n] - last_fix <= position.stale_s + autopilot_streams.CHECK_S + 0.01
        warnings = [
            r for r in caplog.records if r.levelno == logging.WARNING and "no GLOBAL_POSITION_INT" in r.getMessage()
        ]
        assert len(warnings) == 1
        assert not [m for m in vrig.peer.messages if m.get_type() == "COMMAND_LONG" and m.target_system == 255]
    finally:
        autopilot.close()
