"""PX4's two kinds of link to a MAVLink camera and gimbal, replayed in virtual time (issue 42).

What PX4 (main, 2026-03) does on each, from its source and from PX4 SITL:
- the gimbal-mode link (MAV_n_MODE "Gimbal", MNT_MODE_OUT 2): PX4 streams HEARTBEAT and
  AUTOPILOT_STATE_FOR_GIMBAL_DEVICE and handles only HEARTBEAT and the gimbal messages
  (mavlink_receiver.cpp handle_messages_in_gimbal_mode): it acks no command, so
  SET_MESSAGE_INTERVAL brings nothing, and no CAMERA_TRIGGER stream runs there;
- the onboard payload link (4000 B/s in SITL): PX4 acks SET_MESSAGE_INTERVAL, but sends SYSTEM_TIME
  every 3.2-3.9 s; per trigger (TRIG_INTERFACE 3, streams/CAMERA_TRIGGER.hpp) it sends
  CAMERA_TRIGGER, an IMAGE_START_CAPTURE (param3 1, param4 a sequence number; MavlinkCommandSender
  sends it again every 0.5 s, 3 times at most, until acked) and a DO_DIGICAM_CONTROL (param5 1) to
  each of the camera ids 100-105, and its camera_feedback reports its own CAMERA_IMAGE_CAPTURED."""

from __future__ import annotations

import asyncio
import logging
import math
import random
from typing import Any

import pytest
from pymavlink.dialects.v20 import common as ml

from topgimbal.clock import monotonic
from topgimbal.mavlink import autopilot_streams, stream_rates

from .virtual import MemPeer, close_all, fresh_name, start_bridge, start_camera

pytestmark = pytest.mark.virtual

CAMERA = 100
LAT0, LON0 = 47.397742, 8.545594
SPEED_M_S = 10.0  # north
METRES_PER_DEG = math.pi / 180 * 6371008.8
UTC0_S = 1_790_000_000.0  # PX4's UTC at t0: far from our wall clock, so a photo dated by ours shows


class Px4:
    """PX4 (1/1) on one link: `mode` "gimbal" or "onboard", as described above."""

    def __init__(self, mode: str, rng: random.Random) -> None:
        self.mode, self.rng = mode, rng
        self.peer = MemPeer(sysid=1, compid=1)
        self.t0 = monotonic()
        self.triggers = 0
        self.sequence = 1
        self.time_gaps_s: list[float] = []
        self.capture_acked_s: dict[int, float] = {}  # camera id -> when it last acked IMAGE_START_CAPTURE
        self.acks_to_lose = 0  # the camera's next N IMAGE_START_CAPTURE acks are lost (a lossy link)
        self.resent_to_us = 0  # IMAGE_START_CAPTUREs sent again to the bridge's camera (unacked in 0.5 s)
        self.tasks: list[asyncio.Future[Any]] = []

    async def join(self, link: str) -> Px4:
        await self.peer.join(link, heartbeat=False)
        self.peer._got = self._got  # type: ignore[method-assign]
        self.tasks.append(asyncio.ensure_future(self._streams()))
        return self

    def utc_s(self, t: float) -> float:
        return UTC0_S + (t - self.t0)

    def north_m(self, t: float) -> float:
        return SPEED_M_S * (t - self.t0)

    def _got(self, m: Any) -> None:
        self.peer.messages.append(m)
        kind = m.get_type()
        if self.mode == "gimbal":
            return  # handle_messages_in_gimbal_mode: no command is handled, none acked
        if kind == "COMMAND_LONG" and m.target_system == 1 and m.target_component == 1:
            self.peer.send(ml.MAVLink_command_ack_message(m.command, 0, 0, 0, m.get_srcSystem(), m.get_srcComponent()))
        if kind == "COMMAND_ACK" and m.command == ml.MAV_CMD_IMAGE_START_CAPTURE and m.get_srcComponent() == CAMERA:
            if self.acks_to_lose > 0:
                self.acks_to_lose -= 1
                return
            self.capture_acked_s[m.get_srcComponent()] = monotonic()

    async def _streams(self) -> None:
        i = 0
        next_time_s = monotonic()
        while True:
            now = monotonic()
            if i % 4 == 0:
                self.peer.send(ml.MAVLink_heartbeat_message(2, 12, 0, 0, 4, 3))  # a quadrotor, PX4
            if self.mode == "gimbal":
                q = [1.0, 0.0, 0.0, 0.0]
                self.peer.send(ml.MAVLink_autopilot_state_for_gimbal_device_message(
                    0, 0, int(now * 1e6), q, 0, SPEED_M_S, 0, 0, 0, 0, 0, 0, 0))  # fmt: skip
            else:
                lat = LAT0 + self.north_m(now) / METRES_PER_DEG
                self.peer.send(ml.MAVLink_global_position_int_message(int(now * 1000), round(lat * 1e7),
                               round(LON0 * 1e7), 500_000, 20_000, int(SPEED_M_S * 100), 0, 0, 0))  # fmt: skip
                if now >= next_time_s:  # what 4000 B/s leaves for SYSTEM_TIME
                    self.peer.send(ml.MAVLink_system_time_message(int(self.utc_s(now) * 1e6), int(now * 1000)))
                    gap_s = self.rng.uniform(3.2, 3.9)
                    self.time_gaps_s.append(gap_s)
                    next_time_s = now + gap_s
            i += 1
            await asyncio.sleep(0.25)

    async def trigger(self) -> None:
        """One of PX4's camera triggers on this link, as CAMERA_TRIGGER.hpp sends it."""
        self.triggers += 1
        self.peer.send(ml.MAVLink_camera_trigger_message(int(monotonic() * 1e6), self.triggers))
        for camera in range(CAMERA, CAMERA + 6):
            seq = self.sequence
            self.sequence += 1
            start = ml.MAVLink_command_long_message(1, camera, ml.MAV_CMD_IMAGE_START_CAPTURE, 0, 0, 0, 1, seq,
                                                    math.nan, math.nan, math.nan)  # fmt: skip
            self.peer.send(start)
            self.tasks.append(asyncio.ensure_future(self._retransmit(start, camera)))
            self.peer.send(ml.MAVLink_command_long_message(1, camera, ml.MAV_CMD_DO_DIGICAM_CONTROL, 0, math.nan,
                           math.nan, math.nan, math.nan, 1, math.nan, math.nan))  # fmt: skip
        # camera_feedback's own record of the trigger, from 1/1 (index from 0, as the bridge's)
        self.peer.send(ml.MAVLink_camera_image_captured_message(0, int(self.utc_s(monotonic()) * 1e6), 0, 0, 0, 0,
                       0, [1, 0, 0, 0], self.triggers - 1, 1, b""))  # fmt: skip

    async def _retransmit(self, start: Any, camera: int) -> None:
        sent_s = monotonic()
        for _ in range(3):  # MavlinkCommandSender: TIMEOUT_US 0.5 s, RETRIES 3
            await asyncio.sleep(0.5)
            if self.capture_acked_s.get(camera, -math.inf) >= sent_s:
                return
            self.peer.send(start)
            self.resent_to_us += camera == CAMERA

    def close(self) -> None:
        for t in self.tasks:
            t.cancel()
        self.peer.close()


