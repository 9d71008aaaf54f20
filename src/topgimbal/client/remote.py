"""A camera served by `topgimbal zenoh` on another process or host, used like a local one:
`async with topgimbal.connect("zenoh/cam1?connect=tcp/127.0.0.1:7447") as cam: await cam.point(30, -45)`.

`RemoteClient` has the SDK's typed methods (api_core.py, api_motion.py, api_camera.py: the same
names, signatures and argument checks); each becomes one query on `topgimbal/<name>/call/<method>`
and its reply becomes the same return value or the same exception class (the `kind` travels).
`attitude()` subscribes to `topgimbal/<name>/attitude`; the link state follows `.../link`. The
model is the one the server serves (its `info` queryable), so the caller need not repeat it.

Truth rules are the server's SDK client's: "ok" only with what the camera confirmed. A call whose
reply does not come in time raises RequestTimeoutError saying the command may or may not have been
carried out (the server may still be working on it). Frame-level callbacks (`subscribe`,
`on_traffic`) are not carried over Zenoh and raise UnsupportedError."""

from __future__ import annotations

import asyncio
import contextlib
import functools
import inspect
import json
import logging
from collections.abc import AsyncIterator, Awaitable, Callable, Coroutine
from typing import Any, Unpack

from ..clock import monotonic
from ..errors import FieldValueError, LinkLostError, RequestTimeoutError, TopGimbalError, UnsupportedError
from ..protocol import DeviceModel, Dialect, Frame, Message, get_model
from .api_camera import CameraMethods
from .api_core import CoreMethods
from .api_motion import MotionMethods
from .identity import Verdict
from .options import ConnectOptions
from .remote_keys import (
    METHODS,
    RemoteCallError,
    ZenohTarget,
    call_key,
    decode_result,
    error_from_reply,
    key,
    parse_zenoh_url,
)
from .state import GimbalAttitude, StateCache
from .stats import LinkStats
from .zenoh_session import open_session

log = logging.getLogger("topgimbal.client")

CALL_TIMEOUT_S = 30.0  # a call without its own timeout_s
POINT_TIMEOUT_S = 120.0  # point() without timeout_s: the server allows for the whole slew
MARGIN_S = 5.0  # over a call's own timeout_s
QUEUE_SAMPLES = 256  # attitude samples held per stream; the oldest go first
KIND_SERVED_TWICE = "served_twice"


