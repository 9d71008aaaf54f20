"""What a ground station's camera screen asks beyond pointing and shooting: the image source
(MAV_CMD_SET_CAMERA_SOURCE), the thermal range (CAMERA_THERMAL_RANGE), video streaming on / off
(MAV_CMD_VIDEO_START/STOP_STREAMING) and the stream's real figures for VIDEO_STREAM_INFORMATION.
Every fact comes from the catalog, found by role and field name; every ack waits for the camera.

- Source: the picture-in-picture command (TOPOTEK PIP) has four layouts; primary RGB / IR and
  secondary none / the other lens name one of them (main = visible, sub = thermal). A model
  without one (SkyDroid) answers UNSUPPORTED: it has no source switch in its catalog.
- Thermal range: where the temperature command reports the hottest point (TOPOTEK TMP §12.1,
  §12.2), a spot query at the centre subscribes the bridge to the camera's reports; the message
  carries the last report (max, its position normalised by the thermal picture, min and its
  position where the report has them, else NaN). A report older than REPORT_STALE_S is not sent.
- Streaming: a video output switch (SkyDroid VOM `output`) is written; a camera without one streams
  whenever it is on: START is acked once the camera answered a query, STOP is UNSUPPORTED."""

from __future__ import annotations

import asyncio
import math
from typing import TYPE_CHECKING, Any

from ..clock import monotonic
from ..errors import RequestTimeoutError, TopGimbalError
from ..links.mav import mav_id, mavlink, msg_id
from ..outputs.rtp_out import stream_type
from .camera_link import CameraLink
from .commands import Command, Outcome, denied, unsupported
from .gimbal_device import _text

if TYPE_CHECKING:
    from ..links.mav import MAVLinkMessage
    from .node import Component

MSG_THERMAL_RANGE = msg_id("CAMERA_THERMAL_RANGE")
CMD_SET_SOURCE = mav_id("MAV_CMD_SET_CAMERA_SOURCE")
CMD_STREAM_START = mav_id("MAV_CMD_VIDEO_START_STREAMING")
CMD_STREAM_STOP = mav_id("MAV_CMD_VIDEO_STOP_STREAMING")
SOURCE_RGB, SOURCE_IR = 1, 2  # CAMERA_SOURCE
REPORT_STALE_S = 3.0
REPORT_WAIT_S = 2.5
NAN = float("nan")
VIDEO_ENCODING = {"h264": 1, "h265": 2}  # VIDEO_STREAM_ENCODING
# (primary, secondary) -> the catalog's picture-in-picture layout name
LAYOUTS = {(SOURCE_RGB, 0): "main_only", (SOURCE_RGB, SOURCE_IR): "main_sub",
           (SOURCE_IR, SOURCE_RGB): "sub_main", (SOURCE_IR, 0): "sub_only"}  # fmt: skip


def _fields(dialect: Any, ident: str, rw: str, direction: str) -> set[str]:
    spec = dialect.commands.get(ident)
    return {f.name for form in spec.forms_for(rw, direction) for f in form.fields} if spec else set()


