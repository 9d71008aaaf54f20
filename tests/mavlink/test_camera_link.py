"""The bridge follows the client's own link judgement: a camera never heard is never reported
healthy, a silent one is reported failed, a TCP camera that goes and comes back is reconnected by
the client and reported healthy again, and commands fail fast while the link is down."""

from __future__ import annotations

import asyncio
import itertools
import logging
import socket
from typing import Any

import pytest
from pymavlink.dialects.v20 import common as ml

from topgimbal.clock import monotonic
from topgimbal.mavlink import Bridge, BridgeConfig
from topgimbal.mavlink.camera_link import REOPEN_MAX_S, REOPEN_MIN_S
from topgimbal.sim import Simulator
from topgimbal.transport.memory import MemoryPort

from .conftest import Peer, eventually
from .virtual import HealthLog, MemPeer, camera_input, fresh_name, in_virtual_time, start_bridge, start_camera

pytestmark = pytest.mark.virtual

GIMBAL = 154
COMMS_ERROR = ml.GIMBAL_DEVICE_ERROR_FLAGS_COMMS_ERROR


async def _bridge(url: str, model: str = "C12", silence_s: float = 5.0, timeout_s: float = 1.5) -> tuple[Bridge, Peer]:
    # Real-time smoke tests: generous timers (a loaded machine delays a healthy camera); the exact
    # timeouts, retries and back-off are proven in virtual time below.
    bridge = Bridge(BridgeConfig(url=url, model=model, endpoints=["udpin:127.0.0.1:0"], silence_s=silence_s,
                                 timeout_s=timeout_s, retries=1))  # fmt: skip
    await bridge.start(camera_wait_s=0.5)
    peer = await Peer().connect(bridge.addresses[0][1])  # type: ignore[index]
    return bridge, peer


@pytest.mark.loopback
async def test_a_camera_never_heard_is_never_reported_healthy() -> None:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as quiet:  # bound, never answers
        quiet.bind(("127.0.0.1", 0))
        bridge, peer = await _bridge(f"udp://127.0.0.1:{quiet.getsockname()[1]}", silence_s=0.6, timeout_s=0.3)
        try:
            first = await peer.wait("HEARTBEAT", lambda m: m.get_srcComponent() == GIMBAL)
            assert first.system_status in (ml.MAV_STATE_BOOT, ml.MAV_STATE_CRITICAL)  # never ACTIVE
            st = await peer.wait("GIMBAL_DEVICE_ATTITUDE_STATUS")
            assert st.failure_flags & COMMS_ERROR
            # The client declares the link down after `silence_s` of asking for its stream.
            await peer.wait(
                "HEARTBEAT", lambda m: m.get_srcComponent() == GIMBAL and m.system_status == ml.MAV_STATE_CRITICAL
            )
            assert bridge.cam.declared_down and not bridge.cam.heard and not bridge.cam.answering
            ack = await peer.ack(GIMBAL, ml.MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW, -10, 0)
            assert ack.result == ml.MAV_RESULT_FAILED and ack.result_param2 == 3  # link down: nothing sent
            assert not any(
                m.get_type() == "HEARTBEAT" and m.system_status == ml.MAV_STATE_ACTIVE for m in peer.messages
            )
        finally:
            peer.close()
            await bridge.close()


@pytest.mark.loopback
async def test_a_tcp_camera_that_goes_and_comes_back() -> None:
    sim = Simulator("C20")  # the C20 speaks TCP
    await sim.start(tcp=[("127.0.0.1", 0)])
    port = sim.addresses["tcp"][0][1]
    bridge, peer = await _bridge(sim.url, "C20")
    try:
        await peer.wait(
            "HEARTBEAT", lambda m: m.get_srcComponent() == GIMBAL and m.system_status == ml.MAV_STATE_ACTIVE
        )
        client = bridge.cam.client
        await sim.stop()  # the connection closes: the client says so at once
        await peer.wait("GIMBAL_DEVICE_ATTITUDE_STATUS", lambda m: m.failure_flags & COMMS_ERROR)
        ack = await peer.ack(GIMBAL, ml.MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW, 0, 15)
        assert ack.result == ml.MAV_RESULT_FAILED and ack.result_param2 == 3
        sim = Simulator("C20")
        await sim.start(tcp=[("127.0.0.1", port)])
        # The same client reconnects by itself (no new client in the bridge) and restarts the
        # attitude stream; the bridge reports the camera healthy again and commands go through.
        await peer.wait("GIMBAL_DEVICE_ATTITUDE_STATUS", lambda m: not m.failure_flags & COMMS_ERROR, timeout=15)
        assert bridge.cam.client is client
        ack = await peer.ack(GIMBAL, ml.MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW, 0, 15)
        assert ack.result == ml.MAV_RESULT_ACCEPTED
        await eventually(lambda: abs(sim.gimbal.yaw_deg - 15) < 0.1, 10)
    finally:
        peer.close()
        await bridge.close()
        await sim.stop()