class RemoteClient(CoreMethods, MotionMethods, CameraMethods):
    """A remote camera (see the module docstring). Open with `await connect("zenoh/NAME?...")`."""

    def __init__(
        self,
        url: str,
        model: str | DeviceModel | None = None,
        *,
        session: Any = None,
        **options: Unpack[ConnectOptions],
    ) -> None:
        """`session`: a Zenoh session the caller opened and keeps (one for many cameras, as the
        console does); the client then opens none and leaves it open when it closes. Without it,
        the client opens its own from the URL's endpoints and closes it."""
        self.url = url
        self.target: ZenohTarget = parse_zenoh_url(url)
        self.name = self.target.name
        self._wanted_model = model.name if isinstance(model, DeviceModel) else model
        self.timeout_s = float(options.get("timeout_s", 1.0))
        self.dialect: Dialect
        self.model: DeviceModel
        self.dialect, self.model = get_model(self._wanted_model or "C12")
        self.state = StateCache()
        self.stats = LinkStats()
        self.session: Any = None
        self._own_session = session is None
        self._given_session = session
        self.info: dict[str, Any] = {}
        self.served_state: dict[str, Any] = {}  # the server's last `state` sample for this camera
        self._link: dict[str, bool | str | float | None] = {"up": False, "reason": "not opened", "silent_s": None}
        self._link_listeners: list[Callable[[bool, str], Awaitable[None] | None]] = []
        self._subs: list[Any] = []
        self._callbacks: set[asyncio.Future[Any]] = set()
        self._loop: asyncio.AbstractEventLoop | None = None
        self.closed = False

    # -- life cycle ---------------------------------------------------------------------------------

    async def open(self) -> RemoteClient:
        self._loop = asyncio.get_running_loop()
        t = self.target
        if self._own_session:
            self.session = await asyncio.to_thread(
                open_session, listen=t.listen, connect=t.connect, mode=t.mode, config_file=t.config_file
            )
        else:
            self.session = self._given_session
        try:
            self._querier = str(self.session.zid())
        except Exception:  # a session double without zid(): the server counts it as anonymous
            self._querier = ""
        try:
            # every server answers `info` (no consolidation): two answers are refused here, before any call acts
            self.info = await self._query_json(key(self.name, "info"), None, 5.0)
        except TopGimbalError:
            await self.close()
            raise
        served = str(self.info.get("model", ""))
        if self._wanted_model and served and served != self._wanted_model:
            log.warning("%s: served as a %s, not the %s asked for: using %s", self.url, served, self._wanted_model,
                        served)  # fmt: skip
        if served:
            self.dialect, self.model = get_model(served)
        self._subs.append(self.session.declare_subscriber(key(self.name, "link"), self._on_link_sample))
        self._subs.append(self.session.declare_subscriber(key(self.name, "state"), self._on_state_sample))
        self._set_link(True, "served")  # the info query was answered; the server's link key corrects this
        return self

    async def close(self) -> None:
        if self.closed:
            return
        self.closed = True
        for s in self._subs:
            with contextlib.suppress(Exception):
                s.undeclare()
        self._subs.clear()
        if self.session is not None and self._own_session:
            with contextlib.suppress(Exception):
                await asyncio.to_thread(self.session.close)
        self.session = None

    async def __aenter__(self) -> RemoteClient:
        return await self.open()

    async def __aexit__(self, *exc: object) -> None:
        await self.close()

    # -- the link -----------------------------------------------------------------------------------

    @property
    def connected(self) -> bool:
        return bool(self._link["up"])

    @property
    def link_state(self) -> dict[str, bool | str | float | None]:
        return dict(self._link)

    @property
    def model_check(self) -> Verdict:
        return Verdict("off", self.model.name, message="checked by the server")

    def on_model_check(self, callback: Callable[[Verdict], object]) -> Callable[[], None]:
        return lambda: None  # the server checks the model; its verdict is in the state key

    def on_link_change(self, callback: Callable[[bool, str], Awaitable[None] | None]) -> Callable[[], None]:
        self._link_listeners.append(callback)
        return lambda: self._link_listeners.remove(callback) if callback in self._link_listeners else None

    def subscribe(
        self, callback: Callable[[Message], Awaitable[None] | None], ident: str | None = None
    ) -> Callable[[], None]:
        raise UnsupportedError("frames are not carried over Zenoh: use the typed methods and attitude()")

    def on_traffic(
        self, callback: Callable[[str, Frame, Message | None], Awaitable[None] | None]
    ) -> Callable[[], None]:
        raise UnsupportedError("frames are not carried over Zenoh: use the typed methods and attitude()")

    def _set_link(self, up: bool, reason: str) -> None:
        changed = bool(self._link["up"]) != up
        self._link = {"up": up, "reason": "" if up else reason, "silent_s": None}
        self.stats.connected = up
        if changed:
            for cb in list(self._link_listeners):
                try:
                    r = cb(up, reason)
                    if inspect.isawaitable(r):
                        fut = asyncio.ensure_future(r)
                        self._callbacks.add(fut)
                        fut.add_done_callback(self._callbacks.discard)
                except Exception:
                    log.exception("link callback failed")

    def _on_link_sample(self, sample: Any) -> None:
        data = _json(sample)
        if isinstance(data, dict) and self._loop is not None and not self._loop.is_closed():
            self._loop.call_soon_threadsafe(self._set_link, bool(data.get("up")), str(data.get("reason", "")))

    def _on_state_sample(self, sample: Any) -> None:
        data = _json(sample)
        if isinstance(data, dict) and self._loop is not None and not self._loop.is_closed():
            with contextlib.suppress(RuntimeError):  # the loop closed between the check and the call
                self._loop.call_soon_threadsafe(self._keep_state, data)

    def _keep_state(self, data: dict[str, Any]) -> None:
        self.served_state = data
        if "up" in data:
            self._set_link(bool(data.get("up")), str(data.get("reason", "")))

    # -- telemetry ----------------------------------------------------------------------------------

    def attitude(self, rate_hz: float = 50, *, abandon_after_s: float | None = None) -> AsyncIterator[GimbalAttitude]:
        """Attitude samples as the server publishes them, at most `rate_hz` (`t`: arrival here,
        monotonic; `wall`: when the server received the camera's frame)."""
        from .api_core import _rate

        return self._attitude(_rate(rate_hz))

    async def _attitude(self, rate_hz: float) -> AsyncIterator[GimbalAttitude]:
        if self.session is None:
            raise LinkLostError(f"{self.url}: not open")
        loop = asyncio.get_running_loop()
        queue: asyncio.Queue[GimbalAttitude] = asyncio.Queue(QUEUE_SAMPLES)

        def put(att: GimbalAttitude) -> None:
            if queue.full():
                queue.get_nowait()
            queue.put_nowait(att)

        def on_sample(sample: Any) -> None:
            d = _json(sample)
            if not isinstance(d, dict):
                return
            try:
                att = GimbalAttitude(float(d["yaw_deg"]), float(d["pitch_deg"]), float(d["roll_deg"]), monotonic(),
                               float(d.get("t", 0.0)), "zenoh")  # fmt: skip
            except (KeyError, TypeError, ValueError):
                return
            with contextlib.suppress(RuntimeError):
                loop.call_soon_threadsafe(put, att)

        sub = self.session.declare_subscriber(key(self.name, "attitude"), on_sample)
        gap = 1.0 / rate_hz
        last = 0.0
        try:
            while True:
                att = await queue.get()
                if att.t - last < gap * 0.9:
                    continue
                last = att.t
                self.state.attitude = att
                yield att
        finally:
            with contextlib.suppress(Exception):
                sub.undeclare()

    # -- calls --------------------------------------------------------------------------------------

    async def call(self, method: str, kwargs: dict[str, object]) -> object:
        """One SDK method on the remote camera, by name, with keyword arguments."""
        timeout = kwargs.get("timeout_s")
        if isinstance(timeout, (int, float)):
            wait = float(timeout) * (1 + int(kwargs.get("retries", 2) or 0)) + MARGIN_S  # type: ignore[call-overload]
        else:
            wait = POINT_TIMEOUT_S if method == "point" else CALL_TIMEOUT_S
        reply = await self._query_json(call_key(self.name, method), json.dumps(kwargs), wait, method=method)
        if reply.get("ok") is True:
            return decode_result(method, reply.get("result"), self.model.name)
        raise error_from_reply(reply)

    async def _query_json(self, k: str, payload: str | None, wait_s: float, *, method: str = "") -> dict[str, Any]:
        session = self.session
        if session is None:
            raise LinkLostError(f"{self.url}: not open")

        querier = getattr(self, "_querier", "")
        # Every answer, not Zenoh's one per key: two servers of one name must show as two answers.
        extra: dict[str, Any] = {"consolidation": _no_consolidation()}
        if querier:  # names this session, for the server's fair share of a camera's places
            extra["attachment"] = querier

        def ask() -> list[Any]:
            return list(session.get(k, payload=payload, timeout=wait_s, **extra))

        self.stats.requests += 1
        replies = await asyncio.to_thread(ask)
        errors: list[str] = []
        answers = [d for d in (_json(r.ok) for r in replies if r.ok is not None) if isinstance(d, dict)]
        if len(answers) > 1:
            self.stats.replies += 1
            what = f"{method}() may have been carried out by each" if method else "which one is it?"
            raise RemoteCallError(f"{self.url}: {len(answers)} servers answered {k}: {what}; give each camera its own "
                                  "name", KIND_SERVED_TWICE)  # fmt: skip
        if answers:
            self.stats.replies += 1
            return answers[0]
        for r in replies:
            if r.ok is None and r.err is not None:
                errors.append(r.err.payload.to_string()[:200])
        self.stats.timeouts += 1
        if errors:
            what = f"{method}() may or may not have been carried out" if method else "no answer"
            raise RequestTimeoutError(f"{what}: {self.url}: {k}: {'; '.join(errors)}")  # the key words first
        raise LinkLostError(f"{self.url}: nothing answers {k} (is `topgimbal zenoh` serving {self.name!r}?)")


