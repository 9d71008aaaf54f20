"""The narrow ports of the client core: what each helper of `ClientCore` may read and call.

The core (core.py) owns its helpers: `ModelChecker` (model_check.py), `StreamControl` (streams.py)
and `LinkKeeper` (connection.py). Each gets the core typed as one of these Protocols, never as
`ClientCore`: a helper sees the few attributes it reads and the few calls it makes, imports
nothing of the core's (no import circle, even for type checking), and can be tested with a small
fake. Decisions that change the core's state go back through one call (`on_link_event`), as
aioesphomeapi's ReconnectLogic only uses its client's public API and the pure `Engine` and
`LinkMonitor` return what they decided. Which helper owns what: docs/architecture.md ("client/").
"""

from __future__ import annotations

import asyncio
from collections.abc import Mapping
from typing import Protocol

from ..protocol import DeviceModel, Dialect, Frame, Message
from ..transport import Transport, TransportURL
from .link import LinkEvent, LinkMonitor
from .options import ClientOptions
from .stats import LinkStats


class RequestPort(Protocol):
    """What every helper reads, and its one way to the device: a request through the engine."""

    @property
    def url(self) -> str: ...

    @property
    def dialect(self) -> Dialect: ...

    @property
    def model(self) -> DeviceModel: ...

    @property
    def timeout_s(self) -> float: ...

    @property
    def retries(self) -> int: ...

    @property
    def closed(self) -> bool: ...

    @property
    def connected(self) -> bool: ...

    def build(self, ident: str, *, read: bool = False, dst: str | None = None, **values: object) -> Frame: ...

    def build_from(
        self, ident: str, values: Mapping[str, object], *, read: bool = False, dst: str | None = None
    ) -> Frame: ...

    async def transact(
        self,
        frame: Frame,
        *,
        timeout_s: float,
        retries: int,
        expect_reply: bool = True,
        exclusive: bool = False,
        fields: Mapping[str, object] | None = None,
        slow: bool = False,
        lenient: bool = False,
    ) -> Message | None: ...


class ModelCheckPort(RequestPort, Protocol):
    """`ModelChecker` and `ask()`: also the host address (to ask other dialects) and the counters."""

    @property
    def host_address(self) -> str: ...

    @property
    def stats(self) -> LinkStats: ...


class StreamPort(RequestPort, Protocol):
    """`StreamControl`: also the options (stream renewal), the link kind, the event loop, and
    telling the engine whether stream frames are to be expected (samples, not copies)."""

    @property
    def options(self) -> ClientOptions: ...

    @property
    def datagram(self) -> bool: ...

    @property
    def event_loop(self) -> asyncio.AbstractEventLoop | None: ...

    def expect_stream(self, on: bool) -> None: ...


class KeeperPort(RequestPort, Protocol):
    """`LinkKeeper` (reconnection, pings): the link monitor, the transport's address and state, and
    the calls that hand its results back: the bytes of a reopened link, the new transport, a link
    transition, and "the device answers: resume its streams"."""

    @property
    def options(self) -> ClientOptions: ...

    @property
    def link(self) -> LinkMonitor | None: ...

    @property
    def transport_url(self) -> TransportURL: ...

    @property
    def busy(self) -> bool: ...

    @property
    def connected_transport(self) -> bool: ...

    def on_bytes(self, data: bytes) -> None: ...

    def reopened(self, transport: Transport) -> None: ...

    def on_link_event(self, event: LinkEvent) -> None: ...

    def resume_streams(self) -> None: ...
