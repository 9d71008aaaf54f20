"""The WebSocket under hostile or careless pages (issue 9): oversized, deeply nested, huge-number,
binary and random messages get a clear error and the socket stays usable; pages and ops in flight
are capped; a page that stops reading is cut off. No traceback reaches the log for any input."""

from __future__ import annotations

import asyncio
import base64
import json
import logging
import os
import socket
import struct
import threading
from collections.abc import AsyncIterator, Iterator, Mapping
from typing import Any

import aiohttp
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from topgimbal.console import ConsoleServer
from topgimbal.console.limits import MAX_FRAME_BYTES, MAX_MESSAGE_BYTES, MessageError, parse_message
from topgimbal.console.ops import OPS
from topgimbal.console.peer import PeerLimits
from waiting import until

from .conftest import BackgroundConsole, wait_for

pytestmark = [pytest.mark.loopback, pytest.mark.integration]


class LogTrap(logging.Handler):
    """Every record of the process (all threads): the tests assert no traceback and no ERROR."""

    def __init__(self) -> None:
        super().__init__(logging.DEBUG)
        self.records: list[logging.LogRecord] = []
        self._lock_records = threading.Lock()

    def emit(self, record: logging.LogRecord) -> None:
        with self._lock_records:
            self.records.append(record)

    def problems(self) -> list[str]:
        with self._lock_records:
            return [
                f"{r.name}: {r.getMessage()}"
                for r in self.records
                if r.exc_info is not None or r.levelno >= logging.ERROR
            ]


@pytest.fixture
def log_trap() -> Iterator[LogTrap]:
    trap = LogTrap()
    root = logging.getLogger()
    old = root.level
    root.addHandler(trap)
    root.setLevel(logging.DEBUG)
    try:
        yield trap
    finally:
        root.removeHandler(trap)
        root.setLevel(old)


@pytest.fixture
async def console() -> AsyncIterator[ConsoleServer]:
    async with ConsoleServer(sim_model="C12", port=0) as srv:
        yield srv


async def _reply(ws: aiohttp.ClientWebSocketResponse, pred: Any, timeout: float = 10.0) -> dict[str, Any]:
    """The next message satisfying `pred` (pushes in between are skipped)."""
    loop = asyncio.get_running_loop()
    deadline = loop.time() + timeout
    while True:
        msg = await ws.receive_json(timeout=max(0.01, deadline - loop.time()))
        if pred(msg):
            return msg  # type: ignore[no-any-return]


def _refusal(msg: Mapping[str, Any]) -> bool:
    return msg.get("type") == "error" and msg.get("ref") is None and "source" not in msg


async def _still_usable(ws: aiohttp.ClientWebSocketResponse, ref: str) -> None:
    await ws.send_json({"op": "status", "ref": ref})
    ack = await _reply(ws, lambda m: m.get("ref") == ref)
    assert ack["type"] == "ack" and ack["result"]["link"] in ("up", "waiting")


async def test_limits_are_answered_and_the_socket_stays_usable(console: ConsoleServer, log_trap: LogTrap) -> None:
    cases: list[tuple[str | bytes, str]] = [
        ("[" * 100_000 + "]" * 100_000, "message too long"),
        ("[" * 30_000 + "]" * 30_000, "nested too deeply"),
        ('{"op": "point", "ref": 1, "yaw": 1' + "0" * 400 + "}", "too large"),
        ('{"op": "point", "ref": 1, "yaw": 1e400}', "too large"),
        ('{"op": "point", "ref": 1, "yaw": NaN}', "NaN is not allowed"),
        ("x" * (MAX_MESSAGE_BYTES + 1), "message too long"),
        ("not json", "not valid JSON"),
        ("[]", "got an array"),
        (b"\x00\x01binary", "binary messages are not accepted"),
    ]
    async with aiohttp.ClientSession() as http, http.ws_connect(console.base_url + "ws", max_msg_size=0) as ws:
        for i, (data, says) in enumerate(cases):
            if isinstance(data, bytes):
                await ws.send_bytes(data)
            else:
                await ws.send_str(data)
            msg = await _reply(ws, _refusal)
            assert says in msg["message"], (i, msg)
            assert msg["kind"] == "op"
            await _still_usable(ws, f"after-{i}")
        # a big number given as a string reaches the op and is refused there, not as "internal"
        await ws.send_json({"op": "point", "ref": "s", "yaw": "1" + "0" * 400})
        msg = await _reply(ws, lambda m: m.get("ref") == "s")
        assert msg["type"] == "error" and msg["kind"] == "op" and "not a finite number" in msg["message"]
    assert log_trap.problems() == []


