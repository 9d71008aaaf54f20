"""WHEP (video/webrtc.py): a lens's H.264 over WebRTC without re-encoding. aiortc plays the
other side here (as any WHEP player would); the Chromium test is test_console_webrtc.py. ICE stays
on loopback: the console offers only the address the player reached it on."""

from __future__ import annotations

import asyncio
import urllib.error
import urllib.request
from collections.abc import Iterator
from typing import Any

import pytest

from console.conftest import BackgroundConsole
from topgimbal.video import webrtc
from topgimbal.video.render import decode_stamp

pytestmark = [pytest.mark.loopback, pytest.mark.integration]


@pytest.fixture(scope="module")
def console() -> Iterator[BackgroundConsole]:
    with BackgroundConsole("C12", token="t0ken") as bg:
        yield bg


def http(bg: BackgroundConsole, method: str, path: str, body: bytes = b"", headers: dict[str, str] | None = None,
         ) -> tuple[int, dict[str, str], bytes]:  # fmt: skip
    req = urllib.request.Request(bg.url.split("?")[0].rstrip("/") + path, data=body or None, method=method,
                                 headers={"X-Topgimbal-Token": "t0ken", **(headers or {})})  # fmt: skip
    try:
        with urllib.request.urlopen(req, timeout=30) as r:
            return r.status, dict(r.headers), r.read()
    except urllib.error.HTTPError as e:
        return e.code, dict(e.headers), e.read()


async def play(bg: BackgroundConsole, lens: str, pictures: int) -> tuple[list[Any], str]:
    """A WHEP session: the stamps of `pictures` decoded pictures and the session's URL."""
    from aiortc import RTCConfiguration, RTCPeerConnection, RTCSessionDescription

    webrtc._patch_aioice()
    webrtc._ice_host.set("127.0.0.1")  # this player, too, offers loopback only
    pc = RTCPeerConnection(RTCConfiguration(iceServers=[]))
    pc.addTransceiver("video", direction="recvonly")
    got: asyncio.Future[Any] = asyncio.get_running_loop().create_future()
    pc.on("track", lambda track: got.set_result(track))
    await pc.setLocalDescription(await pc.createOffer())
    status, headers, body = await asyncio.to_thread(
        http, bg, "POST", f"/video/{lens}/whep", pc.localDescription.sdp.encode(), {"Content-Type": "application/sdp"}
    )
    assert status == 201, body
    assert headers["Content-Type"].startswith("application/sdp") and "H264" in body.decode()
    await pc.setRemoteDescription(RTCSessionDescription(body.decode(), "answer"))
    track = await asyncio.wait_for(got, 30)
    stamps = []
    try:
        for _ in range(pictures):
            frame = await asyncio.wait_for(track.recv(), 30)
            stamps.append(decode_stamp(frame.to_ndarray(format="rgb24")))
    finally:
        await pc.close()
    return stamps, headers["Location"]


def test_whep_plays_the_lens_as_encoded_and_delete_ends_it(console: BackgroundConsole) -> None:
    stamps, location = asyncio.run(play(console, "visible", 10))
    assert None not in stamps and stamps == sorted(stamps) and len(set(stamps)) == 10
    assert location.startswith("/video/visible/whep/")
    status, _, _ = http(console, "DELETE", location)
    assert status in (200, 404)  # 404: the closed peer connection already ended it
    assert http(console, "DELETE", location)[0] == 404


def test_whep_refuses_what_it_cannot_answer(console: BackgroundConsole) -> None:
    sdp = {"Content-Type": "application/sdp"}
    assert http(console, "POST", "/video/zoom/whep", b"v=0\r\n", sdp)[0] == 404
    assert http(console, "POST", "/video/visible/whep", b"v=0\r\n", {"Content-Type": "text/plain"})[0] == 415
    assert http(console, "POST", "/video/visible/whep", b"v=0\r\n", sdp)[0] == 400  # no video section
    assert http(console, "POST", "/video/visible/whep", b"v=0\r\nm=video 9 x\r\n", sdp)[0] == 400  # garbage
    big = b"v=0\r\nm=video" + b"x" * webrtc.MAX_OFFER_BYTES
    assert http(console, "POST", "/video/visible/whep", big, sdp)[0] == 413
    # the token and the origin rules of every route
    req = urllib.request.Request(console.url.split("?")[0].rstrip("/") + "/video/visible/whep", data=b"v=0",
                                 method="POST", headers=sdp)  # fmt: skip
    with pytest.raises(urllib.error.HTTPError) as e:
        urllib.request.urlopen(req, timeout=30)
    assert e.value.code == 401
    status, _, _ = http(console, "POST", "/video/visible/whep", b"v=0\r\n", {**sdp, "Origin": "http://evil.example"})
    assert status == 403


