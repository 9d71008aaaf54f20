"""The bridge's lifecycle: the camera link, the MAVLink node, and the components for the chosen
role, started and stopped together.

    async with Bridge(BridgeConfig(url="udp://127.0.0.1:5000", model="C12",
                                   endpoints=["udpout:127.0.0.1:14550"])) as bridge:
        await bridge.wait_closed()
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
from typing import Any

from ..autopilot.reboots import RebootWatch
from ..autopilot.streams import AutopilotStreams
from ..autopilot.vehicle import Vehicles
from ..camdef.definition import file_name, render
from ..camdef.http import DefinitionServer
from ..camdef.pacing import FetchPacer
from ..clock import monotonic
from ..errors import TopGimbalError
from ..links.endpoints import parse_endpoint
from ..outputs.cot import CotSender
from ..outputs.klv_record import Recorder
from ..timeouts import stop_tasks, within
from .advertise import Advertiser
from .bridge_build import MAV_TYPE_CAMERA, MAV_TYPE_GIMBAL, NON_MAVLINK_GIMBAL_ID, build_cameras, build_gimbal  # noqa: F401
from .bridge_config import (  # noqa: F401  # re-exported: the public names of topgimbal.mavlink.bridge
    CAMERA_COMPIDS,
    GIMBAL_COMPIDS,
    ROLES,
    BridgeConfig,
    BridgeConfigError,
)
from .camera_feed import CameraFeed
from .camera_link import CameraLink
from .commands import Dispatcher
from .features import FEATURES, BridgeContext, Feature
from .features.cot import CotFeature
from .features.record import RecordFeature
from .ftp import FtpServer
from .node import Node
from .pointing import Pointer
from .services import Services
from .survey import survey_for

log = logging.getLogger("topgimbal.mavlink")

GREETING_GAP_S = 0.1  # HEARTBEATs sent early for new peers come at most this often
MAV_STATE_BOOT, MAV_STATE_ACTIVE, MAV_STATE_CRITICAL = 1, 4, 5


class Bridge:
    def __init__(self, config: BridgeConfig, node: Node | None = None) -> None:
        """`node`: a MAVLink node shared with other bridges (multi.py: N cameras on one set of
        links), started and closed by its owner; None: this bridge's own, from `endpoints`."""
        config.check(need_endpoints=node is None)
        self.config = config
        c = config
        self.cam = CameraLink(
            c.url, c.model, stream_hz=c.stream_hz, silence_s=c.silence_s, timeout_s=c.timeout_s,
            retries=c.retries, client_options=c.client_options,
        )  # fmt: skip
        self._own_node = node is None
        self.node = (
            node
            if node is not None
            else Node(c.sysid, list(c.endpoints), max_peers=c.max_peers, signing_key=c.signing_key)
        )
        self.dispatcher = Dispatcher()
        self.identity: dict[str, Any] = {}
        own = {c.compid} | ({c.camera_compid, c.camera_compid + 1} if c.camera_compid is not None else set())
        self.vehicles = Vehicles(c.sysid, own)
        self.pointer = Pointer(self.cam, self.vehicles)
        gimbal = build_gimbal(c, self.node, self.dispatcher, self.cam, self.pointer, self.vehicles, self.identity)
        gcomp, self.device, self.manager = gimbal.services.comp, gimbal.device, gimbal.manager
        cams = build_cameras(c, self.node, self.dispatcher, self.cam, self.vehicles, self.identity)
        self.cameras, self.video_pushes = cams.cameras, cams.pushes  # --video-out: started and stopped with us
        self.services: list[Services] = [gimbal.services, *cams.services]
        self.survey = survey_for(self.dispatcher, self.cameras, self.pointer, self.vehicles)  # OBLIQUE_SURVEY
        # The attached features (features/: terrain, CoT, the KLV recorder), each asked for by its config
        self.features: list[Feature] = [f for f in (spec.make(c) for spec in FEATURES) if f is not None]
        ctx = BridgeContext(c.sysid, c.model, self.node, self.dispatcher, self.vehicles, self.cameras)
        for feature in self.features:
            feature.attach(ctx)
        self.reboots = RebootWatch(self._peer_rebooted)
        self.feed = CameraFeed(self.cam, self.vehicles, c.sysid, own)  # position, attitude, time to the camera
        self.streams = AutopilotStreams(gcomp, c.sysid, own)  # what the photos need, asked on our link
        p = self.cam.profile
        self.definitions: DefinitionServer | None = None
        self.definition_files = {file_name(p.model, c.lens): render(p.dialect, p.model, c.lens) for c in self.cameras}
        self._wire()
        self.cam.on_health(self._on_health)
        for svc in self.services:
            svc.system_status = MAV_STATE_BOOT  # until the camera has answered (or is declared down)
        self._tasks: list[asyncio.Task[None]] = []
        self._closed = asyncio.Event()
        self._new_peer = asyncio.Event()
        self.node.on_new_peer(self._greet)
        self.started = False

    def _wire(self) -> None:
        """Each part on the messages it reads (node.on, by name), the feed's hooks on the cameras,
        the definitions over MAVLink FTP (QGC's form) unless served over HTTP (_serve_definitions)."""
        node, p = self.node, self.cam.profile
        node.on(RebootWatch.MESSAGES, lambda m: self.reboots.on_message(m, monotonic()))
        node.on_peer_gone(self.reboots.on_peer_gone)
        parts: list[Any] = [self.vehicles, self.feed, self.streams, self.dispatcher, self.device]
        parts += [self.manager] if self.manager is not None else []
        for part in parts:
            node.on(part.MESSAGES, part.on_message)
        for cam in self.cameras:
            cam.utc_at = self.feed.autopilot.utc_at
            cam.before_photo = self.feed.before_photo
            cam.after_photo = self.feed.photo_taken
            ftp = FtpServer(cam.comp, self.definition_files)
            for part in (cam.params, ftp):
                node.on(part.MESSAGES, part.on_message)
            cam.definition_uri = f"mftp://[;comp={cam.comp.compid}]/{file_name(p.model, cam.lens)}"

    @property
    def cot(self) -> CotSender | None:
        """The CoT sender (`cot`), None when not asked for or with no camera to send of."""
        return next((f.sender for f in self.features if isinstance(f, CotFeature)), None)

    @property
    def recorder(self) -> Recorder | None:
        """The KLV recorder (`record`), None when not asked for."""
        return next((f.recorder for f in self.features if isinstance(f, RecordFeature)), None)

    @property
    def addresses(self) -> list[tuple[str, int] | None]:
        """Local addresses of the links (listening links bound to port 0 resolved)."""
        return [link.address for link in self.node.links]

    async def start(self, camera_wait_s: float = 2.0) -> Bridge:
        if self._own_node:
            await self.node.start()
        await self._serve_definitions()
        await self.cam.start(wait_s=camera_wait_s)
        for push in self.video_pushes:
            push.start()
        self.pointer.start()
        self.device.start()
        self.feed.start()
        if self.config.request_streams:
            self.streams.start()
        for cam in self.cameras:
            cam.start()
        for svc in self.services:
            svc.start()
        self._tasks.append(asyncio.ensure_future(self._heartbeats()))
        self._tasks.append(asyncio.ensure_future(self._identify()))
        for feature in self.features:
            await feature.start()
        self.started = True
        links = ", ".join(str(link) for link in self.node.links)
        log.info("MAVLink bridge for %s (%s) on %s as system %d, role %s", self.config.url, self.config.model, links,
                 self.config.sysid, self.config.role)  # fmt: skip
        return self

    async def close(self) -> None:
        await stop_tasks(self._tasks, "mavlink bridge")  # bounded: a close always returns
        await self.dispatcher.close()
        for feature in reversed(self.features):
            await feature.stop()
        for part in [p for p in (self.manager, self.survey) if p is not None]:
            await part.close()
        for cam in self.cameras:
            await cam.close()
        for svc in self.services:
            await svc.close()
        await self.feed.close()
        await self.streams.close()
        await self.device.close()
        await self.pointer.close()
        for push in self.video_pushes:
            await asyncio.to_thread(push.stop)
        await self.cam.close()
        if self._own_node:
            await self.node.close()
        if self.definitions is not None:
            await self.definitions.close()
        self._closed.set()

    async def __aenter__(self) -> Bridge:
        return await self.start()

    async def __aexit__(self, *exc: object) -> None:
        await self.close()

    async def wait_closed(self) -> None:
        await self._closed.wait()

    def info(self) -> dict[str, Any]:
        """What the camera is fed and from where: each autopilot message the photos need (source,
        age in seconds, stale, asked for), where each feed comes from (position, attitude, heading,
        time: message, source, rate, age, or why none) and what the camera link feeds the camera now."""
        client = self.cam.client
        return {
            "autopilot": self.streams.status(),
            "feeds": self.streams.feeds(),
            "camera_feeds": client.feeds.summary() if client is not None else "no camera link",
            "reboots_noticed": self.reboots.reboots,
        }

    def _peer_rebooted(self, sysid: int, why: str) -> None:
        self.dispatcher.forget_system(sysid)
        self.streams.asked.clear()  # a rebooted autopilot forgot the rates we asked for: ask at once
        for cam in self.cameras:
            cam.forget_sequences(sysid)

    async def _serve_definitions(self) -> None:
        """The camera definitions over HTTP; each camera's CAMERA_INFORMATION gives its URI."""
        address = self.config.definition_address()
        if address is None or not self.cameras:
            return
        p = self.cam.profile
        self.definitions = DefinitionServer(self.definition_files, *address)
        await self.definitions.start()
        link_hosts = [parse_endpoint(e).host for e in self.config.endpoints]
        advertiser = Advertiser(address[0], self.config.definition_host, link_hosts)
        server = self.definitions
        # one download at a time: MAVSDK 4.1 deadlocks on a CAMERA_INFORMATION during one (pacing.py)
        pacer = None
        if self.config.definition_one_at_a_time:
            if self.node.definition_pacer is None:
                self.node.definition_pacer = FetchPacer()
            pacer = self.node.definition_pacer
            pacer.add(server)
        for c in self.cameras:
            c.definition_pacer = pacer
            name = file_name(p.model, c.lens)
            c.definition_uri = server.uri(name, advertiser.fixed)
            # bound to all interfaces: the address that reaches whoever asks
            c.definition_uri_for = lambda where, name=name: server.uri(name, advertiser.host_for(where))

    def _on_health(self, answering: bool) -> None:
        for svc in self.services:
            svc.system_status = MAV_STATE_ACTIVE if answering else MAV_STATE_CRITICAL
        if answering:
            self._tasks.append(asyncio.ensure_future(self._identify()))
            self._tasks = [t for t in self._tasks if not t.done()]

    def _greet(self, link: object, peer: object) -> None:
        self._new_peer.set()

    async def _heartbeats(self) -> None:
        """Every component's HEARTBEAT at heartbeat_hz, and at once when a new peer is heard (a
        ground station discovers us without waiting up to a period); early beats at most every
        GREETING_GAP_S, so a flood of new peers cannot multiply the traffic."""
        period_s = 1.0 / self.config.heartbeat_hz
        gap_s = min(GREETING_GAP_S, period_s)
        while True:
            for svc in self.services:
                svc.comp.send(svc.heartbeat())
            await asyncio.sleep(gap_s)
            if self._new_peer.is_set():  # heard during the gap: greet now
                self._new_peer.clear()
                continue
            with contextlib.suppress(asyncio.TimeoutError):
                await within(self._new_peer.wait(), period_s - gap_s)
            self._new_peer.clear()

    async def _identify(self) -> None:
        """Version and model name for the information messages (asked again after a reconnect)."""
        for _ in range(5):
            client = self.cam.client
            if client is not None and self.cam.answering:
                with contextlib.suppress(TopGimbalError, OSError, asyncio.TimeoutError):
                    info = await client.identify(timeout_s=self.config.timeout_s)
                    if info.get("version"):
                        self.identity["version"] = info["version"]
                    if info.get("model_name"):
                        self.identity["model_name"] = info["model_name"]
                    return
            await asyncio.sleep(1.0)