async def test_a_message_beyond_the_frame_limit_closes_with_1009(console: ConsoleServer, log_trap: LogTrap) -> None:
    async with aiohttp.ClientSession() as http:
        async with http.ws_connect(console.base_url + "ws") as ws:
            await ws.send_str("x" * (MAX_FRAME_BYTES + 1))
            while True:
                msg = await ws.receive(timeout=30)
                if msg.type in (aiohttp.WSMsgType.CLOSE, aiohttp.WSMsgType.CLOSED, aiohttp.WSMsgType.CLOSING):
                    break
            assert ws.close_code == 1009  # "message too big", refused before it was buffered
        async with http.ws_connect(console.base_url + "ws") as ws:  # the console carries on
            await _still_usable(ws, "next")
    assert log_trap.problems() == []


async def test_pages_are_capped(console: ConsoleServer, log_trap: LogTrap) -> None:
    assert console.hub is not None
    console.hub.max_pages = 2
    async with aiohttp.ClientSession() as http:
        a = await http.ws_connect(console.base_url + "ws")
        b = await http.ws_connect(console.base_url + "ws")
        with pytest.raises(aiohttp.WSServerHandshakeError) as exc:
            await http.ws_connect(console.base_url + "ws")
        assert exc.value.status == 503
        async with http.get(console.base_url + "ws") as r:
            assert r.status == 503 and "at most 2" in (await r.json())["message"]
        await a.close()
        await wait_for_async(lambda: len(console.hub.peers) == 1 if console.hub else False)
        c = await http.ws_connect(console.base_url + "ws")
        await _still_usable(c, "c")
        await _still_usable(b, "b")
        await b.close()
        await c.close()
    assert any("2 pages are open" in r.getMessage() for r in log_trap.records)
    assert log_trap.problems() == []


async def test_concurrent_handshakes_respect_the_page_cap(console: ConsoleServer, log_trap: LogTrap) -> None:
    assert console.hub is not None
    console.hub.max_pages = 3
    async with aiohttp.ClientSession() as http:
        results = await asyncio.gather(
            *(http.ws_connect(console.base_url + "ws") for _ in range(8)), return_exceptions=True
        )
        opened = [r for r in results if isinstance(r, aiohttp.ClientWebSocketResponse)]
        refused = [r for r in results if isinstance(r, aiohttp.WSServerHandshakeError)]
        assert (len(opened), len(refused)) == (3, 5)
        assert all(r.status == 503 for r in refused)
        for ws in opened:
            await ws.close()
    assert log_trap.problems() == []


async def wait_for_async(pred: Any, timeout: float = 10.0) -> None:
    await until("the hub's state", pred, bound_s=timeout)  # tests/waiting.py


async def test_ops_in_flight_are_capped(
    console: ConsoleServer, monkeypatch: pytest.MonkeyPatch, log_trap: LogTrap
) -> None:
    from topgimbal.console.hub import MAX_OPS_IN_FLIGHT

    release = asyncio.Event()
    started = 0

    async def slow(cam: Any, args: Mapping[str, Any]) -> str:
        nonlocal started
        started += 1
        await release.wait()
        return "done"

    monkeypatch.setitem(OPS, "slow", slow)
    async with aiohttp.ClientSession() as http, http.ws_connect(console.base_url + "ws") as ws:
        for i in range(MAX_OPS_IN_FLIGHT):
            await ws.send_json({"op": "slow", "ref": i})
        await wait_for_async(lambda: started == MAX_OPS_IN_FLIGHT)
        await ws.send_json({"op": "slow", "ref": "one-too-many"})
        msg = await _reply(ws, lambda m: m.get("ref") == "one-too-many")
        assert msg["type"] == "error" and f"at most {MAX_OPS_IN_FLIGHT}" in msg["message"]
        release.set()
        acked = set()
        while len(acked) < MAX_OPS_IN_FLIGHT:
            m = await _reply(ws, lambda m: m.get("type") == "ack" and m.get("op") == "slow")
            acked.add(m["ref"])
        assert acked == set(range(MAX_OPS_IN_FLIGHT))
    assert log_trap.problems() == []


