"""The console's aiohttp application and a server object that owns the camera link.

`ConsoleServer(sim_model="C12")` (or `url="udp://...", model="SIP"`): `await server.start()` starts
the simulator (if any), the client and the HTTP server; `server.page_url` is the URL to open;
`await server.stop()` undoes it all.
"""

from __future__ import annotations

import asyncio
import contextlib
import importlib.resources
import logging
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from aiohttp import web
from aiohttp.http_exceptions import HttpProcessingError

from ..client.jsonable import dumps
from ..client.zenoh_session import check_endpoint
from ..logtext import untrusted
from ..video.webconsole import ConsoleVideo
from ..video.webconsole import attach as attach_video
from .auth import needs_token, resolve_token, token_middleware
from .cameras import CameraSet, local_plan, open_local
from .guard import HostGuard, default_allowed_hosts
from .hub import Hub
from .pages import PageHub
from .routes import CameraVideos, add_camera_routes, camera_handlers
from .zenoh_cameras import ZenohCameras

if TYPE_CHECKING:
    from ..client import AsyncClient
    from ..sim import FaultPlan, Simulator
    from ..wire.proxy import Proxy

log = logging.getLogger(__name__)

DEFAULT_HOST = "127.0.0.1"
DEFAULT_PORT = 8080
VIDEO_SCHEMES = ("rtsp", "rtsps", "http", "https")  # what --video-url accepts (the relay opens them with FFmpeg)
LINK_TIMEOUT_S = 3.0  # the client declares the camera's link lost after this long without a frame
HUB_KEY = web.AppKey("hub", PageHub)
ONE_CAMERA = "this console shows one camera (several: --camera, --cameras, --sim twice or --zenoh)"
SINGLE_ROUTES = (
    ("/", "index"),
    ("/api/catalog", "catalog"),
    ("/api/status", "status"),
    ("/api/traffic.pcap", "pcap"),
    ("/ws", "ws"),
)
# A wildcard listening address, and the address a browser on this machine reaches it by.
WILDCARD_HOSTS = {"0.0.0.0": "127.0.0.1", "": "127.0.0.1", "::": "::1"}


def static_dir() -> Path:
    return Path(str(importlib.resources.files("topgimbal.console") / "static"))


def create_app(
    hub: PageHub, *, token: str | None = None, allowed_hosts: Iterable[str] | None = None
) -> web.Application:
    """The aiohttp app: `/` the page, `/static/*` its files, `/api/*` JSON, `/ws` the socket.

    Every request passes the Host/Origin allow-list first (`guard.py`; default: the loopback
    names), then the token rule (`auth.py`)."""
    guard = HostGuard(default_allowed_hosts(DEFAULT_HOST) if allowed_hosts is None else allowed_hosts)
    app = web.Application(middlewares=[guard.middleware(), token_middleware(token)])  # type: ignore[list-item]
    app[HUB_KEY] = hub
    root = static_dir()

    handlers = camera_handlers(lambda request: hub, root)
    for path, name in SINGLE_ROUTES:
        app.router.add_get(path, handlers[name])
    app.router.add_get("/api/cameras", _one_camera)  # the page's overview poll: "no switcher here"
    app.router.add_static("/static/", root, show_index=False)
    return app


def create_multi_app(
    cameras: CameraSet, videos: CameraVideos, *, token: str | None = None, allowed_hosts: Iterable[str] | None = None
) -> web.Application:
    """The app of a console with several cameras (routes.py): the same guard and token rule."""
    guard = HostGuard(default_allowed_hosts(DEFAULT_HOST) if allowed_hosts is None else allowed_hosts)
    app = web.Application(middlewares=[guard.middleware(), token_middleware(token)])  # type: ignore[list-item]
    root = static_dir()
    add_camera_routes(app, cameras, videos, root)
    app.router.add_static("/static/", root, show_index=False)
    return app


