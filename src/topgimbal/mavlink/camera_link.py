"""The camera side of the bridge: one topgimbal client, kept open, and whether the camera answers.

Liveness is the client's own judgement (its link monitor: `on_link_change`, `connected`,
`LinkLostError`); this module only follows it. The client declares the link down after
`silence_s` without a frame while it expects one (its attitude stream, a request in flight) or
the moment a TCP / serial link closes; it reconnects byte streams itself, pings a quiet device,
and asks for the attitude stream again when the device comes back (a camera that rebooted has
forgotten it). Here: the first open is retried with back-off (a TCP camera that is not up yet, a
serial adapter not plugged in), the attitude stream is asked for once (the client keeps it), and
a model without an attitude stream is asked its version whenever it has been quiet for half of
`silence_s`, so that its silence is noticed too.

`answering` (what the MAVLink side reports: COMMS_ERROR, MAV_STATE_CRITICAL, stream flags) is
the client's link state with two additions: it starts false and turns true with the first frame
heard, so a camera that was never there is never reported healthy; and not before the client's
model check has a verdict that lets the camera be served (`servable`: ok, off, or unknown, the
check done without evidence against `--model`), so a camera that turns out to be another model
is never reported healthy either, not even for the moment between its first answer and the
verdict (until then the components say MAV_STATE_BOOT, as for a camera not heard yet). Commands
go through whenever the client's link is up (`call`).

A camera whose model check (client/model_check.py) says it is another model than `--model` is not
served (issue 35.2): it is reported failed with the model it looks like, logged once as an error,
and every command fails with ModelMismatchError before anything is sent; signs and commands would
be the wrong model's. `topgimbal mavlink --model auto` asks the camera what it is instead."""

from __future__ import annotations

import asyncio
import contextlib
import logging
import math
from collections.abc import Awaitable, Callable
from dataclasses import dataclass
from typing import Any, TypeVar
from urllib.parse import urlsplit

from ..client import AsyncClient, identity
from ..clock import monotonic
from ..errors import LinkLostError, ModelMismatchError, RequestTimeoutError, TopGimbalError
from ..geo.earth import wrap180
from ..protocol import Message, get_model
from ..timeouts import stop_tasks, within
from .profile import Profile, profile_of

log = logging.getLogger("topgimbal.mavlink")
T = TypeVar("T")

NAN = float("nan")
REOPEN_MIN_S = 0.5
REOPEN_MAX_S = 5.0
CLIENT_CLOSE_S = 5.0  # the client's close (stopping the camera's streams) at most this long
# Model check verdicts (client/identity.py) under which the camera is not reported healthy: not
# known yet, or another model.
SUSPENDED_VERDICTS = frozenset({identity.PENDING, identity.MISMATCH})


@dataclass(frozen=True)
class AttitudeSample:
    """Gimbal attitude (API convention, degrees, body frame) and rates estimated from the
    previous sample (deg/s; NaN when there is none close enough)."""

    yaw_deg: float
    pitch_deg: float
    roll_deg: float
    t: float
    yaw_rate_deg_s: float = NAN
    pitch_rate_deg_s: float = NAN
    roll_rate_deg_s: float = NAN


class SentUnansweredError(RequestTimeoutError):
    """The request went to the camera while its link was up, then the link was declared lost
    before an answer: it may have been carried out (a photo taken). Not "not sent"."""


AttitudeCallback = Callable[[AttitudeSample], None]
HealthCallback = Callable[[bool], None]


