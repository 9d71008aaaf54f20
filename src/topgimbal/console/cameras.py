"""The cameras of a console with several cameras (`topgimbal console --camera ... --sim ... --zenoh ...`).

Each camera has a name (the fleet's rules: 1..63 letters, digits, `_`, `-`, `.`; the same check
as `topgimbal zenoh`'s names), its own `Hub` (its pages, pushes, ops) and, on demand, its own
video. `CameraSet` holds them in order (the first one also answers the single-camera routes) and
bounds their number: `MAX_CAMERAS`. Cameras given on the command line are opened here: a
simulator in this process (`sim1`, `sim2`, ... on ephemeral loopback ports) or a camera URL;
cameras served on Zenoh come and go through `zenoh_cameras.py`."""

from __future__ import annotations

import asyncio
import contextlib
import logging
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from ..client.remote_keys import check_name
from ..clock import wall_time
from ..errors import FieldValueError
from .hub import Hub

if TYPE_CHECKING:
    from ..sim import Simulator
    from ..video.webconsole import ConsoleVideo

log = logging.getLogger(__name__)

MAX_CAMERAS = 64  # per console: each is a client, an attitude stream and its pages' pushes
NAME_RULE = "1..63 letters, digits, '_', '-' or '.', starting with a letter or digit"


class TooManyCamerasError(ValueError):
    """More cameras than a console holds (MAX_CAMERAS)."""


class CameraNameError(ValueError):
    """A camera name that breaks the naming rule, or one given twice."""


def check_camera_name(name: str) -> str:
    try:
        return check_name(name)
    except FieldValueError:
        raise CameraNameError(f"camera name {name!r}: {NAME_RULE}") from None


@dataclass
class Camera:
    """One camera of the console; also the `VideoHost` its video reads (video/webconsole.py)."""

    name: str
    hub: Hub
    source: str  # "sim", "url" or "zenoh"
    url: str
    cam: Any  # a client.CameraAPI (AsyncClient, or SharedRemote for Zenoh)
    sim: Simulator | None = None
    video_urls: dict[str, str] = field(default_factory=dict)
    video_port: int | None = None
    video: ConsoleVideo | None = None
    added: float = field(default_factory=wall_time)
    first_read: asyncio.Task[None] | None = None

    @property
    def model(self) -> str:
        return self.hub.model.name

    @property
    def served(self) -> bool:
        return bool(getattr(self.cam, "served", True))

    def summary(self) -> dict[str, Any]:
        """The camera's line in the overview grid (`GET /api/cameras`)."""
        hub = self.hub
        hub._sync_recording()
        link = hub.link_status()
        return {
            "name": self.name,
            "model": self.model,
            "source": self.source,
            "url": self.url,
            "served": self.served,
            "link": link["link"],
            "link_reason": link["link_reason"],
            "attitude": hub.attitude,
            "has_attitude": hub.role("attitude") is not None,
            "recording": hub.recording,
            "pages": len(hub.peers),
            "unavailable": _unavailable(hub),
        }

    def start_first_reads(self) -> None:
        """Ask once whether the camera records, so the grid shows it before any page has asked
        (the hub learns it from every later answer too). A failure is the page's to show."""

        async def read() -> None:
            with contextlib.suppress(Exception):
                await self.hub.carry_out("recording", {})

        if self.hub.role("recording") is not None:
            self.first_read = asyncio.create_task(read())

    async def close(self) -> None:
        if self.first_read is not None:
            self.first_read.cancel()
            with contextlib.suppress(asyncio.CancelledError, Exception):
                await self.first_read
        if self.video is not None:
            with contextlib.suppress(Exception):
                await self.video.close()
            self.video = None
        await self.hub.stop()
        with contextlib.suppress(Exception):
            await self.cam.close()
        if self.sim is not None:
            with contextlib.suppress(Exception):
                await self.sim.stop()
            self.sim = None


def _unavailable(hub: Hub) -> dict[str, str]:
    from .remote_hub import UNAVAILABLE, RemoteHub

    return dict(UNAVAILABLE) if isinstance(hub, RemoteHub) else {}


