"""MAV_CMD_OBLIQUE_SURVEY (260) where the camera and the gimbal are one component (issue 42).

An autopilot with a separate camera and mount runs an oblique survey itself: distance triggers,
and between shots it rolls the mount. A camera that carries its own gimbal can do both, so the
bridge takes the command on the camera component: param1 the distance between photos (m; 0
stops), param2 the shutter integration time (ignored: the camera decides), param3 the minimum
interval between photos (ms), param4 the number of roll positions, param5 the roll limit (deg, each
side of centre), param6 the pitch held (deg). The roll positions are spread evenly over
[-limit, +limit] (-limit + k * 2 * limit / (positions - 1), as PX4's camera_trigger and ArduPilot
space them; one position: 0), one per photo, there and back (-20, 0, 20, 0, -20, ... for three
within 20 deg) so that the gimbal turns one step between photos, never from one limit to the other:
a C12 turns 12.7 deg/s at most, and 40 deg took longer than 20 m at 10 m/s.

The first photo is taken at once (the start of a transect has a photo, as QGroundControl's survey
asks of DO_SET_CAM_TRIGG_DIST with param3 1); then one each time the vehicle has gone the distance
(horizontally, from where the last photo was taken) and the minimum interval has passed. After a
shot the gimbal turns to the next roll position, so it is there for the next one; a shot waits up
to SETTLE_S for the camera to report that roll and the pitch (the first one FIRST_SETTLE_S: the
gimbal starts from wherever it was). Each photo is logged with the roll asked for and
the roll the camera reported at its shutter (`shots`); the camera writes its own attitude,
roll included, into the photo's XMP (video/exif.py)."""

from __future__ import annotations

import asyncio
import contextlib
import logging
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

from ..clock import monotonic
from ..geo.aim import Geodetic, offset_m
from ..links.mav import mav_id
from ..timeouts import within
from .camera_feed import SHUTTER_LATENCY_S
from .camera_photos import INT32_MAX
from .commands import Command, Outcome, denied

if TYPE_CHECKING:
    from ..autopilot.vehicle import Vehicles
    from .camera import CameraComponent
    from .commands import Dispatcher
    from .pointing import Pointer

log = logging.getLogger("topgimbal.mavlink")

CMD_OBLIQUE_SURVEY = mav_id("MAV_CMD_OBLIQUE_SURVEY")
CHECK_S = 0.05  # how often the distance travelled is looked at (0.5 m at 10 m/s)
SETTLE_S = 1.5  # the longest a shot waits for the gimbal to reach its roll position
FIRST_SETTLE_S = 6.0  # the first shot: from wherever the gimbal was (90 deg at 15 deg/s)
SETTLED_DEG = 1.0
MAX_POSITIONS = 32


@dataclass(frozen=True)
class Shot:
    image_index: int
    roll_asked_deg: float
    roll_deg: float | None  # what the camera reported at the shutter
    pitch_deg: float
    from_last_m: float | None  # horizontal distance from the previous photo


def roll_order(count: int) -> list[int]:
    """The roll positions' indices in the order taken, one cycle: there and back."""
    return list(range(count)) + list(range(count - 2, 0, -1))


def roll_positions(count: int, limit_deg: float) -> list[float]:
    """The roll angles of an oblique survey, left to right."""
    if count <= 1:
        return [0.0]
    step = 2.0 * limit_deg / (count - 1)
    return [-limit_deg + k * step for k in range(count)]


