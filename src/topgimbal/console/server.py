"""The console's aiohttp application and a server object that owns the camera link.

`ConsoleServer.from_config(ConsoleConfig(SimSource("C12")))` (or the keyword form,
`ConsoleServer(sim_model="C12")`, `ConsoleServer(url="udp://...", model="SIP")`): `await
server.start()` opens what the config's source names (`modes.py`: a simulator, a camera's client,
a watched proxy, several cameras) and the HTTP server; `server.page_url` is the URL to open;
`await server.stop()` undoes it all.
"""

from __future__ import annotations

import asyncio
import contextlib
import importlib.resources
import logging
from collections.abc import Iterable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from aiohttp import web
from aiohttp.http_exceptions import HttpProcessingError

from ..client.jsonable import dumps
from ..logtext import untrusted
from ..video.webconsole import ConsoleVideo
from ..video.webconsole import attach as attach_video
from .auth import needs_token, resolve_token, token_middleware
from .autopilot import AutopilotListener, listen_address
from .cameras import CameraSet
from .config import (  # the constants and check_video_options: their old home was this module
    DEFAULT_HOST,
    DEFAULT_PORT,
    LINK_TIMEOUT_S,
    VIDEO_SCHEMES,
    CameraSource,
    ConsoleConfig,
    ConsoleKeywords,
    FleetSource,
    ProxySource,
    SimSource,
    check_video_options,
)
from .guard import HostGuard, default_allowed_hosts
from .hub import Hub
from .modes import open_fleet, open_single
from .pages import PageHub
from .routes import CameraVideos, add_camera_routes, camera_handlers
from .zenoh_cameras import ZenohCameras

if TYPE_CHECKING:
    from typing import Unpack

    from ..client import AsyncClient
    from ..sim import Simulator
    from ..wire.proxy import Proxy

log = logging.getLogger(__name__)

HUB_KEY = web.AppKey("hub", PageHub)
ONE_CAMERA = "this console shows one camera (several: --camera, --cameras, --sim twice or --zenoh)"
SINGLE_ROUTES = (
    ("/", "index"),
    ("/api/catalog", "catalog"),
    ("/api/status", "status"),
    ("/api/traffic.pcap", "pcap"),
    ("/api/where", "where"),
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


class HttpLog(logging.LoggerAdapter):
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


def _dumps(obj: object) -> str:
    return dumps(obj)  # the SDK's one encoding: NaN is null, never an invalid literal


class ConsoleServer:
    """Simulator (optional) + client + HTTP server, started and stopped together; or a proxy in
    this process that the page watches (read-only); or several cameras. What it runs is a
    `ConsoleConfig` (config.py): `ConsoleServer.from_config(config)` / `ConsoleServer(config=...)`,
    or the keyword form `ConsoleServer(url=..., model=...)`, which builds one
    (`ConsoleConfig.from_keywords`: the same checks, the same messages)."""

    def __init__(self, *, config: ConsoleConfig | None = None, **keywords: Unpack[ConsoleKeywords]) -> None:
        if config is None:
            config = ConsoleConfig.from_keywords(**keywords)
        elif keywords:
            raise TypeError(f"ConsoleServer: give config= or the keywords ({', '.join(sorted(keywords))}), not both")
        elif not isinstance(config, ConsoleConfig):
            raise TypeError(f"ConsoleServer: config= takes a ConsoleConfig, not {type(config).__name__}")
        self.config = config
        source, serve, link = config.source, config.serve, config.link
        # The attributes the rest of the console (video/webconsole.py's VideoHost), the tests and
        # users read: the config's values, and what start() opens.
        self.multi = config.several
        self.url: str | None = source.url if isinstance(source, CameraSource) else None
        self.model: str | None = None if isinstance(source, FleetSource) else source.model
        self.sim_model = source.model if isinstance(source, SimSource) else None
        self.sim_seed = source.seed if isinstance(source, (SimSource, FleetSource)) else 0
        self.sim_faults = source.faults if isinstance(source, SimSource) else None
        self.proxy_listen = source.listen if isinstance(source, ProxySource) else None
        self.proxy_to = source.to if isinstance(source, ProxySource) else None
        self.video_urls: dict[str, str] = dict(source.video_urls) if isinstance(source, CameraSource) else {}
        self.video_port = source.video_port if isinstance(source, CameraSource) else None
        if isinstance(source, FleetSource):
            self.plan = source.plan
            self.zenoh_endpoints = source.zenoh
        self.host = serve.host
        self.port = serve.port
        self.token, self.token_generated = resolve_token(serve.host, serve.token)
        self.allowed_hosts = default_allowed_hosts(serve.host, serve.allow_hosts)
        self.attitude_hz = link.attitude_hz
        self.timeout_s = link.timeout_s
        self.retries = link.retries
        self.link_timeout_s = link.link_timeout_s
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
        self.autopilot: AutopilotListener | None = None  # --autopilot (one-camera consoles)

    @classmethod
    def from_config(cls, config: ConsoleConfig) -> ConsoleServer:
        """The server of a checked `ConsoleConfig` (the CLI's way; `ConsoleServer(config=...)` too)."""
        return cls(config=config)

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
            source = self.config.source
            if isinstance(source, FleetSource):
                self.zenoh = await open_fleet(source, self.config.link, self.cameras)
                self.app = create_multi_app(
                    self.cameras, self.videos, token=self.token, allowed_hosts=self.allowed_hosts
                )
                await self._serve_app()
                return
            opened = await open_single(source, self.config.link)
            self.hub, self.url, self.cam, self.sim, self.proxy = (
                opened.hub,
                opened.url,
                opened.cam,
                opened.sim,
                opened.proxy,
            )
            if isinstance(self.hub, Hub):
                self.hub.sim = opened.sim
                if self.config.autopilot is not None:
                    self.autopilot = await AutopilotListener.listen(*listen_address(self.config.autopilot))
                    self.hub.autopilot = self.autopilot
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

    async def stop(self) -> None:
        if self.autopilot is not None:
            self.autopilot.close()
            self.autopilot = None
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


__all__ = [
    "DEFAULT_HOST",
    "DEFAULT_PORT",
    "LINK_TIMEOUT_S",
    "VIDEO_SCHEMES",
    "ConsoleServer",
    "check_video_options",
    "create_app",
    "static_dir",
]
