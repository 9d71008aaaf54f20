"""What a console is asked to be, checked before anything starts: `ConsoleConfig` (issue 34).

`ConsoleServer` used to take 22 keywords and decide among four modes inside `__init__`, with the
cross-checks spread between them. As pymodbus and httpx do with their client settings, the
configuration is now a few small frozen dataclasses, each saying one thing and checking itself:

- `ServeOptions`: how the page is served (host, port, token, allow_hosts), whatever it shows;
- `LinkOptions`: how the console talks to a camera (attitude_hz, timeout_s, retries, link_timeout_s);
- a *source*, one class per mode, which is what the page shows:
  `CameraSource` (one camera at a URL: `--url`), `SimSource` (a simulator in this process:
  `--sim MODEL`), `ProxySource` (a proxy in this process that the page watches, read-only:
  `--proxy --listen --to`) and `FleetSource` (several cameras: `--camera`, `--sim` twice, `--zenoh`);
- `ConsoleConfig`: one source, one `ServeOptions`, one `LinkOptions`.

The names say what the user gives ("a source", "options"), not how the server runs it; the
mode is the source's type, so a mixture of modes cannot be written as a `ConsoleConfig` at all.
Mixtures are refused where they can still be written: `ConsoleConfig.from_keywords` (the old
keyword form, `ConsoleServer(url=..., model=...)`, which builds a config: one code path) and the
CLI (`cli/console_cmd.py`, which builds a config from its flags). Every error is a `ValueError`
naming what was wrong and what is allowed, in the CLI's option names (the same words for the
keyword API, as before): `ConsoleConfigError`, or the `FieldValueError` / `HostNameError` /
`CameraNameError` of the check it reuses (a bad device URL: `ConsoleAddressError`, also an
`AddressError`). Pure: no socket, no event loop, no
clock; `modes.py` opens what a source names.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import TYPE_CHECKING, TypedDict

from ..client import checks
from ..client.zenoh_session import check_endpoint
from ..errors import FieldValueError
from .cameras import local_plan
from .config_checks import (
    DEFAULT_HOST,
    DEFAULT_MODEL,
    DEFAULT_PORT,
    FAULTS_NEED_SIM,
    FLEET_ALONE,
    FLEET_EMPTY,
    LINK_TIMEOUT_S,
    NO_SOURCE,
    PROXY_BOTH,
    PROXY_MODEL,
    PROXY_NOT_URL,
    SIM_AND_URL,
    VIDEO_NEED_URL,
    VIDEO_SCHEMES,
    ConsoleAddressError,
    ConsoleConfigError,
    check_video_options,
    device_url,
    known_model,
    port_in_range,
)
from .guard import check_allow_host

if TYPE_CHECKING:
    from typing import Unpack

    from ..sim import FaultPlan

# -- how the page is served, and how the console talks to a camera ---------------------------------


@dataclass(frozen=True)
class ServeOptions:
    """Where the page is served and who may open it: `host` and `port` to listen on (port 0: any
    free one), `token` (None: none on loopback, generated elsewhere: `auth.py`), `allow_hosts`
    (more Host names to answer besides the loopback names and `host`: `guard.py`)."""

    host: str = DEFAULT_HOST
    port: int = DEFAULT_PORT
    token: str | None = None
    allow_hosts: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        if not isinstance(self.host, str):
            raise ConsoleConfigError(f"--host {self.host!r}: give an address to listen on, e.g. {DEFAULT_HOST}")
        port_in_range("--port", self.port, lowest=0)
        if self.token is not None and not isinstance(self.token, str):
            raise ConsoleConfigError("--token: give the token as text")
        if isinstance(self.allow_hosts, str):  # one name, not its letters
            raise ConsoleConfigError(f"--allow-host: give a list of names, not the text {self.allow_hosts!r}")
        hosts = tuple(self.allow_hosts)
        for name in hosts:
            check_allow_host(name)  # HostNameError naming --allow-host and what is allowed
        object.__setattr__(self, "allow_hosts", hosts)


@dataclass(frozen=True)
class LinkOptions:
    """How the console talks to each camera: the attitude push rate to the page (`attitude_hz`;
    the hub sends at most 50 a second), and the client's `timeout_s`, `retries` and
    `link_timeout_s` (checked as `connect()` checks them)."""

    attitude_hz: float = 50.0
    timeout_s: float = 1.0
    retries: int = 2
    link_timeout_s: float = LINK_TIMEOUT_S

    def __post_init__(self) -> None:
        hz = self.attitude_hz
        if not checks.is_number(hz) or hz <= 0:  # finite, too: a NaN rate would never send
            raise FieldValueError("attitude_hz", hz, "a rate above 0 per second (the page gets at most 50)")
        checks.positive_seconds("timeout_s", self.timeout_s, allow_none=False)
        checks.count("retries", self.retries, allow_none=False)
        checks.positive_seconds("link_timeout_s", self.link_timeout_s, allow_none=False)


# -- what the page shows: one source per mode ------------------------------------------------------


@dataclass(frozen=True)
class CameraSource:
    """One camera at `url` (`--url`), of `model` (`--model`); its video where the operator says
    (`video_urls`: {lens: URL}, `--video-url`) or at the documented paths on `video_port`."""

    url: str
    model: str = DEFAULT_MODEL
    video_urls: Mapping[str, str] = field(default_factory=dict, hash=False)
    video_port: int | None = None

    def __post_init__(self) -> None:
        if not self.url:
            raise ConsoleConfigError(NO_SOURCE)
        device_url("--url", self.url)
        known_model("--model", self.model)
        if not isinstance(self.video_urls, Mapping):
            raise ConsoleConfigError("--video-url: give {lens: URL}, e.g. {'visible': 'rtsp://HOST:8554/main'}")
        urls = check_video_options(self.model, self.video_urls, self.video_port)
        object.__setattr__(self, "video_urls", MappingProxyType(urls))


@dataclass(frozen=True)
class SimSource:
    """A simulated `model` in this process (`--sim MODEL`), on an ephemeral loopback UDP port,
    with its `seed` (`--seed`) and a bad link's `faults` (`--faults`)."""

    model: str
    seed: int = 0
    faults: FaultPlan | None = None

    def __post_init__(self) -> None:
        known_model("--sim", self.model)
        if not isinstance(self.seed, int) or isinstance(self.seed, bool):
            raise ConsoleConfigError(f"--seed {self.seed!r}: give a whole number")
        if self.faults is not None:
            from ..sim import FaultPlan

            if not isinstance(self.faults, FaultPlan):
                raise ConsoleConfigError(f"--faults: give a FaultPlan (FaultPlan.parse('silence=20-30')), "
                                         f"not {type(self.faults).__name__}")  # fmt: skip