class HttpLog(logging.LoggerAdapter):  # type: ignore[type-arg]
    """aiohttp's server log, minus the tracebacks of requests that are malformed: a client's bad
    HTTP (a broken Content-Length, a non-HTTP byte stream) is one info line, not an error."""

    def log(self, level: int, msg: object, *args: Any, **kwargs: Any) -> None:
        exc = kwargs.get("exc_info")
        if isinstance(exc, HttpProcessingError):
            first = (str(exc.message) or type(exc).__name__).splitlines()[0]
            self.logger.info("refused a malformed HTTP request (%d): %s", exc.code, untrusted(first))
            return
        super().log(level, msg, *args, **kwargs)


async def _one_camera(request: web.Request) -> web.Response:
    return web.json_response({"several": False, "cameras": [], "message": ONE_CAMERA})


async def _no_video(request: web.Request) -> web.Response:
    """No video (a watched proxy, a model without video facts, no video extra): the page's video
    module shows no panel, and the browser logs no failed request."""
    return web.Response(status=204)


def check_video_options(model: str | None, urls: dict[str, str], port: int | None) -> dict[str, str]:
    """The operator's video URLs, checked: lenses the model has, URLs a player can open (ValueError)."""
    from urllib.parse import urlsplit

    from ..video.lens import streams_for

    if port is not None and not 0 < port <= 65535:
        raise ValueError(f"--video-port {port}: give a port from 1 to 65535")
    if not urls:
        return urls
    lenses = [s.lens for s in streams_for(model or "C12")]
    for lens, url in urls.items():
        if lens not in lenses:
            raise ValueError(f"--video-url: the {model} has no lens {lens!r}; its lenses: {', '.join(lenses)}")
        parts = urlsplit(url)
        if parts.scheme not in VIDEO_SCHEMES or not parts.hostname:
            raise ValueError(
                f"--video-url {lens}={url}: expected a stream URL such as rtsp://HOST:PORT/PATH "
                f"(schemes: {', '.join(VIDEO_SCHEMES)})"
            )
    return urls


def _dumps(obj: object) -> str:
    return dumps(obj)  # the SDK's one encoding: NaN is null, never an invalid literal


