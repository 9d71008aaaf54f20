"""One camera served on a Zenoh session: its SDK client, what it publishes (attitude, state,
link), its liveliness token and its queryables (`call/<method>`, `info`).

Zenoh runs its callbacks on its own threads; every query is handed to this camera's asyncio loop
(`call_soon_threadsafe`) and answered from there, so the SDK client is only ever used on its loop.
Calls are bounded per camera (`max_calls` at once; more are refused at once with kind "busy"), and
per querier (a fair share of those places among the queriers seen in the last ACTIVE_WINDOW_S; the
last place is kept for a querier that holds none), as are their arguments (client/remote_keys.py)
and their time (a `timeout_s` argument at most MAX_ARG_TIMEOUT_S, the whole call at most
MAX_CALL_S). A querier is a Zenoh session connected to this one (a transport): the session id its
call's attachment names counts only while such a transport is open, so a name cannot be invented;
calls naming none share one share. A call whose querier's transport closes is cancelled at once
and its place freed. What is remotely callable is fleet/access.py's. A call is answered
"ok" only with what the SDK method returned: the SDK's truth rules hold unchanged (no success the
camera did not confirm)."""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
import re
from collections.abc import Callable
from math import isfinite
from typing import Any

from ..client import AsyncClient
from ..client.remote_keys import (
    KIND_BUSY,
    METHODS,
    RemoteCallError,
    bind_arguments,
    call_key,
    encode_result,
    error_reply,
    key,
    liveliness_key,
    split_call_key,
)
from ..client.state import GimbalAttitude
from ..clock import MonotonicFn, monotonic, wall_time
from ..errors import RequestTimeoutError, TopGimbalError
from ..logtext import untrusted
from ..logthrottle import ThrottledLog
from ..timeouts import within
from .access import KIND_FORBIDDEN, callable_methods, refusal
from .batch import AttitudeBatch, batch_head, named
from .specs import CameraSpec
from .ticker import CameraTicker

log = logging.getLogger("topgimbal.fleet")

MAX_CALLS = 8  # calls in progress per camera
STATE_POLL_S = 0.25  # how often the state is compared with what was last published
STATE_KEYS = ("zoom", "recording", "mode", "sd", "version", "model_name", "range_m", "temperature")
BUSY_LOG_EVERY_S = 10.0
MAX_ARG_TIMEOUT_S = 60.0  # a call's `timeout_s` argument is lowered to this
MAX_CALL_S = 150.0  # a whole call (point's slew included); then it is cancelled and answered "timeout"
ACTIVE_WINDOW_S = 10.0  # a querier counts for the fair share this long after its last call
MAX_QUERIERS = 1024  # queriers remembered per camera (the oldest forgotten first)
GONE_CHECK_S = 0.5  # backstop of the transport events: calls of a closed transport are looked for this often
# Queriers that name no open transport (no attachment, an invented or stale session id, a querier
# behind a router) share one share: one more name is one more call in that share, not a new share.
ANONYMOUS = "unverified"
_ZID_RE = re.compile(r"[0-9a-f]{1,32}")


def claimed_querier(query: Any) -> str | None:
    """The Zenoh session id the call's attachment names (RemoteClient sends its own), or None."""
    try:
        att = query.attachment
        text = "" if att is None else att.to_string()
    except Exception:  # an attachment that is not text
        return None
    return text if _ZID_RE.fullmatch(text) else None


def querier_of(query: Any, transports: set[str]) -> str:
    """Whom a call counts against: the session id it names when a transport of that id is open on
    this session (the caller cannot invent one), else ANONYMOUS."""
    claim = claimed_querier(query)
    return claim if claim is not None and claim in transports else ANONYMOUS


def served_url(url: str) -> str:
    """The URL the server opens: a UDP camera goes on the loop's shared socket
    (transport/udp_shared.py), unless its URL chose a socket (`socket=own`) or a local port."""
    if not url.lower().startswith("udp://"):
        return url
    query = url.partition("?")[2]
    names = {part.partition("=")[0] for part in query.split("&") if part}
    if names & {"socket", "local_port"}:
        return url
    return f"{url}{'&' if query else '?'}socket=shared"


def direct(callback: Callable[[Any], None]) -> Any:
    """`callback` for Zenoh to call on its own thread. By default zenoh-python gives each Python
    callback a thread of its own to run on (`indirect`): three per camera here (the two queryables
    and the transport events), 3,000 threads in a process serving 1,000 cameras, which is why a
    process once stopped at 256. Every callback here only hands its work to the event loop
    (`call_soon_threadsafe`: a call, a closed transport), sets a flag or answers `info` from data
    already made, so it may run
    where Zenoh calls it: it holds that Zenoh thread only while it waits for the GIL. A Zenoh
    without `indirect=`: the callback as it is."""
    try:
        import zenoh  # the serving process has it (fleet/server.py); a test double may not

        return zenoh.handlers.Callback(callback, indirect=False)
    except (ImportError, AttributeError, TypeError):
        return callback


