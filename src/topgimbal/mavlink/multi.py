"""Several cameras behind one MAVLink bridge: one node (one set of links, one system id), one
`Bridge` per camera sharing it, each with its own component ids.

MAVLink numbers a system's gimbals and cameras: gimbal components 154 (MAV_COMP_ID_GIMBAL) and
171..175 (GIMBAL2..6), camera components 100..105 (CAMERA..CAMERA6). Camera i gets gimbal id
GIMBAL_COMPIDS[i]; its camera components take the next free camera ids in order (two where the model
has a thermal lens and thermal components are wanted, one otherwise). A fleet that needs more ids
than MAVLink has is refused with a message that says how many it needs; several vehicles are
several systems (one bridge each, its own --sysid).

    async with MultiBridge([("left", "udp://127.0.0.1:5000", "C12"), ("right", "udp://127.0.0.1:5001", "C12")],
                           endpoints=["udpin:127.0.0.1:14560"]) as multi:
        await multi.wait_closed()
"""

from __future__ import annotations

import asyncio
import contextlib
import dataclasses
import logging
from collections.abc import Sequence
from typing import Any

from ..links.endpoints import MAX_PEERS
from ..protocol import get_model
from .bridge import CAMERA_COMPIDS, GIMBAL_COMPIDS, Bridge, BridgeConfig, BridgeConfigError
from .node import LinkFactory, Node

log = logging.getLogger("topgimbal.mavlink")


@dataclasses.dataclass(frozen=True)
class Allocation:
    name: str
    url: str
    model: str
    gimbal_compid: int
    camera_compid: int | None
    thermal: bool

    @property
    def camera_compids(self) -> list[int]:
        if self.camera_compid is None:
            return []
        return [self.camera_compid] + ([self.camera_compid + 1] if self.thermal else [])


def allocate(
    cameras: Sequence[tuple[str, str, str]], *, cameras_wanted: bool = True, thermal: bool = True
) -> list[Allocation]:
    """Component ids for each (name, url, model), in order (pure; BridgeConfigError when short)."""
    if not cameras:
        raise BridgeConfigError("at least one camera")
    if len(cameras) > len(GIMBAL_COMPIDS):
        raise BridgeConfigError(
            f"{len(cameras)} cameras: one MAVLink system has {len(GIMBAL_COMPIDS)} gimbal component ids "
            f"({', '.join(map(str, GIMBAL_COMPIDS))}); run another bridge with its own --sysid for the rest"
        )
    out: list[Allocation] = []
    free = list(CAMERA_COMPIDS)
    for i, (name, url, model) in enumerate(cameras):
        cam_id: int | None = None
        two = False
        if cameras_wanted:
            two = thermal and get_model(model)[1].thermal
            need = 2 if two else 1
            if len(free) < need:
                wanted = sum(2 if thermal and get_model(m)[1].thermal else 1 for _, _, m in cameras)
                raise BridgeConfigError(
                    f"{len(cameras)} cameras need {wanted} camera component ids; MAVLink has {len(CAMERA_COMPIDS)} "
                    f"({CAMERA_COMPIDS[0]}..{CAMERA_COMPIDS[-1]}): use --no-thermal, --no-camera or fewer cameras"
                )
            cam_id = free[0]
            del free[:need]
        out.append(Allocation(name, url, model, GIMBAL_COMPIDS[i], cam_id, two))
    return out


class MultiBridge:
    """N cameras as N gimbal (+ camera) component sets of one MAVLink system on shared links.
    `link_factories`: links made elsewhere besides `endpoints` (zenoh_link.zenoh_link_factory: the
    BlueOS key shape on a Zenoh session; then `endpoints` may be empty). `common` holds the BridgeConfig fields every camera shares (role, rates, timeouts...)."""

    def __init__(
        self,
        cameras: Sequence[tuple[str, str, str]],
        *,
        endpoints: list[str],
        sysid: int = 1,
        cameras_wanted: bool = True,
        thermal: bool = True,
        max_peers: int = MAX_PEERS,
        link_factories: Sequence[LinkFactory] = (),
        per_camera: Sequence[dict[str, Any]] = (),
        **common: Any,
    ) -> None:
        """`per_camera`: BridgeConfig fields of each camera alone, in the order of `cameras`
        (its video: video_urls, video_port, video_out)."""
        self.allocations = allocate(cameras, cameras_wanted=cameras_wanted, thermal=thermal)
        if per_camera and len(per_camera) != len(cameras):
            raise BridgeConfigError(f"per_camera: {len(per_camera)} entries for {len(cameras)} cameras")
        own = list(per_camera) or [{} for _ in cameras]
        configs = [
            BridgeConfig(
                url=a.url,
                model=a.model,
                endpoints=list(endpoints),
                sysid=sysid,
                compid=a.gimbal_compid,
                camera_compid=a.camera_compid,
                thermal=a.thermal,
                max_peers=max_peers,
                **common,
                **mine,
            )
            for a, mine in zip(self.allocations, own, strict=True)
        ]
        for c in configs:
            c.check(need_endpoints=not link_factories)
        signing_key = configs[0].signing_key if configs else None
        self.node = Node(sysid, list(endpoints), max_peers=max_peers, signing_key=signing_key,
                         link_factories=link_factories)  # fmt: skip
        self.bridges = [Bridge(c, node=self.node) for c in configs]
        self._closed = asyncio.Event()

    @property
    def addresses(self) -> list[tuple[str, int] | None]:
        return [link.address for link in self.node.links]

    async def start(self, camera_wait_s: float = 2.0) -> MultiBridge:
        await self.node.start()
        try:
            # Cameras come up together: one silent camera delays the start by its wait only once.
            await asyncio.gather(*(b.start(camera_wait_s=camera_wait_s) for b in self.bridges))
        except BaseException:
            for b in self.bridges:
                with contextlib.suppress(Exception):
                    await b.close()
            await self.node.close()
            raise
        for a in self.allocations:
            log.info("%s (%s, %s): gimbal %d, cameras %s", a.name, a.url, a.model, a.gimbal_compid,
                     a.camera_compids or "none")  # fmt: skip
        return self

    async def close(self) -> None:
        for b in self.bridges:
            with contextlib.suppress(Exception):
                await b.close()
        await self.node.close()
        self._closed.set()

    async def __aenter__(self) -> MultiBridge:
        return await self.start()

    async def __aexit__(self, *exc: object) -> None:
        await self.close()

    async def wait_closed(self) -> None:
        await self._closed.wait()
