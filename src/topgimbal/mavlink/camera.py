"""Camera protocol v2: the camera (and its thermal lens, as a second camera) as MAVLink camera
components.

Every answer that describes the camera's state asks the camera first (storage, recording);
every command is acked only once the camera confirmed it. Photo and video bookkeeping that the
camera does not keep (image count, capture interval, mode) is the bridge's own and says so in
docs/mavlink.md."""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from ..autopilot.vehicle import Vehicles
from ..camdef.definition import definition_version, settings_for
from ..camdef.pacing import FetchPacer
from ..clock import monotonic
from ..links.mav import mav_id, mavlink, msg_id
from ..timeouts import stop_tasks
from .camera_extras import CameraExtras
from .camera_link import CameraLink
from .camera_photos import CameraPhotos
from .camera_tracking import MAX_STATUS_HZ as MAX_TRACKING_HZ
from .camera_tracking import Tracker
from .camera_view import CameraView
from .commands import Command, Outcome, denied, rejected, unsupported
from .gimbal_device import _text, firmware_code, flag_bits
from .params_ext import ParamsExt
from .services import Services

if TYPE_CHECKING:
    from ..links.mav import MAVLinkMessage

log = logging.getLogger("topgimbal.mavlink")

MAX_PACED_INFO = 8  # CAMERA_INFORMATION answers waiting for the definition pacer, per camera
MSG_DISTANCE_SENSOR = msg_id("DISTANCE_SENSOR")
MSG_INFO = msg_id("CAMERA_INFORMATION")
MSG_SETTINGS = msg_id("CAMERA_SETTINGS")
MSG_STORAGE = msg_id("STORAGE_INFORMATION")
MSG_CAPTURE_STATUS = msg_id("CAMERA_CAPTURE_STATUS")
MSG_IMAGE_CAPTURED = msg_id("CAMERA_IMAGE_CAPTURED")
MSG_VIDEO_INFO = msg_id("VIDEO_STREAM_INFORMATION")
MSG_VIDEO_STATUS = msg_id("VIDEO_STREAM_STATUS")
MSG_FOV = msg_id("CAMERA_FOV_STATUS")
MSG_TRACKING = msg_id("CAMERA_TRACKING_IMAGE_STATUS")
MSG_TRACKING_GEO = msg_id("CAMERA_TRACKING_GEO_STATUS")
CMD_IMAGE_START = mav_id("MAV_CMD_IMAGE_START_CAPTURE")
CMD_IMAGE_STOP = mav_id("MAV_CMD_IMAGE_STOP_CAPTURE")
CMD_VIDEO_START = mav_id("MAV_CMD_VIDEO_START_CAPTURE")
CMD_VIDEO_STOP = mav_id("MAV_CMD_VIDEO_STOP_CAPTURE")
CMD_SET_MODE = mav_id("MAV_CMD_SET_CAMERA_MODE")
CMD_ZOOM = mav_id("MAV_CMD_SET_CAMERA_ZOOM")
CMD_FOCUS = mav_id("MAV_CMD_SET_CAMERA_FOCUS")
CMD_TRACK_POINT = mav_id("MAV_CMD_CAMERA_TRACK_POINT")
CMD_TRACK_RECT = mav_id("MAV_CMD_CAMERA_TRACK_RECTANGLE")
CMD_TRACK_STOP = mav_id("MAV_CMD_CAMERA_STOP_TRACKING")