@dataclass(frozen=True)
class ProxySource:
    """A proxy in this process between ground stations at `listen` and the camera at `to`
    (`--proxy --listen URL --to URL`); the page watches it, read-only, and reads the traffic with
    `model`'s dialect (`--model`, needed: a proxy cannot ask the camera)."""

    listen: str
    to: str
    model: str

    def __post_init__(self) -> None:
        if not (self.listen and self.to):
            raise ConsoleConfigError(PROXY_BOTH)
        if not self.model:
            raise ConsoleConfigError(PROXY_MODEL)
        device_url("--listen", self.listen)
        device_url("--to", self.to)
        known_model("--model", self.model)


@dataclass(frozen=True)
class FleetSource:
    """Several cameras, each under its name: `cameras` as (name, URL, model) (`--camera`,
    `--cameras`), simulators of the `sims` models in this process (named sim1, sim2, ... with
    `seed`) and the cameras served on Zenoh at the `zenoh` endpoints. Names, duplicates and the
    bound (`cameras.MAX_CAMERAS`) are checked here, before anything starts."""

    cameras: tuple[tuple[str, str, str], ...] = ()
    sims: tuple[str, ...] = ()
    zenoh: tuple[str, ...] = ()
    seed: int = 0
    zenoh_config: str | None = None  # a Zenoh configuration file for the --zenoh session (user/password, TLS)

    def __post_init__(self) -> None:
        for name in ("sims", "zenoh"):
            if isinstance(getattr(self, name), str):  # one model or endpoint, not its letters
                raise ConsoleConfigError(f"{name}: give a list, not the text {getattr(self, name)!r}")
        cams = tuple(tuple(c) for c in self.cameras)
        if any(len(c) != 3 for c in cams):
            raise ConsoleConfigError("--camera: give each camera as (name, URL, model)")
        object.__setattr__(self, "cameras", cams)
        object.__setattr__(self, "sims", tuple(self.sims))
        object.__setattr__(self, "zenoh", tuple(check_endpoint(e) for e in self.zenoh))
        if not (self.cameras or self.sims or self.zenoh):
            raise ConsoleConfigError(FLEET_EMPTY)
        if self.zenoh_config is not None:
            _zenoh_config(self.zenoh_config, bool(self.zenoh))
        if not isinstance(self.seed, int) or isinstance(self.seed, bool):
            raise ConsoleConfigError(f"--seed {self.seed!r}: give a whole number")
        for name, url, model in self.plan:  # CameraNameError / TooManyCamerasError first
            where = f"--camera {name}" if url is not None else "--sim"
            known_model(where, model)
            if url is not None:
                device_url(where, url)

    @property
    def plan(self) -> list[tuple[str, str | None, str]]:
        """(name, URL or None for a simulator, model) of every camera given here, in order."""
        return local_plan(self.cameras, self.sims)


