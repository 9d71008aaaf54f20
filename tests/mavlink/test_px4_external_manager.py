"""PX4's external-manager output (MNT_MODE_OUT 3, PX4 #28059, src/modules/gimbal/
output_gimbal_manager.cpp) replayed against the bridge in role `manager` (issue 42, item 4).

PX4's flow: wait for the manager's GIMBAL_MANAGER_INFORMATION or STATUS; while it has a setpoint,
DO_GIMBAL_MANAGER_CONFIGURE with itself as primary (secondary -1/-1 "leave"), again every 3 s
(kAcquireRetryInterval) until the status names it, and again whenever the status names someone else
(a steal); in control, stream GIMBAL_MANAGER_SET_PITCHYAW (PITCH_LOCK, YAW_LOCK |
YAW_IN_EARTH_FRAME for absolute angles); idle, DO_GIMBAL_MANAGER_CONFIGURE -2/-2, which PX4 means as
"release". MAVLink says -2 is "set itself in control": the bridge does what MAVLink says, so PX4
stays primary after its "release" and a ground station takes control with its own -2
(docs/mavlink.md, PX4's external-manager mode)."""

from __future__ import annotations

import asyncio
import math
from typing import Any

import pytest
from pymavlink.dialects.v20 import common as ml

from topgimbal.clock import monotonic

from .virtual import MemPeer

pytestmark = pytest.mark.virtual

GIMBAL = 154
LAT, LON = 47.397742, 8.545594
HEADING_DEG = 90.0  # the vehicle faces east
ACQUIRE_RETRY_S = 3.0  # kAcquireRetryInterval
LOCKS = ml.GIMBAL_MANAGER_FLAGS_PITCH_LOCK | ml.GIMBAL_MANAGER_FLAGS_YAW_LOCK
EARTH = LOCKS | ml.GIMBAL_MANAGER_FLAGS_YAW_IN_EARTH_FRAME


class Px4Client:
    """OutputToGimbalManager's state machine, on PX4 1/1's link to the bridge."""

    def __init__(self) -> None:
        self.peer = MemPeer(sysid=1, compid=1)
        self.manager: tuple[int, int, int] | None = None  # sysid, compid, gimbal device id
        self.state = "released"
        self.setpoint: tuple[float, float] | None = None  # pitch, earth yaw (deg); None = idle
        self.last_acquire_s = -math.inf
        self.configures: list[tuple[float, float]] = []
        self.tasks: list[asyncio.Future[Any]] = []

    async def join(self, link: str) -> Px4Client:
        await self.peer.join(link, heartbeat=False)
        self.tasks.append(asyncio.ensure_future(self._run()))
        return self

    def primary(self) -> tuple[int, int] | None:
        st = next((m for m in reversed(self.peer.messages) if m.get_type() == "GIMBAL_MANAGER_STATUS"), None)
        return None if st is None else (st.primary_control_sysid, st.primary_control_compid)

    def _configure(self, acquire: bool) -> None:
        assert self.manager is not None
        p = (1.0, 1.0) if acquire else (-2.0, -2.0)
        self.configures.append(p)
        self.peer.send(ml.MAVLink_command_long_message(self.manager[0], self.manager[1],
                       ml.MAV_CMD_DO_GIMBAL_MANAGER_CONFIGURE, 0, *p, -1, -1, 0, 0, self.manager[2]))  # fmt: skip

    async def _run(self) -> None:
        i = 0
        while True:
            now = monotonic()
            if i % 10 == 0:
                self.peer.send(ml.MAVLink_heartbeat_message(2, 12, 0, 0, 4, 3))
            hdg = math.radians(HEADING_DEG)
            self.peer.send(ml.MAVLink_attitude_message(int(now * 1000), 0, 0, hdg, 0, 0, 0))
            self.peer.send(ml.MAVLink_global_position_int_message(int(now * 1000), int(LAT * 1e7), int(LON * 1e7),
                           500_000, 20_000, 0, 0, 0, int(HEADING_DEG * 100)))  # fmt: skip
            if self.manager is None:
                st = next((m for m in self.peer.messages if m.get_type() == "GIMBAL_MANAGER_STATUS"), None)
                if st is not None:
                    self.manager = (st.get_srcSystem(), st.get_srcComponent(), st.gimbal_device_id)
            else:
                self._step(now)
            i += 1
            await asyncio.sleep(0.1)

    def _step(self, now: float) -> None:
        assert self.manager is not None
        mine = self.primary() == (1, 1)
        if self.setpoint is None:
            if self.state != "released":
                self._configure(False)
                self.state = "released"
            return
        if self.state == "released":
            self._configure(True)
            self.last_acquire_s, self.state = now, "acquiring"
        elif self.state == "acquiring":
            if mine:
                self.state = "in control"
            elif now - self.last_acquire_s > ACQUIRE_RETRY_S:
                self._configure(True)
                self.last_acquire_s = now
        elif not mine:  # someone took control: ask for it again
            self._configure(True)
            self.last_acquire_s, self.state = now, "acquiring"
        if self.state == "in control":
            pitch, yaw = self.setpoint
            self.peer.send(ml.MAVLink_gimbal_manager_set_pitchyaw_message(*self.manager[:2], EARTH, self.manager[2],
                           math.radians(pitch), math.radians(yaw), math.nan, math.nan))  # fmt: skip

    def close(self) -> None:
        for t in self.tasks:
            t.cancel()
        self.peer.close()


