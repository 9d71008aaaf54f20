"""`CameraAPI`: the asyncio client as a typing Protocol, for code that takes "a camera" (the web
console's hub and ops, test doubles) instead of an untyped object. `AsyncClient` provides it (mypy checks
that in aio.py); a fake needs only what its user calls.

The typed methods are not restated here: `CoreMethods`, `MotionMethods` and `CameraMethods` are
themselves Protocols whose members are the one definition of each method (api_*.py), which
`AsyncClient` and `Gimbal` inherit and this Protocol extends with the client's attributes."""

from __future__ import annotations

from collections.abc import AsyncIterator, Awaitable, Callable
from typing import Protocol

from ..protocol import DeviceModel, Dialect, Frame, Message
from .api_camera import CameraMethods
from .api_core import CoreMethods
from .api_feed import FeedMethods
from .api_motion import MotionMethods
from .identity import Verdict
from .state import GimbalAttitude, StateCache
from .stats import LinkStats


class CameraAPI(CoreMethods, MotionMethods, CameraMethods, FeedMethods, Protocol):
    url: str
    dialect: Dialect
    model: DeviceModel
    state: StateCache
    stats: LinkStats

    @property
    def connected(self) -> bool: ...
    @property
    def link_state(self) -> dict[str, bool | str | float | None]: ...
    @property
    def model_check(self) -> Verdict: ...
    def on_model_check(self, callback: Callable[[Verdict], object]) -> Callable[[], None]: ...

    # -- callbacks (each returns a function that removes it) --
    def subscribe(
        self, callback: Callable[[Message], Awaitable[None] | None], ident: str | None = None
    ) -> Callable[[], None]: ...
    def on_traffic(
        self, callback: Callable[[str, Frame, Message | None], Awaitable[None] | None]
    ) -> Callable[[], None]: ...
    def on_link_change(self, callback: Callable[[bool, str], Awaitable[None] | None]) -> Callable[[], None]: ...

    # -- telemetry: an iterator object, not a typed method --
    def attitude(
        self, rate_hz: float = 50, *, abandon_after_s: float | None = None
    ) -> AsyncIterator[GimbalAttitude]: ...
