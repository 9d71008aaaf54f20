"""One camera session shared by every open page: pumps attitude, link statistics, traffic and
errors to the WebSockets, and carries out the pages' ops through the client.

Rates are bounded here, not in the browser: attitude goes out at most `attitude_hz` times a second
(only the latest sample), traffic in batches every `traffic_interval_s`, status every
`status_interval_s`. A page that cannot keep up loses periodic pushes, never acks; one that stops
reading is disconnected (`peer.py`). At most `max_pages` pages and `MAX_OPS_IN_FLIGHT` ops per
page; every message from a page is checked against `limits.py` first."""

from __future__ import annotations

import asyncio
import contextlib
import logging
import time
from collections import Counter, deque
from collections.abc import Mapping
from typing import Any

from aiohttp import WSMsgType, web

from .catalog_api import model_json
from .limits import MAX_FRAME_BYTES, MAX_OPS_PER_S, OPS_BURST, MessageError, OpRate, parse_message
from .ops import OPS, OpError, describe_error, jsonable, short
from .peer import Peer

log = logging.getLogger(__name__)

TRAFFIC_HISTORY = 400
MAX_PAGES = 16  # open WebSockets; one more is refused with 503 and a log line
MAX_OPS_IN_FLIGHT = 32  # per page; one more is answered with an error
MOTION_OPS = frozenset({"point", "rates", "stop", "center", "mode", "ptz"})


def _direction(direction: Any) -> str:
    d = str(direction).lower()
    return "in" if d.startswith(("in", "rx", "recv", "<")) else "out"


