"""Discovery as QGroundControl 5 and PX4 do it, replayed against the bridge (issue 22).

QGC (read in its public source: Camera/CameraDiscoveryStateMachine, Vehicle::sendMavCommand,
Gimbal/GimbalController):
- camera: on the first HEARTBEAT from a component that is MAV_TYPE_CAMERA (or has a camera
  component id), up to 10 requests for CAMERA_INFORMATION, alternating MAV_CMD_REQUEST_MESSAGE
  (even attempts) and the legacy MAV_CMD_REQUEST_CAMERA_INFORMATION (odd); each request is one
  command sent up to 3 times 1.2 s apart, always with confirmation 0, and waits 3 s for the
  message; between attempts a back-off of 0.1 s (odd attempt numbers) or 2^(n/2) s (even n >= 2);
  after 10 failed attempts it gives up, and the next HEARTBEAT from that component starts
  discovery again;
- gimbal: on every HEARTBEAT from any component, as long as it sent no GIMBAL_MANAGER_INFORMATION,
  a REQUEST_MESSAGE for it (6 per component); information or status naming gimbal device 0 is
  dropped; then SET_MESSAGE_INTERVAL for GIMBAL_MANAGER_STATUS (at most once a second, 6 times,
  the last two at 0.2 Hz) and for GIMBAL_DEVICE_ATTITUDE_STATUS (to the device's component, or
  the manager's for device ids 1..6; 3 times), until all three messages have come.
QGC's timers are replayed scaled by `time_scale` in real time (same order and ratios, bounded test
time), and as QGC has them in virtual time (memory links, looptime).

PX4 as gimbal manager (MNT_MODE_OUT = MAVLink gimbal v2, src/modules/gimbal/output_mavlink.cpp),
where it differs from ArduPilot: GIMBAL_DEVICE_INFORMATION is asked for by a broadcast
REQUEST_MESSAGE (target 0/0) every second until one comes; GIMBAL_DEVICE_SET_ATTITUDE carries only
the LOCK flags (never YAW_IN_VEHICLE_FRAME / YAW_IN_EARTH_FRAME), goes to target component 0 until
the device is known, and may carry angular velocities next to the quaternion."""

from __future__ import annotations

import asyncio
import math
from typing import Any

import pytest
from pymavlink.dialects.v20 import common as ml

from topgimbal.clock import monotonic
from topgimbal.mavlink import Bridge, BridgeConfig
from topgimbal.mavlink.quaternion import from_euler_deg
from topgimbal.sim import Simulator

from .conftest import NAN, Peer, eventually
from .virtual import MemPeer, fresh_name, in_virtual_time, start_bridge, start_camera

pytestmark = pytest.mark.external

TIME_SCALE = 0.15
ACK_TIMEOUT_S = 1.2
COMMAND_TRIES = 3
INFO_TIMEOUT_S = 3.0
CAMERA_ATTEMPTS = 10
GIMBAL, CAMERA, THERMAL = 154, 100, 101


