"""One peer's command flood must not lock the others out (issue 27): in-flight places are bounded
per peer as well as in total, commands that need no camera traffic are answered whatever the
load, and a silent tcpin connection gives its place back like a silent udpin peer."""

from __future__ import annotations

import asyncio
import socket
from collections.abc import Hashable
from typing import Any

import pytest
from pymavlink.dialects.v20 import common as ml

from topgimbal.links import base as link_base
from topgimbal.links.endpoints import Link, make_link
from topgimbal.mavlink.commands import Command, Dispatcher
from topgimbal.mavlink.fairness import InflightLimits
from topgimbal.mavlink.node import Node
from topgimbal.mavlink.services import Services

from .conftest import Peer, eventually

pytestmark = pytest.mark.loopback

GIMBAL, CAMERA = 154, 100
SLOW = 31000  # a command whose handler waits (the camera is busy)


class _Wire:
    """A link that keeps the acks the node sends."""

    def __init__(self) -> None:
        self.parser = ml.MAVLink(None)
        self.acks: list[Any] = []
        self.dropped_out = 0

    def __str__(self) -> str:
        return "udpin:test"

    def send(self, data: bytes) -> None:
        self.acks += [m for m in self.parser.parse_buffer(data) or [] if m.get_type() == "COMMAND_ACK"]


@pytest.mark.virtual
def test_the_limits_are_per_peer_and_keep_places_for_idle_peers() -> None:
    lim = InflightLimits(total=32, per_peer=8, reserved_for_idle=4)
    for _ in range(8):
        assert lim.refusal("a") is None
        lim.take("a")
    assert "per peer" in (lim.refusal("a") or "")
    for p in ("b", "c"):  # two more flooders: 24 places
        for _ in range(8):
            lim.take(p)
    for _ in range(4):  # a fourth flooder gets 4 more, then hits the reserve
        assert lim.refusal("d") is None
        lim.take("d")
    assert "kept for peers with none" in (lim.refusal("d") or "")
    assert lim.refusal("e") is None  # a peer with nothing in flight still gets a place
    lim.take("e")
    lim.give_back("a")
    assert lim.held("a") == 7 and lim.in_use == 28 + 1 - 1
    lim.give_back("zzz")  # never held: nothing changes
    assert lim.in_use == 28


async def test_a_flooding_peer_leaves_another_peers_commands_answered() -> None:
    node = Node(1, [])
    wire = _Wire()
    node.links.append(wire)  # type: ignore[arg-type]
    dispatcher = Dispatcher()
    node.subscribe(dispatcher.on_message)
    release = asyncio.Event()

    async def slow(cmd: Command) -> None:
        await release.wait()

    comp = node.component(GIMBAL, "gimbal")
    dispatcher.register(comp, SLOW, slow)
    services = Services(comp, dispatcher, 26)  # REQUEST_MESSAGE and the interval commands

    async def information(cmd: Command) -> list[Any]:
        return [ml.MAVLink_gimbal_manager_information_message(0, 0, 1, 0, 0, 0, 0, 0, 0)]

    services.provide(280, information)
    flooder = ml.MAVLink(None, srcSystem=255, srcComponent=190)
    other = ml.MAVLink(None, srcSystem=255, srcComponent=191)
    link: Any = wire
    # Before: the flooder's first 32 commands took every place and the other peer's 20 were
    # refused TEMPORARILY_REJECTED (the sweep: 7 of 20 refused at ~1,900 commands/s).
    # Now the flooder holds 8 places and the other peer gets its own 8.
    for i in range(500):
        data = ml.MAVLink_command_long_message(1, GIMBAL, SLOW, 0, i, 0, 0, 0, 0, 0, 0).pack(flooder)
        node._on_data(link, ("127.0.0.1", 40001), data)
    for i in range(8):  # as many as one peer may have in flight
        data = ml.MAVLink_command_long_message(1, GIMBAL, SLOW, 0, 1000 + i, 0, 0, 0, 0, 0, 0).pack(other)
        node._on_data(link, ("127.0.0.1", 40002), data)
    # Commands that need no camera traffic are answered even from the flooder itself.
    data = ml.MAVLink_command_long_message(1, GIMBAL, 510, 0, 285, 0, 0, 0, 0, 0, 0).pack(flooder)
    node._on_data(link, ("127.0.0.1", 40001), data)
    data = ml.MAVLink_command_long_message(1, GIMBAL, 512, 0, 280, 0, 0, 0, 0, 0, 0).pack(flooder)
    node._on_data(link, ("127.0.0.1", 40001), data)
    await asyncio.sleep(0)

    def final(src_comp: int, command: int = SLOW) -> list[int]:
        return [a.result for a in wire.acks if a.target_component == src_comp and a.command == command
                and a.result != ml.MAV_RESULT_IN_PROGRESS]  # fmt: skip

    await eventually(lambda: final(190, 510) == [ml.MAV_RESULT_ACCEPTED], what="GET_MESSAGE_INTERVAL answered")
    await eventually(lambda: final(190, 512) == [ml.MAV_RESULT_ACCEPTED], what="REQUEST_MESSAGE answered")
    assert final(190) == [ml.MAV_RESULT_TEMPORARILY_REJECTED] * (500 - 8)  # 8 places for the flooder
    assert ml.MAV_RESULT_TEMPORARILY_REJECTED not in final(191)
    release.set()
    await eventually(lambda: len(final(191)) == 8, what="the other peer's 8 acks")
    assert final(191) == [ml.MAV_RESULT_ACCEPTED] * 8
    assert final(190)[-8:] == [ml.MAV_RESULT_ACCEPTED] * 8
    assert dispatcher.limits.in_use == 0  # every place given back
    await dispatcher.close()


