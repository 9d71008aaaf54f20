"""What a page may send (limits.py) and what waits for a page (peer.py), without a server."""

from __future__ import annotations

import asyncio
import json
import logging
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from topgimbal.console.limits import (
    MAX_DEPTH,
    MAX_MESSAGE_BYTES,
    MAX_NUMBER_ABS,
    MessageError,
    OpRate,
    parse_message,
    too_deep,
)
from topgimbal.console.peer import Peer, PeerLimits

pytestmark = [pytest.mark.virtual, pytest.mark.fuzz]

SETTINGS = settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])


def _nested(depth: int) -> str:
    return '{"op": "status", "x": ' + "[" * (depth - 1) + "]" * (depth - 1) + "}"


def test_a_valid_op_passes() -> None:
    assert parse_message('{"op": "point", "ref": 3, "yaw": -12.5, "pitch": 1e2}') == {
        "op": "point",
        "ref": 3,
        "yaw": -12.5,
        "pitch": 100.0,
    }


@pytest.mark.parametrize(
    ("text", "says"),
    [
        ("[" * 100_000 + "]" * 100_000, "message too long"),  # the 100k-deep document of issue 9
        ("[" * 30_000 + "]" * 30_000, "nested too deeply"),
        ('{"op": "point", "yaw": 1' + "0" * 400 + "}", "too large"),  # 10**400
        ('{"op": "point", "yaw": 1e400}', "too large"),
        ('{"op": "point", "yaw": -1e400}', "too large"),
        ('{"op": "point", "yaw": 2e15}', "too large"),
        ('{"op": "point", "yaw": 10000000000000001}', "too large"),
        ('{"op": "point", "yaw": NaN}', "NaN is not allowed"),
        ('{"op": "point", "yaw": Infinity}', "Infinity is not allowed"),
        ('{"op": "point", "yaw": -Infinity}', "-Infinity is not allowed"),
        ('{"op": "x", "pad": "' + "a" * MAX_MESSAGE_BYTES + '"}', "message too long"),
        ("not json", "not valid JSON"),
        ('{"op": "status"', "not valid JSON"),
        ("[1, 2]", "got an array"),
        ('"status"', "got a string"),
        ("42", "got a number"),
        ("null", "got null"),
        ("true", "got true"),
        ("", "not valid JSON"),
    ],
)
def test_refused_messages_say_why(text: str, says: str) -> None:
    with pytest.raises(MessageError) as exc:
        parse_message(text)
    assert says in str(exc.value)
    assert len(str(exc.value)) < 200  # the offending text is never echoed at length


def test_binary_messages_are_refused() -> None:
    with pytest.raises(MessageError, match="binary messages are not accepted"):
        parse_message(b'{"op": "status"}')


def test_depth_limit_is_exact_and_ignores_brackets_in_strings() -> None:
    assert parse_message(_nested(MAX_DEPTH))["op"] == "status"
    with pytest.raises(MessageError, match="nested too deeply"):
        parse_message(_nested(MAX_DEPTH + 1))
    text = '{"op": "raw", "frame": "' + "[{" * 500 + '\\"' + "[" * 100 + '"}'
    assert not too_deep(text)
    assert parse_message(text)["op"] == "raw"


def test_number_limit_is_exact() -> None:
    assert parse_message(f'{{"n": {int(MAX_NUMBER_ABS)}, "m": -{MAX_NUMBER_ABS:.0f}.0}}') == {
        "n": int(MAX_NUMBER_ABS),
        "m": -MAX_NUMBER_ABS,
    }
    with pytest.raises(MessageError):
        parse_message(f'{{"n": {int(MAX_NUMBER_ABS) + 1}}}')


json_values = st.recursive(
    st.none()
    | st.booleans()
    | st.integers(min_value=-(10**30), max_value=10**30)
    | st.floats(allow_nan=True, allow_infinity=True)
    | st.text(max_size=30),
    lambda children: st.lists(children, max_size=5) | st.dictionaries(st.text(max_size=8), children, max_size=5),
    max_leaves=40,
)


@SETTINGS
@given(st.one_of(json_values.map(json.dumps), st.text(max_size=300), st.binary(max_size=100)))
def test_anything_parses_or_is_refused_with_a_message_error(data: Any) -> None:
    try:
        msg = parse_message(data)
    except MessageError as exc:
        assert str(exc)
        return
    assert isinstance(msg, dict)
    json.dumps(msg, allow_nan=False)  # what passed is plain, finite JSON


