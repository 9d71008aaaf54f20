"""The bridge's CAMERA_INFORMATION with an HTTP definition URI waits while a definition download
runs (camdef/pacing.py; MAVSDK 4.1 deadlocks otherwise): both requests are acked at once, the
second camera's answer comes only once the first camera's download is over. `--definition-all-at-once`
(definition_one_at_a_time=False) answers both at once."""

from __future__ import annotations

import asyncio
from typing import Any

import pytest
from pymavlink.dialects.v20 import common as ml

from topgimbal.mavlink.camera import MAX_PACED_INFO

from .conftest import eventually

pytestmark = pytest.mark.loopback

VISIBLE, THERMAL = 100, 101


def _infos(peer: Any) -> list[int]:
    return [m.get_srcComponent() for m in peer.messages if m.get_type() == "CAMERA_INFORMATION"]


def _acks(peer: Any) -> list[tuple[int, int]]:
    return [
        (m.get_srcComponent(), m.result)
        for m in peer.messages
        if m.get_type() == "COMMAND_ACK" and m.command == ml.MAV_CMD_REQUEST_MESSAGE
    ]


def _ask_both(peer: Any) -> None:
    peer.messages.clear()
    for comp in (VISIBLE, THERMAL):
        peer.command(comp, ml.MAV_CMD_REQUEST_MESSAGE, ml.MAVLINK_MSG_ID_CAMERA_INFORMATION)


async def test_the_second_cameras_information_waits_for_the_first_download(rig_factory: Any) -> None:
    r = await rig_factory("C12")
    server = r.bridge.definitions
    _ask_both(r.peer)
    await eventually(lambda: sorted(_acks(r.peer)) == [(VISIBLE, 0), (THERMAL, 0)], 5, "both requests acked")
    await eventually(lambda: len(_infos(r.peer)) == 1, 5, "the first CAMERA_INFORMATION")
    first = next(m for m in r.peer.messages if m.get_type() == "CAMERA_INFORMATION")
    uri = str(first.cam_definition_uri).rstrip("\0")
    path = uri.split("/", 3)[3]
    # a download of the first camera's file, held open (the client is slow): the other waits, however
    # long past the pacer's 1.5 s for an unfetched file
    reader, writer = await asyncio.open_connection("127.0.0.1", server.port)
    await eventually(lambda: server.active == 1, 5, "the download connected")
    await asyncio.sleep(2.5)
    assert len(_infos(r.peer)) == 1, "a CAMERA_INFORMATION went out during a definition download"
    writer.write(f"GET /{path} HTTP/1.1\r\nHost: x\r\n\r\n".encode())
    await writer.drain()
    body = await asyncio.wait_for(reader.read(), 30)
    writer.close()
    assert body.startswith(b"HTTP/1.1 200") and b"<mavlinkcamera>" in body
    await eventually(lambda: len(_infos(r.peer)) == 2, 5, "the second CAMERA_INFORMATION, after the download")
    assert sorted(_infos(r.peer)) == [VISIBLE, THERMAL]
    assert r.bridge.node.definition_pacer is not None and r.bridge.node.definition_pacer.held >= 1


async def test_all_at_once_answers_both_without_waiting(rig_factory: Any) -> None:
    r = await rig_factory("C12", definition_one_at_a_time=False)
    _ask_both(r.peer)
    await eventually(lambda: len(_infos(r.peer)) == 2, 5, "both CAMERA_INFORMATION")
    # answered with their acks, before anyone could have fetched anything
    assert r.bridge.definitions.served == 0 and r.bridge.node.definition_pacer is None


async def test_a_flood_of_requests_is_bounded_and_refused_temporarily(rig_factory: Any) -> None:
    r = await rig_factory("C12")
    server = r.bridge.definitions
    _reader, writer = await asyncio.open_connection("127.0.0.1", server.port)  # a download held open
    await eventually(lambda: server.active == 1, 5, "the download connected")
    r.peer.messages.clear()
    # one after the other, each a new command (confirmation 0), not retransmissions of the first
    results = [(await r.peer.ack(THERMAL, ml.MAV_CMD_REQUEST_MESSAGE, 259)).result for _ in range(12)]
    assert results == [0] * MAX_PACED_INFO + [ml.MAV_RESULT_TEMPORARILY_REJECTED] * (12 - MAX_PACED_INFO)
    assert _infos(r.peer) == []  # all of them wait
    writer.close()
    # every accepted request gets its own answer (each waits for the one before: unfetched, the
    # same file is not waited for again)
    await eventually(lambda: len(_infos(r.peer)) == MAX_PACED_INFO, 15, "an answer per accepted request")
