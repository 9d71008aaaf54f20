"""The bridge follows the client's own link judgement: a camera never heard is never reported
healthy, a silent one is reported failed, a TCP camera that goes and comes back is reconnected by
the client and reported healthy again, and commands fail fast while the link is down."""

from __future__ import annotations

import asyncio
import socket

from pymavlink.dialects.v20 import common as ml

from topgimbal.mavlink import Bridge, BridgeConfig
from topgimbal.sim import Simulator

from .conftest import Peer, eventually

GIMBAL = 154
COMMS_ERROR = ml.GIMBAL_DEVICE_ERROR_FLAGS_COMMS_ERROR


async def _bridge(url: str, model: str = "C12") -> tuple[Bridge, Peer]:
    bridge = Bridge(BridgeConfig(url=url, model=model, endpoints=["udpin:127.0.0.1:0"], silence_s=0.6,
                                 timeout_s=0.3, retries=1))  # fmt: skip
    await bridge.start(camera_wait_s=0.5)
    peer = await Peer().connect(bridge.addresses[0][1])  # type: ignore[index]
    return bridge, peer


async def test_a_camera_never_heard_is_never_reported_healthy() -> None:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as quiet:  # bound, never answers
        quiet.bind(("127.0.0.1", 0))
        bridge, peer = await _bridge(f"udp://127.0.0.1:{quiet.getsockname()[1]}")
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
