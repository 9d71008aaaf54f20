"""The camera side of the bridge: one topgimbal client, kept open, and the answer to "is the
camera answering?".

Until the client reports link changes itself, liveness is judged here, in one place: any frame
from the camera means it answers; silence longer than `silence_s` (while the attitude stream
should be running) or consecutive request timeouts mean it does not. A client whose transport
closed (TCP, serial) is replaced by a new one, with back-off. When the camera comes back, its
attitude stream is asked for again (a camera that rebooted has forgotten it)."""

from __future__ import annotations

import asyncio
import contextlib
import logging
import math
import time
from collections.abc import Awaitable, Callable
from dataclasses import dataclass
from typing import Any, TypeVar

from ..client import AsyncClient
from ..errors import RequestTimeoutError, TopGimbalError, TransportError
from ..protocol import Message, get_model
from .profile import Profile, profile_of

log = logging.getLogger("topgimbal.mavlink")
T = TypeVar("T")

NAN = float("nan")
REOPEN_MIN_S = 0.5
REOPEN_MAX_S = 5.0
TIMEOUTS_FOR_DOWN = 2


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
        self.attitude: AttitudeSample | None = None
        self.last_frame_t = 0.0
        self.reopened = 0
        self._consecutive_timeouts = 0
        self._last_probe = 0.0
        self._seen_att: object = None
        self._attitude_cbs: list[AttitudeCallback] = []
        self._health_cbs: list[HealthCallback] = []
        self._task: asyncio.Task[None] | None = None
        self._closed = False
        self._opened = asyncio.Event()

    # -- what the bridge uses ------------------------------------------------------------------

    def on_attitude(self, cb: AttitudeCallback) -> None:
        self._attitude_cbs.append(cb)

    def on_health(self, cb: HealthCallback) -> None:
        self._health_cbs.append(cb)

    @property
    def camera_host(self) -> str | None:
        from urllib.parse import urlsplit

        return urlsplit(self.url).hostname

    async def call(self, fn: Callable[[AsyncClient], Awaitable[T]]) -> T:
        """Run one client operation; its failures feed the liveness judgement, then propagate."""
        client = self.client
        if client is None or not client.connected:
            raise TransportError(f"{self.url}: the camera link is down (reconnecting)")
        try:
            result = await fn(client)
        except RequestTimeoutError:
            self._consecutive_timeouts += 1
            if self._consecutive_timeouts >= TIMEOUTS_FOR_DOWN:
                self._set_answering(False, "requests time out")
            raise
        self._consecutive_timeouts = 0
        return result

    async def start(self, wait_s: float = 0.0) -> None:
        self._task = asyncio.ensure_future(self._run())
        if wait_s > 0:
            with contextlib.suppress(asyncio.TimeoutError):
                await asyncio.wait_for(self._opened.wait(), wait_s)

    async def close(self) -> None:
        self._closed = True
        if self._task is not None:
            self._task.cancel()
            with contextlib.suppress(asyncio.CancelledError, Exception):
                await self._task
        if self.client is not None:
            with contextlib.suppress(Exception):
                await self.client.close()
            self.client = None

    # -- the keeper ----------------------------------------------------------------------------

    async def _run(self) -> None:
        delay = REOPEN_MIN_S
        while not self._closed:
            try:
                await self._open()
            except (TopGimbalError, OSError) as exc:
                log.warning("camera %s: cannot open (%s); retrying in %.1f s", self.url, exc, delay)
                await asyncio.sleep(delay)
                delay = min(REOPEN_MAX_S, delay * 2)
                continue
            delay = REOPEN_MIN_S
            self._opened.set()
            await self._watch()
            if self._closed:
                return
            self._set_answering(False, "the link closed")
            client, self.client = self.client, None
            if client is not None:
                with contextlib.suppress(Exception):
                    await client.close()
            self.reopened += 1
            await asyncio.sleep(delay)

    async def _open(self) -> None:
        client = AsyncClient(
            self.url, self.model_name, timeout_s=self.timeout_s, retries=self.retries, **self.client_options
        )
        await client.open()
        client.subscribe(self._on_message)
        self.client = client
        self._last_probe = 0.0
        await self._probe()

    async def _watch(self) -> None:
        """Until the client's transport closes: judge silence, ask for the stream again."""
        period = max(0.1, min(0.5, self.silence_s / 4))
        while not self._closed:
            client = self.client
            if client is None or not client.connected:
                return
            now = time.monotonic()
            silent_for = now - self.last_frame_t
            if self.answering and silent_for > self.silence_s and self._streaming:
                self._set_answering(False, f"no frame for {silent_for:.1f} s")
            if not self.answering and now - self._last_probe >= max(1.0, self.silence_s / 2):
                await self._probe()
            await asyncio.sleep(period)

    @property
    def _streaming(self) -> bool:
        return self.profile.has("GAA")

    async def _probe(self) -> None:
        """Ask for something the camera answers: the attitude stream where the model has one
        (which also restarts it after a reboot), else the version."""
        self._last_probe = time.monotonic()
        client = self.client
        if client is None:
            return
        with contextlib.suppress(TopGimbalError, OSError):
            if self._streaming:
                await client.attitude_stream(self.stream_rate_hz)
            else:
                await client.version()

    @property
    def stream_rate_hz(self) -> float:
        top = self.profile.stream_max_hz
        return max(1.0, min(self.stream_hz, top)) if top else self.stream_hz

    def _on_message(self, m: Message) -> None:
        now = time.monotonic()
        self.last_frame_t = now
        self._consecutive_timeouts = 0
        if not self.answering:
            self._set_answering(True, f"frame {m.ident}")
        client = self.client
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

    def _set_answering(self, value: bool, why: str) -> None:
        if value == self.answering:
            return
        self.answering = value
        log.warning("camera %s %s (%s)", self.url, "answers again" if value else "stopped answering", why)
        for cb in list(self._health_cbs):
            try:
                cb(value)
            except Exception:
                log.exception("health listener failed")


def _wrap(deg: float) -> float:
    return (deg + 180.0) % 360.0 - 180.0


def finite(x: float) -> bool:
    return not (math.isnan(x) or math.isinf(x))
