"""One camera session shared by every open page: pumps attitude, link state, statistics, traffic and
errors to the WebSockets, and carries out the pages' ops through the client (`CameraAPI`).

Rates are bounded here, not in the browser: attitude goes out at most `attitude_hz` times a second
(only the latest sample), traffic in batches every `traffic_interval_s`, status every
`status_interval_s`; a change of the link state is pushed at once.

The link state is the client's (`cam.on_link_change`, `cam.link_state`): the page shows LOST, with
the reason and since when, from the moment the client declares the link down until frames arrive
again. The console always expects something from the camera, so that a silent camera is noticed
over UDP too: the attitude stream where the model has one, else a harmless query whenever nothing
has arrived for `KEEPALIVE_IDLE_S` (the client declares the link lost after `link_timeout_s` of
silence while something is expected)."""

from __future__ import annotations

import asyncio
import contextlib
import logging
from collections import Counter
from collections.abc import Coroutine, Iterator
from typing import TYPE_CHECKING, Any

from ..client import CameraAPI
from ..clock import wall_time
from ..errors import LinkLostError
from ..protocol import CommandSpec, Frame, Message
from .capture import link_for
from .ops import OPS, OpArgs, SdStatus, describe_error, jsonable, op_sd
from .pages import MAX_OPS_IN_FLIGHT, PageHub
from .where import WhereCache

if TYPE_CHECKING:
    from ..sim import Simulator
    from .autopilot import AutopilotListener

log = logging.getLogger(__name__)

MOTION_OPS = frozenset({"point", "rates", "stop", "center", "mode", "ptz"})
KEEPALIVE_IDLE_S = 2.0  # ask something when nothing has come for this long
KEEPALIVE_TIMEOUT_S = 1.0  # per attempt of the link check ...
LATE_POLL_S = 10.0  # a poll's answer that comes this long after the poll gave up is still the poll's
KEEPALIVE_RETRIES = 3  # ... so one check outlasts the client's link timeout (3 s) and a lost datagram
# Queries the link check may use, best first (each must be a plain read).
PING_ROLES = ("version", "model_name", "attitude", "sd_capacity", "ip_address")