def backoff_s(retry: int) -> float:
    return float(1 << (retry // 2)) if retry >= 2 and retry % 2 == 0 else 0.1


class Qgc(Peer):
    """The ground station side: its heartbeat, command sender and discovery logic."""

    def __init__(self, time_scale: float = TIME_SCALE) -> None:
        super().__init__(sysid=255, compid=190)
        self.time_scale = time_scale  # QGC's timers x this (1.0 in virtual time: QGC's own)
        self.cameras: dict[int, CameraDiscovery] = {}
        self.gimbal = GimbalDiscovery(self)
        self.sent: list[tuple[int, int, int]] = []  # (target component, command, param1)
        self.sent_at: list[float] = []  # when each of `sent` went out
        self._hb: asyncio.Task[None] | None = None

    async def start(self, port: int) -> Qgc:
        await self.connect(port)
        self._hb = asyncio.ensure_future(self._heartbeats())
        return self

    async def _heartbeats(self) -> None:
        while True:
            self.send(ml.MAVLink_heartbeat_message(ml.MAV_TYPE_GCS, ml.MAV_AUTOPILOT_INVALID, 0, 0, 4, 3))
            await asyncio.sleep(1.0)

    def close(self) -> None:
        if self._hb is not None:
            self._hb.cancel()
        for c in self.cameras.values():
            c.stop()
        for t in self.gimbal.tasks:
            t.cancel()
        super().close()

    def _got(self, m: Any) -> None:
        super()._got(m)
        if m.get_srcSystem() != 1:
            return
        kind, comp = m.get_type(), m.get_srcComponent()
        if kind == "HEARTBEAT":
            if m.type == ml.MAV_TYPE_CAMERA or CAMERA <= comp <= CAMERA + 5:
                self.cameras.setdefault(comp, CameraDiscovery(self, comp)).heartbeat()
            self.gimbal.heartbeat(comp)
        elif kind == "CAMERA_INFORMATION" and comp in self.cameras:
            self.cameras[comp].info = m
        self.gimbal.on_message(m)

    async def send_command(self, compid: int, command: int, *params: float) -> Any | None:
        """Vehicle::sendMavCommand: up to 3 sends ACK_TIMEOUT_S apart, confirmation 0 each time;
        the final ack, or None when none came."""
        for _ in range(COMMAND_TRIES):
            self.sent.append((compid, command, int(params[0]) if params else 0))
            self.sent_at.append(monotonic())
            try:
                return await self.ack(compid, command, *params, timeout=ACK_TIMEOUT_S * self.time_scale)
            except asyncio.TimeoutError:
                continue
        return None


class MemQgc(Qgc, MemPeer):
    """QGC on a `memory:` link (virtual time: its own timers, unscaled)."""

    async def start_on(self, link: str) -> MemQgc:
        await self.join(link)
        self._hb = asyncio.ensure_future(self._heartbeats())
        return self


class CameraDiscovery:
    def __init__(self, qgc: Qgc, compid: int) -> None:
        self.qgc, self.compid = qgc, compid
        self.info: Any = None
        self.attempts: list[int] = []  # the command used by each attempt, in order
        self.gave_up = 0
        self.starts = 0
        self._task: asyncio.Task[None] | None = None

    def heartbeat(self) -> None:
        if self.info is None and (self._task is None or self._task.done()):
            self.starts += 1
            self._task = asyncio.ensure_future(self._discover())

    def stop(self) -> None:
        if self._task is not None:
            self._task.cancel()

    async def _discover(self) -> None:
        retry = 0
        while retry < CAMERA_ATTEMPTS:
            if retry % 2 == 0:
                self.attempts.append(ml.MAV_CMD_REQUEST_MESSAGE)
                ack = await self.qgc.send_command(self.compid, ml.MAV_CMD_REQUEST_MESSAGE, 259)
            else:
                self.attempts.append(ml.MAV_CMD_REQUEST_CAMERA_INFORMATION)
                ack = await self.qgc.send_command(self.compid, ml.MAV_CMD_REQUEST_CAMERA_INFORMATION, 1)
            if ack is not None and ack.result == ml.MAV_RESULT_ACCEPTED:
                end = monotonic() + INFO_TIMEOUT_S * self.qgc.time_scale
                while self.info is None and monotonic() < end:
                    await asyncio.sleep(0.01)
            if self.info is not None:
                return
            retry += 1
            await asyncio.sleep(backoff_s(retry) * self.qgc.time_scale)
        self.gave_up += 1


class GimbalDiscovery:
    def __init__(self, qgc: Qgc) -> None:
        self.qgc = qgc
        self.info_retries: dict[int, int] = {}
        self.managers: dict[int, Any] = {}  # manager compid -> GIMBAL_MANAGER_INFORMATION
        self.status: set[int] = set()
        self.attitude: set[int] = set()
        self.status_retries = 6
        self.attitude_retries = 3
        self._last_status_request = 0.0
        self.dropped: list[str] = []
        self.tasks: list[asyncio.Task[Any]] = []

    def _send(self, compid: int, command: int, *params: float) -> None:
        # QGC sends these "without error display": nobody waits for their result
        self.tasks.append(asyncio.ensure_future(self.qgc.send_command(compid, command, *params)))

    def heartbeat(self, compid: int) -> None:
        left = self.info_retries.setdefault(compid, 6)
        if compid not in self.managers and left > 0:
            self.info_retries[compid] = left - 1
            self._send(compid, ml.MAV_CMD_REQUEST_MESSAGE, 280)

    def on_message(self, m: Any) -> None:
        kind, comp = m.get_type(), m.get_srcComponent()
        if kind == "GIMBAL_MANAGER_INFORMATION":
            if m.gimbal_device_id == 0:
                self.dropped.append(f"GIMBAL_MANAGER_INFORMATION from {comp} with device id 0")
                return
            self.managers[comp] = m
        elif kind == "GIMBAL_MANAGER_STATUS":
            if m.gimbal_device_id == 0:
                self.dropped.append(f"GIMBAL_MANAGER_STATUS from {comp} with device id 0")
                return
            self.status.add(comp)
        elif kind == "GIMBAL_DEVICE_ATTITUDE_STATUS":
            # device id 0: the sender's component id is the device id, looked up among the managers' devices
            device = comp if m.gimbal_device_id == 0 else m.gimbal_device_id
            if m.gimbal_device_id > 6:
                return
            owners = [c for c, info in self.managers.items() if info.gimbal_device_id == device]
            if m.gimbal_device_id == 0 and not owners:
                return
            self.attitude.add(owners[0] if owners else comp)
        else:
            return
        for manager in list(self.managers):
            self._check_complete(manager)

    def _check_complete(self, manager: int) -> None:
        info = self.managers[manager]
        now = monotonic()
        if manager not in self.status and self.status_retries > 0 and now - self._last_status_request > 1.0:
            self._last_status_request = now
            interval = 0 if self.status_retries > 2 else 5_000_000
            self.status_retries -= 1
            self._send(manager, ml.MAV_CMD_SET_MESSAGE_INTERVAL, 281, interval)
        if manager not in self.attitude and self.attitude_retries > 0:
            device = info.gimbal_device_id
            self.attitude_retries -= 1
            self._send(device if device > 6 else manager, ml.MAV_CMD_SET_MESSAGE_INTERVAL, 285, 0)

    def complete(self, manager: int) -> bool:
        return manager in self.managers and manager in self.status and manager in self.attitude


@pytest.mark.parametrize("role, device_id", [("both", GIMBAL), ("manager", 1)])
async def test_qgc5_discovers_the_cameras_and_the_gimbal(rig_factory: Any, role: str, device_id: int) -> None:
    r = await rig_factory("C12", role=role)
    qgc = await Qgc().start(r.bridge.addresses[0][1])
    try:
        await eventually(lambda: all(c in qgc.cameras and qgc.cameras[c].info is not None for c in (CAMERA, THERMAL)),
                         15, "both cameras discovered")  # fmt: skip
        for compid in (CAMERA, THERMAL):
            d = qgc.cameras[compid]
            # answered at the first attempt (REQUEST_MESSAGE), no give-up, no restart
            assert d.attempts[0] == ml.MAV_CMD_REQUEST_MESSAGE and d.gave_up == 0 and d.starts == 1
            assert d.info.get_srcComponent() == compid
        assert b"thermal" in bytes(qgc.cameras[THERMAL].info.model_name)
        await eventually(lambda: qgc.gimbal.complete(GIMBAL), 15, "gimbal complete (information, status, attitude)")
        assert qgc.gimbal.managers[GIMBAL].gimbal_device_id == device_id
        assert set(qgc.gimbal.managers) == {GIMBAL}, "only the gimbal component is a gimbal manager"
        assert qgc.gimbal.dropped == []
        # QGC asks every component for GIMBAL_MANAGER_INFORMATION: the cameras say UNSUPPORTED
        # (targeted, so they answer; no information message from them)
        acks = [m for m in qgc.messages if m.get_type() == "COMMAND_ACK" and m.command == ml.MAV_CMD_REQUEST_MESSAGE]
        camera_acks = {m.result for m in acks if m.get_srcComponent() in (CAMERA, THERMAL)}
        assert ml.MAV_RESULT_UNSUPPORTED in camera_acks

        def infos() -> int:
            return sum(
                1 for m in qgc.messages if m.get_type() == "CAMERA_INFORMATION" and m.get_srcComponent() == CAMERA
            )

        # the legacy REQUEST_CAMERA_INFORMATION (QGC's odd attempts) works as well
        before = infos()
        ack = await qgc.ack(CAMERA, ml.MAV_CMD_REQUEST_CAMERA_INFORMATION, 1)
        assert ack.result == ml.MAV_RESULT_ACCEPTED
        await eventually(lambda: infos() == before + 1, 5, "CAMERA_INFORMATION after the legacy request")
        # QGC's retransmissions carry confirmation 0 (not MAVLink's counting): each is a new
        # request and is answered again, with the message again (it is idempotent)
        for _ in range(2):
            assert (await qgc.ack(CAMERA, ml.MAV_CMD_REQUEST_MESSAGE, 259)).result == ml.MAV_RESULT_ACCEPTED
        await eventually(lambda: infos() == before + 3, 5, "one CAMERA_INFORMATION per request")
    finally:
        qgc.close()


async def _camera(port: int = 0) -> tuple[Simulator, Bridge]:
    sim = Simulator("C12")
    await sim.start(udp=[("127.0.0.1", 0)])
    bridge = Bridge(BridgeConfig(url=sim.url, model="C12", endpoints=[f"udpin:127.0.0.1:{port}"],
                                 silence_s=0.6, timeout_s=0.3, retries=1))  # fmt: skip
    await bridge.start()
    return sim, bridge


async def test_qgc5_rediscovers_a_camera_that_starts_after_it_gave_up() -> None:
    # QGC heard the camera's heartbeat, then the camera went away before answering anything.
    sim, bridge = await _camera()
    port = bridge.addresses[0][1]  # type: ignore[index]
    # The real-time smoke test: the give-up fast (nothing answers then: short timers cannot flake;
    # its exact schedule at QGC's own timers is the virtual test's), the rediscovery at QGC's own
    # timers (generous: a loaded machine's late answer is not a missed one).
    qgc = await Qgc(time_scale=0.03).start(port)
    await qgc.wait("HEARTBEAT", lambda m: m.get_srcComponent() == CAMERA)
    for c in qgc.cameras.values():
        c.stop()
    await bridge.close()
    await sim.stop()
    qgc.cameras.clear()
    qgc.sent.clear()
    started: tuple[Simulator, Bridge] | None = None
    try:
        d = qgc.cameras[CAMERA] = CameraDiscovery(qgc, CAMERA)
        d.heartbeat()  # the heartbeat QGC heard: discovery starts, nothing answers
        await eventually(lambda: d.gave_up == 1, 60, "QGC gives up after 10 attempts")
        assert len(d.attempts) == CAMERA_ATTEMPTS and d.info is None
        assert d.attempts[:4] == [ml.MAV_CMD_REQUEST_MESSAGE, ml.MAV_CMD_REQUEST_CAMERA_INFORMATION] * 2

        def info_requests() -> list[tuple[int, int, int]]:
            return [x for x in qgc.sent if x[0] == CAMERA and (x[2] == 259 or x[1] == 521)]

        camera_requests = info_requests()
        assert len(camera_requests) == CAMERA_ATTEMPTS * COMMAND_TRIES, "every attempt sent 3 times, then no more"
        await asyncio.sleep(1.0)
        assert len(info_requests()) == len(camera_requests), "given up: no more requests"
        # the camera (bridge + camera) starts on the same port; QGC's own heartbeat makes the
        # bridge's udpin link learn it, the bridge's heartbeat restarts QGC's discovery
        qgc.time_scale = 1.0
        started = await _camera(port)
        await eventually(lambda: d.info is not None, 30, "rediscovered on heartbeat")
        assert d.starts == 2 and d.gave_up == 1
        assert d.attempts[CAMERA_ATTEMPTS] == ml.MAV_CMD_REQUEST_MESSAGE, "a restart begins again at attempt 0"
        # the gimbal: QGC spends its 6 information requests only on heartbeats, so none was
        # lost while the component was away
        await eventually(lambda: qgc.gimbal.complete(GIMBAL), 15, "gimbal discovered")
    finally:
        qgc.close()
        if started is not None:
            await started[1].close()
            await started[0].stop()


async def test_px4_gimbal_manager_v2_messages(rig_factory: Any) -> None:
    r = await rig_factory("C12", role="device")
    s = r.sim
    px4 = await Peer(sysid=1, compid=1).connect(r.bridge.addresses[0][1])
    try:
        # 1. GIMBAL_DEVICE_INFORMATION asked for by broadcast (0/0): only the gimbal answers
        px4.send(ml.MAVLink_command_long_message(0, 0, ml.MAV_CMD_REQUEST_MESSAGE, 0, 283, 0, 0, 0, 0, 0, 0))
        info = await px4.wait("GIMBAL_DEVICE_INFORMATION")
        assert info.get_srcComponent() == GIMBAL
        await asyncio.sleep(0.5)
        acks = [m for m in px4.messages if m.get_type() == "COMMAND_ACK" and m.command == ml.MAV_CMD_REQUEST_MESSAGE]
        assert [(m.get_srcComponent(), m.result) for m in acks] == [(GIMBAL, ml.MAV_RESULT_ACCEPTED)]
        # 2. the vehicle's attitude as PX4 streams it (AUTOPILOT_STATE_FOR_GIMBAL_DEVICE, target 0/0)
        q_vehicle = list(from_euler_deg(0, 0, 30))
        state = ml.MAVLink_autopilot_state_for_gimbal_device_message(0, 0, 1, q_vehicle, 0, 0, 0, 0, 0, 0, 0, 0, NAN)
        px4.send(state)
        await eventually(lambda: r.bridge.vehicles.yaw_deg is not None, 5, "heading from PX4")
        # 3. an absolute (yaw-locked) angle: only LOCK flags, target component 0 (device not yet known
        #    to PX4), and angular velocities given next to the quaternion: the quaternion wins
        flags = ml.GIMBAL_DEVICE_FLAGS_ROLL_LOCK | ml.GIMBAL_DEVICE_FLAGS_PITCH_LOCK | ml.GIMBAL_DEVICE_FLAGS_YAW_LOCK
        q = list(from_euler_deg(0, -15, 50))
        px4.send(ml.MAVLink_gimbal_device_set_attitude_message(1, 0, flags, q, 0.0, 0.0, 0.0))
        await eventually(lambda: abs(s.gimbal.yaw_deg - 20) < 0.1 and abs(s.gimbal.pitch_deg + 15) < 0.1, 15,
                         "body yaw 50 - 30 = 20, pitch -15")  # fmt: skip
        # 4. a body-frame angle: no YAW_LOCK (and no frame flag either)
        px4.send(ml.MAVLink_gimbal_device_set_attitude_message(1, GIMBAL, flags & ~ml.GIMBAL_DEVICE_FLAGS_YAW_LOCK,
                                                               list(from_euler_deg(0, -5, -10)), NAN, NAN, NAN))  # fmt: skip
        await eventually(lambda: abs(s.gimbal.yaw_deg + 10) < 0.1 and abs(s.gimbal.pitch_deg + 5) < 0.1, 15)
        # 5. a rate: the quaternion NaN, the yaw rate in rad/s
        px4.send(ml.MAVLink_gimbal_device_set_attitude_message(1, GIMBAL, 0, [NAN] * 4, NAN, NAN, math.radians(8)))
        await eventually(lambda: s.gimbal.yaw_deg > -5, 15, "turning right")
        px4.send(ml.MAVLink_gimbal_device_set_attitude_message(1, GIMBAL, 0, [NAN] * 4, NAN, NAN, 0.0))
    finally:
        px4.close()


@pytest.mark.virtual
@in_virtual_time
async def test_virtual_qgc5_gives_up_on_its_own_schedule_and_rediscovers() -> None:
    """The same in virtual time with QGC's timers as QGC has them (not scaled): 10 attempts of 3
    sends 1.2 s apart, the back-offs between them, the give-up 98.5 s after the first request,
    nothing sent after it, and a fresh discovery from attempt 0 on the next heartbeat."""
    sim, url = await start_camera("C12")
    link = fresh_name("gcs")
    made = await start_bridge(url, "C12", link)
    qgc = await MemQgc(time_scale=1.0).start_on(link)
    await qgc.wait("HEARTBEAT", lambda m: m.get_srcComponent() == CAMERA)
    for c in qgc.cameras.values():
        c.stop()
    await made.close()  # the link closes: QGC is left with a camera it heard once
    await sim.stop()
    qgc.cameras.clear()
    qgc.sent.clear()
    qgc.sent_at.clear()
    later: list[Any] = []
    try:
        d = qgc.cameras[CAMERA] = CameraDiscovery(qgc, CAMERA)
        t0 = monotonic()
        d.heartbeat()
        await eventually(lambda: d.gave_up == 1, 300, "QGC gives up after 10 attempts")
        gave_up = monotonic() - t0
        assert len(d.attempts) == CAMERA_ATTEMPTS and d.info is None
        assert d.attempts == [ml.MAV_CMD_REQUEST_MESSAGE, ml.MAV_CMD_REQUEST_CAMERA_INFORMATION] * (
            CAMERA_ATTEMPTS // 2
        )
        # when each send should go: 3 per attempt 1.2 s apart, then the attempt's back-off
        want, t = [], 0.0
        for retry in range(1, CAMERA_ATTEMPTS + 1):
            for _ in range(COMMAND_TRIES):
                want.append(t)
                t += ACK_TIMEOUT_S
            t += backoff_s(retry)
        sent_at = [at - t0 for (comp, cmd, p1), at in zip(qgc.sent, qgc.sent_at, strict=True)
                   if comp == CAMERA and (p1 == 259 or cmd == ml.MAV_CMD_REQUEST_CAMERA_INFORMATION)]  # fmt: skip
        assert sent_at == pytest.approx(want, abs=0.05)
        assert gave_up == pytest.approx(t, abs=0.05) and t == pytest.approx(98.5)
        sent_before = len(qgc.sent)
        await asyncio.sleep(120.0)
        assert len(qgc.sent) == sent_before, "given up: no more requests"
        # the camera comes back on the same link; QGC joins it again (its heartbeat makes it a
        # peer), the bridge's heartbeat restarts QGC's discovery
        sim, url = await start_camera("C12")
        later = [sim, await start_bridge(url, "C12", link)]
        await qgc.join(link)
        await eventually(lambda: d.info is not None, 30, "rediscovered on heartbeat")
        assert d.starts == 2 and d.gave_up == 1
        assert d.attempts[CAMERA_ATTEMPTS] == ml.MAV_CMD_REQUEST_MESSAGE, "a restart begins again at attempt 0"
        assert len(d.attempts) == CAMERA_ATTEMPTS + 1, "answered at the first attempt"
        await eventually(lambda: qgc.gimbal.complete(GIMBAL), 15, "gimbal discovered")
    finally:
        qgc.close()
        for thing in reversed(later):
            await (thing.close() if isinstance(thing, Bridge) else thing.stop())
