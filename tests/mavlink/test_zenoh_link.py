"""links/zenoh_link.py on a fake Zenoh session: the keys a frame is published on, mavlink/in
handed to the node as a frame from the header's ids, bad input and floods dropped and counted."""

from __future__ import annotations

import asyncio
import json
from collections.abc import Hashable
from typing import Any

import pytest

from topgimbal.links import zenoh_link
from topgimbal.links.endpoints import Link
from topgimbal.links.mav import mavlink

pytestmark = pytest.mark.loopback

mav = mavlink()


class _Sample:
    def __init__(self, data: bytes) -> None:
        self.payload = self
        self._data = data

    def to_bytes(self) -> bytes:
        return self._data


class _Pub:
    def __init__(self, session: FakeSession, key: str) -> None:
        self.session, self.key = session, key

    def put(self, text: str) -> None:
        self.session.puts.append((self.key, text))

    def undeclare(self) -> None:
        pass


class FakeSession:
    def __init__(self) -> None:
        self.puts: list[tuple[str, str]] = []
        self.callback: Any = None

    def declare_subscriber(self, key: str, callback: Any) -> _Pub:
        assert key == "mavlink/in"
        self.callback = callback
        return _Pub(self, key)

    def declare_publisher(self, key: str, encoding: Any = None) -> _Pub:
        return _Pub(self, key)


async def test_published_keys_and_input_handed_to_the_node() -> None:
    session = FakeSession()
    got: list[tuple[Hashable, bytes]] = []

    def on_data(link: Link, peer: Hashable, data: bytes) -> None:
        got.append((peer, data))

    link = zenoh_link.ZenohLink(session, on_data, lambda link, peer: None)
    await link.start()
    enc = mav.MAVLink(None, srcSystem=1, srcComponent=171)
    link.send(bytes(mav.MAVLink_command_ack_message(1000, 0, 0, 0, 255, 190).pack(enc)))
    keys = [k for k, _ in session.puts]
    assert keys[:2] == ["mavlink/out", "mavlink/1/171/COMMAND_ACK"]
    assert "mavlink/1/171/COMMAND_ACK/result" in keys and "mavlink/1/171/COMMAND_ACK/type" in keys
    assert json.loads(dict(session.puts)["mavlink/1/171/COMMAND_ACK/result"]) == {"type": "MAV_RESULT_ACCEPTED"}

    good = json.dumps({"header": {"system_id": 255, "component_id": 190, "sequence": 3},
                       "message": {"type": "HEARTBEAT", "mavtype": {"type": "MAV_TYPE_GCS"}}})  # fmt: skip
    for data in (b"nope", good.encode(), b"[" * 50_000):
        session.callback(_Sample(data))  # as from a Zenoh thread
    await asyncio.sleep(0.05)
    assert link.bad_in == 2 and len(got) == 1
    peer, frame = got[0]
    hb = mav.MAVLink(None).parse_buffer(frame)[0]
    assert peer == "zenoh" and (hb.get_srcSystem(), hb.get_srcComponent(), hb.get_seq()) == (255, 190, 3)
    assert hb.type == 6  # MAV_TYPE_GCS

    # a flood while the loop is busy: at most MAX_PENDING_IN wait, the rest are dropped and counted
    for _ in range(zenoh_link.MAX_PENDING_IN + 50):
        session.callback(_Sample(good.encode()))
    await asyncio.sleep(0.2)
    assert link.dropped_in == 50 and len(got) == 1 + zenoh_link.MAX_PENDING_IN
    await link.close()
