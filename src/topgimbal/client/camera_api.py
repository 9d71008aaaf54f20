"""`CameraAPI`: the asyncio client as a typing Protocol, for code that takes "a camera" (the web
console's hub and ops, test doubles) instead of an untyped object. `AsyncClient` provides it (mypy checks
that in aio.py); a fake needs only what its user calls."""

from __future__ import annotations

from collections.abc import AsyncIterator, Awaitable, Callable
from typing import Protocol

from ..protocol import DeviceModel, Dialect, Frame, Message
from .identity import Verdict
from .state import Attitude, SdCard, StateCache
from .stats import LinkStats


class CameraAPI(Protocol):
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

    # -- telemetry --
    def attitude(self, rate_hz: float = 50, *, abandon_after_s: float | None = None) -> AsyncIterator[Attitude]: ...
    async def get_attitude(self, *, earth: bool = False) -> Attitude: ...
    async def attitude_stream(self, rate_hz: float = 50) -> None: ...
    async def stop_attitude_stream(self) -> None: ...

    # -- any command --
    async def request(
        self,
        ident: str,
        *,
        read: bool = False,
        timeout_s: float | None = None,
        retries: int | None = None,
        wait_reply: bool | None = None,
        dst: str | None = None,
        **values: object,
    ) -> Message: ...
    async def send_raw(
        self, frame: Frame | str | bytes, *, wait_reply: bool = True, timeout_s: float | None = None
    ) -> Message | None: ...

    # -- motion --
    async def set_angles(
        self,
        yaw_deg: float | None = None,
        pitch_deg: float | None = None,
        roll_deg: float | None = None,
        *,
        speed_deg_s: float | None = None,
        frame: str = "body",
    ) -> None: ...
    async def rates(
        self,
        yaw_deg_s: float = 0,
        pitch_deg_s: float = 0,
        roll_deg_s: float = 0,
        *,
        wait_reply: bool | None = None,
        timeout_s: float | None = None,
        retries: int | None = None,
    ) -> None: ...
    async def stop(self) -> None: ...
    async def center(self) -> None: ...
    async def set_mode(self, mode: str) -> None: ...
    async def point(
        self,
        yaw_deg: float,
        pitch_deg: float,
        *,
        tolerance_deg: float = 0.5,
        timeout_s: float | None = None,
        speed_deg_s: float | None = None,
        poll_s: float = 0.05,
    ) -> Attitude: ...

    # -- camera --
    async def photo(self, **values: object) -> Message: ...
    async def start_recording(self) -> None: ...
    async def stop_recording(self) -> None: ...
    async def recording(self) -> bool: ...
    async def sd_card(self) -> SdCard: ...
    async def zoom(self, action_or_level: str | float) -> None: ...
    async def focus(self, action: str) -> None: ...
    async def version(self) -> str: ...
    async def identify(self, *, timeout_s: float | None = None) -> dict[str, str | None]: ...
    async def range(self, *, timeout_s: float | None = None) -> float | None: ...
    async def network(self) -> dict[str, str | None]: ...
    async def set_network(
        self, ip: str | None = None, gateway: str | None = None, dns: str | None = None, backup_dns: str | None = None
    ) -> None: ...
