"""A failure text says what happened in its first words (issue 41 item 13): STATUSTEXT carries at
most 200 bytes (statustext.py), and a camera's address and the link's reason can fill that on their
own, so "may or may not have been ..." at the end was cut off. Virtual tier: a camera on a long
memory:// name that stops answering."""

from __future__ import annotations

import pytest
from pymavlink.dialects.v20 import common as ml

from .conftest import eventually
from .virtual import MemPeer, close_all, fresh_name, silence_replies, start_bridge, start_camera

pytestmark = pytest.mark.virtual

CAMERA = 100
PHOTO = ml.MAV_CMD_IMAGE_START_CAPTURE
LONG_NAME = "camera-on-the-left-wing-pod-of-the-survey-aircraft-" * 3  # a long address: 150+ bytes


def failure_text(peer: MemPeer) -> str:
    """The error STATUSTEXTs from the camera component, chunks joined (200 bytes at most)."""
    parts = [m.text for m in peer.messages if m.get_type() == "STATUSTEXT" and m.get_srcComponent() == CAMERA
             and m.severity <= ml.MAV_SEVERITY_ERROR]  # fmt: skip
    return "".join(parts)


@pytest.mark.parametrize(
    ("silence_s", "timeout_s", "words"),
    [
        (0.6, 3.0, "may or may not have been carried out"),  # the link declared lost in flight
        (30.0, 0.5, "may or may not have been taken"),  # the photo's own timeout
    ],
    ids=["link-lost-in-flight", "photo-timeout"],
)
async def test_photo_failure_keeps_its_key_words(silence_s: float, timeout_s: float, words: str) -> None:
    sim, url = await start_camera("C12", name=fresh_name(LONG_NAME))
    link = fresh_name("gcs")
    bridge = await start_bridge(url, "C12", link, silence_s=silence_s, timeout_s=timeout_s, retries=0)
    peer = MemPeer()
    try:
        await peer.join(link)
        await eventually(lambda: bridge.cam.answering, 10, "camera answering")
        silence_replies(sim, 60.0)
        ack = await peer.ack(CAMERA, PHOTO, 0, 0, 1, 0, timeout=30)
        assert ack.result == ml.MAV_RESULT_FAILED
        await eventually(lambda: "failed" in failure_text(peer), 5, "the failure's STATUSTEXT")
        text = failure_text(peer)
        assert len(text.encode()) > 150, f"not a long text, the test proves nothing: {text!r}"
        assert words in text, f"{words!r} cut off: {text!r}"
    finally:
        await close_all([peer, bridge, sim])