async def test_a_flood_over_udp_leaves_another_ground_stations_commands_answered(rig: Any) -> None:
    """End to end: two pymavlink peers on their own UDP ports; one floods zoom commands at a
    camera that takes 0.3 s per zoom (its handler is slowed down here), the other's are answered."""
    key = (CAMERA, ml.MAV_CMD_SET_CAMERA_ZOOM)
    zoom = rig.bridge.dispatcher._handlers[key]

    async def slow_zoom(cmd: Command) -> Any:
        await asyncio.sleep(0.3)
        return await zoom(cmd)

    rig.bridge.dispatcher._handlers[key] = slow_zoom
    port = rig.bridge.addresses[0][1]
    flooder = await Peer(sysid=200, compid=190).connect(port)
    stop = asyncio.Event()

    async def flood() -> None:
        i = 0
        while not stop.is_set():
            for _ in range(20):
                i += 1
                flooder.command(CAMERA, ml.MAV_CMD_SET_CAMERA_ZOOM, 1, 0.001 * (i % 1000))
            await asyncio.sleep(0.01)

    task = asyncio.ensure_future(flood())
    try:
        await eventually(lambda: rig.bridge.dispatcher.busy_rejected > 100, what="the flood refused in part")
        # Before: the flood held all 32 places and these were refused TEMPORARILY_REJECTED.
        answers = [await _command_until_answered(rig.peer, 0.5 + 0.01 * i) for i in range(5)]
        assert answers == [ml.MAV_RESULT_ACCEPTED] * 5, answers
    finally:
        stop.set()
        await task
        flooder.close()


async def _command_until_answered(me: Peer, zoom: float) -> int:
    """A zoom command, retransmitted (confirmation 1, 2, ...) as ground stations do until its final
    ack comes: a flood over UDP fills the bridge's receive buffer and some datagrams are lost.
    Acks go to every peer: only those addressed to this one count."""
    for confirmation in range(30):
        fut = asyncio.ensure_future(me.wait("COMMAND_ACK", lambda m: m.target_system == 255 and m.command == 531
                                            and m.result != ml.MAV_RESULT_IN_PROGRESS, timeout=1.0))  # fmt: skip
        await asyncio.sleep(0)
        me.command(CAMERA, ml.MAV_CMD_SET_CAMERA_ZOOM, 1, zoom, confirmation=confirmation)
        try:
            return int((await fut).result)
        except asyncio.TimeoutError:
            continue
    raise AssertionError("no answer to 30 copies of the command")


async def test_a_silent_tcpin_connection_gives_its_place_back(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(link_base, "PEER_TIMEOUT_S", 0.3)
    got: list[tuple[Hashable, bytes]] = []
    gone: list[Hashable] = []

    def on_data(_link: Link, peer: Hashable, data: bytes) -> None:
        got.append((peer, data))

    link = make_link("tcpin:127.0.0.1:0", on_data, lambda _l, p: gone.append(p), max_peers=2)
    await link.start()
    assert link.address is not None
    silent = [socket.create_connection(link.address) for _ in range(2)]
    try:
        await eventually(lambda: link.peer_count == 2, what="two connections")
        await asyncio.sleep(0.5)  # both silent for longer than PEER_TIMEOUT_S
        # Before: a third connection was refused for as long as the silent ones stayed open.
        fresh = socket.create_connection(link.address)
        fresh.sendall(b"hello")
        await eventually(lambda: any(d == b"hello" for _, d in got), what="the new connection's bytes delivered")
        assert len(gone) == 2
        assert link.peer_count == 1
        fresh.close()
    finally:
        for s in silent:
            s.close()
        await link.close()


async def test_a_tcpin_connection_that_talks_keeps_its_place(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(link_base, "PEER_TIMEOUT_S", 0.3)
    got: list[bytes] = []
    link = make_link("tcpin:127.0.0.1:0", lambda _l, _p, d: got.append(d), lambda _l, _p: None, max_peers=1)
    await link.start()
    assert link.address is not None
    talker = socket.create_connection(link.address)
    try:
        for i in range(5):
            talker.sendall(b"x%d" % i)
            await asyncio.sleep(0.1)
        await eventually(lambda: len(b"".join(got)) == 10, what="the talker's bytes")
        late = socket.create_connection(link.address)
        late.sendall(b"late")
        await asyncio.sleep(0.3)
        assert b"late" not in b"".join(got)  # the table is full of a live peer: refused
        assert link.peer_count == 1
        late.close()
    finally:
        talker.close()
        await link.close()