async def _bridge(links: list[str]) -> tuple[Any, Any]:
    sim, url = await start_camera("C12")
    made = await start_bridge(url, "C12", links[0], role="device", endpoints=[f"memory:{n}" for n in links],
                              stream_hz=5.0, attitude_hz=1.0)  # fmt: skip
    return sim, made


def _photos(peer: MemPeer) -> list[Any]:
    return [m for m in peer.peer.messages if m.get_type() == "CAMERA_IMAGE_CAPTURED"]


def _acks(px4: Px4, command: int) -> list[Any]:
    return [m for m in px4.peer.messages if m.get_type() == "COMMAND_ACK" and m.command == command
            and m.get_srcComponent() == CAMERA]  # fmt: skip


async def test_the_gimbal_mode_link_is_named_and_asked_ever_more_rarely(caplog: Any) -> None:
    """PX4 acks nothing on its gimbal-mode link: the bridge says so once (what it means, what to
    do) and asks 7 times a minute per message, not 12."""
    caplog.set_level(logging.INFO, logger="topgimbal.mavlink")
    gimbal = fresh_name("px4gimbal")
    sim, made = await _bridge([gimbal])
    px4 = await Px4("gimbal", random.Random(1)).join(gimbal)
    try:
        await asyncio.sleep(60.0)
        asks = [m for m in px4.peer.messages if m.get_type() == "COMMAND_LONG" and m.command == 511 and m.param1 == 2]
        said = [r.getMessage() for r in caplog.records if "gimbal-mode link" in r.getMessage()]
        assert len(said) == 1, said
        assert "PX4 onboard link" in said[0] and "GLOBAL_POSITION_INT" in said[0]
        # 3 asks 5 s apart, then waits of 10, 20, 40 s: asked at about 1, 6, 11, 21, 41 s
        assert len(asks) == 5, len(asks)
        status = made.streams.status()["SYSTEM_TIME"]
        assert status["stale"] and status["age_s"] is None
    finally:
        px4.close()
        await close_all([made, sim])


