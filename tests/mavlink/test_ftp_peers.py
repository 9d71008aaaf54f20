"""Issue 33.13: MAVLink FTP replies go to the requester only (no amplification to every peer) and
sessions belong to their peer (one peer cannot read, close, reset or evict another's)."""

from __future__ import annotations

import asyncio
from typing import Any

import pytest
from pymavlink.dialects.v20 import common as ml

from topgimbal.mavlink.ftp import MAX_ALL_SESSIONS, MAX_SESSIONS, OP_ACK, OP_NAK, FtpFiles

from .conftest import Peer, Rig
from .test_ftp import parse, req

pytestmark = pytest.mark.loopback

A, B = ("udp", ("127.0.0.1", 1), 255, 190), ("udp", ("127.0.0.1", 2), 255, 190)


def test_sessions_belong_to_their_peer() -> None:
    ftp = FtpFiles({"a.xml": b"x" * 1000})
    assert parse(ftp.answer(req(4, b"a.xml", session=0), A)[0])[2] == OP_ACK
    # B: the same session number is not A's; its reset and terminate leave A's session open
    assert parse(ftp.answer(req(5, session=0, size=10), B)[0])[6] == bytes([4])  # InvalidSession
    assert parse(ftp.answer(req(2), B)[0])[2] == OP_ACK
    assert parse(ftp.answer(req(1, session=0), B)[0])[2] == OP_ACK
    for n in range(MAX_SESSIONS + 2):  # B opening many evicts only B's own
        ftp.answer(req(4, b"a.xml", session=n), B)
    reply = parse(ftp.answer(req(5, session=0, size=10), A)[0])
    assert reply[2] == OP_ACK and reply[6] == b"x" * 10
    # all peers together stay bounded
    for n in range(MAX_ALL_SESSIONS * 2):
        ftp.answer(req(4, b"a.xml", session=0), ("udp", ("127.0.0.1", 100 + n), 1, 1))
    assert len(ftp.sessions) <= MAX_ALL_SESSIONS
    assert parse(ftp.answer(req(5, session=0, size=10), A)[0])[2] == OP_NAK  # A's, the oldest, went


async def test_a_reply_goes_to_the_requester_only(rig_factory: Any) -> None:
    rig: Rig = await rig_factory("SIP", definition_http=None)
    port = rig.bridge.addresses[0][1]  # type: ignore[index]
    other = await Peer(sysid=250).connect(port)
    try:
        await other.wait("HEARTBEAT")  # a peer of the bridge: it hears the telemetry
        payload = list(req(4, b"/sip-thermal.xml", session=1).ljust(251, b"\0"))
        fut = asyncio.ensure_future(rig.peer.wait("FILE_TRANSFER_PROTOCOL", timeout=10))
        await asyncio.sleep(0)
        rig.peer.send(ml.MAVLink_file_transfer_protocol_message(0, 1, 101, payload))
        answer = await fut
        assert parse(bytes(answer.payload))[2] == OP_ACK
        await rig.peer.wait("HEARTBEAT")  # time for a stray copy to arrive
        assert not [m for m in other.messages if m.get_type() == "FILE_TRANSFER_PROTOCOL"]
    finally:
        other.close()