class CameraComponent(CameraPhotos):
    def __init__(
        self,
        services: Services,
        cam: CameraLink,
        vehicles: Vehicles,
        *,
        lens: str = "visible",
        gimbal_device_id: int = 0,
        video_urls: list[str] | None = None,
        identity: dict[str, Any] | None = None,
        range_hz: float = 0.0,
        media_url: str | None = None,
        companion_tracking: bool = False,
    ) -> None:
        self.services = services
        self.comp = services.comp
        self.cam = cam
        self.profile = cam.profile
        self.vehicles = vehicles
        self.lens = lens
        self.gimbal_device_id = gimbal_device_id
        self.video_urls = list(video_urls or [])
        self.identity = identity if identity is not None else {}
        self.range_hz = range_hz if lens == "visible" and self.profile.rangefinder else 0.0
        self.media_url = media_url  # the camera's files over HTTP (sim --media-port): CAMERA_IMAGE_CAPTURED.file_url
        self.mode_id = 0  # CAMERA_MODE_IMAGE; the camera has no modes: the bridge's own bookkeeping
        self.init_photos()  # camera_photos.py: counts, records, the interval capture, the feed's hooks
        self.recording: bool | None = None
        self.record_started = 0.0
        self.zoom_pct: float = float("nan")
        self.available_mib: float = float("nan")
        self._range_task: asyncio.Task[None] | None = None
        self.view = CameraView(self.comp, cam, vehicles, lens=lens, range_hz=self.range_hz)
        companion = self.video_urls[0] if companion_tracking and lens == "visible" and self.video_urls else None
        self.tracker = Tracker(
            cam, fov=self.view.fov_deg, vehicles=vehicles, companion_url=companion, locate=self.view.locate
        )
        p = self.profile
        self.definition_uri = ""  # set by the bridge once its definition server listens
        # the URI for a request from (link, peer): the address that reaches that peer (advertise.py)
        self.definition_uri_for: Callable[[Any], str] | None = None
        # set with an HTTP definition server unless --definition-all-at-once (camdef/pacing.py):
        # a CAMERA_INFORMATION naming an HTTP URI then follows its ack when no download runs
        self.definition_pacer: FetchPacer | None = None
        self._info_tasks: set[asyncio.Task[None]] = set()  # CAMERA_INFORMATION waiting for the pacer
        self.params = ParamsExt(self.comp, cam, settings_for(p.dialect, p.model, lens))
        self.extras = CameraExtras(self.comp, cam, lens)
        self.extras.register(services)
        provide = services.provide
        provide(MSG_INFO, self._information)
        provide(MSG_SETTINGS, self._settings)
        provide(MSG_STORAGE, self._storage)
        provide(MSG_CAPTURE_STATUS, self._capture_status)
        provide(MSG_IMAGE_CAPTURED, self._image_captured)
        provide(MSG_FOV, self.view.fov_status)
        services.add_stream(MSG_FOV, self.view.fov_message, 0.0, 10.0)  # on SET_MESSAGE_INTERVAL only
        if self.video_urls:
            provide(MSG_VIDEO_INFO, lambda cmd: self.extras.video_info(cmd, self.video_urls))
            provide(MSG_VIDEO_STATUS, lambda cmd: self.extras.video_status(cmd, self.video_urls))
        if self.tracks_point or self.tracks_rect:
            # Tracking status on request, and streamed at the interval a ground station sets
            # (QGC: 2 Hz after a track command, -1 after a stop); off until then.
            provide(MSG_TRACKING, self.tracker.status)
            provide(MSG_TRACKING_GEO, self.tracker.geo_status)
            services.add_stream(MSG_TRACKING, self.tracker.status_message, 0.0, MAX_TRACKING_HZ)
            services.add_stream(MSG_TRACKING_GEO, self.tracker.geo_message, 0.0, MAX_TRACKING_HZ)
        if self.range_hz or (lens == "visible" and p.rangefinder):
            provide(MSG_DISTANCE_SENSOR, self.view.distance_now)
        d = services.dispatcher
        reg = d.register
        reg(self.comp, CMD_SET_MODE, self._set_mode)
        if self.photo_values is not None:
            reg(self.comp, CMD_IMAGE_START, self._image_start)
            reg(self.comp, CMD_IMAGE_STOP, self._image_stop)
        if self.can_record:
            reg(self.comp, CMD_VIDEO_START, self._video_start)
            reg(self.comp, CMD_VIDEO_STOP, self._video_stop)
        if self.zoom_any:
            reg(self.comp, CMD_ZOOM, self._zoom)
        if lens == "visible" and p.can_focus:
            reg(self.comp, CMD_FOCUS, self._focus)
        if self.tracks_point:
            reg(self.comp, CMD_TRACK_POINT, self.tracker.point)
        if self.tracks_rect:
            reg(self.comp, CMD_TRACK_RECT, self.tracker.rect)
        if self.tracks_point or self.tracks_rect:
            reg(self.comp, CMD_TRACK_STOP, self.tracker.stop)

    # -- what this lens can do (from the catalog) ------------------------------------------------

    @property
    def photo_values(self) -> dict[str, Any] | None:
        p = self.profile
        if not p.can_photo:
            return None
        if self.lens == "thermal":
            mode = p.thermal_photo_mode()
            return {"mode": mode} if mode else None
        return {"mode": "visible"} if "visible" in p.photo_modes and p.thermal else {}

    @property
    def can_record(self) -> bool:
        return self.lens == "visible" and self.profile.can_record

    @property
    def zoom_any(self) -> bool:
        p = self.profile
        if self.lens == "thermal":
            return p.can("digital_zoom") and p.digital_zoom_has_lens
        return p.zoom_continuous or p.zoom_absolute

    @property
    def tracks_point(self) -> bool:
        own = self.profile.track_point
        return self.lens == "visible" and (own or self.tracker.companion_url is not None)

    @property
    def tracks_rect(self) -> bool:
        own = self.profile.track_rectangle
        return self.lens == "visible" and (own or self.tracker.companion_url is not None)

    def cap_flags(self) -> int:
        """CAMERA_CAP_FLAGS: video (also in image mode) 1|16, images (also in video mode) 2|8, zoom
        64, focus 128, video stream 256, point / rectangle tracking 512 / 1024."""
        visible = self.lens == "visible"
        record, photo = self.can_record, self.photo_values is not None
        return flag_bits({1 | 16: record, 2 | 8: photo, 64: self.zoom_any, 128: visible and self.profile.can_focus,
                          256: bool(self.video_urls), 512: self.tracks_point, 1024: self.tracks_rect,
                          4096: self.extras.has_thermal_range})  # fmt: skip

    # -- lifecycle ------------------------------------------------------------------------------

    def start(self) -> None:
        if self.range_hz > 0:
            self._range_task = asyncio.ensure_future(self.view.range_loop())

    async def close(self) -> None:
        await self.tracker.close()
        await self.params.close()
        await self.extras.close()
        tasks = [self._interval_task, self._range_task, *self._info_tasks]
        await stop_tasks([t for t in tasks if t is not None], "camera")

    # -- information ----------------------------------------------------------------------------

    async def _information(self, cmd: Command) -> list[Any]:
        m = self.profile.model
        name = self.identity.get("model_name") or m.name
        if self.lens == "thermal":
            name = f"{name} thermal"
        lens = self.profile.lens(self.lens)
        # Focal length and sensor size are in no profile; the resolution only where the profile
        # gives the stream's picture size (0 = unknown, as MAVLink says).
        w, h = lens.size if lens is not None and lens.size_documented else (0, 0)
        uri = self.definition_uri_for(cmd.peer) if self.definition_uri_for is not None else self.definition_uri
        version = definition_version(self.profile.dialect, m, self.lens) if uri else 0
        msg = mavlink().MAVLink_camera_information_message(
            self.comp.node.time_boot_ms(), list(_text(self.profile.vendor, 32).ljust(32, b"\0")),
            list(_text(name, 32).ljust(32, b"\0")), firmware_code(self.identity.get("version")),
            0.0, 0.0, 0.0, w, h, 0 if self.lens == "visible" else 1, self.cap_flags(), version,
            _text(uri, 140), self.gimbal_device_id, 0)  # fmt: skip
        pacer = self.definition_pacer
        if pacer is None or not uri.startswith(("http://", "https://")):
            return [msg]
        # after the ack, once no definition download runs (pacing.py); each request its own answer,
        # and at most MAX_PACED_INFO waiting (more: TEMPORARILY_REJECTED, the requester asks again)
        if len(self._info_tasks) >= MAX_PACED_INFO:
            raise rejected(f"{MAX_PACED_INFO} CAMERA_INFORMATION answers already wait for a definition download")
        task = asyncio.ensure_future(self._paced(pacer, uri.rsplit("/", 1)[-1], msg))
        self._info_tasks.add(task)
        task.add_done_callback(self._info_tasks.discard)
        return []

    async def _paced(self, pacer: FetchPacer, name: str, msg: MAVLinkMessage) -> None:
        await pacer.turn(name)
        self.comp.send(msg)

    async def _settings(self, cmd: Command) -> list[Any]:
        return [self._settings_message()]

    def _settings_message(self) -> MAVLinkMessage:
        return mavlink().MAVLink_camera_settings_message(
            self.comp.node.time_boot_ms(), self.mode_id, self.zoom_pct, float("nan")
        )

    async def _storage(self, cmd: Command) -> list[Any]:
        if not self.profile.has_sd:
            msg = mavlink().MAVLink_storage_information_message(
                self.comp.node.time_boot_ms(), 0, 0, 3, 0.0, 0.0, 0.0, float("nan"), float("nan"), 0)  # fmt: skip
            return [msg]
        sd = await self.cam.call(lambda c: c.sd_card())
        if not sd.present or not sd.total_mb:
            status, total, free = 0, 0.0, 0.0  # STORAGE_STATUS_EMPTY: no card
        else:
            status, total, free = 2, float(sd.total_mb), float(sd.remaining_mb or 0)
        self.available_mib = free
        return [mavlink().MAVLink_storage_information_message(
            self.comp.node.time_boot_ms(), 1, 1, status, total, total - free, free,
            float("nan"), float("nan"), 2)]  # fmt: skip

    async def _capture_status(self, cmd: Command) -> list[Any]:
        if self.can_record and self.profile.dialect.require_role("recording", self.profile.model).readable:
            rec = await self.cam.call(lambda c: c.recording())
            self._recording_now(rec)
        if self.profile.has_sd:  # available_capacity: what the card says now
            sd = await self.cam.call(lambda c: c.sd_card())
            self.available_mib = float(sd.remaining_mb or 0) if sd.present else 0.0
        return [self._capture_status_message()]

    def _capture_status_message(self) -> MAVLinkMessage:
        rec_ms = int((monotonic() - self.record_started) * 1000) if self.recording else 0
        return mavlink().MAVLink_camera_capture_status_message(
            self.comp.node.time_boot_ms(), self.image_status, 1 if self.recording else 0, self.interval_s,
            rec_ms, self.available_mib, self.image_count, 0)  # fmt: skip

    def _recording_now(self, rec: bool) -> None:
        if rec and not self.recording:
            self.record_started = monotonic()
        self.recording = rec

    async def _set_mode(self, cmd: Command) -> Outcome:
        mode = cmd.whole(2, "camera mode: 0 image, 1 video", 0, 1)
        self.mode_id = mode
        return Outcome(after=[self._settings_message()])

    # -- video -----------------------------------------------------------------------------------

    async def _video_start(self, cmd: Command) -> Outcome:
        await self.cam.call(lambda c: c.start_recording())
        self._recording_now(True)
        return Outcome(after=[self._capture_status_message()])

    async def _video_stop(self, cmd: Command) -> Outcome:
        await self.cam.call(lambda c: c.stop_recording())
        self._recording_now(False)
        return Outcome(after=[self._capture_status_message()])

    # -- zoom and focus --------------------------------------------------------------------------

    async def _zoom(self, cmd: Command) -> Outcome:
        kind, value = cmd.whole(1, "zoom type", 0, 255), cmd.p(2)
        if kind in (0, 1):
            value = cmd.finite(2, "zoom step or direction")
        p = self.profile
        if self.lens == "thermal":
            if kind == 0:
                await self.cam.call(lambda c: c.digital_zoom("in" if value > 0 else "out", lens="thermal"))
                return Outcome()
            if kind == 2:
                level = self._level(value, p.model.digital_zoom_max)
                await self.cam.call(lambda c: c.digital_zoom(level, lens="thermal"))
                self.zoom_pct = value
                return Outcome()
            raise unsupported(f"zoom type {kind} on the thermal lens (supported: 0 step, 2 range)")
        if kind == 1:  # continuous: -1 out, 0 stop, 1 in
            if not p.zoom_continuous:
                raise unsupported(f"the {p.model.name} has no continuous zoom")
            action = "in" if value > 0 else "out" if value < 0 else "stop"
            await self.cam.call(lambda c: c.zoom(action))
            return Outcome()
        if kind == 2:
            if not p.zoom_absolute:
                raise unsupported(f"the {p.model.name} cannot be set to a zoom level")
            if not 0 <= value <= 100:
                raise denied(f"zoom range {value:g} %: expected 0..100")
            level = self._level(value, p.zoom_max_x)
            await self.cam.call(lambda c: c.zoom(level))
            self.zoom_pct = value
            return Outcome(after=[self._settings_message()])
        if kind == 0:
            if not p.can("digital_zoom"):
                raise unsupported(f"the {p.model.name} has no zoom steps")
            await self.cam.call(lambda c: c.digital_zoom("in" if value > 0 else "out"))
            return Outcome()
        raise unsupported(f"zoom type {kind} (supported: 0 step, 1 continuous, 2 range)")

    def _level(self, pct: float, top: float) -> float:
        if not 0 <= pct <= 100:
            raise denied(f"zoom range {pct:g} %: expected 0..100")
        level = 1.0 + (top - 1.0) * pct / 100.0
        if not self.profile.can("optical_zoom") and not self.profile.digital_zoom_has_lens:
            level = float(round(level))  # whole steps only (SkyDroid DZM 1x..4x)
        return round(level, 1)

    async def _focus(self, cmd: Command) -> Outcome:
        kind = cmd.whole(1, "focus type", 0, 255)
        value = cmd.finite(2, "focus direction") if kind == 1 else 0.0
        acts = self.profile.focus_actions
        if kind == 1:
            action = "plus" if value > 0 else "minus" if value < 0 else "stop"
        elif kind in (4, 5, 6) and "auto" in acts:
            action = "auto"
        else:
            raise unsupported(f"focus type {kind} (supported: 1 continuous, 4/5/6 auto)")
        await self.cam.call(lambda c: c.focus(action))
        return Outcome()