def attitude_json(att: GimbalAttitude, seq: int, head: str = "{") -> str:
    """`{"yaw_deg", "pitch_deg", "roll_deg", "t", "seq"}`; a float's repr is JSON when finite.
    `head` opens the object: `batch_head(name)` puts the camera's name first, as the batch key's
    samples carry it (the same text as `batch.named`, made in one step: this runs per sample)."""
    y, p, r, t = att.yaw_deg, att.pitch_deg, att.roll_deg, att.wall
    if not (isfinite(y) and isfinite(p) and isfinite(r)):
        return head + json.dumps({"yaw_deg": encode_result(y), "pitch_deg": encode_result(p),
                                  "roll_deg": encode_result(r), "t": t, "seq": seq})[1:]  # fmt: skip
    return f'{head}"yaw_deg":{y!r},"pitch_deg":{p!r},"roll_deg":{r!r},"t":{t!r},"seq":{seq}}}'


class ServedCamera:
    def __init__(
        self,
        spec: CameraSpec,
        session: Any,
        *,
        rate_hz: float = 50.0,
        max_calls: int = MAX_CALLS,
        client_options: dict[str, Any] | None = None,
        allow_remote: frozenset[str] = frozenset(),
        clock: MonotonicFn = monotonic,
        batch: AttitudeBatch | None = None,
        ticker: CameraTicker | None = None,
    ) -> None:
        self.spec = spec
        self.batch = batch  # the serving process's batch key (fleet/batch.py), if it has one
        self.ticker = ticker  # the serving process's periodic checks (fleet/ticker.py), if it has one
        self._own_ticker: CameraTicker | None = None  # made by start() when none was given
        self._mark: tuple[object, ...] | None = None  # what the last published state was made of
        self.allow_remote = allow_remote
        self.clock = clock
        self.name = spec.name
        self.session = session
        self.rate_hz = rate_hz
        self.max_calls = max_calls
        self.client = AsyncClient(served_url(spec.url), spec.model, **(client_options or {}))
        self.loop: asyncio.AbstractEventLoop | None = None
        # Calls accepted and not yet ended. A set, not a counter: a call cancelled before its
        # coroutine first ran (its querier gone in the same loop turn) never runs its `finally`,
        # and a counter decremented there kept that place taken for good (a run under load
        # ended with 3 of 8 places held by nobody).
        self._holding: set[asyncio.Task[None]] = set()
        self.published = 0  # attitude samples
        # Whether a subscriber of this camera's attitude key exists (Zenoh's matching status): no
        # put per sample when none does (_follow_att_subscribers). True until Zenoh says otherwise.
        self.att_subscribed = True
        self.calls = 0
        self.refused = 0
        self._seq = 0
        self._batch_head = batch_head(self.name)
        self._decls: list[Any] = []
        self._tasks: list[asyncio.Task[None]] = []
        self._calls: set[asyncio.Task[None]] = set()
        self._by_querier: dict[str, int] = {}  # calls in progress per querier
        self._seen: dict[str, float] = {}  # querier -> when it last asked (bounded: MAX_QUERIERS)
        self._call_querier: dict[asyncio.Task[None], tuple[str, bool]] = {}  # (querier, had a transport)
        self.gone = 0  # calls cancelled because their querier left
        # cancelled and not yet ended: the transport event and the poll may both see such a call
        # before it ends, and it is one call gone, counted once
        self._cancelled: set[asyncio.Task[None]] = set()
        self._link_lost: str | None = None
        self._last_state: str | None = None
        self._throttle = ThrottledLog(log, BUSY_LOG_EVERY_S)
        self._closing = False
        self._unsubscribe: list[Callable[[], None]] = []

    async def start(self) -> ServedCamera:
        self.loop = asyncio.get_running_loop()
        await self.client.open()
        s = self.session
        self._att = s.declare_publisher(key(self.name, "attitude"))
        self._state = s.declare_publisher(key(self.name, "state"))
        self._link = s.declare_publisher(key(self.name, "link"))
        self._decls += [self._att, self._state, self._link]
        self._follow_att_subscribers()
        self._decls.append(s.declare_queryable(key(self.name, "call/*"), direct(self._on_query_thread)))
        self._decls.append(s.declare_queryable(key(self.name, "info"), direct(self._on_info_thread)))
        self._decls.append(s.liveliness().declare_token(liveliness_key(self.name)))
        self._unsubscribe = [self.client.on_link_change(self._on_link), self.client.streams.tap(self._on_attitude)]
        self._tasks.append(asyncio.ensure_future(self._attitude_loop()))
        if self.ticker is None:  # served alone: a ticker of its own
            self.ticker = self._own_ticker = CameraTicker(STATE_POLL_S, GONE_CHECK_S)
        self.poll_state()  # the first state at once; then every STATE_POLL_S
        self._unsubscribe.append(self.ticker.add(self))
        self._listen_transports()
        return self

    async def close(self) -> None:
        self._closing = True
        for remove in self._unsubscribe:
            remove()
        for t in [*self._tasks, *self._calls]:
            t.cancel()
        for t in [*self._tasks, *self._calls]:
            with contextlib.suppress(asyncio.CancelledError, Exception):
                await t
        for d in reversed(self._decls):
            with contextlib.suppress(Exception):
                d.undeclare()
        self._decls.clear()
        if self._own_ticker is not None:
            await self._own_ticker.close()
        await self.client.close()

    # -- what it publishes --------------------------------------------------------------------------

    async def _attitude_loop(self) -> None:
        """Asks the camera for its attitude stream at `rate_hz` until it has accepted once; the SDK
        keeps it on from then (asked again after a link loss). Samples are published by `_on_frame`,
        every frame the camera sends: a stream consumer would wake a task per sample and thin out
        samples that come a little early (one in three under load on a busy host). No remote call
        starts, re-rates or stops it (fleet/access.py: SERVER_OWNED)."""
        while True:
            try:
                await self.client.attitude_stream(self.rate_hz)
                return
            except TopGimbalError as exc:
                log.debug("%s: attitude stream not started: %s", self.name, exc)
            await asyncio.sleep(1.0)

    def _on_attitude(self, att: GimbalAttitude) -> None:
        """Every sample the client decoded, published at once (a tap, not a consumer: no task, no
        queue, no rate thinning). The JSON is written by hand: json.dumps was a fifth of the cost."""
        if self._closing:
            return
        self._seq += 1
        if self.att_subscribed:
            text = attitude_json(att, self._seq)
            self._att.put(text)
            if self.batch is not None:
                self.batch.add(named(self.name, text), att.t)
        elif self.batch is not None:  # (every sample of a server whose cameras nobody watches one by one)
            self.batch.add(attitude_json(att, self._seq, self._batch_head), att.t)
        self.published += 1

    def _follow_att_subscribers(self) -> None:
        """Keep `att_subscribed` true while a subscriber anywhere matches this camera's attitude key
        (Zenoh's matching status, which follows subscribers on peers and behind routers). With
        none (every sample on the batch key only, 1,000 cameras), a put per sample was an eighth of
        the server's CPU, for samples Zenoh then dropped. Zenoh without the matching API: always."""
        declare = getattr(self._att, "declare_matching_listener", None)
        if declare is None:
            return

        def matching(status: Any) -> None:  # on a Zenoh thread, not the loop: one attribute set
            self.att_subscribed = bool(status.matching)

        self._decls.append(declare(direct(matching)))
        self.att_subscribed = bool(self._att.matching_status.matching)

    def state(self) -> dict[str, Any]:
        c = self.client
        out: dict[str, Any] = {"name": self.name, "model": c.model.name, **c.link_state}
        out.pop("silent_s", None)
        for k in STATE_KEYS:
            s = getattr(c.state, k)
            out[k] = None if s is None else encode_result(s.value)
        out["model_check"] = c.model_check.status
        return out

    def _state_mark(self) -> tuple[object, ...]:
        """What the published state is made of, by identity: the cache replaces an entry when the
        device says something, so an equal mark means nothing to encode (4 times a second x N)."""
        c = self.client
        up = c.connected
        reason = "" if up else c.link_state["reason"]  # link_state's reason is "" while up
        state = c.state
        return (up, reason, c.model_check.status, *[getattr(state, k) for k in STATE_KEYS])

    def poll_state(self) -> None:
        """Put the state if it changed (every STATE_POLL_S, by the ticker)."""
        now_mark = self._state_mark()
        if now_mark == self._mark:
            return
        self._mark = now_mark
        state = self.state()
        text = json.dumps(state, sort_keys=True)
        if text != self._last_state:
            self._last_state = text
            state["stats"] = self.client.stats.as_dict()
            state["t"] = wall_time()
            self._state.put(json.dumps(state))

    def _on_link(self, up: bool, reason: str) -> None:
        if self._closing:
            return
        # The SDK logs a loss; its return is said here, so a log read later shows both ends.
        if not up:
            self._link_lost = reason
        elif self._link_lost is not None:
            log.warning("%s: camera link back (it was lost: %s)", self.name, self._link_lost)
            self._link_lost = None
        self._link.put(json.dumps({"up": up, "reason": reason, "t": wall_time()}))

    # -- queries ------------------------------------------------------------------------------------

    def _on_query_thread(self, query: Any) -> None:
        loop = self.loop
        if loop is None or self._closing or loop.is_closed():
            with contextlib.suppress(Exception):
                query.drop()
            return
        try:
            loop.call_soon_threadsafe(self._on_query, query)
        except RuntimeError:  # the loop closed meanwhile
            with contextlib.suppress(Exception):
                query.drop()

    def _on_info_thread(self, query: Any) -> None:
        try:
            with query:
                query.reply(key(self.name, "info"), json.dumps(self.info()))
        except Exception as exc:  # a querier gone: nothing to answer
            log.debug("%s: info reply failed: %s", self.name, exc)

    def info(self) -> dict[str, Any]:
        return {"name": self.name, "model": self.client.model.name, "dialect": self.client.dialect.name,
                "methods": callable_methods(self.allow_remote), "max_calls": self.max_calls, "rate_hz": self.rate_hz}  # fmt: skip

    def _on_query(self, query: Any) -> None:
        where = split_call_key(str(query.key_expr))
        if where is None or where[0] != self.name:
            self._reply(query, call_key(self.name, "*"), error_reply(RemoteCallError(
                "one call names one camera and one method (no wildcards): topgimbal/NAME/call/METHOD")))  # fmt: skip
            return
        reply_key = call_key(*where)
        why = refusal(where[1], self.allow_remote) if where[1] in METHODS else None
        if why is not None:
            self._reply(query, reply_key, error_reply(RemoteCallError(f"{self.name}: {why}", KIND_FORBIDDEN)))
            return
        live = self._transports()
        querier = querier_of(query, live)
        share = self._share(querier)
        held = self._by_querier.get(querier, 0)
        if self._full(held, share):
            self.refused += 1
            if self._throttle.allow("busy") is not None:
                log.warning("%s: %d calls in progress (%d of them %s's, its share %d), refusing more "
                            "(limit %d; %d refused in all)", self.name, self.inflight, held, querier, share,
                            self.max_calls, self.refused)  # fmt: skip
            self._reply(query, reply_key, error_reply(RemoteCallError(
                f"{self.name}: {self.inflight} calls are in progress ({held} of yours, your share {share} of "
                f"{self.max_calls}); try again", KIND_BUSY)))  # fmt: skip
            return
        self._by_querier[querier] = held + 1
        task = asyncio.ensure_future(self._call(query, reply_key, where[1]))
        self._holding.add(task)
        self._calls.add(task)
        self._call_querier[task] = (querier, querier in live)
        task.add_done_callback(self._call_done)

    @property
    def inflight(self) -> int:
        """Calls in progress on this camera (accepted, not yet ended)."""
        return len(self._holding)

    def _full(self, held: int, share: int) -> bool:
        """No place for a querier holding `held` calls: the camera's places are taken, its share
        is, or only the last place is free and it already holds one (that one is kept for a
        querier holding none, so a newcomer is served at once, whatever the others hold)."""
        if self.inflight >= self.max_calls or held >= share:
            return True
        return held > 0 and self.max_calls > 1 and self.inflight >= self.max_calls - 1

    def _share(self, querier: str) -> int:
        """Places one querier may hold: the camera's `max_calls` split among the queriers that
        asked within ACTIVE_WINDOW_S (this one included), at least one each."""
        now = self.clock()
        self._seen.pop(querier, None)
        self._seen[querier] = now  # the newest last: the oldest are forgotten first
        while len(self._seen) > MAX_QUERIERS:
            del self._seen[next(iter(self._seen))]
        active = sum(1 for t in self._seen.values() if now - t <= ACTIVE_WINDOW_S)
        return max(1, self.max_calls // max(1, active))

    def _call_done(self, task: asyncio.Task[None]) -> None:
        self._holding.discard(task)  # one cancelled before it ran: its place is free now
        self._calls.discard(task)
        self._cancelled.discard(task)
        querier, _direct = self._call_querier.pop(task, (ANONYMOUS, False))
        left = self._by_querier.get(querier, 1) - 1
        if left > 0:
            self._by_querier[querier] = left
        else:
            self._by_querier.pop(querier, None)

    def _transports(self) -> set[str]:
        """Session ids of the peers and clients connected to this session directly."""
        try:
            return {str(t.zid) for t in self.session.info.transports()}
        except Exception:  # a session without that API (a test double) or closing
            return set()

    def _listen_transports(self) -> None:
        """Zenoh's transport events: a closed transport's calls are cancelled as it closes (the
        poll of `_gone_loop` is the backstop)."""
        loop = self.loop

        def on_event(event: Any) -> None:  # a Zenoh thread: hands the closed transport to the loop
            if loop is not None and not loop.is_closed() and str(event.kind).endswith("DELETE"):
                with contextlib.suppress(RuntimeError):  # the loop closed meanwhile
                    loop.call_soon_threadsafe(self._transport_closed, str(event.transport.zid))

        try:
            self._decls.append(self.session.info.declare_transport_events_listener(direct(on_event)))
        except Exception as exc:  # an eclipse-zenoh without it, or a test double: the poll does it
            log.debug("%s: no transport events (%s): polling every %g s", self.name, exc, GONE_CHECK_S)

    def _transport_closed(self, zid: str) -> None:
        """On the loop: a transport closed; the calls of its querier end (the session may still
        list it while the event is delivered). No call running: nothing to ask Zenoh."""
        if any(not t.done() for t in self._call_querier):
            self._cancel_gone(self._transports() - {zid})

    def _cancel_gone(self, present: set[str]) -> None:
        """Cancels the calls of queriers whose transport is not in `present`; with no transport
        left at all, every call (one naming no transport too: nobody is left to read it)."""
        for task, (querier, direct) in list(self._call_querier.items()):
            if task.done() or task in self._cancelled:
                continue
            if (direct and querier not in present) or not present:
                self._cancelled.add(task)
                self.gone += 1
                log.info("%s: a call's querier %s has gone: cancelled (%d in all)", self.name, querier, self.gone)
                task.cancel(msg="querier gone")

    def poll_gone(self) -> None:
        """Cancels the calls of a querier whose transport has closed (every GONE_CHECK_S, by the
        ticker): its place is free at once, not at the end of a wait nobody reads. (Calls that name
        no open transport cannot be seen leaving; they end at the latest after MAX_CALL_S, within
        the one share they have.)"""
        if any(not t.done() for t in self._call_querier):
            self._cancel_gone(self._transports())

    async def _call(self, query: Any, reply_key: str, method: str) -> None:
        self.calls += 1
        try:
            payload = query.payload
            _spec, kwargs = bind_arguments(method, None if payload is None else payload.to_bytes())
            why = refusal(method, self.allow_remote, kwargs)
            if why is not None:
                raise RemoteCallError(f"{self.name}: {why}", KIND_FORBIDDEN)
            t = kwargs.get("timeout_s")
            if isinstance(t, (int, float)) and not isinstance(t, bool) and t > MAX_ARG_TIMEOUT_S:
                kwargs["timeout_s"] = MAX_ARG_TIMEOUT_S  # the server's wait is bounded, whoever asks
            try:
                result = await within(getattr(self.client, method)(**kwargs), MAX_CALL_S)
            except TimeoutError as exc:
                if isinstance(exc, TopGimbalError):
                    raise  # the SDK's own RequestTimeoutError, as it is
                raise RequestTimeoutError(
                    f"{method} may or may not have been carried out: {self.name} took more than the server's "
                    f"{MAX_CALL_S:g} s"
                ) from None
            out: dict[str, Any] = {"ok": True, "result": encode_result(result)}
        except asyncio.CancelledError:
            if not self._closing:
                return  # its querier left: nobody to answer
            out = error_reply(RemoteCallError(f"{self.name}: the server is closing", "closing"))
            self._reply(query, reply_key, out)
            raise
        except Exception as exc:  # the SDK's errors, and anything unexpected: a reply either way
            if not isinstance(exc, TopGimbalError):
                log.warning("%s: %s failed unexpectedly: %r", self.name, untrusted(method), exc)
            out = error_reply(exc)
        finally:
            # Free the place before the reply: a querier that asks again as soon as it hears must
            # find it free (the done callback runs a loop turn later).
            task = asyncio.current_task()
            if task is not None:
                self._holding.discard(task)
        self._reply(query, reply_key, out)

    @staticmethod
    def _reply(query: Any, reply_key: str, body: dict[str, Any]) -> None:
        try:
            with query:
                query.reply(reply_key, json.dumps(body))
        except Exception as exc:  # the querier timed out or left
            log.debug("reply on %s failed: %s", reply_key, exc)