@pytest.mark.loopback
async def test_a_tcp_camera_that_is_not_up_yet_is_opened_when_it_is() -> None:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    bridge, peer = await _bridge(f"tcp://127.0.0.1:{port}", "C20")
    sim = Simulator("C20")
    try:
        await eventually(lambda: bridge.cam.declared_down, 5)  # "cannot open", said once
        assert bridge.cam.client is None and "cannot open" in bridge.cam.reason
        await sim.start(tcp=[("127.0.0.1", port)])
        await peer.wait("HEARTBEAT", lambda m: m.get_srcComponent() == GIMBAL and m.system_status == ml.MAV_STATE_ACTIVE,
                        timeout=15)  # fmt: skip
        assert bridge.cam.answering
    finally:
        peer.close()
        await bridge.close()
        await sim.stop()
        await asyncio.sleep(0)


# -- the same behaviours in virtual time (memory links, looptime): the product's own timers -------


def _gimbal_hb(status: int) -> Any:
    return lambda m: m.get_srcComponent() == GIMBAL and m.get_type() == "HEARTBEAT" and m.system_status == status


@pytest.mark.parametrize("silence_s", [0.6, 3.0])
@in_virtual_time
async def test_virtual_a_camera_never_heard_is_declared_down_after_silence_s(silence_s: float) -> None:
    port = MemoryPort.listen(fresh_name("quiet"))  # listens, never answers
    asked: list[float] = []
    port.on_bytes = lambda data: asked.append((monotonic(), data))
    link = fresh_name("gcs")
    t0 = monotonic()
    made = await start_bridge(port.url, "C12", link, camera_wait_s=0.0, silence_s=silence_s, timeout_s=1.0, retries=2)
    health = HealthLog(made)
    peer = await MemPeer().join(link)
    try:
        first = await peer.wait("HEARTBEAT", lambda m: m.get_srcComponent() == GIMBAL)
        assert first.system_status == ml.MAV_STATE_BOOT  # not yet known: never ACTIVE
        await peer.wait("HEARTBEAT", _gimbal_hb(ml.MAV_STATE_CRITICAL), timeout=silence_s + 5)
        down = health.when(False)
        assert down is not None and silence_s <= down - t0 <= silence_s + 0.05, (down - t0, silence_s)
        # the attitude stream request (GAA) went out at once (after the model check's first query),
        # then again every timeout_s, 1 + retries times in all, until the link was declared down
        gaa = [t for t, data in asked if b"GAA" in data]
        assert gaa and gaa[0] - t0 < 0.1
        assert gaa == pytest.approx([gaa[0] + k * 1.0 for k in range(3) if gaa[0] + k * 1.0 < down]), gaa
        assert made.cam.declared_down and not made.cam.heard and not made.cam.answering
        ack = await peer.ack(GIMBAL, ml.MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW, -10, 0)
        assert (ack.result, ack.result_param2) == (ml.MAV_RESULT_FAILED, 3)  # link down: nothing sent
        assert not any(_gimbal_hb(ml.MAV_STATE_ACTIVE)(m) for m in peer.messages)
    finally:
        peer.close()
        await made.close()
        port.close()