async def test_px4_on_both_links_photos_carry_its_position_and_utc_one_per_trigger(caplog: Any) -> None:
    """The bridge on PX4's gimbal-mode link and its onboard link: every photo PX4 triggers is one
    photo, within 1 m of PX4's position and 0.1 s of its UTC; SYSTEM_TIME every 3.2-3.9 s is not
    called stale over 60 s; the DO_DIGICAM_CONTROL next to each trigger and the retransmissions of
    IMAGE_START_CAPTURE take no second photo."""
    caplog.set_level(logging.INFO, logger="topgimbal.mavlink")
    gimbal, onboard = fresh_name("px4gimbal"), fresh_name("px4onboard")
    sim, made = await _bridge([gimbal, onboard])
    px4_gimbal = await Px4("gimbal", random.Random(2)).join(gimbal)
    px4 = await Px4("onboard", random.Random(3)).join(onboard)
    px4.t0 = px4_gimbal.t0
    px4.acks_to_lose = 3  # PX4 sends those captures again: still one photo each
    shutters: list[float] = []
    sim.device.state.capture_listeners.append(lambda event, index: shutters.append(monotonic()))
    try:
        await asyncio.sleep(5.0)
        for _ in range(6):  # 1 s triggers, as TRIG_MODE 1 with TRIG_INTERV 1000 ms
            await px4.trigger()
            await asyncio.sleep(1.0)
        await asyncio.sleep(50.0)  # 61 s in all
        # a capture sent again is answered with its photo's record again (same index): one photo
        by_index = {m.image_index: m for m in _photos(px4) if m.get_srcComponent() == CAMERA}
        assert sorted(by_index) == list(range(px4.triggers)) and px4.triggers == 6, sorted(by_index)
        ours = [by_index[i] for i in sorted(by_index)]
        assert len(shutters) == 6  # the camera itself took six, not one more
        assert px4.resent_to_us >= 2  # (one resend may come while the photo is still being taken)
        digicam_acks = [m for m in _acks(px4, ml.MAV_CMD_DO_DIGICAM_CONTROL)]
        # the old trigger command next to the new one: never a photo, answered UNSUPPORTED
        assert digicam_acks and all(m.result == ml.MAV_RESULT_UNSUPPORTED for m in digicam_acks)
        assert len(_acks(px4, ml.MAV_CMD_IMAGE_START_CAPTURE)) >= 6
        for m, shutter in zip(ours, shutters, strict=True):
            error_m = abs((m.lat / 1e7 - LAT0) * METRES_PER_DEG - px4.north_m(shutter))
            time_error_s = abs(m.time_utc / 1e6 - px4.utc_s(shutter))
            assert error_m < 1.0, f"photo {m.image_index}: {error_m:.2f} m from PX4's position"
            assert time_error_s < 0.1, f"photo {m.image_index}: {time_error_s:.3f} s from PX4's UTC"
        assert max(px4.time_gaps_s) > autopilot_streams.WANTED[1].stale_s  # slower than the fixed guess
        stale = [r.getMessage() for r in caplog.records if "go stale" in r.getMessage()]
        assert stale == []
        assert not made.streams.status()["SYSTEM_TIME"]["stale"]
        assert not any("gimbal-mode link" in r.getMessage() for r in caplog.records)  # the onboard one answers
    finally:
        px4.close()
        px4_gimbal.close()
        await close_all([made, sim])


async def test_a_stream_that_stops_still_goes_stale_after_twice_its_longest_gap(caplog: Any) -> None:
    caplog.set_level(logging.INFO, logger="topgimbal.mavlink")
    onboard = fresh_name("px4onboard")
    sim, made = await _bridge([onboard])
    px4 = await Px4("onboard", random.Random(4)).join(onboard)
    try:
        await asyncio.sleep(30.0)
        px4.tasks[0].cancel()  # PX4 goes quiet
        heard_s = made.streams.heard["SYSTEM_TIME"]
        sent_gaps_s = px4.time_gaps_s[:-1]  # the last one was never waited out
        limit_s = stream_rates.GAP_MARGIN * max(sent_gaps_s[-stream_rates.GAPS_KEPT :])
        stale_at: float | None = None
        while stale_at is None and monotonic() - heard_s < 30.0:
            await asyncio.sleep(0.05)
            if any("no SYSTEM_TIME" in r.getMessage() for r in caplog.records):
                stale_at = monotonic()
        assert stale_at is not None, "never called stale"
        # the gaps the bridge measured are PX4's within the 0.25 s the replay sends at
        assert limit_s - 0.6 < stale_at - heard_s <= limit_s + 0.6 + autopilot_streams.CHECK_S
        assert made.streams.status()["SYSTEM_TIME"]["stale"]
    finally:
        px4.close()
        await close_all([made, sim])
