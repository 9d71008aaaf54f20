"""What a bridge feature is given and what it must do.

The core (bridge.py) builds the node, the dispatcher, the gimbal and camera components; then each
feature asked for in the BridgeConfig is made by its spec's `make`, given a `BridgeContext` by
`attach` (while the bridge is constructed: a feature that cannot work raises a ValueError there,
before anything is sent), started after the components and stopped before them."""

from __future__ import annotations

import argparse
import logging
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Protocol

from ...errors import TopGimbalError

if TYPE_CHECKING:
    from ...autopilot.vehicle import Vehicles
    from ...outputs.cot_stream import CotTls
    from ...outputs.sighting import Sighting
    from ..camera import CameraComponent
    from ..commands import Dispatcher
    from ..node import Node


log = logging.getLogger("topgimbal.mavlink")


class FeatureConfigError(TopGimbalError, ValueError):
    """A feature cannot work with the bridge it is attached to (raised while the bridge is made)."""


class BridgeOptions(Protocol):
    """What features read of the bridge's configuration (BridgeConfig has these fields and more;
    features never import it, so the config can list and check them: bridge_config.py)."""

    sysid: int
    model: str
    video_urls: list[str] | None
    terrain: str | None
    cot: str | None
    cot_tls: CotTls | None
    cot_name: str | None
    record: str | None
    # the options of features without a field of their own: {feature name: its option value}, filled
    # by each spec's `from_args` on the CLI (a new feature needs no BridgeConfig field)
    features: Mapping[str, Any]


@dataclass(frozen=True)
class BridgeContext:
    """The core's parts a feature may use. `node.on(NAMES, handler)` for messages it reads,
    `dispatcher` for commands, `cameras` (the visible lens first), `vehicles` for where the
    vehicle is, and `sighting` (below) as the port outputs are fed through."""

    sysid: int
    model: str
    node: Node
    dispatcher: Dispatcher
    vehicles: Vehicles
    cameras: list[CameraComponent]

    def sighting(self) -> Callable[[], Sighting | None] | None:
        """Where the first camera looks, as a `Sighting` when called (None: no camera)."""
        if not self.cameras:
            return None
        view, urls = self.cameras[0].view, self.cameras[0].video_urls
        return lambda: view.sighting(urls[0] if urls else None)


class Feature(Protocol):
    name: str

    def attach(self, ctx: BridgeContext) -> None: ...

    async def start(self) -> None: ...

    async def stop(self) -> None: ...


class Output(Protocol):
    """An output fed the sighting port: it runs until cancelled and closes what it holds."""

    async def run(self) -> None: ...


class SightingOutput:
    """A feature that feeds the first camera's sighting port to an output (CoT, the sightings log):
    the output is built at attach (`build`, given the port), run as a task from start, and that task
    is stopped at stop, bounded. A bridge with no camera has no port: said once, nothing built."""

    name = "output"

    def __init__(self) -> None:
        self.output: Output | None = None
        self._tasks: list[Any] = []  # the output's run(): one asyncio.Task

    def build(self, ctx: BridgeContext, source: Callable[[], Sighting | None]) -> Output:
        raise NotImplementedError

    def attach(self, ctx: BridgeContext) -> None:
        source = ctx.sighting()
        if source is None:
            log.warning("%s: no camera component on this bridge: nothing to send", self.name)
            return
        self.output = self.build(ctx, source)

    async def start(self) -> None:
        import asyncio

        if self.output is not None:
            self._tasks.append(asyncio.ensure_future(self.output.run()))

    async def stop(self) -> None:
        from ...timeouts import stop_tasks

        await stop_tasks(self._tasks, self.name)


@dataclass(frozen=True)
class FeatureSpec:
    """`make(config)`: the feature, None when the config does not ask for it; `check(config)`:
    raises a ValueError for options it cannot use (BridgeConfig.check calls it, nothing started);
    `add_arguments(parser)`: its flags on `topgimbal mavlink`; `from_args(namespace)`: its option
    value from those flags (None: not asked for), kept in `BridgeConfig.features[name]`, for a
    feature that has no BridgeConfig field of its own."""

    name: str
    make: Callable[[BridgeOptions], Feature | None]
    check: Callable[[BridgeOptions], None]
    add_arguments: Callable[[argparse.ArgumentParser], None]
    from_args: Callable[[Any], Any] | None = None


def option(c: BridgeOptions, name: str) -> Any:
    """A feature's option in `c.features` (None: not asked for)."""
    return c.features.get(name)