class Hub(PageHub):
    # Whether an attitude sample counts as something heard from the camera (`last_in`): here the
    # traffic subscription already counts every frame; a hub without one says True.
    samples_are_heard = False

    def __init__(
        self,
        cam: CameraAPI,
        *,
        url: str = "",
        attitude_hz: float = 50.0,
        sd_interval_s: float = 5.0,
    ) -> None:
        super().__init__(dialect=cam.dialect, model=cam.model, url=url, link=link_for(url, cam.model))
        self.cam = cam
        self.attitude_hz = min(max(attitude_hz, 1.0), 50.0)
        self.sd_interval_s = sd_interval_s
        self._polls: Counter[str] = Counter()  # identifiers of the console's own periodic queries
        # frames a poll sent minus the answers it saw (its retries and timeouts leave some owed)
        self._poll_owed: Counter[str] = Counter()
        # answers a finished poll is still owed, and until when: the camera (or a loaded machine)
        # may answer after the poll gave up; that answer is the poll's, not the operator's
        self._late_polls: dict[str, tuple[int, float]] = {}
        # Motion ops from every page, one at a time and in arrival order: a drag's rates, the pad
        # release's stop and another page's stop share the client's GSM/PTZ requests.
        self._motion = asyncio.Lock()
        self.attitude: dict[str, float] | None = None
        self._attitude_seq = 0
        self.recording_since: float | None = None
        self.recording: bool | None = None
        self.sd: SdStatus | None = None
        self.version: str | None = None
        self.lost_since: float | None = None  # wall clock of the client's "link down"
        self.link_reason = ""
        self.sim: Simulator | None = None  # --sim: the simulated camera (where.py reads its fed position)
        self.autopilot: AutopilotListener | None = None  # --autopilot: the autopilot's fix (where.py)
        self._where = WhereCache()

    def role(self, role: str) -> CommandSpec | None:
        """The command playing `role` on this model (None when it has none)."""
        return self.dialect.by_role(role, self.model)

    # -- lifecycle ---------------------------------------------------------------------------

    async def start(self) -> None:
        self._unsubscribe.append(self.cam.on_traffic(self._on_traffic))
        self._unsubscribe.append(self.cam.on_link_change(self._on_link_change))
        if not self.cam.link_state.get("up", True):
            self._on_link_change(False, str(self.cam.link_state.get("reason") or "the link is down"))
        await super().start()

    def loops(self) -> list[Coroutine[object, object, None]]:
        loops: list[Coroutine[object, object, None]] = [self._keepalive_loop()]
        if self.role("attitude") is not None:
            loops += [self._attitude_loop(), self._attitude_ticker()]
        if self.role("sd_capacity") is not None:
            loops.append(self._sd_loop())
        if self.role("version") is not None:
            loops.append(self._version_once())
        return loops

    # -- what comes from the client ----------------------------------------------------------

    def _on_traffic(self, direction: str, frame: Frame, message: Message | None = None) -> None:
        d = "in" if str(direction).lower().startswith(("in", "rx", "<")) else "out"
        ident = getattr(frame, "ident", None)
        # the page hides the console's own periodic queries (and the telemetry streams) by default
        self.record(d, frame, message, poll=self._is_poll(d, ident))

    def _is_poll(self, direction: str, ident: str | None) -> bool:
        """Whether a frame belongs to the console's own polls: sent or answered while a poll runs,
        or an answer a finished poll was still owed (protocol frames carry no request id: an answer
        is the poll's as long as the poll has unanswered frames out, within LATE_POLL_S)."""
        if ident is None:
            return False
        if ident in self._polls:
            self._poll_owed[ident] += 1 if direction == "out" else -1
            return True
        owed, until = self._late_polls.get(ident, (0, 0.0))
        if direction == "in" and owed > 0 and wall_time() < until:
            if owed > 1:
                self._late_polls[ident] = (owed - 1, until)
            else:
                del self._late_polls[ident]
            return True
        return False

    def _on_link_change(self, up: bool, reason: str) -> None:
        if up:
            if self.lost_since is not None:
                log.info("camera link back after %.1f s: %s", wall_time() - self.lost_since, reason)
            self.lost_since, self.link_reason = None, ""
        else:
            if self.lost_since is None:
                self.lost_since = wall_time()
            self.link_reason = reason
            log.warning("camera link lost: %s", reason)
        try:  # at once: a page must not show "up" for another push interval
            self.broadcast(self.status())
        except Exception:  # called from the client's notifier: never let a status oddity reach it
            log.exception("status after a link change failed")

    def link_status(self) -> dict[str, Any]:
        """The link as the page shows it: `up`, `waiting` (nothing heard yet) or `lost`."""
        state = self.cam.link_state
        up = bool(state.get("up", True))
        if not up and self.lost_since is None:  # down before we were told (closed at start)
            self.lost_since, self.link_reason = wall_time(), str(state.get("reason") or "")
        return {
            "link": "lost" if not up else ("waiting" if self.last_in is None else "up"),
            "link_reason": "" if up else (self.link_reason or str(state.get("reason") or "")),
            "lost_since": None if up else self.lost_since,
            "last_in": self.last_in,
            "silent_s": state.get("silent_s"),
        }

    def status(self) -> dict[str, Any]:
        self._sync_recording()
        return {
            **super().status(),
            **self.link_status(),
            "stats": jsonable(self.cam.stats),
            "state": jsonable(self.cam.state),
            "recording": self.recording,
            "recording_since": self.recording_since,
            "sd": self.sd,
            "version": self.version,
            "feeds": _feeds_summary(self.cam),
        }

    async def where(self) -> dict[str, Any]:
        return await self._where.get(self.cam, self.sim, self.autopilot)

    def hello(self) -> dict[str, Any]:
        return {**super().hello(), "attitude_hz": self.attitude_hz}

    def _sync_recording(self) -> None:
        """Recording as the client last heard it (REC answers, ours or another program's)."""
        stamped = self.cam.state.recording
        value = getattr(stamped, "value", None)
        if isinstance(value, bool) and value != self.recording:
            self.recording = value
            self.recording_since = wall_time() if value else None

    def _background_failure(self, exc: Exception, what: str, source: str) -> None:
        """Report a background job's failure once; a lost link is already shown as LOST."""
        if isinstance(exc, LinkLostError) or not self.cam.connected:
            return
        kind, msg = describe_error(exc, what)
        self.report_error(msg, kind=kind, source=source, once=source)

    # -- background work ---------------------------------------------------------------------

    async def _attitude_loop(self) -> None:
        """Read the client's attitude stream; on failure report once and retry."""
        while True:
            try:
                async for att in self.cam.attitude(self.attitude_hz):
                    self.attitude = {
                        "yaw": float(att.yaw_deg),
                        "pitch": float(att.pitch_deg),
                        "roll": float(att.roll_deg),
                        "t": float(att.wall or wall_time()),
                    }
                    if self.samples_are_heard:
                        self.last_in = wall_time()
                    self._attitude_seq += 1
                    self.clear_error("attitude")
            except asyncio.CancelledError:
                raise
            except Exception as exc:
                self._background_failure(exc, "the attitude stream", "attitude")
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

    @contextlib.contextmanager
    def _polling(self, ident: str) -> Iterator[None]:
        """Mark the frames of a periodic query (and its answer) as the console's own polls."""
        self._polls[ident] += 1
        try:
            yield
        finally:
            self._polls[ident] -= 1
            if self._polls[ident] <= 0:
                del self._polls[ident]
                owed = self._poll_owed.pop(ident, 0)
                if owed > 0:  # a timeout, or a retry whose first frame's answer is still coming
                    self._late_polls[ident] = (owed, wall_time() + LATE_POLL_S)

    async def refresh_sd(self, *, poll: bool = False) -> SdStatus | None:
        spec = self.role("sd_capacity")
        try:
            with self._polling(spec.ident) if poll and spec is not None else contextlib.nullcontext():
                self.sd = await op_sd(self.cam, {})
            self.clear_error("sd")
        except asyncio.CancelledError:
            raise
        except Exception as exc:
            self._background_failure(exc, "the SD card query", "sd")
        return self.sd

    async def _sd_loop(self) -> None:
        while True:
            await self.refresh_sd(poll=True)
            await asyncio.sleep(self.sd_interval_s)

    def _ping_ident(self) -> str | None:
        for role in PING_ROLES:
            spec = self.role(role)
            if spec is not None and spec.readable and not spec.request_form("r").fields:
                return spec.ident
        return None

    async def _keepalive_loop(self) -> None:
        """When nothing has come from the camera for `KEEPALIVE_IDLE_S` (no attitude stream on
        this model, the stream stopped, or the camera is gone), ask it something harmless: the
        client then expects an answer, and declares the link lost when none comes."""
        ident = self._ping_ident()
        if ident is None:
            return
        while True:
            await asyncio.sleep(KEEPALIVE_IDLE_S / 4)
            if self.last_in is not None and wall_time() - self.last_in < KEEPALIVE_IDLE_S:
                continue
            try:
                with self._polling(ident):
                    await self.cam.request(ident, read=True, timeout_s=KEEPALIVE_TIMEOUT_S, retries=KEEPALIVE_RETRIES)
                self.clear_error("link")
            except asyncio.CancelledError:
                raise
            except Exception as exc:
                self._background_failure(exc, f"the link check ({ident} query)", "link")

    async def _version_once(self) -> None:
        while self.version is None:
            try:
                self.version = await self.cam.version()
                self.clear_error("version")
            except asyncio.CancelledError:
                raise
            except Exception as exc:
                self._background_failure(exc, "the version query", "version")
                await asyncio.sleep(5.0)  # asked again: a camera that was off at start answers later

    # -- ops ---------------------------------------------------------------------------------

    async def carry_out(self, op: str, msg: OpArgs) -> object:
        async with self._motion if self._is_motion(op, msg) else contextlib.nullcontext():
            result = await OPS[op](self.cam, msg)
        self._after(op, msg, result)
        return result

    def _is_motion(self, op: str, msg: OpArgs) -> bool:
        if op in MOTION_OPS:
            return True
        ident = msg.get("id")
        if op != "request" or not isinstance(ident, str):
            return False
        spec = self.dialect.commands.get(ident)
        return bool(spec is not None and (spec.motion or spec.role == "gimbal_control"))

    def _after(self, op: str, msg: OpArgs, result: object) -> None:
        if op == "record":
            if msg.get("action") == "start":
                self.recording, self.recording_since = True, wall_time()
            else:
                self.recording, self.recording_since = False, None
        elif op == "recording" and isinstance(result, bool):
            if result and not self.recording:
                self.recording_since = wall_time()
            if not result:
                self.recording_since = None
            self.recording = result
        elif op == "sd" and isinstance(result, dict):
            self.sd = result  # op_sd's SdStatus


__all__ = ["MAX_OPS_IN_FLIGHT", "Hub"]


def _feeds_summary(cam: object) -> str:
    """What the client keeps sending the camera (client/feeds.py), for the page's "Fed" line."""
    feeds = getattr(cam, "feeds", None)
    summary = getattr(feeds, "summary", None)
    return str(summary()) if callable(summary) else "nothing"
