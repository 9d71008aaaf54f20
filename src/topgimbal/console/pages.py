"""What every console serves its pages, whatever the frames come from: the WebSockets (bounded in
number, each checked by `limits.py` and paced), pushes to them, background errors reported once,
and the traffic: the pane's recent items and the recorder behind the pcap download.

`Hub` (a camera through the client) and `WatchHub` (a proxy's traffic, read-only) build on it;
they say what `status()` holds, which loops run and how an op is carried out."""

from __future__ import annotations

import asyncio
import contextlib
import logging
from collections import deque
from collections.abc import Callable, Coroutine, Mapping
from typing import Any

from aiohttp import WSMsgType, web

from ..clock import monotonic, wall_time
from ..logtext import untrusted
from ..protocol import DeviceModel, Dialect, Frame, Message
from ..timeouts import within
from ..wire.packets import Endpoint
from .capture import Link, Recorder
from .catalog_api import model_json
from .limits import MAX_FRAME_BYTES, MAX_OPS_PER_S, OPS_BURST, MessageError, OpRate, parse_message
from .ops import OPS, JsonValue, OpArgs, describe_error, jsonable, short
from .peer import Peer, PeerLimits

log = logging.getLogger("topgimbal.console.hub")

TRAFFIC_HISTORY = 400  # items a page gets on connect (it keeps its own 3000)
MAX_PENDING = 500  # traffic items waiting for the next batch
MAX_PAGES = 16  # open WebSockets; one more is refused with 503 and a log line
MAX_OPS_IN_FLIGHT = 32  # per page; one more is answered with an error
# Roles whose frames are telemetry streams (the traffic pane hides them with the console's polls).
STREAM_ROLES = ("attitude", "earth_attitude", "earth_attitude_stream")


