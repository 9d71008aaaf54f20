"""Issue 33.12: MAVLink signing keeps one replay state per (link id, system, component) for the
node, as the MAVLink signing spec does, not one per UDP source; a timestamp far in the future is
refused and a frame without the key changes no stream; a sender that signs nothing takes no peer
place and hears no telemetry; a weak key file is warned about."""

from __future__ import annotations

import asyncio
import hashlib
import logging
import socket
from pathlib import Path
from typing import Any

import pytest
from pymavlink.dialects.v20 import common as ml

from topgimbal.links.signing import SIGNING_EPOCH_S, SignedStreams, load_key, sign_outgoing

from .conftest import Peer, eventually
from .test_signing import KEY, _answer, keep_sent, signed_peer

pytestmark = pytest.mark.loopback


def _frame(key: bytes, sysid: int, ts: int, link_id: int = 0) -> bytes:
    mav = ml.MAVLink(None, srcSystem=sysid, srcComponent=190)
    sign_outgoing(mav, key, link_id)
    mav.signing.timestamp = ts
    return bytes(ml.MAVLink_heartbeat_message(6, 8, 0, 0, 4, 3).pack(mav))


def _now_ts(now_s: float) -> int:
    return int((now_s - SIGNING_EPOCH_S) * 100_000)


@pytest.mark.virtual
def test_streams_are_the_nodes_and_nothing_unsigned_changes_them() -> None:
    now = 1.8e9
    guard = SignedStreams(KEY, clock=lambda: now)
    t = _now_ts(now)
    first = _frame(KEY, 201, t + 10)
    assert guard.check(first) is None
    assert guard.check(first) == "a replay: timestamp not newer than the stream's last"
    # a frame without the key, far in the future, poisons nothing
    assert guard.check(_frame(b"\x01" * 32, 201, t + 10**12)) == "wrongly signed"
    assert guard.check(_frame(KEY, 201, t + 20)) is None
    # with the key but an hour ahead: refused, and the stream keeps its timestamp
    assert str(guard.check(_frame(KEY, 201, t + 3600 * 100_000))).startswith("a timestamp from the future")
    assert guard.check(_frame(KEY, 201, t + 30)) is None
    # another link id is another stream
    assert guard.check(_frame(KEY, 201, t + 25, link_id=1)) is None
    assert guard.check(_frame(KEY, 201, t - 2 * 6000 * 1000, link_id=2)) == (
        "a replay: a new stream over a minute older than the newest timestamp"
    )


async def test_a_signed_command_replayed_from_another_port_is_refused(rig_factory: Any) -> None:
    rig = await rig_factory("C12", signing_key=KEY)
    port = rig.bridge.addresses[0][1]
    good = await signed_peer(KEY, sysid=201).connect(port)
    try:
        sent, _ = keep_sent(good)
        assert (await _answer(good, -15)).result == ml.MAV_RESULT_ACCEPTED
        before = rig.bridge.node.unsigned_in
        acks = sum(m.get_type() == "COMMAND_ACK" for m in good.messages)
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:  # a new source port
            s.sendto(sent[-1], ("127.0.0.1", port))
            await eventually(lambda: rig.bridge.node.unsigned_in > before, 5, "the replay refused")
            await asyncio.sleep(0.5)  # and no second answer comes (checked below)
        assert rig.bridge.node.unsigned_in == before + 1
        assert rig.bridge.node.signed is not None and rig.bridge.node.signed.refused.get("a replay") == 1
        # not carried out again: no second answer (the bridge sends on every link to every peer)
        assert sum(m.get_type() == "COMMAND_ACK" for m in good.messages) == acks
    finally:
        good.close()


async def test_an_unsigned_sender_hears_nothing_and_takes_no_place(rig_factory: Any) -> None:
    rig = await rig_factory("C12", signing_key=KEY)
    link = rig.bridge.node.links[0]
    peers = link.peer_count
    unsigned = await Peer(sysid=203).connect(rig.bridge.addresses[0][1])
    try:
        unsigned.send(ml.MAVLink_heartbeat_message(6, 8, 0, 0, 4, 3))
        await rig.peer.wait("HEARTBEAT")  # the signed rig peer hears the bridge meanwhile
        await rig.peer.wait("HEARTBEAT")
        assert unsigned.messages == [] and link.peer_count == peers
        assert (await _answer(unsigned, -30, timeout=1.0)) is None
    finally:
        unsigned.close()


@pytest.mark.virtual
def test_a_weak_key_file_is_warned_about(tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    zero = tmp_path / "zero.key"
    zero.write_text("00" * 32)
    zero.chmod(0o644)
    good = tmp_path / "good.key"
    good.write_text(hashlib.sha256(b"x").hexdigest())
    good.chmod(0o600)
    with caplog.at_level(logging.WARNING, logger="topgimbal.mavlink"):
        assert load_key(zero) == bytes(32)
        assert load_key(good) == hashlib.sha256(b"x").digest()
    text = caplog.text
    assert "all zeros" in text and "mode is 0644" in text and "chmod 600" in text
    assert "good.key" not in text


async def test_tcp_a_connection_that_signs_nothing_hears_nothing_and_is_closed() -> None:
    from topgimbal.mavlink.bridge import Bridge, BridgeConfig
    from topgimbal.sim import Simulator

    sim = Simulator("C12")
    await sim.start(udp=[("127.0.0.1", 0)])
    bridge = Bridge(BridgeConfig(url=sim.url, model="C12", endpoints=["tcpin:127.0.0.1:0"], signing_key=KEY,
                                 silence_s=0.6, timeout_s=0.3, retries=1))  # fmt: skip
    await bridge.start()
    port = bridge.addresses[0][1]  # type: ignore[index]
    try:
        good_r, good_w = await asyncio.open_connection("127.0.0.1", port)
        bad_r, bad_w = await asyncio.open_connection("127.0.0.1", port)
        signer = ml.MAVLink(None, srcSystem=201, srcComponent=190)
        sign_outgoing(signer, KEY)
        plain = ml.MAVLink(None, srcSystem=203, srcComponent=190)
        good_w.write(ml.MAVLink_heartbeat_message(6, 8, 0, 0, 4, 3).pack(signer))
        bad_w.write(ml.MAVLink_heartbeat_message(6, 8, 0, 0, 4, 3).pack(plain))
        assert await asyncio.wait_for(good_r.read(1), 10) == b"\xfd"  # the signed one hears the bridge
        await asyncio.sleep(1.0)  # a second of the bridge's telemetry
        bad_w.write(ml.MAVLink_heartbeat_message(6, 8, 0, 0, 4, 3).pack(plain) * 200)  # > 4 KiB, none signed
        await bad_w.drain()
        assert await asyncio.wait_for(bad_r.read(), 10) == b""  # nothing heard, then closed
        good_w.close()
        bad_w.close()
    finally:
        await bridge.close()
        await sim.stop()
