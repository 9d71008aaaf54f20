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
from dataclasses import dataclass, field
from typing import Any

from ..clock import monotonic
from ..errors import TopGimbalError
from ..outputs.cot import CotSender, check_config, cot_names
from ..outputs.cot_stream import CotTls
from ..outputs.klv_record import Recorder, check_directory
from ..outputs.rtp_out import VideoOutError, advertised, parse_targets
from ..timeouts import stop_tasks, within
from ..video.rtp_push import RtpPush
from .advertise import Advertiser
from .autopilot_streams import AutopilotStreams
from .camdef import file_name, render
from .camdef_http import DefinitionServer
from .camera import CameraComponent
from .camera_feed import CameraFeed
from .camera_link import CameraLink
from .commands import Dispatcher
from .endpoints import MAX_PEERS, parse_endpoint
from .ftp import FtpServer
from .gimbal_device import GimbalDevice
from .gimbal_manager import GimbalManager
from .node import Node
from .pointing import Pointer
from .reboots import RebootWatch
from .services import Services
from .survey import survey_for
from .vehicle import Vehicles

log = logging.getLogger("topgimbal.mavlink")

ROLES = ("device", "manager", "both")
GIMBAL_COMPIDS = (154, 171, 172, 173, 174, 175)  # MAV_COMP_ID_GIMBAL, GIMBAL2..6
CAMERA_COMPIDS = (100, 101, 102, 103, 104, 105)  # MAV_COMP_ID_CAMERA..CAMERA6
MAV_TYPE_GIMBAL, MAV_TYPE_CAMERA = 26, 30
NON_MAVLINK_GIMBAL_ID = 1
GREETING_GAP_S = 0.1  # HEARTBEATs sent early for new peers come at most this often
MAV_STATE_BOOT, MAV_STATE_ACTIVE, MAV_STATE_CRITICAL = 1, 4, 5


class BridgeConfigError(TopGimbalError, ValueError):
    pass