async def _until(check: Any, timeout_s: float) -> float:
    t0 = monotonic()
    while not check():
        assert monotonic() - t0 < timeout_s, f"not within {timeout_s} s"
        await asyncio.sleep(0.05)
    return monotonic() - t0


async def test_px4_external_manager_flow(vrig_maker: Any) -> None:
    vrig = await vrig_maker("C12", role="manager")
    gcs, gimbal = vrig.peer, vrig.sim.gimbal
    px4 = await Px4Client().join(vrig.link)
    try:
        await _until(lambda: px4.manager is not None, 5.0)
        assert px4.manager is not None and px4.manager[1] == GIMBAL
        # a setpoint: pitch -30, yaw 120 deg in the earth frame = 30 deg right of the nose (east)
        px4.setpoint = (-30.0, 120.0)
        took_s = await _until(lambda: px4.state == "in control", 2.0)
        assert px4.configures == [(1.0, 1.0)] and took_s < 1.0
        await _until(lambda: abs(gimbal.yaw_deg - 30.0) < 0.5 and abs(gimbal.pitch_deg + 30.0) < 0.5, 10.0)
        # a ground station takes control (steal) and points elsewhere: PX4 asks again at once
        ack = await gcs.ack(GIMBAL, ml.MAV_CMD_DO_GIMBAL_MANAGER_CONFIGURE, -2, -2, -1, -1, 0, 0, 0)
        assert ack.result == ml.MAV_RESULT_ACCEPTED
        back_s = await _until(lambda: px4.primary() == (1, 1) and px4.state == "in control", 2.0)
        assert back_s < 1.0 and px4.configures == [(1.0, 1.0)] * 2
        denied = await gcs.ack(GIMBAL, ml.MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW, -10, 0, math.nan, math.nan, 0, 0, 0)
        assert denied.result == ml.MAV_RESULT_DENIED  # PX4 is primary again
        px4.setpoint = (-45.0, 60.0)  # PX4's new setpoint: 30 deg left of the nose
        await _until(lambda: abs(gimbal.yaw_deg + 30.0) < 0.5 and abs(gimbal.pitch_deg + 45.0) < 0.5, 10.0)
        # idle: PX4 sends -2/-2 ("release" to PX4, "set itself in control" to MAVLink)
        px4.setpoint = None
        await _until(lambda: px4.configures[-1] == (-2.0, -2.0), 2.0)
        await asyncio.sleep(1.0)
        assert vrig.bridge.manager.primary == (1, 1) and len(px4.configures) == 3
        # the ground station takes control itself and steers; PX4, idle, does not take it back
        ack = await gcs.ack(GIMBAL, ml.MAV_CMD_DO_GIMBAL_MANAGER_CONFIGURE, -2, -2, -1, -1, 0, 0, 0)
        assert ack.result == ml.MAV_RESULT_ACCEPTED
        ack = await gcs.ack(GIMBAL, ml.MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW, -10, 5, math.nan, math.nan, 0, 0, 0)
        assert ack.result == ml.MAV_RESULT_ACCEPTED
        await _until(lambda: abs(gimbal.yaw_deg - 5.0) < 0.5 and abs(gimbal.pitch_deg + 10.0) < 0.5, 10.0)
        await asyncio.sleep(ACQUIRE_RETRY_S * 2)
        assert vrig.bridge.manager.primary == (gcs.mav.srcSystem, gcs.mav.srcComponent)
        assert len(px4.configures) == 3
    finally:
        px4.close()