async def test_a_flooding_page_is_paced_and_does_not_starve_another(
    console: ConsoleServer, monkeypatch: pytest.MonkeyPatch, log_trap: LogTrap
) -> None:
    """1000 ops sent at once are handled at the page's rate (100 a second after a burst of 50),
    so another page's op is answered while most of the flood still waits, unread, in TCP."""
    handled = 0

    async def count(cam: Any, args: Mapping[str, Any]) -> int:
        nonlocal handled
        handled += 1
        return handled

    monkeypatch.setitem(OPS, "count", count)
    async with aiohttp.ClientSession() as http:
        flooder = aiohttp.ClientSession()
        flood = await flooder.ws_connect(console.base_url + "ws")
        good = await http.ws_connect(console.base_url + "ws")
        for i in range(1000):
            await flood.send_json({"op": "count", "ref": i})
        await _still_usable(good, "good")
        assert 0 < handled < 1000
        await flooder.connector.close()  # gone without a goodbye: the rest is never handled
        await wait_for_async(lambda: len(console.hub.peers) == 1 if console.hub else False)
        assert handled < 1000
        await flooder.close()
        await good.close()
    assert log_trap.problems() == []


# -- a page that never reads, over a raw socket ----------------------------------------------------


def _client_frame(text: str) -> bytes:
    """One masked WebSocket text frame (what a browser sends)."""
    payload = text.encode()
    mask = os.urandom(4)
    n = len(payload)
    head = bytes([0x81]) + (bytes([0x80 | n]) if n < 126 else bytes([0x80 | 126]) + struct.pack("!H", n))
    return head + mask + bytes(b ^ mask[i % 4] for i, b in enumerate(payload))


def _open_raw_ws(port: int) -> socket.socket:
    s = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)  # fill up quickly
    s.connect(("127.0.0.1", port))
    key = base64.b64encode(os.urandom(16)).decode()
    s.sendall(
        (
            f"GET /ws HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
            f"Sec-WebSocket-Key: {key}\r\nSec-WebSocket-Version: 13\r\n\r\n"
        ).encode()
    )
    head = b""
    while b"\r\n\r\n" not in head:
        head += s.recv(1)
    assert head.startswith(b"HTTP/1.1 101"), head
    return s


def test_a_page_that_stops_reading_is_disconnected(log_trap: LogTrap) -> None:
    """The page asks for many status replies and never reads one: the console's queue for it
    stays within its limit, the page is cut off with a log line, and another page is served."""
    limits = PeerLimits(soft_limit=8, max_messages=64, max_bytes=64 * 1024)
    with BackgroundConsole("C12") as bg:
        hub = bg.server.hub if bg.server else None
        assert hub is not None
        hub.peer_limits = limits
        hub.op_rate = (1e6, 1e6)  # this page floods on purpose: fill its queue fast
        port = bg.server.bound_port if bg.server else 0
        assert port
        stuck = _open_raw_ws(port)
        try:
            stuck.setblocking(True)
            stuck.settimeout(10)
            peak = 0
            sent = 0
            request = _client_frame(json.dumps({"op": "status", "ref": 0}))
            # kernel buffers first (several MB on loopback), then the console's queue fills
            while sent < 20_000:
                try:
                    stuck.sendall(request * 50)
                except OSError:
                    break  # the console aborted the connection
                sent += 50
                peers = bg.call(lambda: list(hub.peers))
                peak = max([peak, *(p.queued_bytes for p in peers)])
                if not peers:
                    break
            wait_for(lambda: not bg.call(lambda: list(hub.peers)), 20, what="the stuck page disconnected")
        finally:
            stuck.close()
        assert peak <= limits.max_bytes
        lines = [r.getMessage() for r in log_trap.records if "stopped reading" in r.getMessage()]
        assert len(lines) == 1 and "disconnected" in lines[0], lines
        print(lines[0], f"(after {sent} status ops, peak {peak} bytes queued)")

        async def good_page() -> str:
            async with aiohttp.ClientSession() as http, http.ws_connect(bg.base + "ws") as ws:
                await _still_usable(ws, "good")
                return "ok"

        assert bg.run(good_page()) == "ok"
    assert log_trap.problems() == []


