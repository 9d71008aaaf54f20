"""The camera component's photos (camera protocol v2): IMAGE_START_CAPTURE one at a time (a
capture sequence number seen again within the retransmission window answers with the photo it
took) or at an interval until IMAGE_STOP_CAPTURE, CAMERA_IMAGE_CAPTURED with the vehicle's position
and the autopilot's UTC at the shutter, and the last MAX_REMEMBERED_IMAGES records for a ground
station that asks again. A part of `CameraComponent` (camera.py), kept apart for its size: the
state it reads and writes is declared below and set by `init_photos`."""

from __future__ import annotations

import asyncio
import contextlib
import logging
from collections import OrderedDict
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from ..clock import monotonic, wall_time
from ..links.mav import mavlink
from ..timeouts import stop_tasks, within
from .camera_feed import SHUTTER_LATENCY_S, file_url
from .commands import RETRANSMIT_WINDOW_S, Command, Outcome, denied
from .gimbal_device import _text

if TYPE_CHECKING:
    from ..autopilot.vehicle import Vehicles
    from ..links.mav import MAVLinkMessage
    from .camera_link import CameraLink
    from .camera_view import CameraView
    from .node import Component

log = logging.getLogger("topgimbal.mavlink")

# IMAGE_STOP_CAPTURE during an interval photo: how long the photo asked of the camera is waited for
# (its own request timeout is shorter) before the capture is cancelled anyway
STOP_PHOTO_WAIT_S = 10.0
INT32_MAX = 2**31 - 1
MAX_REMEMBERED_IMAGES = 64
MAX_INTERVAL_S = 3600.0