@in_virtual_time
async def test_virtual_a_camera_that_goes_and_comes_back_is_reconnected_by_the_same_client() -> None:
    sim, url = await start_camera("C12")
    name = url.removeprefix("memory://")
    link = fresh_name("gcs")
    made = await start_bridge(url, "C12", link)  # the product's defaults: silence 3 s, 1 s x 3
    health = HealthLog(made)
    peer = await MemPeer().join(link)
    try:
        await peer.wait("HEARTBEAT", _gimbal_hb(ml.MAV_STATE_ACTIVE))
        client = made.cam.client
        gone, seen = monotonic(), len(health.changes)
        await sim.stop()  # the memory port closes, as a TCP connection would: the client says so at once
        await peer.wait("GIMBAL_DEVICE_ATTITUDE_STATUS", lambda m: m.failure_flags & COMMS_ERROR)
        assert health.changes[seen] == (gone, False)  # at once, not after silence_s
        ack = await peer.ack(GIMBAL, ml.MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW, 0, 15)
        assert (ack.result, ack.result_param2) == (ml.MAV_RESULT_FAILED, 3)
        await asyncio.sleep(20.0)  # away for a while: the client keeps trying, backing off to 5 s
        sim, _ = await start_camera("C12", name)
        back = monotonic()
        await peer.wait("GIMBAL_DEVICE_ATTITUDE_STATUS", lambda m: not m.failure_flags & COMMS_ERROR, timeout=15)
        # the client's own reconnection: after 1 s, then doubling up to 5 s (client/connection.py)
        tries, delay = [gone + 1.0], 2.0
        while tries[-1] < back:
            tries.append(tries[-1] + delay)
            delay = min(5.0, delay * 2)
        assert [u for _, u in health.changes[seen:]] == [False, True], health.changes  # down once, up once
        assert health.changes[-1][0] == pytest.approx(tries[-1], abs=0.05), (health.changes, tries)
        assert made.cam.client is client  # the same client reopened its link
        ack = await peer.ack(GIMBAL, ml.MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW, 0, 15)
        assert ack.result == ml.MAV_RESULT_ACCEPTED
        await eventually(lambda: abs(sim.gimbal.yaw_deg - 15) < 0.1, 10)
    finally:
        peer.close()
        await made.close()
        await sim.stop()


@in_virtual_time
async def test_virtual_a_camera_that_is_not_up_yet_is_opened_at_the_next_try(caplog: Any) -> None:
    caplog.set_level(logging.INFO, logger="topgimbal.mavlink")
    name, link = fresh_name("cam"), fresh_name("gcs")
    t0 = monotonic()
    made = await start_bridge(f"memory://{name}", "C12", link, camera_wait_s=0.0)
    health = HealthLog(made)
    peer = await MemPeer().join(link)
    sim: Simulator | None = None
    try:
        await asyncio.sleep(10.0)
        assert made.cam.declared_down and made.cam.client is None and "cannot open" in made.cam.reason
        # tries at 0, 0.5, 1.5, 3.5, 7.5, 12.5 ...: back-off doubling from REOPEN_MIN_S up to REOPEN_MAX_S
        tries, delay, t = [0.0], REOPEN_MIN_S, 0.0
        while t + delay < 30.0:
            t += delay
            tries.append(t)
            delay = min(REOPEN_MAX_S, delay * 2)
        failed = [r for r in caplog.records if "cannot open" in r.getMessage() and "retrying" in r.getMessage()]
        assert len(failed) == sum(1 for x in tries if x <= 10.0)
        sim, _ = await start_camera("C12", name)
        await peer.wait("HEARTBEAT", _gimbal_hb(ml.MAV_STATE_ACTIVE), timeout=15)
        answering = health.when(True)
        next_try = next(x for x in tries if x > 10.0)
        assert answering is not None and next_try <= answering - t0 <= next_try + 0.1, (answering, tries)
        assert made.cam.answering
    finally:
        peer.close()
        await made.close()
        if sim is not None:
            await sim.stop()


@pytest.mark.parametrize("stream", [False, True])
@in_virtual_time
async def test_virtual_the_cameras_attitude_stream_is_renewed_on_a_datagram_link(stream: bool) -> None:
    """The client asks a camera on a datagram link for its stream again at most stream_renew_s
    apart (20 s: a camera that keeps a UDP peer's stream only for a while keeps it; each wait in
    its last quarter, client/streams.py RENEW_SPREAD, so clients started together spread out); on a byte stream
    (TCP, serial: the device knows its peer) it never does. Proven over 65 s of the product's
    timers, with no real waiting."""
    sim, url = await start_camera("C12")
    link = fresh_name("gcs")
    sent = camera_input(sim)
    t0 = monotonic()
    made = await start_bridge(url + ("?stream=1" if stream else ""), "C12", link, stream_hz=5.0, attitude_hz=1.0)
    try:
        await asyncio.sleep(65.0)
        gaa = [t - t0 for t, data in sent if data[6:10] == b"wGAA"]
        assert gaa and gaa[0] < 0.1  # asked for at once
        if stream:
            assert len(gaa) == 1, gaa
        else:  # and again every 15-20 s: 3 or 4 times in 65 s
            gaps = [b - a for a, b in itertools.pairwise(gaa)]
            assert len(gaps) in (3, 4) and all(15.0 - 0.01 <= g <= 20.0 + 0.01 for g in gaps), gaa
        assert made.cam.answering and made.cam.client is not None
    finally:
        await made.close()
        await sim.stop()