# -- fuzz: whatever a page sends, one clear answer each and no traceback ---------------------------

IDENTS = ["VER", "SDC", "IMG", "GAY", "PTZ", "TSM", "XYZ", "", "REC", "CAP", "ZMC", "TAS"]
any_json = st.recursive(
    st.none() | st.booleans() | st.integers(min_value=-(10**20), max_value=10**20) | st.floats() | st.text(max_size=20),
    lambda c: st.lists(c, max_size=4) | st.dictionaries(st.text(max_size=6), c, max_size=4),
    max_leaves=20,
)
frames = st.one_of(
    st.text(max_size=30),
    st.builds(lambda i, d: f"#TPUD{len(d):X}r{i}{d}", st.sampled_from(IDENTS), st.text("0123456789ABCDEF", max_size=4)),
)
ops = st.fixed_dictionaries(
    {"op": st.sampled_from([*OPS, "status", "nope", ""]) | any_json},
    optional={
        "id": st.sampled_from(IDENTS) | any_json,
        "read": any_json,
        "values": st.dictionaries(st.sampled_from(["palette", "yaw_deg", "action", "read", "x"]), any_json, max_size=3)
        | any_json,
        "yaw": any_json,
        "pitch": any_json,
        "frame": frames | any_json,
        "action": st.sampled_from(["start", "stop", "calibrate", "zoom_in", "x"]) | any_json,
        "mode": st.sampled_from(["follow", "lock"]) | any_json,
        "confirmed": any_json,
    },
)
messages = st.one_of(
    ops.map(lambda o: ("op", o)),
    any_json.map(lambda v: ("text", json.dumps(v))),
    st.text(max_size=100).map(lambda t: ("text", t)),
    st.binary(max_size=64).map(lambda b: ("binary", b)),
)


@pytest.fixture(scope="module")
def fuzz_console() -> Iterator[BackgroundConsole]:
    with BackgroundConsole("C12") as bg:
        yield bg


async def _exchange(base: str, batch: list[tuple[str, Any]]) -> list[dict[str, Any]]:
    """Send the batch on one socket, collect one answer per message, then check the socket."""
    async with aiohttp.ClientSession() as http, http.ws_connect(base + "ws") as ws:
        refs: set[str] = set()
        refusals = 0
        for i, (kind, value) in enumerate(batch):
            if kind == "binary":
                await ws.send_bytes(value)
                refusals += 1
                continue
            text = json.dumps({**value, "ref": f"fuzz-{i}"}) if kind == "op" else value
            try:
                parsed = parse_message(text)
            except MessageError:
                refusals += 1  # answered with ref null
            else:
                # an op: answered with its ref (text that happens to be an object gets one too)
                parsed["ref"] = f"fuzz-{i}"
                text = json.dumps(parsed)
                refs.add(parsed["ref"])
            await ws.send_str(text)
        answers: list[dict[str, Any]] = []
        loop = asyncio.get_running_loop()
        deadline = loop.time() + 30
        while (refs or refusals > 0) and loop.time() < deadline:
            msg = await ws.receive_json(timeout=max(0.01, deadline - loop.time()))
            if msg.get("ref") in refs and msg["type"] in ("ack", "error"):
                refs.discard(msg["ref"])
                answers.append(msg)
            elif _refusal(msg):
                refusals -= 1
                answers.append(msg)
        assert not refs, f"no answer to {sorted(refs)}"
        await _still_usable(ws, "fuzz-end")
        return answers