class CameraPhotos:
    # what the camera component has (camera.py)
    comp: Component
    cam: CameraLink
    vehicles: Vehicles
    view: CameraView
    lens: str
    media_url: str | None

    @property
    def photo_values(self) -> dict[str, Any] | None:
        raise NotImplementedError  # CameraComponent's: what a photo of this lens asks of the camera

    def init_photos(self) -> None:
        self.image_count = 0
        self.images: OrderedDict[int, Any] = OrderedDict()
        self.interval_s = 0.0
        self.image_status = 0
        self._interval_task: asyncio.Task[None] | None = None
        self._interval_stop = asyncio.Event()  # set: the interval loop ends after its photo in flight
        # (sender system, component) -> (capture sequence number, when taken, image index)
        self._last_sequence: dict[tuple[int, int], tuple[int, float, int]] = {}
        self.utc_at: Callable[[float], float | None] | None = None  # the autopilot's UTC (camera_feed.py)
        self.before_photo: Callable[[], None] | None = None  # camera_feed.CameraFeed.before_photo
        self.after_photo: Callable[[float], None] | None = None  # camera_feed.CameraFeed.photo_taken

    async def _image_captured(self, cmd: Command) -> list[Any]:
        index = cmd.whole(2, "image index", -1, INT32_MAX, default=-1)
        if index < 0 and self.images:
            index = next(reversed(self.images))
        msg = self.images.get(index)
        if msg is None:
            raise denied(f"no image {index} taken through this bridge (it knows {len(self.images)})")
        return [msg]

    def forget_sequences(self, sysid: int) -> None:
        """A peer rebooted (autopilot/reboots.py): its capture sequence starts again at 1."""
        for key in [k for k in self._last_sequence if k[0] == sysid]:
            del self._last_sequence[key]
        log.info("system %d rebooted: its next capture sequence numbers are new photos", sysid)

    async def _take_photo(self) -> MAVLinkMessage:
        values = self.photo_values or {}
        if self.before_photo is not None:
            self.before_photo()  # the camera's own tag: a position fresh for the shutter
        sent = monotonic()
        answer = await self.cam.call(lambda c: c.photo(**values))
        # the shutter: just before the camera's answer (it answers once the photo is taken). Not
        # the request's time: that waits behind the position frames and the model's command gap.
        shutter = max(sent, monotonic() - SHUTTER_LATENCY_S)
        if self.after_photo is not None:
            self.after_photo(shutter)
        return self._record_image(
            True, file_url(self.media_url, self.cam.model_name, self.lens, answer.fields), shutter
        )

    async def take_photo(self) -> MAVLinkMessage:
        """One photo now, its CAMERA_IMAGE_CAPTURED sent (the oblique survey, survey.py)."""
        msg = await self._take_photo()
        self.comp.send(msg)
        return msg

    def _record_image(self, ok: bool, url: str = "", shutter: float | None = None) -> MAVLinkMessage:
        """CAMERA_IMAGE_CAPTURED for a photo taken at `shutter` (this clock): the vehicle's position
        then (interpolated between fixes, not the last one heard), the autopilot's UTC then (its
        SYSTEM_TIME) else ours. No fix: lat, lon and alt INT32_MAX (unknown, as CAMERA_FOV_STATUS
        says it), never 0, 0."""
        index = self.image_count
        self.image_count += 1
        t = monotonic() if shutter is None else shutter
        fix = self.vehicles.position_at(t)
        lat = lon = alt = INT32_MAX
        rel = 0
        if fix is not None:
            lat, lon = round(fix.position.lat_deg * 1e7), round(fix.position.lon_deg * 1e7)
            alt, rel = round(fix.position.alt_m * 1000), round(fix.relative_alt_m * 1000)
        else:
            log.warning("image %d: no position from the autopilot (GLOBAL_POSITION_INT) at the shutter: "
                        "CAMERA_IMAGE_CAPTURED says unknown (INT32_MAX)", index)  # fmt: skip
        utc = self.utc_at(t) if self.utc_at is not None else None
        if utc is None:
            utc = wall_time() - (monotonic() - t)
        msg = mavlink().MAVLink_camera_image_captured_message(
            self.comp.node.time_boot_ms(), int(utc * 1e6), 0, lat, lon, alt, rel,
            list(self.view.earth_quaternion()), index, 1 if ok else 0, _text(url, 205))  # fmt: skip
        self.images[index] = msg
        while len(self.images) > MAX_REMEMBERED_IMAGES:
            self.images.popitem(last=False)
        return msg

    async def _image_start(self, cmd: Command) -> Outcome:
        interval = cmd.p(2) if cmd.has(2) else 0.0
        total = cmd.whole(3, "total images, 0 = until stopped", 0, INT32_MAX, default=1)
        if not 0 <= interval <= MAX_INTERVAL_S:
            raise denied(f"interval {interval:g} s: expected 0..{MAX_INTERVAL_S:g} s")
        if total != 1 and interval <= 0:
            raise denied("several images need an interval (param2 > 0)")
        if total == 1:
            seq_key = (cmd.src_system, cmd.src_component)
            seq = cmd.whole(4, "capture sequence number", 0, INT32_MAX, default=0)
            last = self._last_sequence.get(seq_key)
            if seq and last is not None and last[0] == seq:
                age_s = monotonic() - last[1]
                if age_s <= RETRANSMIT_WINDOW_S:
                    # the same capture sequence number within the retransmission window: that
                    # photo was taken; say so and answer with it rather than take another
                    log.info("photo request from %d/%d with capture sequence %d again after %.1f s: a "
                             "retransmission, image %d answers it (no new photo)", *seq_key, seq, age_s, last[2])  # fmt: skip
                    earlier = self.images.get(last[2])
                    return Outcome(after=[earlier] if earlier is not None else [])
                log.info("photo request from %d/%d with capture sequence %d, as %.0f s ago: a new photo (a "
                         "sender that rebooted counts from 1 again)", *seq_key, seq, age_s)  # fmt: skip
            await self._stop_interval()
            self.image_status = 1
            try:
                msg = await self._take_photo()
            finally:
                self.image_status = 0
            if seq:
                self._last_sequence[seq_key] = (seq, monotonic(), msg.image_index)
                if len(self._last_sequence) > 64:
                    self._last_sequence.pop(next(iter(self._last_sequence)))
            return Outcome(after=[msg])
        await self._stop_interval()
        first = await self._take_photo()  # acked once the camera confirmed the first image
        self.interval_s = interval
        self.image_status = 2
        self._interval_task = asyncio.ensure_future(self._interval_loop(interval, total - 1 if total else -1))
        return Outcome(after=[first])

    async def _interval_loop(self, interval: float, remaining: int) -> None:
        stop = self._interval_stop
        try:
            while remaining != 0:  # -1: until MAV_CMD_IMAGE_STOP_CAPTURE
                with contextlib.suppress(asyncio.TimeoutError):
                    await within(stop.wait(), interval)
                if stop.is_set():
                    break
                self.image_status = 3
                try:
                    msg = await self._take_photo()
                except Exception as exc:
                    log.warning("interval photo failed: %s", exc)
                    msg = self._record_image(False)
                self.image_status = 2
                self.comp.send(msg)
                remaining -= 1
        finally:
            self.image_status = 0
            self.interval_s = 0.0

    async def _stop_interval(self) -> None:
        """End an interval capture. A photo already asked of the camera is waited for (bounded), so
        it is counted and announced with CAMERA_IMAGE_CAPTURED like the others: cancelled in flight,
        the camera took it and the bridge never said so (image_count one short, a geotag missing)."""
        task, self._interval_task = self._interval_task, None
        if task is not None:
            self._interval_stop.set()
            with contextlib.suppress(asyncio.TimeoutError, Exception):
                await within(asyncio.shield(task), STOP_PHOTO_WAIT_S)
            await stop_tasks([task], "interval capture")
            self._interval_stop = asyncio.Event()
        self.image_status = 0
        self.interval_s = 0.0

    async def _image_stop(self, cmd: Command) -> Outcome:
        await self._stop_interval()
        return Outcome()