class CameraSet:
    """The console's cameras by name, in the order they came; at most `max_cameras`."""

    def __init__(self, max_cameras: int = MAX_CAMERAS) -> None:
        self.max_cameras = max_cameras
        self._cams: dict[str, Camera] = {}

    def __len__(self) -> int:
        return len(self._cams)

    def __iter__(self) -> Iterator[Camera]:
        return iter(list(self._cams.values()))

    def names(self) -> list[str]:
        return list(self._cams)

    def get(self, name: str) -> Camera | None:
        return self._cams.get(name)

    @property
    def first(self) -> Camera | None:
        return next(iter(self._cams.values()), None)

    def check_room(self, name: str) -> None:
        check_camera_name(name)
        if name in self._cams:
            raise CameraNameError(f"camera name {name!r} is given twice: each camera needs its own name")
        if len(self._cams) >= self.max_cameras:
            raise TooManyCamerasError(
                f"camera {name!r}: a console shows at most {self.max_cameras} cameras ({len(self._cams)} already)"
            )

    def add(self, camera: Camera) -> Camera:
        self.check_room(camera.name)
        self._cams[camera.name] = camera
        return camera

    def remove(self, name: str) -> Camera | None:
        return self._cams.pop(name, None)

    def overview(self) -> list[dict[str, Any]]:
        out = []
        for cam in self:
            try:
                out.append(cam.summary())
            except Exception as exc:  # one odd camera must not hide the others
                log.exception("overview of %s failed", cam.name)
                out.append({"name": cam.name, "model": cam.model, "source": cam.source, "link": "lost",
                            "link_reason": f"console error: {exc}"})  # fmt: skip
        return out

    async def close(self) -> None:
        for name in list(self._cams):
            cam = self._cams.pop(name)
            await cam.close()


def local_plan(
    cameras: Sequence[tuple[str, str, str]], sims: Sequence[str], max_cameras: int = MAX_CAMERAS
) -> list[tuple[str, str | None, str]]:
    """(name, url or None for a simulator, model) for every camera given on the command line,
    checked before anything starts: names, duplicates, the bound."""
    plan: list[tuple[str, str | None, str]] = [(n, u, m) for n, u, m in cameras]
    taken = {n for n, _, _ in plan}
    i = 0
    for model in sims:
        i += 1
        while f"sim{i}" in taken:
            i += 1
        plan.append((f"sim{i}", None, model))
        taken.add(f"sim{i}")
    if len(plan) > max_cameras:
        raise TooManyCamerasError(f"{len(plan)} cameras given: a console shows at most {max_cameras}")
    seen: set[str] = set()
    for name, _, _ in plan:
        check_camera_name(name)
        if name in seen:
            raise CameraNameError(f"camera name {name!r} is given twice: each camera needs its own name")
        seen.add(name)
    return plan


async def open_local(
    name: str,
    url: str | None,
    model: str,
    *,
    attitude_hz: float,
    timeout_s: float,
    retries: int,
    link_timeout_s: float,
    sim_seed: int = 0,
) -> Camera:
    """A camera given on the command line: its simulator (url None) or its URL, its client, its hub."""
    from .. import client as client_mod

    sim = None
    if url is None:
        from ..sim import Simulator

        sim = Simulator(model=model, seed=sim_seed)
        await sim.start(udp=[("127.0.0.1", 0)])
        url = sim.url
    try:
        cam = await client_mod.connect(
            url, model=model, timeout_s=timeout_s, retries=retries, link_timeout_s=link_timeout_s
        )
    except BaseException:
        if sim is not None:
            await sim.stop()
        raise
    hub = Hub(cam, url=url, attitude_hz=attitude_hz)
    hub.sim = sim
    return Camera(name, hub, "sim" if sim is not None else "url", url, cam, sim=sim)


__all__ = [
    "MAX_CAMERAS",
    "Camera",
    "CameraNameError",
    "CameraSet",
    "TooManyCamerasError",
    "check_camera_name",
    "local_plan",
    "open_local",
]