def _no_consolidation() -> Any:
    import zenoh  # a session is open, so eclipse-zenoh is installed

    return zenoh.ConsolidationMode.NONE


def _json(sample: Any) -> object:
    try:
        return json.loads(sample.payload.to_bytes())
    except (ValueError, AttributeError):
        return None


def _remote_method(name: str) -> Callable[..., Coroutine[object, object, object]]:
    spec = METHODS[name]
    sig = inspect.signature(spec.fn)
    public = sig.replace(parameters=list(sig.parameters.values())[1:])

    @functools.wraps(spec.fn)
    async def method(self: RemoteClient, *args: object, **kwargs: object) -> object:
        spec.check(args, kwargs)  # the local client's own checks, before anything is sent
        if name == "locate" and kwargs.get("terrain") is not None:  # the server refuses it too (fleet/access.py)
            raise FieldValueError("terrain", kwargs["terrain"], "none over Zenoh (a path names a file on the server's "
                                  "machine): locate without it, or locally with connect(URL) to use a DEM")  # fmt: skip
        bound = public.bind(*args, **kwargs)
        values = dict(bound.arguments)
        for p in public.parameters.values():
            if p.kind is p.VAR_KEYWORD and p.name in values:
                values.update(values.pop(p.name))
        return await self.call(name, values)

    method.__signature__ = public  # type: ignore[attr-defined]
    return method


for _name in METHODS:  # the typed signatures come from the inherited Protocols; the calls from here
    setattr(RemoteClient, _name, _remote_method(_name))
