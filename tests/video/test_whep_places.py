"""Issue 43.5: the WHEP places of a lens hold under concurrent offers and offers that never
finish ICE, and the last place is the console's page's."""

from __future__ import annotations

import asyncio
import json
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor

import pytest

from console.conftest import BackgroundConsole
from topgimbal.video import webrtc

from .test_whep import http, play

pytestmark = pytest.mark.loopback

SDP = {"Content-Type": "application/sdp"}


@pytest.fixture(scope="module")
def console() -> Iterator[BackgroundConsole]:
    with BackgroundConsole("C12", token="t0ken") as bg:
        yield bg


async def idle_offer() -> str:
    """A real offer from a player that will never finish ICE (it never reads the answer)."""
    from aiortc import RTCConfiguration, RTCPeerConnection

    pc = RTCPeerConnection(RTCConfiguration(iceServers=[]))
    pc.addTransceiver("video", direction="recvonly")
    await pc.setLocalDescription(await pc.createOffer())
    sdp: str = pc.localDescription.sdp
    await pc.close()
    return sdp.replace("\r\na=candidate:", "\r\na=x-none:")  # no candidate: nothing to connect to


def webrtc_peers(bg: BackgroundConsole) -> int:
    status, _, body = http(bg, "GET", "/api/video")
    assert status == 200, body
    (visible,) = [x for x in json.loads(body)["lenses"] if x["lens"] == "visible"]
    return int(visible["webrtc"]["peers"])


def test_concurrent_offers_never_pass_the_limit_and_idle_offers_lock_nobody_out(console: BackgroundConsole) -> None:
    offer = asyncio.run(idle_offer()).encode()
    with ThreadPoolExecutor(12) as pool:
        statuses = list(pool.map(lambda _: http(console, "POST", "/video/visible/whep", offer, SDP)[0], range(12)))
    assert statuses.count(201) <= webrtc.MAX_PEERS and set(statuses) <= {201, 503}, statuses
    assert webrtc_peers(console) <= webrtc.MAX_CONNECTING  # none of them connects: at most this many wait
    for _ in range(4):  # four more that never finish ICE
        assert http(console, "POST", "/video/visible/whep", offer, SDP)[0] in (201, 503)
    stamps, location = asyncio.run(play(console, "visible", 5))  # a real viewer still gets a place
    assert None not in stamps and len(set(stamps)) == 5
    http(console, "DELETE", location)


def test_the_last_place_is_the_pages() -> None:
    server = webrtc.WhepServer({"visible": "rtsp://127.0.0.1:9/x"})  # port 9: nothing answers
    # placeholders for connected peers (no peer connection: counted as connected)
    server.sessions = {str(i): webrtc._Session(str(i), "visible", None, None, 0.0) for i in range(webrtc.MAX_PEERS - 1)}
    offer = "v=0\r\nm=video 9 UDP/TLS/RTP/SAVPF 96\r\n"
    with pytest.raises(webrtc.WebRtcError) as e:
        asyncio.run(server.answer("visible", offer, "127.0.0.1", page=False))
    assert e.value.status == 503
    with pytest.raises(webrtc.WebRtcError) as e:  # the page passes the place check (then: no picture)
        asyncio.run(server.answer("visible", offer, "127.0.0.1", page=True))
    assert e.value.status == 502 and server.peers("visible") == webrtc.MAX_PEERS - 1