class CameraLink:
    def __init__(
        self,
        url: str,
        model: str,
        *,
        stream_hz: float = 50.0,
        silence_s: float = 3.0,
        timeout_s: float = 1.0,
        retries: int = 2,
        client_options: dict[str, Any] | None = None,
    ) -> None:
        self.url = url
        self.model_name = model
        dialect, dev_model = get_model(model)
        self.profile: Profile = profile_of(dialect, dev_model)
        self.stream_hz = stream_hz
        self.silence_s = silence_s
        self.timeout_s = timeout_s
        self.retries = retries
        self.client_options = dict(client_options or {})
        self.client: AsyncClient | None = None
        self.answering = False
        self.heard = False  # any frame since the bridge started (before: not yet known, not failed)
        self.declared_down = False  # the client said the link is down (or it could not be opened)
        self.reason = "not opened yet"
        self.attitude: AttitudeSample | None = None
        self.last_frame_t = 0.0
        self.link_changes = 0
        self._seen_att: object = None
        self._attitude_cbs: list[AttitudeCallback] = []
        self._health_cbs: list[HealthCallback] = []
        self._task: asyncio.Task[None] | None = None
        self._closed = False
        self._opened = asyncio.Event()
        self.wrong_model = ""  # the model check's message when the camera is another model: not served

    # -- what the bridge uses ------------------------------------------------------------------

    def on_attitude(self, cb: AttitudeCallback) -> None:
        self._attitude_cbs.append(cb)

    def on_health(self, cb: HealthCallback) -> None:
        self._health_cbs.append(cb)

    @property
    def camera_host(self) -> str | None:
        return urlsplit(self.url).hostname

    async def call(self, fn: Callable[[AsyncClient], Awaitable[T]]) -> T:
        """Run one client operation. Its errors are the client's: LinkLostError while the link
        is down (at once: nothing is sent), RequestTimeoutError, DeviceError... A link declared
        lost while the request was in flight (the camera went quiet for `silence_s` with our
        frame sent) is SentUnansweredError: sent, outcome unknown, never "not sent"."""
        client = self.client
        if self.wrong_model:
            raise ModelMismatchError(f"{self.url}: not served: {self.wrong_model}")
        if client is None or not client.connected:
            reason = client.link_state["reason"] if client is not None else self.reason
            raise LinkLostError(f"{self.url}: the camera link is down ({reason})")
        try:
            return await fn(client)
        except LinkLostError as exc:
            # The key words first: a failure text is cut at 200 bytes (STATUSTEXT), the link's
            # address and reason can fill that on their own.
            raise SentUnansweredError(
                f"sent, then the link went down: it may or may not have been carried out ({exc})"
            ) from None

    async def start(self, wait_s: float = 0.0) -> None:
        self._task = asyncio.ensure_future(self._run())
        if wait_s > 0:
            with contextlib.suppress(asyncio.TimeoutError):
                await within(self._opened.wait(), wait_s)

    async def close(self) -> None:
        """Bounded, whatever the camera does: the keeper task through stop_tasks (cancelled again
        if it swallows a cancellation, given up on and logged after its rounds), the client's close
        within CLIENT_CLOSE_S (it stops the camera's streams first)."""
        self._closed = True
        if self._task is not None:
            await stop_tasks([self._task], "camera link")
        if self.client is not None:
            client, self.client = self.client, None
            with contextlib.suppress(Exception, asyncio.TimeoutError):
                await within(client.close(), CLIENT_CLOSE_S)

    @property
    def stream_rate_hz(self) -> float:
        top = self.profile.stream_max_hz
        return max(1.0, min(self.stream_hz, top)) if top else self.stream_hz

    @property
    def _streaming(self) -> bool:
        return self.profile.can("attitude_stream")

    # -- keeping the client --------------------------------------------------------------------

    async def _run(self) -> None:
        delay = REOPEN_MIN_S
        while not self._closed:
            client = AsyncClient(
                self.url, self.model_name, timeout_s=self.timeout_s, retries=self.retries,
                link_timeout_s=self.silence_s, **self.client_options,
            )  # fmt: skip
            try:
                await client.open()
            except (TopGimbalError, OSError) as exc:
                self._set_answering(False, f"cannot open: {exc}", force=True)
                log.warning("camera %s: cannot open (%s); retrying in %.1f s", self.url, exc, delay)
                await asyncio.sleep(delay)
                delay = min(REOPEN_MAX_S, delay * 2)
                continue
            self.client = client
            self.reason = "no frame from the camera yet"
            client.subscribe(self._on_message)
            client.on_link_change(self._on_link_change)
            client.on_model_check(self._on_model_check)
            self._on_model_check(client.model_check)  # a verdict reached before the callback was added
            self._opened.set()
            await self._keep(client)
            return

    async def _keep(self, client: AsyncClient) -> None:
        """Ask for the attitude stream once (the client resumes it after every outage); for a
        model without one, ask the version whenever the camera has been quiet a while."""
        if self._streaming:
            # Asked at once, beside the model check (the stream is what makes a silent camera's
            # silence noticed); once the check says the camera is another model the client stops
            # keeping it (client/streams.py `halt`): this one request is all it gets.
            # Recorded by the client even when this first request fails: it asks again itself
            # once the camera answers (its ping, or a reconnected byte stream).
            with contextlib.suppress(TopGimbalError, OSError):
                await client.attitude_stream(self.stream_rate_hz)
            return
        period = max(0.1, self.silence_s / 2)
        while not self._closed:
            # not served (another model): its version query is the wrong model's; nothing is asked
            if not self.wrong_model and monotonic() - self.last_frame_t >= period:
                with contextlib.suppress(TopGimbalError, OSError):
                    await client.version()
            await asyncio.sleep(period)

    # -- what the client reports ---------------------------------------------------------------

    @property
    def servable(self) -> bool:
        """Whether the model check lets the camera be served: a verdict other than pending (not
        known yet) or mismatch (another model). Unknown (firmware the profiles do not know, the
        identity queries refused or unanswered) is served, as the client's commands go ahead then."""
        client = self.client
        return not self.wrong_model and client is not None and client.model_check.status not in SUSPENDED_VERDICTS

    def _on_model_check(self, verdict: Any) -> None:
        if self.wrong_model:
            return
        if verdict.status == identity.MISMATCH:
            self.wrong_model = verdict.message
            log.error("camera %s: not served: %s", self.url, verdict.message)
            self._set_answering(False, f"another model: {verdict.message}", force=True)
            return
        client = self.client
        if self.last_frame_t and self.servable and client is not None and client.connected:
            self._set_answering(True, f"model check: {verdict.status}")  # heard before the verdict

    def _on_link_change(self, up: bool, reason: str) -> None:
        self.link_changes += 1
        if not up:
            self._set_answering(False, reason, force=True)
        elif self.last_frame_t and reason != "reconnected" and self.servable:
            self._set_answering(True, reason)  # a frame came (a reconnected stream: wait for one)

    def _on_message(self, m: Message) -> None:
        self.last_frame_t = monotonic()
        client = self.client
        if self.wrong_model:
            return  # not served: no health, no attitude read through the wrong model's signs
        if not self.servable:
            return  # the model check has no verdict yet: neither health nor attitude until it has
        if not self.answering and client is not None and client.connected:
            self._set_answering(True, f"frame {m.frame.ident}")
        att = client.state.attitude if client is not None else None
        if att is None or att is self._seen_att:
            return
        self._seen_att = att
        prev = self.attitude
        rates = (NAN, NAN, NAN)
        if prev is not None and 0.0 < att.t - prev.t <= 1.0:
            dt = att.t - prev.t
            rates = (
                _wrap(att.yaw_deg - prev.yaw_deg) / dt,
                (att.pitch_deg - prev.pitch_deg) / dt,
                (att.roll_deg - prev.roll_deg) / dt,
            )
        sample = AttitudeSample(att.yaw_deg, att.pitch_deg, att.roll_deg, att.t, *rates)
        self.attitude = sample
        for cb in list(self._attitude_cbs):
            try:
                cb(sample)
            except Exception:
                log.exception("attitude listener failed")

    def _set_answering(self, value: bool, why: str, *, force: bool = False) -> None:
        """A change of `answering`; `force`: tell the listeners also when it stays false (the
        camera was never heard and is now declared down: from "not yet known" to "failed")."""
        self.reason = "" if value else why
        first_down = force and not value and not self.declared_down
        self.heard = self.heard or value
        self.declared_down = not value and (self.declared_down or force)
        if value == self.answering and not first_down:
            return
        self.answering = value
        log.log(logging.INFO if value else logging.WARNING, "camera %s %s (%s)", self.url,
                "answers" if value else "stopped answering", why)  # fmt: skip
        for cb in list(self._health_cbs):
            try:
                cb(value)
            except Exception:
                log.exception("health listener failed")


_wrap = wrap180


def finite(x: float) -> bool:
    return not (math.isnan(x) or math.isinf(x))
