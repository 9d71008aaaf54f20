"""The console's per-camera routes, for one camera or several.

One camera: `/`, `/api/catalog`, `/api/status`, `/api/traffic.pcap`, `/ws` (server.py).

Several cameras (`add_camera_routes`): each camera's page and API under `/cam/<name>/` (the page's
relative URLs resolve there, so the same page serves any camera), the overview `GET /api/cameras`,
and the single-camera routes answered by the first camera. An unknown name is a 404 that lists the
valid ones. Video starts for a camera when its page first asks for it, for at most
`MAX_VIDEO_CAMERAS` cameras at once (the least recently viewed one stops first): each is a
simulator's renderer or a relay of the camera's RTSP streams. A camera reached through Zenoh has
no video here (its RTSP address is not served on Zenoh)."""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
import time
from collections import OrderedDict
from collections.abc import Awaitable, Callable
from pathlib import Path

from aiohttp import web

from ..client.jsonable import dumps
from ..clock import wall_time
from .cameras import MAX_CAMERAS, NAME_RULE, Camera, CameraSet
from .capture import pcap
from .catalog_api import catalog_json
from .pages import PageHub

log = logging.getLogger(__name__)

MAX_VIDEO_CAMERAS = 2  # cameras whose video runs at once (a renderer or relay each: CPU)
OVERVIEW_INTERVAL_S = 0.25  # how often the page asks /api/cameras (the grid's update rate: 4 Hz)

Resolve = Callable[[web.Request], PageHub]
Handler = Callable[[web.Request], Awaitable[web.StreamResponse]]


def _dumps(obj: object) -> str:
    return dumps(obj)  # the SDK's one encoding: NaN is null, never an invalid literal


def camera_handlers(resolve: Resolve, root: Path) -> dict[str, Handler]:
    """The page and the API of one camera, whichever hub `resolve` picks for a request."""

    async def index(request: web.Request) -> web.StreamResponse:
        return web.FileResponse(root / "index.html", headers={"Cache-Control": "no-store"})

    async def catalog(request: web.Request) -> web.Response:
        hub = resolve(request)
        return web.json_response(catalog_json(hub.dialect, hub.model))

    async def status(request: web.Request) -> web.Response:
        return web.json_response(resolve(request).status(), dumps=_dumps)

    async def where(request: web.Request) -> web.Response:
        return web.json_response(await resolve(request).where(), dumps=_dumps)

    async def ws(request: web.Request) -> web.StreamResponse:
        return await resolve(request).handle_ws(request)

    async def traffic_pcap(request: web.Request) -> web.Response:
        hub = resolve(request)
        from .remote_hub import UNAVAILABLE, RemoteHub

        if isinstance(hub, RemoteHub):  # a Zenoh camera: no frames cross this console, so no pcap (never an empty one)
            raise web.HTTPConflict(text=f"no pcap for this camera: {UNAVAILABLE['pcap']}")
        frames = hub.recorder.frames()  # taken here, written in a thread (a temporary file)
        data = await asyncio.to_thread(pcap, frames, hub.link)
        stamp = time.strftime("%Y%m%d-%H%M%S", time.localtime(wall_time()))  # the operator's local date
        return web.Response(
            body=data,
            content_type="application/vnd.tcpdump.pcap",
            headers={
                "Content-Disposition": f'attachment; filename="topgimbal-{hub.model.name}-{stamp}.pcap"',
                "Cache-Control": "no-store",
                "X-Topgimbal-Frames": str(len(frames)),
            },
        )

    return {"index": index, "catalog": catalog, "status": status, "ws": ws, "pcap": traffic_pcap, "where": where}


def _unknown(name: str, cameras: CameraSet) -> web.HTTPNotFound:
    names = cameras.names()
    listed = ", ".join(names) if names else "none yet"
    body = {
        "error": "unknown camera",
        "camera": name[:80],
        "cameras": names,
        "message": f"no camera named {name[:80]!r} on this console; its cameras: {listed} (names: {NAME_RULE})",
    }
    return web.HTTPNotFound(text=json.dumps(body), content_type="application/json")


def _no_camera_yet() -> web.HTTPServiceUnavailable:
    body = {"error": "no camera", "message": "no camera yet: the console is waiting for cameras served on Zenoh"}
    return web.HTTPServiceUnavailable(text=json.dumps(body), content_type="application/json")


