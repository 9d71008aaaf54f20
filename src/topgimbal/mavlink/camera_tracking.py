"""Object tracking for MAVLink (CAMERA_TRACK_POINT / _RECTANGLE / _STOP_TRACKING and
CAMERA_TRACKING_IMAGE_STATUS / _GEO_STATUS): the model's own tracking requests, acked once the
camera confirmed, and a status that says what the camera says.

The status is honest (docs/mavlink.md, "Object tracking"):
- IDLE before tracking starts and after a stop;
- ACTIVE while the camera tracks, with the target's place in the picture: the companion loop's
  measurement in the video where it runs (no box while it searches), the camera's own box where
  the model reports one (none of today's profiles does), else estimated: the camera's tracker
  pulls the target to the centre and keeps it there, so the box the user gave moves towards the
  centre by the angle the gimbal has turned, never further out than a pull-in that halves within
  PULL_IN_TAU_S * ln 2 (a target moving away from where it was picked is followed, not left
  behind: the gimbal's turn counts a moving target's own motion, issue 41.4), and stays centred;
- ERROR when the camera says it lost the target: on a model with a tracking state query (TOPOTEK
  `TRC`), polled every POLL_S while tracking, a state that fell back from "tracking" to "waiting"
  or "stopped" without a stop from us, "lens cannot track", or no "tracking" within START_GRACE_S.
  SkyDroid cameras have no such query: their status stays ACTIVE until a stop (docs/errata.md E41).
CAMERA_TRACKING_GEO_STATUS gives where the estimated line of sight meets flat ground
(geo/aim.py) when the vehicle's position and heading are known; it is sent only then.
Both are streamed at the interval a ground station sets (SET_MESSAGE_INTERVAL; off by default).
"""

from __future__ import annotations

import asyncio
import contextlib
import functools
import logging
import math
from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Any

from ..clock import MonotonicFn, monotonic
from ..geo.aim import ground_point
from ..geo.earth import wrap180
from ..links.mav import mavlink
from ..protocol.picture_tracking import tracking_requests
from ..protocol.streams import VideoError
from .camera_link import CameraLink
from .commands import Command, Outcome, denied, rejected, unsupported

if TYPE_CHECKING:
    from ..autopilot.vehicle import Vehicles
    from ..client import AsyncClient
    from ..geo import Fix as GeoFix
    from ..protocol import Message
    from ..track import CompanionTracker

log = logging.getLogger("topgimbal.mavlink")

POLL_S = 0.2  # how often a camera with a tracking state query is asked while tracking
START_GRACE_S = 1.0  # a camera that does not say "tracking" within this after the request failed
COMPANION_START_S = 5.0  # the companion loop must find the target in a picture within this to ack
MAX_STATUS_HZ = 20.0
# The camera's tracker pulls a target to the centre about this fast (the simulated SIP and C12 in
# 0.25 to 0.33 s; undocumented for the real ones: docs/errata.md E41). The estimated box is never
# further from the centre than the picked offset times exp(-t / PULL_IN_TAU_S).
PULL_IN_TAU_S = 0.3
NAN = float("nan")
INT32_MAX = 2**31 - 1
# MAVLink's CAMERA_TRACKING_STATUS_FLAGS / _MODE / _TARGET_DATA
IDLE, ACTIVE, ERROR = 0, 1, 2
MODE_NONE, MODE_POINT, MODE_RECTANGLE = 0, 1, 2
DATA_NONE, DATA_IN_STATUS = 0, 4
FovFn = Callable[[], tuple[float, float]]
LocateFn = Callable[[float, float], "GeoFix | None"]  # picture (x, y), -1..1 from the centre


