"""Opening what a console's source names (config.py), one function per mode.

`open_single` opens a single-camera source and returns what it opened (`Opened`): the page's hub
and whatever the server must close later. `open_fleet` opens the cameras of a `FleetSource` into
the server's `CameraSet` and follows its Zenoh endpoints. Each cleans up what it started when a
later step fails, so the server holds only what did start (and `ConsoleServer.stop` closes that).
The server keeps the HTTP side and the order of shutdown; nothing here touches aiohttp's app."""

from __future__ import annotations

import contextlib
from dataclasses import dataclass
from typing import TYPE_CHECKING

from .cameras import CameraSet, open_local
from .config import CameraSource, FleetSource, LinkOptions, ProxySource, SimSource
from .hub import Hub
from .pages import PageHub
from .zenoh_cameras import ZenohCameras

if TYPE_CHECKING:
    from ..client import AsyncClient
    from ..sim import Simulator
    from ..wire.proxy import Proxy


@dataclass
class Opened:
    """What a single-camera mode opened: the page's hub, the URL to show, and the client /
    simulator / proxy behind it (None where the mode has none)."""

    hub: PageHub
    url: str
    cam: AsyncClient | None = None
    sim: Simulator | None = None
    proxy: Proxy | None = None


async def open_camera(url: str, model: str, link: LinkOptions) -> tuple[AsyncClient, Hub]:
    """The client of the camera at `url` and its hub."""
    from .. import client as client_mod

    cam = await client_mod.connect(
        url, model=model, timeout_s=link.timeout_s, retries=link.retries, link_timeout_s=link.link_timeout_s
    )
    return cam, Hub(cam, url=url, attitude_hz=link.attitude_hz)


async def open_sim(source: SimSource, link: LinkOptions) -> Opened:
    """A simulator on an ephemeral loopback UDP port, and the camera at its URL."""
    from ..sim import Simulator

    sim = Simulator(model=source.model, seed=source.seed, faults=source.faults)
    await sim.start(udp=[("127.0.0.1", 0)])
    try:
        cam, hub = await open_camera(sim.url, source.model, link)
    except BaseException:
        with contextlib.suppress(Exception):
            await sim.stop()
        raise
    return Opened(hub, sim.url, cam=cam, sim=sim)


async def open_proxy(source: ProxySource, link: LinkOptions) -> Opened:
    """A proxy between `listen` and `to` in this process, and the read-only hub that watches it."""
    from ..protocol import get_model
    from ..wire.proxy import Proxy
    from .watch import WatchHub

    dialect, model = get_model(source.model)
    proxy = Proxy(source.listen, source.to, model=source.model)
    try:
        await proxy.start()
    except BaseException:
        with contextlib.suppress(Exception):
            await proxy.stop()
        raise
    hub = WatchHub(proxy, dialect, model, attitude_hz=link.attitude_hz)
    return Opened(hub, f"{proxy.url} -> {proxy.to.text}", proxy=proxy)


async def open_single(source: CameraSource | SimSource | ProxySource, link: LinkOptions) -> Opened:
    """What a single-camera source names, opened (its hub not started yet)."""
    if isinstance(source, SimSource):
        return await open_sim(source, link)
    if isinstance(source, ProxySource):
        return await open_proxy(source, link)
    cam, hub = await open_camera(source.url, source.model, link)
    return Opened(hub, source.url, cam=cam)


async def open_fleet(source: FleetSource, link: LinkOptions, cameras: CameraSet) -> ZenohCameras | None:
    """Every camera of the command line into `cameras` (each started, its first reads asked), then
    the Zenoh endpoints followed (None without any). A camera that fails stops the start; those
    already in `cameras` are the caller's to close."""
    for name, url, model in source.plan:
        cam = await open_local(name, url, model, attitude_hz=link.attitude_hz, timeout_s=link.timeout_s,
                               retries=link.retries, link_timeout_s=link.link_timeout_s, sim_seed=source.seed)  # fmt: skip
        cameras.add(cam)
    for cam in cameras:
        await cam.hub.start()
        cam.start_first_reads()
    if not source.zenoh:
        return None
    zenoh = ZenohCameras(cameras, source.zenoh, attitude_hz=link.attitude_hz, config_file=source.zenoh_config)
    try:
        await zenoh.start()
    except BaseException:
        await zenoh.close()
        raise
    return zenoh


__all__ = ["Opened", "open_camera", "open_fleet", "open_proxy", "open_sim", "open_single"]
