"""Object tracking for MAVLink (CAMERA_TRACK_POINT / _RECTANGLE / _STOP_TRACKING and
CAMERA_TRACKING_IMAGE_STATUS): the model's own tracking requests, acked once the camera confirmed."""

from __future__ import annotations

import functools
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

from ..video.lens import VideoError, tracking_requests
from ._mav import mavlink
from .camera_link import CameraLink
from .commands import Command, Outcome, denied, unsupported

if TYPE_CHECKING:
    from ..client import AsyncClient
    from ..protocol import Message


class Tracker:
    def __init__(self, cam: CameraLink) -> None:
        self.cam = cam
        self.profile = cam.profile
        self.state: tuple[int, tuple[float, ...]] = (0, ())  # (1 point | 2 rectangle | 0 none, its values)

    async def point(self, cmd: Command) -> Outcome:
        x, y = cmd.p(1), cmd.p(2)
        radius = cmd.p(3) if cmd.has(3) else 0.05
        if not (0 <= x <= 1 and 0 <= y <= 1):
            raise denied(f"point ({x:g}, {y:g}): expected 0..1 each")
        await self._track(x, y)
        self.state = (1, (x, y, radius))
        return Outcome()

    async def rect(self, cmd: Command) -> Outcome:
        x0, y0, x1, y1 = cmd.p(1), cmd.p(2), cmd.p(3), cmd.p(4)
        if not all(0 <= v <= 1 for v in (x0, y0, x1, y1)) or x1 <= x0 or y1 <= y0:
            raise denied("rectangle: expected 0 <= top-left < bottom-right <= 1")
        await self._track(x0, y0, x1, y1)
        self.state = (2, (x0, y0, x1, y1))
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

    async def stop(self, cmd: Command) -> Outcome:
        p = self.profile
        role = "tracking_confirm" if p.can("tracking_confirm") else "tracking" if p.can("tracking") else None
        if role is not None:
            await self.cam.call(functools.partial(_request, ident=p.ident(role), values={"action": "stop"}))
        else:
            raise unsupported(f"the {self.profile.model.name} cannot stop tracking")
        self.state = (0, ())
        return Outcome()

    async def status(self, cmd: Command) -> list[Any]:
        mode, v = self.state
        nan = float("nan")
        pt = (v[0], v[1], v[2]) if mode == 1 else (nan, nan, nan)
        rect = tuple(v) if mode == 2 else (nan, nan, nan, nan)
        return [mavlink().MAVLink_camera_tracking_image_status_message(
            1 if mode else 0, mode, 1 if mode == 1 else 2 if mode == 2 else 0, *pt, *rect, 0)]  # fmt: skip


async def _request(client: AsyncClient, *, ident: str, values: Mapping[str, object]) -> Message:
    return await client.send_request(client.build_from(ident, values))