@SETTINGS
@given(st.integers(min_value=1, max_value=3 * MAX_DEPTH), st.sampled_from("[{"))
def test_depth_scan_agrees_with_the_parser(depth: int, bracket: str) -> None:
    close = "]" if bracket == "[" else "}"
    inner = "1" if bracket == "[" else ""
    text = bracket * depth + inner + close * depth if bracket == "[" else '{"a":' * depth + "1" + "}" * depth
    assert too_deep(text) == (depth > MAX_DEPTH)
    assert not too_deep(json.dumps({"s": text}))  # the same text inside a string


# -- the outgoing queue ------------------------------------------------------------------------


class _StuckSocket:
    """A page that never reads: send_str blocks once the first message is handed over."""

    closed = False

    def __init__(self) -> None:
        self.sent: list[str] = []
        self.release = asyncio.Event()

    async def send_str(self, text: str) -> None:
        self.sent.append(text)
        await self.release.wait()


class _Transport:
    def __init__(self) -> None:
        self.aborted = 0

    def abort(self) -> None:
        self.aborted += 1


async def test_a_page_that_stops_reading_loses_periodic_pushes_then_is_disconnected(
    caplog: pytest.LogCaptureFixture,
) -> None:
    caplog.set_level(logging.INFO)
    ws, transport = _StuckSocket(), _Transport()
    peer = Peer(
        ws, "test-page", limits=PeerLimits(soft_limit=8, max_messages=50, max_bytes=10_000), transport=transport
    )  # type: ignore[arg-type]
    writer = asyncio.create_task(peer.run())
    try:
        for i in range(1000):
            peer.send({"type": "attitude", "yaw": i}, essential=False)
            await asyncio.sleep(0)
        assert len(ws.sent) == 1  # stuck in the first send
        assert len(peer.queue) == 8 and peer.dropped == 1000 - 9
        assert sum(1 for r in caplog.records if "not keeping up" in r.getMessage()) == 1
        assert not peer.closed
        # replies are never dropped: they queue up to the limit, then the page is cut off
        n = 0
        while not peer.closed:
            peer.send({"type": "ack", "ref": n, "result": "x" * 100})
            n += 1
            assert len(peer.queue) <= 50 and peer.queued_bytes <= 10_000
        assert n < 100 and transport.aborted == 1 and peer.overflowed
        assert len(peer.queue) == 0 and peer.queued_bytes == 0  # freed
        line = next(r.getMessage() for r in caplog.records if "stopped reading" in r.getMessage())
        assert "test-page" in line and "disconnected" in line
        peer.send({"type": "ack"})  # after the disconnect: ignored, nothing grows
        assert len(peer.queue) == 0
    finally:
        ws.release.set()
        await asyncio.wait_for(writer, 5)


async def test_a_page_that_keeps_up_gets_everything_in_order() -> None:
    class Reader:
        closed = False

        def __init__(self) -> None:
            self.got: list[dict[str, Any]] = []

        async def send_str(self, text: str) -> None:
            self.got.append(json.loads(text))

    ws = Reader()
    peer = Peer(ws, "fast", limits=PeerLimits(soft_limit=4))  # type: ignore[arg-type]
    writer = asyncio.create_task(peer.run())
    for i in range(100):
        peer.send({"i": i}, essential=i % 2 == 0)
        await asyncio.sleep(0)
    while peer.queue:
        await asyncio.sleep(0)
    peer.close()
    await asyncio.wait_for(writer, 5)
    assert [m["i"] for m in ws.got] == list(range(100)) and peer.dropped == 0


def test_op_rate_lets_bursts_through_and_spaces_out_a_flood() -> None:
    rate = OpRate(rate_per_s=100, burst=50)
    now = 1000.0
    assert [rate.delay_s(now) for _ in range(50)] == [0.0] * 50  # a burst of 50 at once
    assert rate.delay_s(now) == pytest.approx(0.01)  # the 51st waits one period
    assert rate.delay_s(now) == pytest.approx(0.02)
    now += 10.0  # after a quiet spell the burst is back (and no more than the burst)
    assert [rate.delay_s(now) for _ in range(50)] == [0.0] * 50
    assert rate.delay_s(now) > 0
    # a steady 100 a second never waits
    steady = OpRate(rate_per_s=100, burst=50)
    assert all(steady.delay_s(2000.0 + i / 100) == 0.0 for i in range(1000))
    # a flood of 1000 at once is spread over (1000 - 50) / 100 s
    flood = OpRate(rate_per_s=100, burst=50)
    assert max(flood.delay_s(3000.0) for _ in range(1000)) == pytest.approx(9.5)