def _zenoh_config(path: str, with_zenoh: bool) -> None:
    """--zenoh-config: only with --zenoh, and a regular file (its content is Zenoh's to judge,
    when the session opens)."""
    if not with_zenoh:
        raise ConsoleConfigError(f"--zenoh-config {path}: only with --zenoh ENDPOINT (the session it configures)")
    if not os.path.isfile(path):
        raise ConsoleConfigError(f"--zenoh-config {path}: not a file; give a Zenoh configuration file (json5)")


Source = CameraSource | SimSource | ProxySource | FleetSource
SOURCES = (CameraSource, SimSource, ProxySource, FleetSource)


class ConsoleKeywords(TypedDict, total=False):
    """The keyword form of `ConsoleServer(...)` (before issue 34; kept): see `ConsoleConfig.from_keywords`."""

    url: str | None
    model: str | None
    sim_model: str | None
    sim_seed: int
    sim_faults: FaultPlan | None
    proxy_listen: str | None
    proxy_to: str | None
    host: str
    port: int
    token: str | None
    allow_hosts: Sequence[str]
    attitude_hz: float
    timeout_s: float
    retries: int
    link_timeout_s: float
    video_urls: Mapping[str, str] | None
    video_port: int | None
    cameras: Sequence[tuple[str, str, str]]
    sims: Sequence[str]
    zenoh: Sequence[str]
    zenoh_config: str | None


@dataclass(frozen=True)
class ConsoleConfig:
    """A whole console: what it shows (`source`), how it serves the page (`serve`) and how it
    talks to cameras (`link`). `ConsoleServer.from_config(config)` runs it."""

    source: Source
    serve: ServeOptions = field(default_factory=ServeOptions)
    link: LinkOptions = field(default_factory=LinkOptions)
    autopilot: str | None = None  # HOST:PORT: listen there for the autopilot's fix (autopilot.py)

    def __post_init__(self) -> None:
        if not isinstance(self.source, SOURCES):
            raise ConsoleConfigError(
                f"source: a CameraSource, SimSource, ProxySource or FleetSource, not {type(self.source).__name__}"
            )
        if not isinstance(self.serve, ServeOptions) or not isinstance(self.link, LinkOptions):
            raise ConsoleConfigError("serve: a ServeOptions and link: a LinkOptions")
        if self.autopilot is not None:
            from .autopilot import listen_address

            listen_address(self.autopilot)
            if self.several:
                raise ConsoleConfigError("--autopilot: a console of one camera only (its fix is shown on that page)")

    @property
    def several(self) -> bool:
        """Several cameras (the switcher, the overview, `/cam/<name>/`)."""
        return isinstance(self.source, FleetSource)

    @classmethod
    def from_keywords(cls, **kw: Unpack[ConsoleKeywords]) -> ConsoleConfig:
        """The config the old keyword form describes, refusing every mixture it refused (same words)."""
        unknown = set(kw) - set(ConsoleKeywords.__annotations__)
        if unknown:
            raise TypeError(f"ConsoleServer() got unexpected keyword(s): {', '.join(sorted(unknown))}")
        source = _source_from_keywords(kw)  # first, as before: the mode's refusals come before the page's
        serve = ServeOptions(
            host=kw.get("host", DEFAULT_HOST),
            port=kw.get("port", DEFAULT_PORT),
            token=kw.get("token"),
            allow_hosts=tuple(kw.get("allow_hosts", ())),
        )
        link = LinkOptions(
            attitude_hz=kw.get("attitude_hz", 50.0),
            timeout_s=kw.get("timeout_s", 1.0),
            retries=kw.get("retries", 2),
            link_timeout_s=kw.get("link_timeout_s", LINK_TIMEOUT_S),
        )
        return cls(source, serve, link)


