"""What the console's video routes (webconsole.py) read of the console and of a request, and the
error they answer with: the `VideoHost` the console is to its video, the origin check it passes in,
the lens and the fractions of the picture a POST body gives (checked: a bad one is a 400 saying what
is allowed, never a 500), and stream URLs as the page shows them (no password)."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Any, Protocol
from urllib.parse import urlsplit, urlunsplit

from .lens import StreamSpec, VideoError

if TYPE_CHECKING:  # named for the type checker only: aiohttp is imported by the routes when they run
    from aiohttp import web

    from ..sim.simulator import Simulator


class VideoHost(Protocol):
    """What video reads of the console that hosts it (console/server.py)."""

    @property
    def model(self) -> str | None: ...
    @property
    def url(self) -> str | None: ...
    @property
    def sim(self) -> Simulator | None: ...
    @property  # a client.CameraAPI; video/ sits below client/, so it cannot name the type
    def cam(self) -> Any: ...
    @property  # {lens: URL} given by the operator (`console --video-url`), instead of the documented ones
    def video_urls(self) -> Mapping[str, str]: ...
    @property  # the port the camera's video is on, if not the documented one (`console --video-port`)
    def video_port(self) -> int | None: ...


OriginCheck = Callable[["web.Request"], bool]


def shown_url(url: str) -> str:
    """A stream URL as the page shows it: a password given in it is not repeated."""
    parts = urlsplit(url)
    if parts.password is None:
        return url
    host = parts.netloc.rsplit("@", 1)[1]
    return urlunsplit(parts._replace(netloc=f"{parts.username}:***@{host}"))


def error_response(status: int, message: str) -> web.Response:
    from aiohttp import web

    return web.json_response({"error": "video", "message": message}, status=status)


def lens_of(body: Mapping[str, object], specs: dict[str, StreamSpec]) -> str:
    lens = body.get("lens", "visible")
    if not isinstance(lens, str) or lens not in specs:  # a list or an object is unhashable: not a 500
        raise VideoError(f"lens must be one of {', '.join(specs)} (got {lens!r})")
    return str(lens)


def fraction_of(body: Mapping[str, object], key: str) -> float:
    v = body.get(key)
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not 0.0 <= v <= 1.0:
        raise VideoError(f"{key} must be a number from 0 to 1 (a fraction of the picture), got {v!r}")
    return float(v)