@settings(
    max_examples=150,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large, HealthCheck.function_scoped_fixture],
)
@given(st.lists(messages, min_size=1, max_size=6))
def test_fuzzed_messages_get_one_clear_answer_each(
    fuzz_console: BackgroundConsole, log_trap: LogTrap, batch: list[tuple[str, Any]]
) -> None:
    answers = fuzz_console.run(_exchange(fuzz_console.base, batch), timeout=60)
    for a in answers:
        assert a.get("kind") != "internal", a  # an unexpected exception somewhere: a bug to fix
        if a["type"] == "error":
            assert isinstance(a["message"], str) and a["message"]
    assert log_trap.problems() == []


# -- malformed HTTP and WebSocket frames: refused by aiohttp, one line each, no traceback -----------


def _masked(opcode: int, payload: bytes, *, fin: bool = True) -> bytes:
    mask = os.urandom(4)
    return (
        bytes([(0x80 if fin else 0) | opcode, 0x80 | len(payload)])
        + mask
        + bytes(b ^ mask[i % 4] for i, b in enumerate(payload))
    )


async def _raw_exchange(port: int, data: bytes, *, upgrade: bool) -> bytes:
    reader, writer = await asyncio.open_connection("127.0.0.1", port)
    try:
        if upgrade:
            key = base64.b64encode(os.urandom(16)).decode()
            writer.write(
                f"GET /ws HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
                f"Sec-WebSocket-Key: {key}\r\nSec-WebSocket-Version: 13\r\n\r\n".encode()
            )
        writer.write(data)
        await writer.drain()
        try:
            return await asyncio.wait_for(reader.read(1 << 20), 5)
        except asyncio.TimeoutError:
            return b""
    finally:
        writer.close()


WS_GARBAGE = [
    _masked(0x1, b"\xff\xfe{"),  # text that is not UTF-8
    _masked(0x3, b"x"),  # reserved opcode
    _masked(0x1, b"abc", fin=False) + _masked(0x2, b"x"),  # a new message inside a fragmented one
    bytes([0x81, 0x05]) + b"hello",  # an unmasked client frame
    _masked(0x9, b"x" * 125) + _masked(0x8, b"\x03"),  # a ping, then a close with a broken payload
]
HTTP_GARBAGE = [
    b"GARBAGE\r\n\r\n",
    b"GET / HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Length: -1\r\n\r\n",
    b"GET / HTTP/1.1\r\nHost: 127.0.0.1\r\nTransfer-Encoding: chunked\r\n\r\nzz\r\n",
    b"GET /static/../../etc/passwd HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\n\r\n",
    b"GET /%ff%fe HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\n\r\n",
    b"GET / HTTP/1.1\r\nHost: \xff\xfe:{port}\r\n\r\n",
    b"GET /ws HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
    b"Sec-WebSocket-Version: 99\r\n\r\n",
]


async def test_malformed_http_and_frames_leave_no_traceback(console: ConsoleServer, log_trap: LogTrap) -> None:
    port = _port_of(console)
    for data in WS_GARBAGE:
        answer = await _raw_exchange(port, data, upgrade=True)
        assert answer.startswith(b"HTTP/1.1 101")
    for template in HTTP_GARBAGE:
        answer = await _raw_exchange(port, template.replace(b"{port}", str(port).encode()), upgrade=False)
        assert answer.startswith((b"HTTP/1.1 4", b"HTTP/1.0 4")), (template, answer[:80])
    async with aiohttp.ClientSession() as http, http.ws_connect(console.base_url + "ws") as ws:
        await _still_usable(ws, "after-garbage")
    assert log_trap.problems() == []
    assert any("malformed HTTP request" in r.getMessage() for r in log_trap.records)


def _port_of(srv: ConsoleServer) -> int:
    assert srv.bound_port
    return srv.bound_port