def _source_from_keywords(kw: ConsoleKeywords) -> Source:
    """The mode the keywords name, with the old constructor's checks in its order."""
    url, model, sim_model = kw.get("url"), kw.get("model"), kw.get("sim_model")
    listen, to, faults = kw.get("proxy_listen"), kw.get("proxy_to"), kw.get("sim_faults")
    video_urls, video_port, seed = kw.get("video_urls"), kw.get("video_port"), kw.get("sim_seed", 0)
    cameras, sims, zenoh = kw.get("cameras", ()), kw.get("sims", ()), kw.get("zenoh", ())
    if cameras or sims or zenoh:  # several cameras: no single-camera form besides them (a model is not used)
        single = {"--url": url, "--sim MODEL (alone)": sim_model, "--proxy": listen or to, "--faults": faults,
                  "--video-url": video_urls, "--video-port": video_port}  # fmt: skip
        given = [k for k, v in single.items() if v]
        if given:
            raise ConsoleConfigError(f"{', '.join(given)} {FLEET_ALONE}")
        return FleetSource(tuple(cameras), tuple(sims), tuple(zenoh), seed, kw.get("zenoh_config"))
    watch = listen is not None or to is not None
    if watch and not (listen and to):
        raise ConsoleConfigError(PROXY_BOTH)
    if watch and (sim_model is not None or url):
        raise ConsoleConfigError(PROXY_NOT_URL)
    if watch and not model:
        raise ConsoleConfigError(PROXY_MODEL)
    if not watch and sim_model is None and not url:
        raise ConsoleConfigError(NO_SOURCE)
    if sim_model is not None and url:
        raise ConsoleConfigError(SIM_AND_URL)
    if faults is not None and sim_model is None:
        raise ConsoleConfigError(FAULTS_NEED_SIM)
    if (video_urls or video_port is not None) and not url:
        raise ConsoleConfigError(VIDEO_NEED_URL)
    if watch:
        assert listen and to and model
        return ProxySource(listen, to, model)
    if sim_model is not None:
        return SimSource(sim_model, seed, faults)
    assert url
    return CameraSource(url, model or DEFAULT_MODEL, dict(video_urls or {}), video_port)


# Names kept importable from here (config_checks.py has them).
__all__ = [
    "DEFAULT_HOST",
    "DEFAULT_MODEL",
    "DEFAULT_PORT",
    "FAULTS_NEED_SIM",
    "FLEET_ALONE",
    "FLEET_EMPTY",
    "LINK_TIMEOUT_S",
    "NO_SOURCE",
    "PROXY_BOTH",
    "PROXY_MODEL",
    "PROXY_NOT_URL",
    "SIM_AND_URL",
    "SOURCES",
    "VIDEO_NEED_URL",
    "VIDEO_SCHEMES",
    "CameraSource",
    "ConsoleAddressError",
    "ConsoleConfig",
    "ConsoleConfigError",
    "ConsoleKeywords",
    "FleetSource",
    "LinkOptions",
    "ProxySource",
    "ServeOptions",
    "SimSource",
    "Source",
    "check_video_options",
]