def test_peers_per_lens_are_bounded() -> None:
    server = webrtc.WhepServer({"visible": "rtsp://127.0.0.1:9/x"})
    server.sessions = {str(i): webrtc._Session(str(i), "visible", None, None, 0.0) for i in range(webrtc.MAX_PEERS)}
    with pytest.raises(webrtc.WebRtcError) as e:
        asyncio.run(server.answer("visible", "v=0\r\nm=video 9 UDP/TLS/RTP/SAVPF 96\r\n", "127.0.0.1"))
    assert e.value.status == 503


def test_no_session_for_a_stream_that_is_not_there() -> None:
    async def offer() -> None:
        server = webrtc.WhepServer({"visible": "rtsp://127.0.0.1:9/nothing"})  # port 9: refused at once
        try:
            await server.answer("visible", "v=0\r\nm=video 9 UDP/TLS/RTP/SAVPF 96\r\n", "127.0.0.1")
        finally:
            await server.close()

    with pytest.raises(webrtc.WebRtcError) as e:
        asyncio.run(offer())
    assert e.value.status == 502 and "no picture from the visible stream" in str(e.value)


def test_the_page_can_ask_whether_a_lens_plays_over_webrtc(console: BackgroundConsole) -> None:
    import json

    status, _, body = http(console, "GET", "/video/visible/whep")
    assert status == 200 and json.loads(body) == {"ready": True, "codec": "h264", "why": None}
    assert http(console, "GET", "/video/zoom/whep")[0] == 404


def test_a_loopback_console_keeps_only_loopback_candidates() -> None:
    """A browser lists every interface and mDNS names; a console reached on loopback must put no
    connectivity check on any other address (nor resolve x.local by multicast)."""
    from topgimbal.video.webrtc import remote_candidates

    offer = "\r\n".join([
        "v=0",
        "m=video 9 UDP/TLS/RTP/SAVPF 96",
        "a=candidate:1 1 udp 2122260223 127.0.0.1 50000 typ host",
        "a=candidate:2 1 udp 2122194687 192.0.2.2 50001 typ host",
        "a=candidate:3 1 udp 2122129151 0f1e2d3c-aaaa.local 50002 typ host",
        "a=candidate:4 1 udp 2122063615 ::1 50003 typ host",
        "a=mid:0",
    ]) + "\r\n"  # fmt: skip
    kept = remote_candidates(offer, "127.0.0.1")
    assert "127.0.0.1 50000" in kept and "::1 50003" in kept
    assert "192.0.2.2" not in kept and ".local" not in kept
    assert "a=mid:0" in kept and "m=video" in kept


def test_a_lan_console_keeps_only_candidates_on_its_own_network(monkeypatch: pytest.MonkeyPatch) -> None:
    """Issue 43.5: a token holder's offer must not make the console send STUN anywhere: only
    candidates on the network of the address the browser reached are kept."""
    import ifaddr

    from topgimbal.video.webrtc import remote_candidates

    lan = ifaddr.Adapter("eth0", "eth0", [ifaddr.IP("192.0.2.2", 24, "eth0"), ifaddr.IP(("fd00::2", 0, 0), 64, "eth0")])
    other = ifaddr.Adapter("wg0", "wg0", [ifaddr.IP("10.7.0.1", 16, "wg0")])
    monkeypatch.setattr(ifaddr, "get_adapters", lambda: [lan, other])
    cands = ["192.0.2.77", "10.7.0.9", "10.1.2.3", "169.254.169.254", "8.8.8.8", "224.0.0.251", "0.0.0.0",
             "127.0.0.1", "0f1e2d3c-aaaa.local", "fd00::9", "fe80::1", "ff02::1"]  # fmt: skip
    offer = "\r\n".join(["v=0", "m=video 9 UDP/TLS/RTP/SAVPF 96"] + [
        f"a=candidate:{i} 1 udp 2122260223 {a} {50000 + i} typ host" for i, a in enumerate(cands)] + ["a=mid:0"]) + "\r\n"  # fmt: skip
    kept = [line.split()[4] for line in remote_candidates(offer, "192.0.2.2").splitlines() if "candidate" in line]
    assert kept == ["192.0.2.77"], kept
    kept6 = [line.split()[4] for line in remote_candidates(offer, "fd00::2").splitlines() if "candidate" in line]
    assert kept6 == ["fd00::9"], kept6
    # an address no interface holds: no network, no candidate
    assert "candidate" not in remote_candidates(offer, "198.51.100.1")