@dataclass
class BridgeConfig:
    url: str
    model: str
    endpoints: list[str]
    sysid: int = 1
    compid: int = 154
    camera_compid: int | None = 100  # None: no camera components
    thermal: bool = True  # a second camera component for the thermal lens, where the model has one
    role: str = "both"
    attitude_hz: float = 20.0
    stream_hz: float = 50.0
    heartbeat_hz: float = 1.0
    range_hz: float = 1.0
    video_urls: list[str] | None = None  # None: the model's streams at the camera's address
    video_port: int | None = None  # the first stream's RTSP port when not the profile's (others keep the spacing)
    video_out: list[str] | None = None  # "[LENS=]udp://HOST:PORT": the lens's stream pushed as RTP (rtp_out.py)
    media_url: str | None = None  # the camera's files over HTTP (sim --media-port): CAMERA_IMAGE_CAPTURED.file_url
    companion_tracking: bool = False  # track commands run topgimbal.track on a model without a tracker
    timeout_s: float = 1.0
    retries: int = 2
    silence_s: float = 3.0
    max_peers: int = MAX_PEERS
    signing_key: bytes | None = None  # MAVLink 2 signing (signing.py): sign all, accept only signed
    client_options: dict[str, Any] = field(default_factory=dict)
    definition_http: str | None = "127.0.0.1:0"  # HOST:PORT serving the camera definitions; None: not served
    terrain: str | None = None  # a GeoTIFF DEM: CAMERA_FOV_STATUS's image centre on it (else flat at home)
    cot: str | None = None  # udp:// tcp:// tls://HOST:PORT: Cursor-on-Target of what the camera looks at (cot.py)
    cot_tls: CotTls | None = None  # tls://: the client certificate, key and CA (cot_stream.py)
    cot_name: str | None = None  # the camera's name in its CoT uid/callsign (several cameras on one system)
    record: str | None = None  # DIR: the camera's video as MPEG-TS with MISB ST 0601 KLV (klv_record.py)

    definition_host: str | None = None  # the host written into the definition URI (advertise.py); None: found
    request_streams: bool = True  # ask the autopilot for GLOBAL_POSITION_INT and SYSTEM_TIME (autopilot_streams.py)

    def definition_address(self) -> tuple[str, int] | None:
        if not self.definition_http:
            return None
        host, sep, port = self.definition_http.rpartition(":")
        if not sep or not port.isdigit() or not 0 <= int(port) <= 65535:
            raise BridgeConfigError(f"definition_http={self.definition_http!r}: expected HOST:PORT (port 0..65535)")
        return host.strip("[]") or "127.0.0.1", int(port)

    def check(self, need_endpoints: bool = True) -> None:
        """`need_endpoints` False: the links come from elsewhere (a shared node's, zenoh_link.py)."""
        if need_endpoints and not self.endpoints:
            raise BridgeConfigError("at least one MAVLink endpoint is needed (--mavlink udpout:HOST:PORT)")
        for e in self.endpoints:
            parse_endpoint(e)
        if self.role not in ROLES:
            raise BridgeConfigError(f"role {self.role!r}: expected one of {', '.join(ROLES)}")
        if not 1 <= self.sysid <= 255:
            raise BridgeConfigError(f"system id {self.sysid}: expected 1..255")
        if self.compid not in GIMBAL_COMPIDS:
            raise BridgeConfigError(f"gimbal component id {self.compid}: expected one of {GIMBAL_COMPIDS}")
        allowed = CAMERA_COMPIDS[:-1] if self.thermal else CAMERA_COMPIDS  # the thermal lens takes the next id
        if self.camera_compid is not None and self.camera_compid not in allowed:
            raise BridgeConfigError(f"camera component id {self.camera_compid}: expected one of {allowed}")
        for name, lo, hi in (("attitude_hz", 0.0, 100.0), ("stream_hz", 1.0, 100.0), ("heartbeat_hz", 0.1, 10.0),
                             ("range_hz", 0.0, 10.0), ("silence_s", 0.2, 60.0), ("timeout_s", 0.05, 30.0)):  # fmt: skip
            v = getattr(self, name)
            if not lo <= v <= hi:
                raise BridgeConfigError(f"{name}={v:g}: expected {lo:g}..{hi:g}")
        if self.video_port is not None and not 1 <= self.video_port <= 65535:
            raise BridgeConfigError(f"video_port={self.video_port}: expected 1..65535")
        try:
            parse_targets(self.video_out)
        except VideoOutError as exc:
            raise BridgeConfigError(str(exc)) from None
        if self.signing_key is not None and len(self.signing_key) != 32:
            raise BridgeConfigError(f"signing_key: {len(self.signing_key)} bytes, expected 32")
        self.definition_address()
        if self.media_url is not None and not self.media_url.startswith(("http://", "https://")):
            raise BridgeConfigError(
                f"media_url {self.media_url!r}: expected http://HOST:PORT/ (sim --media-port prints it)"
            )
        if not 1 <= self.max_peers <= 256:
            raise BridgeConfigError(f"max_peers={self.max_peers}: expected 1..256")
        if self.record is not None:  # made and written to now (RecordDirError, a ValueError: exit 2)
            check_directory(self.record)
        check_config(self.cot, self.cot_tls, self.video_urls)  # CotConfigError: the target, its files, the URLs


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
        self.services: list[Services] = []
        gcomp = self.node.component(c.compid, "gimbal")
        gsvc = Services(gcomp, self.dispatcher, MAV_TYPE_GIMBAL)
        self.services.append(gsvc)
        device_id = 0 if c.role in ("device", "both") else NON_MAVLINK_GIMBAL_ID
        self.device = GimbalDevice(
            gsvc, self.cam, self.pointer, attitude_hz=c.attitude_hz, gimbal_device_id=device_id,
            accept_set_attitude=c.role != "manager", identity=self.identity,
        )  # fmt: skip
        self.manager: GimbalManager | None = None
        if c.role in ("manager", "both"):
            managed = c.compid if c.role == "both" else NON_MAVLINK_GIMBAL_ID
            self.manager = GimbalManager(gsvc, self.cam, self.pointer, self.vehicles, gimbal_device_id=managed)
        self.cameras: list[CameraComponent] = []
        self.video_pushes: list[RtpPush] = []  # --video-out: started and stopped with the bridge
        pushed = parse_targets(c.video_out)
        if pushed and c.camera_compid is None:
            raise BridgeConfigError(
                "video_out needs the camera components (it is advertised by them): drop --no-camera"
            )
        if c.camera_compid is not None:
            gimbal_ref = c.compid if c.role in ("device", "both") else NON_MAVLINK_GIMBAL_ID
            lenses = ["visible"] + (["thermal"] if c.thermal and self.cam.profile.thermal else [])
            by_lens = self.cam.profile.rtsp_urls(self.cam.camera_host, port=c.video_port)
            for i, lens in enumerate(lenses):
                comp = self.node.component(c.camera_compid + i, f"camera-{lens}")
                svc = Services(comp, self.dispatcher, MAV_TYPE_CAMERA)
                self.services.append(svc)
                if c.video_urls is not None:  # given: the first to the visible camera, the second to the thermal one
                    urls = c.video_urls
                    mine = urls if len(lenses) == 1 else urls[i : i + 1] if i < len(urls) else []
                else:
                    mine = [by_lens[lens]] if lens in by_lens else []
                if lens in pushed:
                    if not mine:
                        raise BridgeConfigError(
                            f"video_out: the {lens} lens has no RTSP stream to push (give --video-url)"
                        )
                    self.video_pushes.append(RtpPush(mine[0], pushed.pop(lens), name=lens))
                    mine = [*mine, advertised(self.video_pushes[-1].target_url)]
                self.cameras.append(CameraComponent(
                    svc, self.cam, self.vehicles, lens=lens, gimbal_device_id=gimbal_ref, video_urls=mine,
                    identity=self.identity, range_hz=c.range_hz, media_url=c.media_url,
                    companion_tracking=c.companion_tracking))  # fmt: skip
        if pushed:
            raise BridgeConfigError(
                f"video_out: no {', '.join(pushed)} camera on this bridge ({self.cam.profile.model})"
            )
        self.survey = survey_for(self.dispatcher, self.cameras, self.pointer, self.vehicles)  # OBLIQUE_SURVEY
        if c.terrain is not None:  # read once, shared by the cameras (DemError for a file it cannot use)
            from ..geo.dem import load_dem

            terrain = load_dem(c.terrain)
            for camera in self.cameras:
                camera.view.terrain = terrain
        self.cot: CotSender | None = None
        if c.cot is not None and self.cameras:
            view, urls = self.cameras[0].view, self.cameras[0].video_urls
            uid, callsign = cot_names(c.sysid, c.model, c.cot_name)
            self.cot = CotSender(c.cot, lambda: view.sighting(urls[0] if urls else None), uid=uid, callsign=callsign,
                                 tls=c.cot_tls)  # fmt: skip
        self.recorder: Recorder | None = None
        if c.record is not None:
            if not self.cameras or not self.cameras[0].video_urls:
                raise BridgeConfigError("--record needs the camera's video stream (a model with one, or --video-url)")
            self.recorder = Recorder(self.cameras[0].video_urls[0], c.record, self.cameras[0].view.klv_values)
        self.reboots = RebootWatch(self._peer_rebooted)
        self.node.subscribe(lambda m: self.reboots.on_message(m, monotonic()))

        self.node.on_peer_gone(self.reboots.on_peer_gone)
        self.node.subscribe(self.vehicles.on_message)
        self.feed = CameraFeed(self.cam, self.vehicles, c.sysid, own)  # position, attitude, time to the camera
        self.node.subscribe(self.feed.on_message)
        for cam in self.cameras:
            cam.utc_at = self.feed.autopilot.utc_at
            cam.before_photo = self.feed.before_photo
            cam.after_photo = self.feed.photo_taken
        self.streams = AutopilotStreams(gcomp, c.sysid, own)  # what the photos need, asked on our link
        self.node.subscribe(self.streams.on_message)
        self.node.subscribe(self.dispatcher.on_message)
        self.node.subscribe(self.device.on_message)
        if self.manager is not None:
            self.node.subscribe(self.manager.on_message)
        self.definitions: DefinitionServer | None = None
        p = self.cam.profile
        self.definition_files = {file_name(p.model, c.lens): render(p.dialect, p.model, c.lens) for c in self.cameras}
        for cam in self.cameras:
            self.node.subscribe(cam.params.on_message)
            self.node.subscribe(FtpServer(cam.comp, self.definition_files).on_message)
            # over MAVLink FTP (QGC's form) unless served over HTTP (_serve_definitions)
            cam.definition_uri = f"mftp://[;comp={cam.comp.compid}]/{file_name(p.model, cam.lens)}"
        self.cam.on_health(self._on_health)
        for svc in self.services:
            svc.system_status = MAV_STATE_BOOT  # until the camera has answered (or is declared down)
        self._tasks: list[asyncio.Task[None]] = []
        self._closed = asyncio.Event()
        self._new_peer = asyncio.Event()
        self.node.on_new_peer(self._greet)
        self.started = False

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
        if self.cot is not None:
            self._tasks.append(asyncio.ensure_future(self.cot.run()))
        if self.recorder is not None:
            self.recorder.start()
        self.started = True
        links = ", ".join(str(link) for link in self.node.links)
        log.info("MAVLink bridge for %s (%s) on %s as system %d, role %s", self.config.url, self.config.model, links,
                 self.config.sysid, self.config.role)  # fmt: skip
        return self

    async def close(self) -> None:
        await stop_tasks(self._tasks, "mavlink bridge")  # bounded: a close always returns
        await self.dispatcher.close()
        if self.recorder is not None:  # its thread finishes the file it writes (a few ms)
            await asyncio.to_thread(self.recorder.close)
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
        for c in self.cameras:
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
