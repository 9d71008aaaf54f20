"""What each console option may be, checked with the option's name in the message: a model the
catalog knows, a device URL the transports parse, a port in range, the operator's video URLs; the
refusals of a mixture of forms, worded alike for the CLI and the keyword API; and the errors
(`ConsoleConfigError`, `ConsoleAddressError`). Pure: config.py builds the config objects on these."""

from __future__ import annotations

from collections.abc import Mapping

from ..errors import AddressError, TopGimbalError
from ..transport import parse_url

DEFAULT_HOST = "127.0.0.1"
DEFAULT_PORT = 8080
DEFAULT_MODEL = "C12"  # a camera given by URL without a model (the keyword API; the CLI insists on --model)
LINK_TIMEOUT_S = 3.0  # the client declares the camera's link lost after this long without a frame
VIDEO_SCHEMES = ("rtsp", "rtsps", "http", "https")  # what --video-url accepts (the relay opens them with FFmpeg)

# The refusals of a mixture of forms (ConsoleConfig.from_keywords and the CLI say them alike).
NO_SOURCE = "give the camera's --url (and --model), or --sim MODEL to run a simulator"
SIM_AND_URL = "--sim runs its own simulator: give either --url or --sim, not both"
PROXY_BOTH = "--proxy needs both --listen URL (where clients connect) and --to URL (the camera)"
PROXY_NOT_URL = "--proxy watches the camera behind it: give --listen and --to, not --url or --sim"
PROXY_MODEL = "give --model with --proxy: the page describes the camera's commands from its model"
FAULTS_NEED_SIM = "--faults applies to the simulator: use it with --sim"
VIDEO_NEED_URL = (
    "--video-url and --video-port are for a camera given with --url (the simulator of --sim serves its "
    "own video; a watched proxy has no video panel)"
)
FLEET_ALONE = (
    "cannot be combined with --camera, several --sim or --zenoh: give every camera with --camera NAME=URL,MODEL "
    "(or --sim MODEL, --zenoh ENDPOINT)"
)
FLEET_EMPTY = "a console of several cameras needs at least one --camera NAME=URL,MODEL, --sim MODEL or --zenoh ENDPOINT"


class ConsoleConfigError(TopGimbalError, ValueError):
    """A console configuration that cannot work: says what was wrong and what is allowed."""


class ConsoleAddressError(ConsoleConfigError, AddressError):
    """A device URL of the config that is not usable: an AddressError (the CLI exits 2, as it did
    when the URL was refused at start) and a ValueError, like every refusal here."""


def known_model(flag: str, model: object) -> str:
    """A model name the catalog knows (case as given), else ConsoleConfigError with the list."""
    from ..protocol import get_model

    if not isinstance(model, str) or not model:
        raise ConsoleConfigError(f"{flag}: give a model name, e.g. {DEFAULT_MODEL}")
    try:
        get_model(model)
    except TopGimbalError as exc:
        raise ConsoleConfigError(f"{flag} {exc}") from None
    return model


def device_url(flag: str, url: object) -> str:
    """A device URL the transports can parse, else ConsoleAddressError naming the option."""
    if not isinstance(url, str):
        raise ConsoleAddressError(f"{flag}: give a device URL such as udp://HOST:PORT, not {url!r}")
    try:
        parse_url(url)
    except AddressError as exc:
        raise ConsoleAddressError(f"{flag}: {exc}") from None
    return url


def port_in_range(flag: str, port: object, *, lowest: int) -> None:
    if not isinstance(port, int) or isinstance(port, bool) or not lowest <= port <= 65535:
        free = " (0: any free port)" if lowest == 0 else ""
        raise ConsoleConfigError(f"{flag} {port}: give a port from {lowest} to 65535{free}")


def check_video_options(model: str | None, urls: Mapping[str, str], port: int | None) -> dict[str, str]:
    """The operator's video URLs, checked: lenses the model has, URLs a player can open (ValueError)."""
    from urllib.parse import urlsplit

    from ..video.lens import streams_for

    if port is not None and not 0 < port <= 65535:
        raise ConsoleConfigError(f"--video-port {port}: give a port from 1 to 65535")
    if not urls:
        return dict(urls)
    lenses = [s.lens for s in streams_for(model or DEFAULT_MODEL)]
    for lens, url in urls.items():
        if lens not in lenses:
            raise ConsoleConfigError(f"--video-url: the {model} has no lens {lens!r}; its lenses: {', '.join(lenses)}")
        parts = urlsplit(url)
        if parts.scheme not in VIDEO_SCHEMES or not parts.hostname:
            raise ConsoleConfigError(
                f"--video-url {lens}={url}: expected a stream URL such as rtsp://HOST:PORT/PATH "
                f"(schemes: {', '.join(VIDEO_SCHEMES)})"
            )
    return dict(urls)
