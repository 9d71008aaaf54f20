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
import time
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from aiohttp import web
from aiohttp.http_exceptions import HttpProcessingError

from ..video.webconsole import ConsoleVideo
from ..video.webconsole import attach as attach_video
from .auth import needs_token, resolve_token, token_middleware
from .capture import pcap
from .catalog_api import catalog_json
from .guard import HostGuard, default_allowed_hosts
from .hub import Hub
from .pages import PageHub

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

    async def index(request: web.Request) -> web.StreamResponse:
        return web.FileResponse(root / "index.html", headers={"Cache-Control": "no-store"})

    async def catalog(request: web.Request) -> web.Response:
        return web.json_response(catalog_json(hub.dialect, hub.model))

    async def status(request: web.Request) -> web.Response:
        return web.json_response(hub.status(), dumps=_dumps)

    async def ws(request: web.Request) -> web.StreamResponse:
        return await hub.handle_ws(request)

    async def traffic_pcap(request: web.Request) -> web.Response:
        frames = hub.recorder.frames()  # taken here, written in a thread (a temporary file)
        data = await asyncio.to_thread(pcap, frames, hub.link)
        stamp = time.strftime("%Y%m%d-%H%M%S")
        return web.Response(
            body=data,
            content_type="application/vnd.tcpdump.pcap",
            headers={
                "Content-Disposition": f'attachment; filename="topgimbal-{hub.model.name}-{stamp}.pcap"',
                "Cache-Control": "no-store",
                "X-Topgimbal-Frames": str(len(frames)),
            },
        )

    app.router.add_get("/", index)
    app.router.add_get("/api/catalog", catalog)
    app.router.add_get("/api/status", status)
    app.router.add_get("/api/traffic.pcap", traffic_pcap)
    app.router.add_get("/ws", ws)
    app.router.add_static("/static/", root, show_index=False)
    return app


class HttpLog(logging.LoggerAdapter):  # type: ignore[type-arg]
    """aiohttp's server log, minus the tracebacks of requests that are malformed: a client's bad
    HTTP (a broken Content-Length, a non-HTTP byte stream) is one info line, not an error."""

    def log(self, level: int, msg: object, *args: Any, **kwargs: Any) -> None:
        exc = kwargs.get("exc_info")
        if isinstance(exc, HttpProcessingError):
            first = (str(exc.message) or type(exc).__name__).splitlines()[0]
            self.logger.info("refused a malformed HTTP request (%d): %s", exc.code, first)
            return
        super().log(level, msg, *args, **kwargs)


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
    import json

    return json.dumps(obj, default=str)


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
    ) -> None:
        watch = proxy_listen is not None or proxy_to is not None
        if watch and not (proxy_listen and proxy_to):
            raise ValueError("--proxy needs both --listen URL (where clients connect) and --to URL (the camera)")
        if watch and (sim_model is not None or url):
            raise ValueError("--proxy watches the camera behind it: give --listen and --to, not --url or --sim")
        if watch and not model:
            raise ValueError("give --model with --proxy: the page describes the camera's commands from its model")
        if not watch and sim_model is None and not url:
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

    @property
    def base_url(self) -> str:
        host = self.host if ":" not in self.host else f"[{self.host}]"
        return f"http://{host}:{self.bound_port or self.port}/"

    @property
    def page_url(self) -> str:
        """The URL to open (with the token when one is enforced)."""
        return self.base_url + (f"?token={self.token}" if self.token else "")

    async def start(self) -> None:
        try:
            self.hub = await (self._watch() if self.proxy_listen else self._connect())
            await self.hub.start()
            self.app = create_app(self.hub, token=self.token, allowed_hosts=self.allowed_hosts)
            if self.cam is not None:  # video needs a camera to point; a watched proxy has none of ours
                # video routes sit behind the same Host/Origin guard middleware as every other route
                self.video = await attach_video(self, self.app)  # topgimbal.video: streams, relay, routes
            if self.video is None:  # (the reason is logged by topgimbal.video)
                self.app.router.add_get("/api/video", _no_video)
            self._runner = web.AppRunner(
                self.app, access_log=None, handle_signals=False, logger=HttpLog(logging.getLogger("aiohttp.server"))
            )
            await self._runner.setup()
            site = web.TCPSite(self._runner, self.host, self.port)
            await site.start()
            server = getattr(site, "_server", None)
            sockets = getattr(server, "sockets", None) or []
            self.bound_port = sockets[0].getsockname()[1] if sockets else self.port
        except BaseException:
            await self.stop()
            raise

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

    async def __aenter__(self) -> ConsoleServer:
        await self.start()
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.stop()

    def banner(self) -> str:
        watching = " (watching the proxy: read-only)" if self.proxy is not None else ""
        lines = [f"topgimbal console for {self.model} at {self.url}{watching}", f"open {self.page_url}"]
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
