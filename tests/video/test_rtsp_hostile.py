"""One RTSP client must not change what the others receive (issue 27): a PLAY flood asks the
encoder for a bounded number of keyframes, and URLs Python cannot parse are a 400, not a 500 with
a traceback. The server runs in-process with a stream fed by hand and a fake clock: the keyframe
count is checked, not a time."""

from __future__ import annotations

import logging
from collections.abc import AsyncIterator
from typing import Any

import pytest

from topgimbal.video import rtsp
from topgimbal.video.rtsp import RtspServer, Stream
from video.test_rtsp_abuse import Client, _picture

pytestmark = pytest.mark.loopback


class FakeClock:
    def __init__(self) -> None:
        self.t = 1000.0

    def __call__(self) -> float:
        return self.t


@pytest.fixture
async def counted() -> AsyncIterator[tuple[RtspServer, list[float], FakeClock]]:
    """A server whose stream counts the keyframes it asks the encoder for (at fake times)."""
    clock = FakeClock()
    asked: list[float] = []
    stream = Stream("/stream=1", "h264", on_keyframe_wanted=lambda: asked.append(clock.t), clock=clock)
    stream.publish(_picture(0))  # parameter sets known: DESCRIBE answers at once
    srv = await RtspServer("127.0.0.1", 0, [stream]).start()
    try:
        yield srv, asked, clock
    finally:
        await srv.close()


async def test_a_play_flood_asks_for_a_bounded_number_of_keyframes(
    counted: tuple[RtspServer, list[float], FakeClock],
) -> None:
    srv, asked, clock = counted
    stream = srv.streams["/stream=1"]
    viewer = await Client.connect(srv)
    flooder = await Client.connect(srv)
    try:
        clock.t += 60  # long after the last keyframe: the first receiver starts at once
        await viewer.play_tcp()
        assert len(asked) == 1
        sid = await flooder.play_tcp("2-3")
        # Before: every PLAY asked for a keyframe (200 PLAYs, 200 forced keyframes for everyone).
        for _ in range(200):
            assert (await flooder.ask("PLAY", Session=sid))[0] == 200
        assert len(asked) == 1
        # A new PLAY after a TEARDOWN + SETUP cycle is a new receiver: still bounded per stream.
        for n in range(20):
            assert (await flooder.ask("TEARDOWN", Session=sid))[0] == 200
            sid = await flooder.play_tcp("2-3")
            stream.publish(_picture(n % 100))  # pictures go on at the same (fake) instant
        assert len(asked) == 1
        # Time passes: one more is allowed per KEYFRAME_MIN_INTERVAL_S, however many want one.
        clock.t += rtsp.KEYFRAME_MIN_INTERVAL_S
        for _ in range(5):
            assert (await flooder.ask("TEARDOWN", Session=sid))[0] == 200
            sid = await flooder.play_tcp("2-3")
        stream.publish(AccessUnitLike.delta())
        assert len(asked) == 2
        assert asked[1] - asked[0] >= rtsp.KEYFRAME_MIN_INTERVAL_S
    finally:
        viewer.close()
        flooder.close()


async def test_a_wanted_keyframe_is_asked_for_once_the_interval_has_passed(
    counted: tuple[RtspServer, list[float], FakeClock],
) -> None:
    """A receiver refused a forced keyframe is not forgotten: the next picture after the interval
    asks for it, unless a keyframe came meanwhile (the encoder's own, every GOP)."""
    srv, asked, clock = counted
    stream = srv.streams["/stream=1"]
    stream.want_keyframe()
    assert len(asked) == 0  # the fixture's keyframe was just published (same fake instant)
    stream.publish(AccessUnitLike.delta())
    assert len(asked) == 0
    clock.t += rtsp.KEYFRAME_MIN_INTERVAL_S
    stream.publish(AccessUnitLike.delta())
    assert len(asked) == 1
    stream.publish(AccessUnitLike.delta())
    assert len(asked) == 1  # asked once, not on every picture
    # A keyframe that arrives on its own satisfies the wish.
    stream.want_keyframe()
    clock.t += 0.1
    stream.publish(_picture(3))
    clock.t += rtsp.KEYFRAME_MIN_INTERVAL_S
    stream.publish(AccessUnitLike.delta())
    assert len(asked) == 1