class Hub:
    def __init__(
        self,
        cam: Any,
        *,
        url: str = "",
        attitude_hz: float = 50.0,
        status_interval_s: float = 0.5,
        traffic_interval_s: float = 0.1,
        sd_interval_s: float = 5.0,
        max_pages: int = MAX_PAGES,
        peer_limits: Mapping[str, int] | None = None,
    ) -> None:
        self.cam = cam
        self.url = url
        self.attitude_hz = min(max(attitude_hz, 1.0), 50.0)
        self.status_interval_s = status_interval_s
        self.traffic_interval_s = traffic_interval_s
        self.sd_interval_s = sd_interval_s
        self.max_pages = max_pages
        self.peer_limits = dict(peer_limits or {})  # Peer keyword arguments (tests use small ones)
        self.op_rate = (MAX_OPS_PER_S, OPS_BURST)  # messages a second per page, burst
        self.peers: set[Peer] = set()
        self._handshakes = 0
        self._polls: Counter[str] = Counter()  # identifiers of the console's own periodic queries
        # Motion ops from every page, one at a time and in arrival order: a drag's rates, the pad
        # release's stop and another page's stop share the client's GSM/PTZ requests.
        self._motion = asyncio.Lock()
        self.attitude: dict[str, float] | None = None
        self._attitude_seq = 0
        self.traffic: deque[dict[str, Any]] = deque(maxlen=TRAFFIC_HISTORY)
        self._pending: list[dict[str, Any]] = []
        self.last_in: float | None = None
        self.recording_since: float | None = None
        self.recording: bool | None = None
        self.sd: dict[str, Any] | None = None
        self.version: Any = None
        self.errors = 0
        self._tasks: list[asyncio.Task[None]] = []
        self._unsubscribe: list[Any] = []
        self._quiet: dict[str, str] = {}  # background error kind -> last message (reported once)

    # -- lifecycle ---------------------------------------------------------------------------

    @property
    def dialect(self) -> Any:
        return self.cam.dialect

    @property
    def model(self) -> Any:
        return self.cam.model

    def supports(self, ident: str) -> bool:
        return bool(self.dialect.supports(self.model, ident))

    async def start(self) -> None:
        on_traffic = getattr(self.cam, "on_traffic", None)
        if on_traffic is not None:
            self._unsubscribe.append(on_traffic(self._on_traffic))
        loops = [self._status_loop(), self._traffic_loop(), self._keepalive_loop()]
        if self.supports("GAA"):
            loops += [self._attitude_loop(), self._attitude_ticker()]
        if self.supports("SDC"):
            loops.append(self._sd_loop())
        if self.supports("VER") or self.supports("VSN"):
            loops.append(self._version_once())
        self._tasks = [asyncio.create_task(c) for c in loops]

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
                await asyncio.wait_for(p.ws.close(), 2.0)

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
            {"type": "error", "ref": None, "kind": kind, "source": source, "message": message, "t": time.time()}
        )

    def clear_error(self, once: str) -> None:
        if self._quiet.pop(once, None) is not None:
            self.broadcast({"type": "recovered", "source": once, "t": time.time()})

    def _on_traffic(self, direction: Any, frame: Any, message: Any = None) -> None:
        now = time.time()
        d = _direction(direction)
        if d == "in":
            self.last_in = now
        item: dict[str, Any] = {"t": now, "dir": d, "frame": _frame_text(frame)}
        if message is not None:
            try:
                m = jsonable(message)
            except Exception as exc:  # a decoding oddity must never break the link
                m = {"error": str(exc)}
            if isinstance(m, dict):
                item.update(
                    {"id": m.get("id"), "name": m.get("name"), "fields": m.get("fields"), "error": m.get("error")}
                )
        if "id" not in item or item.get("id") is None:
            item["id"] = getattr(frame, "ident", None)
        if item["id"] in self._polls:
            item["poll"] = True  # the page hides the console's own periodic queries by default
        self.traffic.append(item)
        self._pending.append(item)
        if len(self._pending) > 500:
            del self._pending[:-500]

    async def _traffic_loop(self) -> None:
        while True:
            await asyncio.sleep(self.traffic_interval_s)
            if self._pending:
                items, self._pending = self._pending, []
                self.broadcast({"type": "traffic", "items": items}, essential=False)

    async def _attitude_loop(self) -> None:
        """Read the client's attitude stream; on failure report once and retry."""
        while True:
            try:
                async for att in self.cam.attitude(self.attitude_hz):
                    self.attitude = {
                        "yaw": float(att.yaw_deg),
                        "pitch": float(att.pitch_deg),
                        "roll": float(att.roll_deg),
                        "t": float(getattr(att, "wall", 0.0) or time.time()),
                    }
                    self._attitude_seq += 1
                    self.clear_error("attitude")
            except asyncio.CancelledError:
                raise
            except Exception as exc:
                kind, msg = describe_error(exc, "the attitude stream")
                self.report_error(msg, kind=kind, source="attitude", once="attitude")
            await asyncio.sleep(1.0)

    async def _attitude_ticker(self) -> None:
        """Send the newest attitude sample, at most attitude_hz times a second."""
        sent = 0
        period = 1.0 / self.attitude_hz
        while True:
            await asyncio.sleep(period)
            if self._attitude_seq != sent and self.attitude is not None:
                sent = self._attitude_seq
                self.broadcast({"type": "attitude", **self.attitude}, essential=False)

    def status(self) -> dict[str, Any]:
        stats = jsonable(self.cam.stats) if getattr(self.cam, "stats", None) is not None else {}
        state = jsonable(self.cam.state) if getattr(self.cam, "state", None) is not None else {}
        now = time.time()
        age = None if self.last_in is None else now - self.last_in
        connected = stats.get("connected", True) if isinstance(stats, dict) else True
        if not connected:
            link = "down"
        elif age is None:
            link = "waiting"
        elif age > 3.0:
            link = "stale"
        else:
            link = "up"
        self._sync_recording()
        return {
            "type": "status",
            "now": now,
            "link": link,
            "last_in_age_s": age,
            "stats": stats,
            "state": state,
            "recording": self.recording,
            "recording_since": self.recording_since,
            "sd": self.sd,
            "version": self.version,
            "errors": self.errors,
            "pages": len(self.peers),
        }

    def _sync_recording(self) -> None:
        """Recording as the client last heard it (REC answers, ours or another program's)."""
        stamped = getattr(getattr(self.cam, "state", None), "recording", None)
        value = getattr(stamped, "value", None)
        if isinstance(value, bool) and value != self.recording:
            self.recording = value
            self.recording_since = time.time() if value else None

    async def _status_loop(self) -> None:
        while True:
            await asyncio.sleep(self.status_interval_s)
            if self.peers:
                try:
                    self.broadcast(self.status(), essential=False)
                except Exception as exc:  # never let a status oddity kill the loop
                    log.exception("status failed")
                    self.report_error(f"status: {exc}", kind="internal", source="console", once="status")

    @contextlib.contextmanager
    def _polling(self, ident: str) -> Any:
        """Mark the frames of a periodic query (and its answer) as the console's own polls."""
        self._polls[ident] += 1
        try:
            yield
        finally:
            self._polls[ident] -= 1
            if self._polls[ident] <= 0:
                del self._polls[ident]

    async def refresh_sd(self, *, poll: bool = False) -> dict[str, Any] | None:
        try:
            with self._polling("SDC") if poll else contextlib.nullcontext():
                self.sd = await OPS["sd"](self.cam, {})
            self.clear_error("sd")
        except asyncio.CancelledError:
            raise
        except Exception as exc:
            kind, msg = describe_error(exc, "the SD card query")
            self.report_error(msg, kind=kind, source="sd", once="sd")
        return self.sd

    async def _sd_loop(self) -> None:
        while True:
            await self.refresh_sd(poll=True)
            await asyncio.sleep(self.sd_interval_s)

    def _ping_ident(self) -> str | None:
        for ident in ("VER", "VSN", "SDC", "IPV", "GAC"):
            if self.supports(ident) and self.dialect.command(ident).readable:
                return ident
        return None

    async def _keepalive_loop(self, idle_s: float = 2.0) -> None:
        """When nothing has come from the camera for `idle_s` (no attitude stream on this model,
        or the stream stopped), ask it something harmless so the link state stays true."""
        ident = self._ping_ident()
        if ident is None:
            return
        while True:
            await asyncio.sleep(idle_s)
            if self.last_in is not None and time.time() - self.last_in < idle_s:
                continue
            try:
                with self._polling(ident):
                    await self.cam.request(ident, read=True)
                self.clear_error("link")
            except asyncio.CancelledError:
                raise
            except Exception as exc:
                kind, msg = describe_error(exc, f"the link check ({ident} query)")
                self.report_error(msg, kind=kind, source="link", once="link")

    async def _version_once(self) -> None:
        try:
            self.version = jsonable(await self.cam.version())
        except asyncio.CancelledError:
            raise
        except Exception as exc:
            kind, msg = describe_error(exc, "the version query")
            self.report_error(msg, kind=kind, source="version", once="version")

    # -- ops ---------------------------------------------------------------------------------

    def hello(self) -> dict[str, Any]:
        return {
            "type": "hello",
            "url": self.url,
            "model": model_json(self.model),
            "dialect": self.dialect.name,
            "attitude_hz": self.attitude_hz,
            "traffic": list(self.traffic)[-200:],
            "status": self.status(),
        }

    async def execute(self, msg: Mapping[str, Any]) -> dict[str, Any]:
        """Carry out one op; the `ack` or `error` reply (never raises)."""
        ref = msg.get("ref")
        op = msg.get("op")
        handler = OPS.get(op) if isinstance(op, str) else None
        if handler is None and op == "status":
            return {"type": "ack", "ref": ref, "op": op, "result": self.status()}
        if handler is None:
            known = ", ".join(sorted([*OPS, "status"]))
            return {
                "type": "error",
                "ref": ref,
                "op": op,
                "kind": "op",
                "message": f"unknown op {short(op)}; known: {known}",
            }
        try:
            async with self._motion if self._is_motion(msg) else contextlib.nullcontext():
                result = await handler(self.cam, msg)
        except asyncio.CancelledError:
            raise
        except Exception as exc:
            kind, text = describe_error(exc, _what(msg))
            if not isinstance(exc, OpError):
                self.errors += 1
            return {"type": "error", "ref": ref, "op": op, "kind": kind, "message": text}
        self._after(str(op), msg, result)
        return {"type": "ack", "ref": ref, "op": op, "result": jsonable(result)}

    def _is_motion(self, msg: Mapping[str, Any]) -> bool:
        op = msg.get("op")
        if op in MOTION_OPS:
            return True
        ident = msg.get("id")
        if op != "request" or not isinstance(ident, str):
            return False
        spec = self.dialect.commands.get(ident)
        return bool(spec is not None and (spec.motion or ident == "PTZ"))

    def _after(self, op: str, msg: Mapping[str, Any], result: Any) -> None:
        if op == "record":
            if msg.get("action") == "start":
                self.recording, self.recording_since = True, time.time()
            else:
                self.recording, self.recording_since = False, None
        elif op == "recording" and isinstance(result, bool):
            if result and not self.recording:
                self.recording_since = time.time()
            if not result:
                self.recording_since = None
            self.recording = result
        elif op == "sd" and isinstance(result, dict):
            self.sd = result

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
        peer = Peer(ws, name, transport=request.transport, **self.peer_limits)
        self.peers.add(peer)
        sender = asyncio.create_task(peer.run())
        peer.send(self.hello())
        running: set[asyncio.Task[None]] = set()
        rate = OpRate(*self.op_rate)
        loop = asyncio.get_running_loop()
        try:
            async for raw in ws:
                if peer.closed or request.transport is None or request.transport.is_closing():
                    break  # the page is gone: its buffered messages need no answer
                # One message per turn of the loop, and at most the page's rate: buffered
                # messages of a flooding page would otherwise be handled without yielding.
                await asyncio.sleep(rate.delay_s(loop.time()))
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

    async def _run_op(self, peer: Peer, msg: Mapping[str, Any]) -> None:
        reply = await self.execute(msg)
        peer.send(reply)
        if reply["type"] == "error" and reply.get("kind") != "op":
            log.info("op %s failed: %s", short(msg.get("op")), reply["message"])


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


def _what(msg: Mapping[str, Any]) -> str:
    op = msg.get("op")
    if op == "request":
        return f"{short(msg.get('id'), quote=False)} ({'read' if msg.get('read') else 'write'})"
    if op == "raw":
        return f"the raw frame {short(msg.get('frame'))}"
    return OP_NAMES.get(str(op), short(op, quote=False))


def _frame_text(frame: Any) -> str:
    """The frame as printable text for the traffic pane (never raises: a frame the parser let
    through must not break the link)."""
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


__all__ = ["Hub", "OpError", "Peer"]