class ConsoleServer:
    """Simulator (optional) + client + HTTP server, started and stopped together; or, with
    `proxy_listen` and `proxy_to`, a proxy in this process that the page watches (read-only)."""

    def __init__(
        self,
        *,
        url: str | None = None,
        model: str | None = None,
        sim_model: str | None = None,
        sim_seed: int = 0,
        sim_faults: FaultPlan | None = None,
        proxy_listen: str | None = None,
        proxy_to: str | None = None,
        host: str = DEFAULT_HOST,
        port: int = DEFAULT_PORT,
        token: str | None = None,
        allow_hosts: Sequence[str] = (),
        attitude_hz: float = 50.0,
        timeout_s: float = 1.0,
        retries: int = 2,
        link_timeout_s: float = LINK_TIMEOUT_S,
        video_urls: Mapping[str, str] | None = None,
        video_port: int | None = None,
        cameras: Sequence[tuple[str, str, str]] = (),
        sims: Sequence[str] = (),
        zenoh: Sequence[str] = (),
    ) -> None:
        self.multi = bool(cameras or sims or zenoh)
        if self.multi:  # several cameras (routes.py, cameras.py): checked before anything starts
            single = {"--url": url, "--sim MODEL (alone)": sim_model, "--proxy": proxy_listen or proxy_to,
                      "--faults": sim_faults, "--video-url": video_urls, "--video-port": video_port}  # fmt: skip
            given = [k for k, v in single.items() if v]
            if given:
                raise ValueError(f"{', '.join(given)} cannot be combined with --camera, several --sim or --zenoh: "
                                 "give every camera with --camera NAME=URL,MODEL (or --sim MODEL, --zenoh ENDPOINT)")  # fmt: skip
            self.plan = local_plan(cameras, sims)
            self.zenoh_endpoints = tuple(check_endpoint(e) for e in zenoh)
            url, model = None, None
            sim_model = None
        watch = proxy_listen is not None or proxy_to is not None
        if watch and not (proxy_listen and proxy_to):
            raise ValueError("--proxy needs both --listen URL (where clients connect) and --to URL (the camera)")
        if watch and (sim_model is not None or url):
            raise ValueError("--proxy watches the camera behind it: give --listen and --to, not --url or --sim")
        if watch and not model:
            raise ValueError("give --model with --proxy: the page describes the camera's commands from its model")
        if not watch and sim_model is None and not url and not self.multi:
            raise ValueError("give the camera's --url (and --model), or --sim MODEL to run a simulator")
        if sim_model is not None and url:
            raise ValueError("--sim runs its own simulator: give either --url or --sim, not both")
        if sim_faults is not None and sim_model is None:
            raise ValueError("--faults applies to the simulator: use it with --sim")
        if (video_urls or video_port is not None) and not url:
            raise ValueError(
                "--video-url and --video-port are for a camera given with --url (the simulator of --sim serves its "
                "own video; a watched proxy has no video panel)"
            )
        self.video_urls = check_video_options(model, dict(video_urls or {}), video_port)
        self.video_port = video_port
        self.url = url
        self.model = model or sim_model
        self.sim_model = sim_model
        self.sim_seed = sim_seed
        self.sim_faults = sim_faults
        self.proxy_listen = proxy_listen
        self.proxy_to = proxy_to
        self.host = host
        self.port = port
        self.token, self.token_generated = resolve_token(host, token)
        self.allowed_hosts = default_allowed_hosts(host, allow_hosts)  # HostNameError on a bad name
        self.attitude_hz = attitude_hz
        self.timeout_s = timeout_s
        self.retries = retries
        self.link_timeout_s = link_timeout_s
        self.sim: Simulator | None = None
        self.cam: AsyncClient | None = None  # the hub sees it as a CameraAPI
        self.proxy: Proxy | None = None
        self.hub: PageHub | None = None
        self.app: web.Application | None = None
        self._runner: web.AppRunner | None = None
        self.bound_port: int | None = None
        self.video: ConsoleVideo | None = None
        self.cameras = CameraSet()  # several cameras: every camera (the single-camera forms: empty)
        self.videos = CameraVideos(self.cameras)
        self.zenoh: ZenohCameras | None = None

    @property
    def base_url(self) -> str:
        """The URL to print: for a wildcard --host (0.0.0.0, ::) this machine's loopback address, a
        URL a browser can open (http://0.0.0.0:PORT/ is none); `banner` says so."""
        host = WILDCARD_HOSTS.get(self.host, self.host)
        host = host if ":" not in host else f"[{host}]"
        return f"http://{host}:{self.bound_port or self.port}/"

    @property
    def page_url(self) -> str:
        """The URL to open (with the token when one is enforced)."""
        return self.base_url + (f"?token={self.token}" if self.token else "")

    async def start(self) -> None:
        try:
            if self.multi:
                await self._start_multi()
                return
            self.hub = await (self._watch() if self.proxy_listen else self._connect())
            await self.hub.start()
            self.app = create_app(self.hub, token=self.token, allowed_hosts=self.allowed_hosts)
            if self.cam is not None:  # video needs a camera to point; a watched proxy has none of ours
                # video routes sit behind the same Host/Origin guard middleware as every other route
                self.video = await attach_video(self, self.app)  # topgimbal.video: streams, relay, routes
            if self.video is None:  # (the reason is logged by topgimbal.video)
                self.app.router.add_get("/api/video", _no_video)
            await self._serve_app()
        except BaseException:
            await self.stop()
            raise

    async def _start_multi(self) -> None:
        for name, url, model in self.plan:
            cam = await open_local(name, url, model, attitude_hz=self.attitude_hz, timeout_s=self.timeout_s,
                                   retries=self.retries, link_timeout_s=self.link_timeout_s, sim_seed=self.sim_seed)  # fmt: skip
            self.cameras.add(cam)
        for cam in self.cameras:
            await cam.hub.start()
            cam.start_first_reads()
        if self.zenoh_endpoints:
            self.zenoh = ZenohCameras(self.cameras, self.zenoh_endpoints, attitude_hz=self.attitude_hz)
            await self.zenoh.start()
        self.app = create_multi_app(self.cameras, self.videos, token=self.token, allowed_hosts=self.allowed_hosts)
        await self._serve_app()

    async def _serve_app(self) -> None:
        assert self.app is not None
        self._runner = web.AppRunner(
            self.app, access_log=None, handle_signals=False, logger=HttpLog(logging.getLogger("aiohttp.server"))
        )
        await self._runner.setup()
        site = web.TCPSite(self._runner, self.host, self.port)
        await site.start()
        server = getattr(site, "_server", None)
        sockets = getattr(server, "sockets", None) or []
        self.bound_port = sockets[0].getsockname()[1] if sockets else self.port

    async def _connect(self) -> Hub:
        from .. import client as client_mod

        if self.sim_model is not None:
            from ..sim import Simulator

            self.sim = Simulator(model=self.sim_model, seed=self.sim_seed, faults=self.sim_faults)
            await self.sim.start(udp=[("127.0.0.1", 0)])
            self.url = self.sim.url
        assert self.url is not None
        self.cam = await client_mod.connect(
            self.url,
            model=self.model or "C12",
            timeout_s=self.timeout_s,
            retries=self.retries,
            link_timeout_s=self.link_timeout_s,
        )
        return Hub(self.cam, url=self.url, attitude_hz=self.attitude_hz)

    async def _watch(self) -> PageHub:
        from ..protocol import get_model
        from ..wire.proxy import Proxy
        from .watch import WatchHub

        assert self.proxy_listen and self.proxy_to and self.model
        dialect, model = get_model(self.model)
        self.proxy = Proxy(self.proxy_listen, self.proxy_to, model=self.model)
        await self.proxy.start()
        self.url = f"{self.proxy.url} -> {self.proxy.to.text}"
        return WatchHub(self.proxy, dialect, model, attitude_hz=self.attitude_hz)

    async def stop(self) -> None:
        await self.videos.close()
        if self.zenoh is not None:
            await self.zenoh.stop()
        if self.video is not None:  # first: it ends the endless picture responses
            await self.video.close()
            self.video = None
        if self._runner is not None:
            with contextlib.suppress(Exception):
                await self._runner.cleanup()
            self._runner = None
        if self.hub is not None:
            await self.hub.stop()
            self.hub = None
        if self.cam is not None:
            with contextlib.suppress(Exception):
                await self.cam.close()
            self.cam = None
        if self.proxy is not None:
            with contextlib.suppress(Exception):
                await self.proxy.stop()
            self.proxy = None
        if self.sim is not None:
            with contextlib.suppress(Exception):
                await self.sim.stop()
            self.sim = None
        await self.cameras.close()
        if self.zenoh is not None:
            await self.zenoh.close()
            self.zenoh = None

    async def __aenter__(self) -> ConsoleServer:
        await self.start()
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.stop()

    def banner(self) -> str:
        watching = " (watching the proxy: read-only)" if self.proxy is not None else ""
        what = f"{self.model} at {self.url}{watching}"
        if self.multi:
            cams = ", ".join(f"{c.name} ({c.model})" for c in self.cameras) or "none yet"
            where = (
                f"; following the cameras served on Zenoh at {', '.join(self.zenoh_endpoints)}" if self.zenoh else ""
            )
            what = f"{len(self.cameras)} cameras: {cams}{where}"
        lines = [f"topgimbal console for {what}", f"open {self.page_url}"]
        if self.host in WILDCARD_HOSTS:
            lines.append(f"(listening on every address: from another machine, its address in place of "
                         f"{WILDCARD_HOSTS[self.host]})")  # fmt: skip
        if needs_token(self.host):
            lines.append(
                f"(answers to the names {', '.join(sorted(self.allowed_hosts))} and to the address a "
                "browser connects to; add others with --allow-host NAME)"
            )
        if self.token_generated:
            lines.append(
                "(a token was generated because the console listens beyond this machine; keep the URL private)"
            )
        return "\n".join(lines)

    async def serve_forever(self, seconds: float | None = None) -> None:
        """Run until cancelled (Ctrl-C), or for `seconds`."""
        if seconds is None:
            await asyncio.Event().wait()
        else:
            await asyncio.sleep(seconds)


__all__ = ["DEFAULT_HOST", "DEFAULT_PORT", "ConsoleServer", "create_app", "static_dir"]
