"""The failure sign a ground station gets under ArduPilot (issue 32, item 5): STATUSTEXT longer
than 50 bytes goes as MAVLink 2 chunks (`id`, `chunk_seq`), with the command first."""

from __future__ import annotations

from typing import Any

import pytest
from pymavlink.dialects.v20 import common as ml

from topgimbal.mavlink.statustext import CHUNK_BYTES, MAX_CHUNKS, chunks

from .conftest import eventually

pytestmark = pytest.mark.external

CAMERA = 100


def test_chunks() -> None:
    assert chunks("short") == [b"short"]
    assert chunks("") == [b""]
    text = "x" * 120
    assert [len(c) for c in chunks(text)] == [50, 50, 20]
    assert [len(c) for c in chunks("y" * 100)] == [50, 50, 0]  # the last chunk full: an empty one ends it
    long = chunks("z" * 1000)
    assert len(long) == MAX_CHUNKS and long[-1].endswith(b"...")
    # never inside a UTF-8 character: each chunk decodes on its own
    for c in chunks("é" * 80):
        assert len(c) <= CHUNK_BYTES
        c.decode("utf-8")
    assert b"".join(chunks("é" * 80)).decode() == "é" * 80


def reassemble(messages: list[Any]) -> dict[int, str]:
    """Each chunked STATUSTEXT's full text by id (chunks in chunk_seq order)."""
    by_id: dict[int, list[Any]] = {}
    for m in messages:
        if m.get_type() == "STATUSTEXT" and m.id:
            by_id.setdefault(m.id, []).append(m)
    return {i: "".join(c.text for c in sorted(parts, key=lambda c: c.chunk_seq)) for i, parts in by_id.items()}


async def test_a_failed_photo_is_said_whole_with_the_command_first(rig_factory: Any) -> None:
    r = await rig_factory("C12")
    p = r.peer
    await r.sim.stop()
    await eventually(lambda: not r.bridge.cam.answering, 10, "camera down")
    ack = await p.ack(CAMERA, ml.MAV_CMD_IMAGE_START_CAPTURE, 0, 0, 1, 1)
    assert ack.result == ml.MAV_RESULT_FAILED
    await eventually(lambda: bool(reassemble(p.messages)), 5, "a chunked STATUSTEXT")
    texts = list(reassemble(p.messages).values())
    assert texts[0].startswith("IMAGE_START_CAPTURE failed: "), texts
    assert r.sim.url.split("//")[1] in texts[0], "the text is cut: the camera's address is missing"
    chunked = [m for m in p.messages if m.get_type() == "STATUSTEXT" and m.id]
    assert [m.chunk_seq for m in chunked][:2] == [0, 1] and all(m.severity == 3 for m in chunked)