class ObliqueSurvey:
    def __init__(self, dispatcher: Dispatcher, camera: CameraComponent, pointer: Pointer, vehicles: Vehicles) -> None:
        self.camera, self.pointer, self.vehicles = camera, pointer, vehicles
        self.shots: list[Shot] = []
        self.distance_m = 0.0
        self._task: asyncio.Task[None] | None = None
        dispatcher.register(camera.comp, CMD_OBLIQUE_SURVEY, self._command)

    @property
    def running(self) -> bool:
        return self._task is not None and not self._task.done()

    async def _command(self, cmd: Command) -> Outcome:
        distance_m = cmd.p(1) if cmd.has(1) else 0.0
        if not 0.0 <= distance_m <= 10_000.0:
            raise denied(f"distance {distance_m:g} m: expected 0 (stop) .. 10000 m")
        await self.stop()
        if distance_m == 0.0:
            return Outcome()
        min_interval_s = (cmd.p(3) if cmd.has(3) else 0.0) / 1000.0
        count = cmd.whole(4, "roll positions", 0, MAX_POSITIONS, default=1)
        limit_deg = cmd.p(5) if cmd.has(5) else 0.0
        pitch_deg = cmd.p(6) if cmd.has(6) else -90.0
        profile = self.camera.cam.profile
        low, high = profile.model.roll_range_deg
        rolls_ok = profile.has_roll and low <= -abs(limit_deg) and abs(limit_deg) <= high
        if count > 1 and limit_deg != 0.0 and not rolls_ok:
            raise denied(f"roll +-{limit_deg:g} deg: this gimbal rolls {low:g}..{high:g} deg" if profile.has_roll
                         else "this gimbal has no roll axis")  # fmt: skip
        p_low, p_high = profile.model.pitch_range_deg
        if not p_low <= pitch_deg <= p_high:
            raise denied(f"pitch {pitch_deg:g} deg: this gimbal pitches {p_low:g}..{p_high:g} deg")
        if not 0.0 <= min_interval_s <= 60.0:
            raise denied(f"minimum interval {min_interval_s * 1000:g} ms: expected 0..60000 ms")
        spread = roll_positions(count, abs(limit_deg))
        rolls = [spread[i] for i in roll_order(len(spread))]
        self.distance_m = distance_m
        log.info("oblique survey: a photo every %g m (%g s apart at least), roll %s deg, pitch %g deg",
                 distance_m, min_interval_s, ", ".join(f"{r:g}" for r in rolls), pitch_deg)  # fmt: skip
        self._task = asyncio.ensure_future(self._run(distance_m, min_interval_s, rolls, pitch_deg))
        return Outcome()

    async def _run(self, distance_m: float, min_interval_s: float, rolls: list[float], pitch_deg: float) -> None:
        """Distance is measured shutter to shutter: from where the last photo was taken (its
        record's position) to where the vehicle will be at the next shutter (now plus the time the
        last photo took from request to shutter, carried forward at the vehicle's velocity)."""
        k = 0
        last: Geodetic | None = None  # where the last photo was taken
        last_t = -math.inf
        lag_s = 0.0  # request to shutter, of the last photo
        await self._aim(rolls[0], pitch_deg)
        await self._settle(rolls[0], pitch_deg, FIRST_SETTLE_S)  # the gimbal starts from anywhere
        while True:
            now = monotonic()
            ahead = self.vehicles.position_at(now)
            gone_m = None
            if ahead is not None and last is not None:
                north, east, _ = offset_m(last, ahead.position)
                v_north, v_east, _ = ahead.velocity_ned_m_s
                gone_m = math.hypot(north + v_north * lag_s, east + v_east * lag_s)  # at the next shutter
            due = last is None or (gone_m is not None and gone_m >= distance_m)
            if ahead is None or not due or now - last_t < min_interval_s:
                await asyncio.sleep(CHECK_S)
                continue
            roll = rolls[k % len(rolls)]
            await self._settle(roll, pitch_deg, SETTLE_S)  # at once when the gimbal is there already
            last_t = monotonic()
            try:
                msg = await self.camera.take_photo()
            except Exception as exc:  # a failed photo is logged and the survey goes on
                log.warning("oblique survey: photo at roll %g deg failed: %s", roll, exc)
                last = ahead.position
            else:
                lag_s = max(0.0, monotonic() - SHUTTER_LATENCY_S - last_t)
                known = msg.lat != INT32_MAX
                last = Geodetic(msg.lat / 1e7, msg.lon / 1e7, ahead.position.alt_m) if known else ahead.position
                att = self.camera.cam.attitude
                shot = Shot(msg.image_index, roll, None if att is None else att.roll_deg, pitch_deg, gone_m)
                self.shots.append(shot)
                log.info("oblique survey: image %d at roll %g deg (camera %s), pitch %g deg, %s from the last",
                         shot.image_index, roll, "?" if shot.roll_deg is None else f"{shot.roll_deg:.1f}",
                         pitch_deg, "-" if gone_m is None else f"{gone_m:.1f} m")  # fmt: skip
            k += 1
            await self._aim(rolls[k % len(rolls)], pitch_deg)  # there before the next shot

    async def _aim(self, roll_deg: float, pitch_deg: float) -> None:
        """Straight ahead, at `pitch_deg` and `roll_deg`. Through the camera link rather than the
        pointer: the pointer leaves a roll near 0 alone (no roll asked), the survey's centre
        position has to go back to 0."""
        self.pointer.cancel_stream()
        await self.camera.cam.call(lambda c: c.set_angles(0.0, pitch_deg, roll_deg))

    async def _settle(self, roll_deg: float, pitch_deg: float, longest_s: float) -> None:
        """Wait (`longest_s` at most) until the camera reports the roll and pitch asked for."""

        async def reached() -> None:
            while True:
                att = self.camera.cam.attitude
                if att is not None and max(abs(att.roll_deg - roll_deg), abs(att.pitch_deg - pitch_deg)) <= SETTLED_DEG:
                    return
                await asyncio.sleep(CHECK_S)

        with contextlib.suppress(asyncio.TimeoutError):
            await within(reached(), longest_s)

    async def stop(self) -> None:
        if self._task is not None:
            self._task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._task
            self._task = None
            log.info("oblique survey: stopped after %d photos", len(self.shots))

    async def close(self) -> None:
        await self.stop()


def survey_for(
    dispatcher: Dispatcher, cameras: list[CameraComponent], pointer: Pointer, vehicles: Vehicles
) -> ObliqueSurvey | None:
    """The visible camera's oblique survey; None without a camera that takes photos."""
    if not cameras or cameras[0].photo_values is None:
        return None
    return ObliqueSurvey(dispatcher, cameras[0], pointer, vehicles)