class AccessUnitLike:
    @staticmethod
    def delta() -> Any:
        from topgimbal.video.encode import AccessUnit

        return AccessUnit(b"\x00\x00\x00\x01\x41" + b"\x9a" * 16, False, 0.0, "h264")


@pytest.mark.parametrize(
    "url",
    [
        "rtsp://[::1/stream=1",  # unterminated IPv6 literal
        "rtsp://[abc]/stream=1",  # not an IPv6 address in brackets
        "rtsp://a]b/stream=1",
        "rtsp://host\uff03:554/stream=1",  # NFKC makes a '#' of it: urlsplit refuses
        "rtsp://[v1.x/stream=1",
    ],
)
@pytest.mark.parametrize("method", ["DESCRIBE", "SETUP"])
async def test_a_url_that_cannot_be_parsed_is_a_400_without_a_traceback(
    server: RtspServer, url: str, method: str, caplog: Any
) -> None:
    caplog.set_level(logging.INFO, "topgimbal.video.rtsp")
    c = await Client.connect(server)
    try:
        code, _ = await c.ask(method, url, Transport="RTP/AVP/TCP;unicast;interleaved=0-1")
        assert code == 400
        assert not [r for r in caplog.records if r.exc_info], "no traceback for a client's bad URL"
        assert any("URL" in r.getMessage() for r in caplog.records), "a clear log line"
        assert (await c.ask("OPTIONS"))[0] == 200  # the connection goes on
    finally:
        c.close()


@pytest.fixture
async def server() -> AsyncIterator[RtspServer]:
    stream = Stream("/stream=1", "h264")
    stream.publish(_picture(0))
    srv = await RtspServer("127.0.0.1", 0, [stream]).start()
    try:
        yield srv
    finally:
        await srv.close()


async def test_a_setup_after_the_codec_changed_since_describe_is_refused_until_described_again() -> None:
    """ffprobe asked DESCRIBE (the SDP said H.264), the encoder then restarted in H.265, and its SETUP
    and PLAY got H.265 under an H.264 SDP: nothing decodable, and ffprobe read until killed (the
    flake harness, tests/video/test_stream.py). A SETUP now answers 503 when the stream's codec
    changed since this connection's DESCRIBE; describing again gives the new SDP and a session."""
    stream = Stream("/stream=1", "h264")
    stream.publish(_picture(0))
    srv = await RtspServer("127.0.0.1", 0, [stream]).start()
    client = await Client.connect(srv)
    try:
        assert (await client.ask("DESCRIBE"))[0] == 200  # told: H.264
        stream.restart("h265")  # the encoder restarts (the poll of the codec setting)
        code, _ = await client.ask("SETUP", Transport="RTP/AVP/TCP;unicast;interleaved=0-1")
        assert code == 503
        assert not stream.sessions  # nothing set up under the stale SDP
        stream.publish(_picture(1))  # an H.264 picture after the change: not this stream's any more
        assert not stream.ready.is_set()
        # A client that never described is not refused (it reads the codec from the RTP it gets).
        other = await Client.connect(srv)
        try:
            assert (await other.ask("SETUP", Transport="RTP/AVP/TCP;unicast;interleaved=0-1"))[0] == 200
        finally:
            other.close()
        # Describing again, once the stream is ready, tells the codec of now: SETUP then goes on.
        stream.restart("h264")  # back (a third generation), so that a hand-made picture makes it ready
        stream.publish(_picture(2))
        assert (await client.ask("DESCRIBE"))[0] == 200
        assert (await client.ask("SETUP", Transport="RTP/AVP/TCP;unicast;interleaved=0-1"))[0] == 200
    finally:
        client.close()
        await srv.close()