class CameraVideos:
    """Video per camera, started on demand, at most MAX_VIDEO_CAMERAS at once (LRU)."""

    def __init__(self, cameras: CameraSet, limit: int = MAX_VIDEO_CAMERAS) -> None:
        self.cameras = cameras
        self.limit = limit
        self.running: OrderedDict[str, Camera] = OrderedDict()
        self._lock = asyncio.Lock()
        self._failed: dict[str, str] = {}  # camera -> why it has no video (said once)

    async def for_camera(self, cam: Camera) -> object | None:
        """The camera's ConsoleVideo (started if needed), or None when it has none."""
        if cam.source == "zenoh" or cam.name in self._failed:
            return None
        async with self._lock:
            if cam.video is not None and self.running.get(cam.name) is cam:
                self.running.move_to_end(cam.name)
                return cam.video
            from ..video.webconsole import ConsoleVideo

            while len(self.running) >= self.limit:
                _, old = self.running.popitem(last=False)
                if old.video is not None:
                    log.info("video of camera %s stopped: video runs for at most %d cameras at once", old.name,
                             self.limit)  # fmt: skip
                    video, old.video = old.video, None
                    with contextlib.suppress(Exception):
                        await video.close()
            try:
                import av  # noqa: F401
                import numpy  # noqa: F401
                import PIL  # noqa: F401

                cam.video = await ConsoleVideo(cam).start()
            except Exception as exc:
                self._failed[cam.name] = str(exc)
                log.warning("camera %s has no video: %s", cam.name, exc)
                return None
            self.running[cam.name] = cam
            return cam.video

    async def close(self) -> None:
        for cam in list(self.running.values()):
            if cam.video is not None:
                video, cam.video = cam.video, None
                with contextlib.suppress(Exception):
                    await video.close()
        self.running.clear()


def add_camera_routes(app: web.Application, cameras: CameraSet, videos: CameraVideos, root: Path) -> None:
    def by_name(request: web.Request) -> Camera:
        name = request.match_info.get("name", "")
        cam = cameras.get(name)
        if cam is None:
            raise _unknown(name, cameras)
        return cam

    def first(request: web.Request) -> Camera:
        cam = cameras.first
        if cam is None:
            raise _no_camera_yet()
        return cam

    named = camera_handlers(lambda r: by_name(r).hub, root)
    legacy = camera_handlers(lambda r: first(r).hub, root)

    async def overview(request: web.Request) -> web.Response:
        body = {
            "several": True,
            "cameras": cameras.overview(),
            "max_cameras": cameras.max_cameras,
            "interval_s": OVERVIEW_INTERVAL_S,
            "now": wall_time(),
        }
        return web.json_response(body, dumps=_dumps)

    async def page(request: web.Request) -> web.StreamResponse:
        by_name(request)
        return await named["index"](request)

    async def bare(request: web.Request) -> web.StreamResponse:
        cam = by_name(request)
        raise web.HTTPFound(f"/cam/{cam.name}/" + (f"?{request.query_string}" if request.query_string else ""))

    async def static(request: web.Request) -> web.StreamResponse:
        by_name(request)
        base = root.resolve()
        path = (base / request.match_info["path"]).resolve()
        if base not in path.parents or not path.is_file():
            raise web.HTTPNotFound()
        return web.FileResponse(path)

    def video(action: str, picked: Callable[[web.Request], Camera]) -> Handler:
        async def handler(request: web.Request) -> web.StreamResponse:
            cam = picked(request)
            console_video = await videos.for_camera(cam)
            if console_video is None:
                return web.Response(status=204)  # the page shows no video panel
            method: Handler = getattr(console_video, action)
            return await method(request)

        return handler

    r = app.router
    r.add_get("/api/cameras", overview)
    r.add_get("/cam/{name}", bare)
    r.add_get("/cam/{name}/", page)
    r.add_get("/cam/{name}/static/{path:.+}", static)
    r.add_get("/cam/{name}/api/catalog", named["catalog"])
    r.add_get("/cam/{name}/api/status", named["status"])
    r.add_get("/cam/{name}/api/traffic.pcap", named["pcap"])
    r.add_get("/cam/{name}/api/where", named["where"])
    r.add_get("/cam/{name}/ws", named["ws"])
    r.add_get("/", legacy["index"])
    r.add_get("/api/catalog", legacy["catalog"])
    r.add_get("/api/status", legacy["status"])
    r.add_get("/api/traffic.pcap", legacy["pcap"])
    r.add_get("/api/where", legacy["where"])
    r.add_get("/ws", legacy["ws"])
    for prefix, picked in (("/cam/{name}", by_name), ("", first)):
        r.add_get(f"{prefix}/api/video", video("info", picked))
        r.add_get(prefix + "/video/{lens}.mjpg", video("mjpeg", picked))
        r.add_get(prefix + "/video/{lens}/whep", video("whep_ready", picked))
        r.add_post(prefix + "/video/{lens}/whep", video("whep_offer", picked))
        r.add_delete(prefix + "/video/{lens}/whep/{session}", video("whep_delete", picked))
        for action in ("point", "track", "zoom"):
            r.add_post(f"{prefix}/api/video/{action}", video(action, picked))


__all__ = ["MAX_CAMERAS", "MAX_VIDEO_CAMERAS", "OVERVIEW_INTERVAL_S", "CameraVideos", "add_camera_routes",
           "camera_handlers"]  # fmt: skip