class CameraExtras:
    def __init__(self, comp: Component, cam: CameraLink, lens: str) -> None:
        self.comp = comp
        self.cam = cam
        self.lens = lens
        p = cam.profile
        self.pip = p.ident("picture_in_picture") if p.can("picture_in_picture") else ""
        temp = p.ident("temperature") if p.can("temperature") else ""
        reported = _fields(p.dialect, temp, "w", "response") if temp else set()
        self.temperature = temp if lens == "thermal" and "hot_temp_c" in reported else ""
        self.output = ""
        if p.can("video_output") and "output" in _fields(p.dialect, p.ident("video_output"), "w", "request"):
            self.output = p.ident("video_output")
        self._subscribing: asyncio.Task[None] | None = None

    # -- what this lens offers ---------------------------------------------------------------------

    @property
    def has_thermal_range(self) -> bool:
        return bool(self.temperature)

    def register(self, services: Any) -> None:
        reg = services.dispatcher.register
        if self.pip:
            reg(self.comp, CMD_SET_SOURCE, self.set_source)
        if self.lens == "visible":
            reg(self.comp, CMD_STREAM_START, self.stream_start)
            if self.output:
                reg(self.comp, CMD_STREAM_STOP, self.stream_stop)
        if self.temperature:
            services.provide(MSG_THERMAL_RANGE, self.thermal_range)
            services.add_stream(MSG_THERMAL_RANGE, self.thermal_range_now, 0.0, 10.0)

    async def close(self) -> None:
        if self._subscribing is not None:
            self._subscribing.cancel()

    # -- source ------------------------------------------------------------------------------------

    async def set_source(self, cmd: Command) -> Outcome:
        primary = cmd.whole(2, "primary source: 1 RGB, 2 IR", 0, 3)
        secondary = cmd.whole(3, "secondary source: 0 none, 1 RGB, 2 IR", 0, 3, default=0)
        if primary == 0:
            primary = SOURCE_RGB  # CAMERA_SOURCE_DEFAULT: the visible picture alone
        layout = LAYOUTS.get((primary, secondary))
        if layout is None:
            raise denied(f"source {primary}/{secondary}: this camera shows 1 RGB / 2 IR, with the other or none")
        await self.cam.call(lambda c: c.request(self.pip, mode=layout))
        return Outcome()

    # -- streaming ---------------------------------------------------------------------------------

    async def stream_start(self, cmd: Command) -> Outcome:
        if self.output:
            await self._output("on")
        else:
            await self.cam.call(lambda c: c.version())  # the stream runs while the camera does
        return Outcome()

    async def stream_stop(self, cmd: Command) -> Outcome:
        if not self.output:
            raise unsupported("this camera's stream runs whenever it is on")
        await self._output("off")
        return Outcome()

    async def _output(self, value: str) -> None:
        ident = self.output
        current = await self.cam.call(lambda c: c.request(ident, read=True))
        values = {**(current.fields or {}), "output": value}
        await self.cam.call(lambda c: c.request(ident, **values))

    async def stream_figures(self) -> dict[str, float]:
        """What the camera says of its stream: fps, bitrate_kbps (where a query answers them)."""
        out: dict[str, float] = {}
        p = self.cam.profile
        for role in ("video_output", "bitrate"):
            if not p.can(role) or not p.dialect.require_role(role, p.model).readable:
                continue
            ident = p.ident(role)
            try:
                fields = (await self.cam.call(lambda c, i=ident: c.request(i, read=True))).fields or {}  # type: ignore[misc]
            except (TopGimbalError, OSError):
                continue
            for key in ("fps", "bitrate_kbps"):
                if isinstance(fields.get(key), (int, float)):
                    out.setdefault(key, float(fields[key]))
        return out

    def _stream_flags(self) -> int:
        return (1 if self.cam.answering else 0) | (2 if self.lens == "thermal" else 0)

    async def video_info(self, cmd: Command, urls: list[str]) -> list[Any]:
        """VIDEO_STREAM_INFORMATION: the profile's stream (field of view; picture size and codec
        where the profile documents them, else 0 = unknown) and what the camera says now of its
        frame rate and bitrate (visible stream; 0 = unknown)."""
        sid = cmd.whole(2, "stream id", 0, 255, default=0)
        if sid not in range(len(urls) + 1):
            raise denied(f"no stream {sid} (streams 1..{len(urls)})")
        lens = self.cam.profile.lens(self.lens)
        hfov = round(lens.hfov_deg) if lens is not None else 0
        w, h = lens.size if lens is not None and lens.size_documented else (0, 0)
        encoding = VIDEO_ENCODING.get(lens.codec, 0) if lens is not None and lens.codec_documented else 0
        figures = await self.stream_figures() if self.lens == "visible" else {}
        fps, kbps = figures.get("fps", 0.0), figures.get("bitrate_kbps", 0.0)
        return [mavlink().MAVLink_video_stream_information_message(
            i, len(urls), stream_type(url), self._stream_flags(), fps, w, h, int(kbps * 1000), 0, hfov,
            _text(f"{self.lens} {i}", 32), _text(url, 160), encoding, 0)
            for i, url in enumerate(urls, start=1) if sid in (0, i)]  # fmt: skip

    async def video_status(self, cmd: Command, urls: list[str]) -> list[Any]:
        sid = cmd.whole(2, "stream id", 0, 255, default=0)
        ids = [i for i in range(1, len(urls) + 1) if sid in (0, i)]
        if not ids:
            raise denied(f"no stream {sid} (streams 1..{len(urls)})")
        return [mavlink().MAVLink_video_stream_status_message(i, self._stream_flags(), 0.0, 0, 0, 0, 0, 0, 0)
                for i in ids]  # fmt: skip

    # -- thermal range -----------------------------------------------------------------------------

    def _report(self) -> dict[str, Any] | None:
        client = self.cam.client
        st = client.state.temperature if client is not None else None
        if st is None or monotonic() - st.t > REPORT_STALE_S or not isinstance(st.value, dict):
            return None
        return st.value if isinstance(st.value.get("hot_temp_c"), (int, float)) else None

    async def _subscribe(self) -> None:
        """A spot query at the picture's centre: the camera answers it and then reports the
        hottest point every second to whoever asked."""
        lens = self.cam.profile.lens("thermal")
        w, h = lens.size if lens is not None else (640, 512)
        ident = self.temperature
        await self.cam.call(lambda c: c.request(ident, read=True, x_px=w // 2, y_px=h // 2))

    def _message(self, rep: dict[str, Any]) -> MAVLinkMessage:
        lens = self.cam.profile.lens("thermal")
        w, h = lens.size if lens is not None else (0, 0)

        def norm(key: str, size: int) -> float:
            v = rep.get(key)
            return min(1.0, v / (size - 1)) if isinstance(v, (int, float)) and size > 1 else NAN

        cold = rep.get("cold_temp_c")
        return mavlink().MAVLink_camera_thermal_range_message(
            self.comp.node.time_boot_ms(), 0, self.comp.compid, float(rep["hot_temp_c"]),
            norm("hot_x_px", w), norm("hot_y_px", h), float(cold) if isinstance(cold, (int, float)) else NAN,
            norm("cold_x_px", w), norm("cold_y_px", h))  # fmt: skip

    async def thermal_range(self, cmd: Command) -> list[Any]:
        rep = self._report()
        if rep is None:
            await self._subscribe()
            end = monotonic() + REPORT_WAIT_S
            while (rep := self._report()) is None:
                if monotonic() > end:
                    raise RequestTimeoutError("the camera sent no temperature report")
                await asyncio.sleep(0.05)
        return [self._message(rep)]

    def thermal_range_now(self) -> MAVLinkMessage | None:
        """The streamed message: the last report; a stale one asks the camera again (once at a time)."""
        rep = self._report()
        if rep is None:
            if self.cam.answering and (self._subscribing is None or self._subscribing.done()):
                self._subscribing = asyncio.ensure_future(self._quiet(self._subscribe()))
            return None
        msg = self._message(rep)
        return msg if not math.isnan(msg.max) else None

    @staticmethod
    async def _quiet(work: Any) -> None:
        try:
            await work
        except (TopGimbalError, OSError):
            pass