class PageHub:
    mode = "camera"
    # Pacing and limits: constructors take none of them; a test lowers one on its hub instance.
    status_interval_s = 0.5
    traffic_interval_s = 0.1
    max_pages = MAX_PAGES

    def __init__(self, *, dialect: Dialect, model: DeviceModel, url: str, link: Link) -> None:
        self.dialect = dialect
        self.model = model
        self.url = url
        self.link = link
        self.peer_limits = PeerLimits()  # what may wait for each page (tests use small ones)
        self.op_rate = (MAX_OPS_PER_S, OPS_BURST)  # messages a second per page, burst
        self.peers: set[Peer] = set()
        self._handshakes = 0
        self.traffic: deque[dict[str, Any]] = deque(maxlen=TRAFFIC_HISTORY)
        self._pending: list[dict[str, Any]] = []
        self.recorder = Recorder()
        self.streams = frozenset(
            spec.ident for role in STREAM_ROLES for spec in dialect.commands_with_role(role, model)
        )
        self.last_in: float | None = None
        self.errors = 0
        self._tasks: list[asyncio.Task[None]] = []
        self._unsubscribe: list[Callable[[], None]] = []
        self._quiet: dict[str, str] = {}  # background error source -> last message (reported once)

    # -- lifecycle ---------------------------------------------------------------------------

    def loops(self) -> list[Coroutine[object, object, None]]:
        """The subclass's background work, run beside the status and traffic pushes."""
        return []

    async def start(self) -> None:
        self._tasks = [asyncio.create_task(c) for c in [self._status_loop(), self._traffic_loop(), *self.loops()]]

    async def stop(self) -> None:
        for unsub in self._unsubscribe:
            with contextlib.suppress(Exception):
                unsub()
        for t in self._tasks:
            t.cancel()
        for t in self._tasks:
            with contextlib.suppress(asyncio.CancelledError, Exception):
                await t
        for p in list(self.peers):
            p.close()
            with contextlib.suppress(Exception):
                await within(p.ws.close(), 2.0)

    # -- pushing -----------------------------------------------------------------------------

    def broadcast(self, obj: Mapping[str, Any], *, essential: bool = True) -> None:
        for p in list(self.peers):
            p.send(obj, essential=essential)

    def report_error(
        self, message: str, *, kind: str = "error", source: str = "camera", once: str | None = None
    ) -> None:
        """Push an error not tied to an op. With `once`, a repeat of the same message is not pushed
        again until `clear_error(once)` (a poll that keeps timing out reports once)."""
        if once is not None:
            if self._quiet.get(once) == message:
                return
            self._quiet[once] = message
        self.errors += 1
        self.broadcast(
            {"type": "error", "ref": None, "kind": kind, "source": source, "message": message, "t": wall_time()}
        )

    def clear_error(self, once: str) -> None:
        if self._quiet.pop(once, None) is not None:
            self.broadcast({"type": "recovered", "source": once, "t": wall_time()})

    def record(
        self,
        direction: str,
        frame: Frame,
        message: Message | None,
        *,
        t: float | None = None,
        host: Endpoint | None = None,
        **marks: JsonValue,
    ) -> dict[str, Any]:
        """One frame for the traffic pane and the recorder; `marks` (poll, client) are added to the
        pane's item, and `stream` to the frames of telemetry streams. Never raises: a frame the
        parser let through must not break the link."""
        now = wall_time() if t is None else t
        if direction == "in":
            self.last_in = now
        item: dict[str, Any] = {"t": now, "dir": direction, "frame": _frame_text(frame)}
        if message is not None:
            try:
                m = jsonable(message)
            except Exception as exc:  # a decoding oddity must never break the link
                m = {"error": str(exc)}
            if isinstance(m, dict):
                item.update(
                    {"id": m.get("id"), "name": m.get("name"), "fields": m.get("fields"), "error": m.get("error")}
                )
            form = getattr(message, "form", None)
            if form is not None:
                item["form"] = form.title
                item["echo"] = form.role == "echo"  # a write's echo, not something the device reports
        if item.get("id") is None:
            item["id"] = getattr(frame, "ident", None)
        marks["stream"] = getattr(frame, "ident", None) in self.streams
        item.update({k: v for k, v in marks.items() if v})
        with contextlib.suppress(Exception):
            self.recorder.add(now, direction, frame.to_bytes(), host)
        return self._push(item)

    def note(
        self, direction: str, raw: bytes, error: str, *, t: float | None = None, **marks: JsonValue
    ) -> dict[str, Any]:
        """Bytes that are not a frame (what the parser said about them), for the traffic pane only."""
        item: dict[str, Any] = {
            "t": wall_time() if t is None else t,
            "dir": direction,
            "frame": _frame_text(raw),
            "id": None,
            "error": error,
        }
        item.update({k: v for k, v in marks.items() if v})
        return self._push(item)

    def _push(self, item: dict[str, Any]) -> dict[str, Any]:
        self.traffic.append(item)
        self._pending.append(item)
        if len(self._pending) > MAX_PENDING:
            del self._pending[:-MAX_PENDING]
        return item

    async def _traffic_loop(self) -> None:
        while True:
            await asyncio.sleep(self.traffic_interval_s)
            if self._pending:
                items, self._pending = self._pending, []
                self.broadcast({"type": "traffic", "items": items}, essential=False)

    def status(self) -> dict[str, Any]:
        now = wall_time()
        return {
            "type": "status",
            "mode": self.mode,
            "now": now,
            "last_in_age_s": None if self.last_in is None else now - self.last_in,
            "errors": self.errors,
            "pages": len(self.peers),
            "recorded": self.recorder.describe(),
        }

    async def _status_loop(self) -> None:
        while True:
            await asyncio.sleep(self.status_interval_s)
            if self.peers:
                try:
                    self.broadcast(self.status(), essential=False)
                except Exception as exc:  # never let a status oddity kill the loop
                    log.exception("status failed")
                    self.report_error(f"status: {exc}", kind="internal", source="console", once="status")

    async def where(self) -> dict[str, Any]:
        """Where the vehicle and the target are (`GET api/where`, where.py): a hub without a
        client of its own (a watched proxy) knows neither."""
        return {"vehicle": None, "target": None, "why": "this console watches a proxy: it has no client to ask"}

    def hello(self) -> dict[str, Any]:
        return {
            "type": "hello",
            "mode": self.mode,
            "url": self.url,
            "model": model_json(self.model),
            "dialect": self.dialect.name,
            "traffic": list(self.traffic)[-200:],
            "status": self.status(),
        }

    # -- ops ---------------------------------------------------------------------------------

    async def carry_out(self, op: str, msg: OpArgs) -> object:
        """Run one op (a name in `OPS`); raise what the client raises."""
        raise NotImplementedError

    async def execute(self, msg: OpArgs) -> dict[str, Any]:
        """Carry out one op; the `ack` or `error` reply (never raises)."""
        ref = msg.get("ref")
        op = msg.get("op")
        if op == "status":
            return {"type": "ack", "ref": ref, "op": op, "result": self.status()}
        if not isinstance(op, str) or op not in OPS:
            known = ", ".join(sorted([*OPS, "status"]))
            return {
                "type": "error",
                "ref": ref,
                "op": op,
                "kind": "op",
                "message": f"unknown op {short(op)}; known: {known}",
            }
        try:
            result = await self.carry_out(op, msg)
        except asyncio.CancelledError:
            raise
        except Exception as exc:
            kind, text = describe_error(exc, _what(msg))
            if kind not in ("op", "readonly"):
                self.errors += 1
            return {"type": "error", "ref": ref, "op": op, "kind": kind, "message": text}
        return {"type": "ack", "ref": ref, "op": op, "result": jsonable(result)}

    # -- the WebSocket -----------------------------------------------------------------------

    async def handle_ws(self, request: web.Request) -> web.StreamResponse:
        peername = request.transport.get_extra_info("peername") if request.transport is not None else None
        name = f"{peername[0]}:{peername[1]}" if isinstance(peername, tuple) else (request.remote or "?")
        if len(self.peers) + self._handshakes >= self.max_pages:
            log.warning("refused page %s: %d pages are open (the limit)", name, len(self.peers))
            return web.json_response(
                {
                    "error": "busy",
                    "message": f"{len(self.peers)} pages are already open on this console (at most "
                    f"{self.max_pages}); close one and reload",
                },
                status=503,
            )
        ws = web.WebSocketResponse(heartbeat=20.0, max_msg_size=MAX_FRAME_BYTES)
        self._handshakes += 1  # counted against the limit while the handshake awaits
        try:
            await ws.prepare(request)
        finally:
            self._handshakes -= 1
        peer = Peer(ws, name, limits=self.peer_limits, transport=request.transport)
        self.peers.add(peer)
        sender = asyncio.create_task(peer.run())
        peer.send(self.hello())
        running: set[asyncio.Task[None]] = set()
        rate = OpRate(*self.op_rate)
        try:
            async for raw in ws:
                if peer.closed or request.transport is None or request.transport.is_closing():
                    break  # the page is gone: its buffered messages need no answer
                # One message per turn of the loop, and at most the page's rate: buffered
                # messages of a flooding page would otherwise be handled without yielding.
                await asyncio.sleep(rate.delay_s(monotonic()))
                if raw.type not in (WSMsgType.TEXT, WSMsgType.BINARY):
                    continue
                try:
                    msg = parse_message(raw.data)
                except MessageError as exc:
                    peer.send({"type": "error", "ref": None, "op": None, "kind": "op", "message": str(exc)})
                    continue
                if len(running) >= MAX_OPS_IN_FLIGHT:
                    peer.send(
                        {
                            "type": "error",
                            "ref": msg.get("ref"),
                            "op": msg.get("op"),
                            "kind": "op",
                            "message": f"too many ops in flight ({len(running)}, at most {MAX_OPS_IN_FLIGHT} "
                            "per page): wait for their replies",
                        }
                    )
                    continue
                # Ops run concurrently (a slow query must not hold up stop), each acked.
                task = asyncio.create_task(self._run_op(peer, msg))
                running.add(task)
                task.add_done_callback(running.discard)
        finally:
            self.peers.discard(peer)
            for t in list(running):
                t.cancel()
            peer.close()
            with contextlib.suppress(asyncio.CancelledError, Exception):
                await sender
            if peer.dropped:
                log.info("page %s closed; %d periodic pushes were dropped for it", name, peer.dropped)
        return ws

    async def _run_op(self, peer: Peer, msg: OpArgs) -> None:
        reply = await self.execute(msg)
        peer.send(reply)
        if reply["type"] == "error" and reply.get("kind") not in ("op", "readonly"):
            log.info("op %s failed: %s", untrusted(short(msg.get("op"))), untrusted(reply["message"], 600))


OP_NAMES = {
    "point": "the angle command",
    "rates": "the rate command",
    "stop": "stop",
    "center": "center",
    "mode": "the follow / lock command",
    "ptz": "the gimbal control code",
    "photo": "the photo command",
    "record": "the recording command",
    "recording": "the recording query",
    "sd": "the SD card query",
    "version": "the version query",
    "range": "the range measurement",
    "network": "the network query",
    "set_network": "the network settings",
}


def _what(msg: OpArgs) -> str:
    op = msg.get("op")
    if op == "request":
        return f"{short(msg.get('id'), quote=False)} ({'read' if msg.get('read') else 'write'})"
    if op == "raw":
        return f"the raw frame {short(msg.get('frame'))}"
    return OP_NAMES.get(str(op), short(op, quote=False))


def _frame_text(frame: Frame | bytes | bytearray | str) -> str:
    """The frame as printable text for the traffic pane (never raises)."""
    try:
        if hasattr(frame, "text"):
            text = str(frame.text())
        elif isinstance(frame, (bytes, bytearray)):
            text = bytes(frame).decode("latin-1")
        else:
            text = str(frame)
    except Exception:
        text = repr(getattr(frame, "raw", frame))
    return text.rstrip("\r\n")