class Tracker:
    def __init__(
        self,
        cam: CameraLink,
        *,
        fov: FovFn | None = None,
        vehicles: Vehicles | None = None,
        clock: MonotonicFn = monotonic,
        companion_url: str | None = None,
        locate: LocateFn | None = None,
    ) -> None:
        self.cam = cam
        # Where a picture point lands (CameraView.locate: the --terrain DEM, else flat ground at
        # home); None: the flat-ground estimate below.
        self.locate = locate
        self.profile = cam.profile
        self.fov = fov
        self.vehicles = vehicles
        self.clock = clock
        self.state: tuple[int, tuple[float, ...]] = (0, ())  # (1 point | 2 rectangle | 0 none, its values)
        self.camera_state: str | None = None  # the camera's last tracking state (a model that says it)
        self.lost = False
        self._seen_tracking = False
        self._started_at = 0.0
        self._start_attitude: tuple[float, float] | None = None  # gimbal (yaw, pitch) when tracking started
        self._poll: asyncio.Task[None] | None = None
        spec = self.profile.dialect.by_role("tracking", self.profile.model)
        self.reads_state = spec is not None and any(f.rw == "r" and f.fields for f in spec.forms)
        # The companion loop (topgimbal.track) on this RTSP stream, for a model without a tracker
        # of its own (bridge --companion-tracking); None: the camera's tracker or nothing.
        own = self.profile.track_point or self.profile.track_rectangle
        self.companion_url = companion_url if not own else None
        self.companion: CompanionTracker | None = None
        self._companion_task: asyncio.Task[Any] | None = None
        self._picture_size: tuple[int, int] | None = None

    # -- commands ----------------------------------------------------------------------------------

    async def point(self, cmd: Command) -> Outcome:
        x, y = cmd.p(1), cmd.p(2)
        radius = cmd.p(3)
        if not (0 <= x <= 1 and 0 <= y <= 1):
            raise denied(f"point ({x:g}, {y:g}): expected 0..1 each")
        # the spec's radius is 0..1 of the image width (0: one pixel); NaN, inf, 1e30 are no radius
        if not 0 <= radius <= 1:
            raise denied(f"point radius {radius:g}: expected 0..1 of the image width")
        if self.companion_url is not None:
            r = max(0.02, min(0.25, radius))
            await self._start_companion(max(0.0, x - r), max(0.0, y - r), min(1.0, x + r), min(1.0, y + r))
            self._started(1, (x, y, radius))
            return Outcome()
        await self._track(x, y)
        self._started(1, (x, y, radius))
        return Outcome()

    async def rect(self, cmd: Command) -> Outcome:
        x0, y0, x1, y1 = cmd.p(1), cmd.p(2), cmd.p(3), cmd.p(4)
        if not all(0 <= v <= 1 for v in (x0, y0, x1, y1)) or x1 <= x0 or y1 <= y0:
            raise denied("rectangle: expected 0 <= top-left < bottom-right <= 1")
        if self.companion_url is not None:
            await self._start_companion(x0, y0, x1, y1)
            self._started(2, (x0, y0, x1, y1))
            return Outcome()
        await self._track(x0, y0, x1, y1)
        self._started(2, (x0, y0, x1, y1))
        return Outcome()

    async def _track(self, x0: float, y0: float, x1: float | None = None, y1: float | None = None) -> None:
        """The model's tracking request for this point or box (one helper for the console and
        the bridge: `video.lens.tracking_requests`)."""
        try:
            requests = tracking_requests(self.profile.dialect, self.profile.model, x0, y0, x1, y1)
        except VideoError as exc:
            raise unsupported(str(exc)) from None
        for ident, values in requests:
            await self.cam.call(functools.partial(_request, ident=ident, values=values))

    def _started(self, mode: int, values: tuple[float, ...]) -> None:
        self.state = (mode, values)
        self.lost, self._seen_tracking, self.camera_state = False, False, None
        self._started_at = self.clock()
        att = self.cam.attitude
        self._start_attitude = None if att is None else (att.yaw_deg, att.pitch_deg)
        if self.reads_state and self._poll is None:
            self._poll = asyncio.ensure_future(self._poll_loop())

    async def _start_companion(self, x0: float, y0: float, x1: float, y1: float) -> None:
        """Run the companion loop on the box; acked once it found the target in a picture."""
        from ..track import CompanionTracker, TrackConfig, TrackerError, rtsp_frames

        await self._stop_companion()
        client = self.cam.client
        if client is None or self.companion_url is None:
            raise rejected("the camera is not connected")
        try:
            tracker = CompanionTracker(client, TrackConfig(box=(x0, y0, x1 - x0, y1 - y0)))
        except TrackerError as exc:
            raise denied(str(exc)) from None

        def seen(pic: Any, box: Any) -> None:
            self._picture_size = (int(pic.image.shape[1]), int(pic.image.shape[0]))

        tracker.on_picture = seen
        self.companion = tracker
        self._companion_task = asyncio.ensure_future(tracker.run(rtsp_frames(self.companion_url)))
        end = self.clock() + COMPANION_START_S
        while tracker.state == "starting" and not self._companion_task.done() and self.clock() < end:
            await asyncio.sleep(0.05)
        if tracker.state != "tracking":
            why = "the video could not be read" if self._companion_task.done() else "no target in the box"
            await self._stop_companion()
            raise rejected(f"companion tracking did not start: {why}")
        log.info("tracking: the companion loop follows the box on %s", self.companion_url)

    async def _stop_companion(self) -> None:
        task, self._companion_task = self._companion_task, None
        self.companion = None
        if task is not None:
            task.cancel()
            with contextlib.suppress(asyncio.CancelledError, Exception):
                await task  # its end stops the gimbal

    async def stop(self, cmd: Command) -> Outcome:
        if self.companion_url is not None:
            await self._stop_companion()
            self.state = (0, ())
            return Outcome()
        p = self.profile
        role = "tracking_confirm" if p.can("tracking_confirm") else "tracking" if p.can("tracking") else None
        if role is not None:
            await self.cam.call(functools.partial(_request, ident=p.ident(role), values={"action": "stop"}))
        else:
            raise unsupported(f"the {self.profile.model.name} cannot stop tracking")
        self.state = (0, ())
        self.lost = False
        await self.close()
        return Outcome()

    async def close(self) -> None:
        await self._stop_companion()
        task, self._poll = self._poll, None
        if task is not None:
            task.cancel()
            with contextlib.suppress(asyncio.CancelledError, Exception):
                await task

    # -- the camera's state --------------------------------------------------------------------------

    async def _poll_loop(self) -> None:
        ident = self.profile.ident("tracking")
        while self.state[0]:
            try:
                m = await self.cam.call(functools.partial(_read, ident=ident))
                self.observe(str((m.fields or {}).get("state")))
            except Exception as exc:  # a lost link: the status keeps what the camera said last
                log.debug("tracking state query failed: %s", exc)
            await asyncio.sleep(POLL_S)

    def observe(self, camera_state: str) -> None:
        """What the camera answered to its tracking state query."""
        self.camera_state = camera_state
        if not self.state[0] or self.lost:
            return
        if camera_state == "tracking":
            self._seen_tracking = True
        elif camera_state == "lens_cannot_track" or self._seen_tracking:
            self.lost = True
            log.info("tracking: the camera lost the target (its state: %s)", camera_state)
        elif self.clock() - self._started_at > START_GRACE_S:
            self.lost = True
            log.info("tracking: the camera did not start tracking (its state: %s)", camera_state)

    # -- status ----------------------------------------------------------------------------------------

    def offset_frac(self) -> tuple[float, float] | None:
        """How far (picture fractions) the gimbal has turned towards the box since tracking started:
        None without attitude or field of view."""
        att, start = self.cam.attitude, self._start_attitude
        if att is None or start is None or self.fov is None:
            return None
        hfov, vfov = self.fov()
        if not (math.isfinite(hfov) and math.isfinite(vfov)) or hfov <= 0 or vfov <= 0:
            return None
        dyaw = wrap180(att.yaw_deg - start[0])
        dpitch = att.pitch_deg - start[1]
        tx, ty = math.tan(math.radians(hfov) / 2), math.tan(math.radians(vfov) / 2)
        return math.tan(math.radians(dyaw)) / (2 * tx), -math.tan(math.radians(dpitch)) / (2 * ty)

    def estimated_centre(self) -> tuple[float, float] | None:
        """The target's centre in the picture now (fractions): the companion loop's own
        measurement where it runs, else estimated from the gimbal."""
        mode, v = self.state
        if not mode:
            return None
        comp, size = self.companion, self._picture_size
        if comp is not None and size is not None and comp.vision.centre is not None:
            return comp.vision.centre[0] / size[0], comp.vision.centre[1] / size[1]
        cx, cy = (v[0], v[1]) if mode == 1 else ((v[0] + v[2]) / 2, (v[1] + v[3]) / 2)
        turned = self.offset_frac() or (0.0, 0.0)
        pull = math.exp(-max(0.0, self.clock() - self._started_at) / PULL_IN_TAU_S)
        return _towards_centre(cx, turned[0], pull), _towards_centre(cy, turned[1], pull)

    def status_message(self) -> Any:
        mode, v = self.state
        ml = mavlink()
        if not mode:
            return ml.MAVLink_camera_tracking_image_status_message(IDLE, MODE_NONE, DATA_NONE, *(NAN,) * 7)
        if self.companion is not None and self.companion.state == "lost":
            self.lost = True
        if self.lost:
            return ml.MAVLink_camera_tracking_image_status_message(ERROR, mode, DATA_NONE, *(NAN,) * 7)
        if self.companion is not None and self.companion.state != "tracking":
            # searching: the loop does not see the target now, so no box where none may be
            return ml.MAVLink_camera_tracking_image_status_message(ACTIVE, mode, DATA_NONE, *(NAN,) * 7)
        c = self.estimated_centre()
        assert c is not None
        if mode == 1:
            pt, rect = (c[0], c[1], v[2]), (NAN,) * 4
        else:
            hw, hh = (v[2] - v[0]) / 2, (v[3] - v[1]) / 2
            pt, rect = (NAN,) * 3, (c[0] - hw, c[1] - hh, c[0] + hw, c[1] + hh)
        return ml.MAVLink_camera_tracking_image_status_message(ACTIVE, mode, DATA_IN_STATUS, *pt, *rect)

    async def status(self, cmd: Command) -> list[Any]:
        return [self.status_message()]

    def target_bearing(self) -> tuple[float, float] | None:
        """Earth-frame (bearing, pitch) of the estimated target, when the heading is known."""
        att, c = self.cam.attitude, self.estimated_centre()
        vyaw = self.vehicles.yaw_deg if self.vehicles is not None else None
        if att is None or c is None or vyaw is None or self.fov is None:
            return None
        hfov, vfov = self.fov()
        tx, ty = math.tan(math.radians(hfov) / 2), math.tan(math.radians(vfov) / 2)
        dx = math.degrees(math.atan((c[0] - 0.5) * 2 * tx))
        dy = math.degrees(math.atan((0.5 - c[1]) * 2 * ty))
        return att.yaw_deg + vyaw + dx, att.pitch_deg + dy

    def geo_message(self) -> Any | None:
        """CAMERA_TRACKING_GEO_STATUS where the target's position is known, else None: the
        estimated box centre located on the --terrain DEM (with its 1-sigma horizontal error), or
        on flat ground at home altitude."""
        mode = self.state[0]
        if not mode or self.lost:
            return None if not mode else _geo(ERROR)
        fix = self.vehicles.fix() if self.vehicles is not None else None
        if fix is None:
            return None
        centre = self.estimated_centre()
        if self.locate is not None and centre is not None:
            hit = self.locate(2 * centre[0] - 1, 2 * centre[1] - 1)
            if hit is None:
                return None
            return mavlink().MAVLink_camera_tracking_geo_status_message(
                ACTIVE, int(hit.lat_deg * 1e7), int(hit.lon_deg * 1e7), hit.alt_m,
                hit.error_m, NAN, NAN, NAN, NAN, NAN, hit.range_m, NAN, NAN)  # fmt: skip
        look = self.target_bearing()
        if look is None:
            return None
        ground = ground_point(fix.position, look[0], look[1], fix.home_alt_m)
        if ground is None:
            return None
        north = (ground.lat_deg - fix.position.lat_deg) * 111_195.0
        east = (ground.lon_deg - fix.position.lon_deg) * 111_195.0 * math.cos(math.radians(fix.position.lat_deg))
        dist = math.sqrt(north * north + east * east + (fix.position.alt_m - ground.alt_m) ** 2)
        return mavlink().MAVLink_camera_tracking_geo_status_message(
            ACTIVE, int(ground.lat_deg * 1e7), int(ground.lon_deg * 1e7), ground.alt_m,
            NAN, NAN, NAN, NAN, NAN, NAN, dist, NAN, NAN)  # fmt: skip

    async def geo_status(self, cmd: Command) -> list[Any]:
        m = self.geo_message()
        if m is None:
            raise unsupported("the target's position is not known (no tracking, no vehicle position or heading)")
        return [m]


def _geo(status: int) -> Any:
    return mavlink().MAVLink_camera_tracking_geo_status_message(
        status, INT32_MAX, INT32_MAX, NAN, NAN, NAN, NAN, NAN, NAN, NAN, NAN, NAN, NAN
    )


def _towards_centre(c: float, turned: float, pull: float = 1.0) -> float:
    """A picture coordinate moved towards the centre (0.5) by what the gimbal turned, never past it
    (once the camera's tracker centred the target, it keeps it there), and never further out than
    `pull` (1 at the start, falling to 0) times where it was picked: a gimbal turning away from the
    picked side follows a target moving that way, it does not leave it behind."""
    off = c - 0.5
    left = off - turned
    if off * left <= 0:
        return 0.5
    return 0.5 + math.copysign(min(abs(left), abs(off) * pull), off)


async def _request(client: AsyncClient, *, ident: str, values: Mapping[str, object]) -> Message:
    return await client.send_request(client.build_from(ident, values))


async def _read(client: AsyncClient, *, ident: str) -> Message:
    return await client.send_request(client.build_from(ident, {}, read=True))
