"""Requests: a built frame handed to the engine, the connection's policy for it (retries, echoes,
acknowledgement rules, slow answers; the options as attributes), and errors that say why (a silent
device, a wrong model); the frames the catalog builds (`spec`, `build`) and the link's state as the
API reports it (`connected`, `link_state`, `busy`). A part of the client core (`ClientCore`
inherits it); kept apart so each module has one job."""

from __future__ import annotations

import asyncio
import copy
from collections.abc import Mapping

from ..errors import DecodeError, DeviceError, LinkLostError, TopGimbalError, TransportError
from ..protocol import CommandSpec, DeviceModel, Dialect, Frame, Message
from ..transport import Transport
from . import identity
from .builder import FrameBuilder
from .engine import Engine, Transaction
from .link import LinkMonitor
from .model_check import ModelChecker
from .options import Behaviour, ClientOptions


class Requests:
    """The request half of `ClientCore` (its attributes are the core's)."""

    url: str
    dialect: Dialect
    model: DeviceModel
    behaviour: Behaviour
    options: ClientOptions
    timeout_s: float
    retries: int
    closed: bool
    link: LinkMonitor | None
    identity: ModelChecker
    _engine: Engine | None
    _loop: asyncio.AbstractEventLoop | None
    _transport: Transport | None
    _builder: FrameBuilder

    def _drive(self) -> None:
        raise NotImplementedError

    # -- options as attributes (stable API) -------------------------------------------------------

    @property
    def stop_repeats(self) -> int:
        return self.behaviour.stop_repeats

    @property
    def combined_motion(self) -> bool:
        return self.behaviour.combined

    @property
    def link_timeout_s(self) -> float:
        return self.options.link_timeout_s

    @property
    def event_loop(self) -> asyncio.AbstractEventLoop | None:
        """The loop the client was opened on (None before open)."""
        return self._loop

    @property
    def connected_transport(self) -> bool:
        return not self.closed and self._transport is not None and self._transport.connected

    @property
    def connected(self) -> bool:
        """True while the transport is open and the device has not gone quiet."""
        return self.connected_transport and (self.link is None or self.link.up)

    @property
    def link_up(self) -> bool:
        return self.connected

    @property
    def link_state(self) -> dict[str, bool | str | float | None]:
        """`{"up", "reason", "silent_s"}`: why the link is down, how long nothing has come."""
        link = self.link
        silent = None if link is None or link.last_in is None else round(link.silent_for(), 3)
        reason = "" if self.connected else (link.reason if link is not None and link.reason else "closed")
        return {"up": self.connected, "reason": reason, "silent_s": silent}

    @property
    def datagram(self) -> bool:
        """UDP (and memory://): no connection, so the device may forget this peer."""
        return self._transport is not None and self._transport.is_datagram

    @property
    def busy(self) -> bool:
        """A request the device should answer soon is in flight (slow queries do not count)."""
        return self._engine is not None and any(not tx.slow for tx in self._engine.live.values())

    def send_nowait(self, frame: Frame, *, background: bool = False) -> None:
        """Send without waiting for an answer (in the engine's order and pacing; `background`: a
        periodic feed, which other frames may pass while they wait for their turn)."""
        self._check_usable(frame)
        assert self._engine is not None
        self._engine.submit(frame, timeout_s=self.timeout_s, expect_reply=False, background=background)
        self._drive()

    async def send_request(
        self,
        frame: Frame,
        *,
        timeout_s: float | None = None,
        retries: int | None = None,
        wait_reply: bool | None = None,
    ) -> Message:
        """A built request with this connection's policy: retried only when idempotent, awaited
        where the model acknowledges it, compared with its acknowledgement as the profile says.
        Returns the answer (API convention), or a reply-less Message when none is awaited."""
        spec = self.dialect.command(frame.ident)
        read = frame.rw == "r"
        if wait_reply is None:
            wait_reply = read or self.behaviour.expects_echo(spec)
        exclusive = not spec.is_idempotent(frame)  # sent once (and waits as long in all)
        reply = await self.transact(
            frame,
            timeout_s=self.timeout_s if timeout_s is None else float(timeout_s),
            retries=self.retries if retries is None else retries,
            expect_reply=wait_reply,
            exclusive=exclusive,
            fields=self.dialect.decode(frame).fields if frame.ident in self.model.echo_rules else None,
            slow=read and self.behaviour.is_slow(spec),
        )
        if reply is None:
            return Message(frame, spec, None, None, "sent without waiting for a reply")
        return reply  # already in the API convention (mapped on arrival)

    def _check_usable(self, frame: Frame | None = None) -> None:
        """Raise (with `frame` as the error's request) when nothing can be sent now."""
        if self.closed:
            raise TransportError(f"{self.url}: the client is closed", request=frame)
        if self._engine is None or self._loop is None:
            raise TransportError(f"{self.url}: not open (await connect(...) first)", request=frame)
        if not self.connected_transport:
            reason = self.link_state["reason"]
            raise LinkLostError(f"{self.url}: the link is down ({reason}); reconnecting", request=frame)

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
    ) -> Message | None:
        """Hand one frame to the engine and wait for what it decides."""
        self._check_usable(frame)
        engine, loop = self._engine, self._loop
        assert engine is not None and loop is not None
        tx: Transaction = engine.submit(
            frame,
            timeout_s=timeout_s,
            retries=retries,
            expect_reply=expect_reply,
            exclusive=exclusive,
            fields=fields,
            slow=slow,
            lenient=lenient,
        )
        if not expect_reply:
            self._drive()
            return None
        tx.waiter = fut = loop.create_future()
        self._drive()
        try:
            return await fut
        except asyncio.CancelledError:
            engine.cancel(tx)
            self._drive()
            raise
        except TopGimbalError as exc:
            raise self._explained(exc, timeout_s) from None

    _request = transact  # its older name (client modules, tests)

    def _explained(self, exc: TopGimbalError, timeout_s: float) -> TopGimbalError:
        """The error with what the client knows about why: a silent device, a wrong model."""
        text = str(exc)
        link = self.link
        if isinstance(exc, TimeoutError) and link is not None:
            if link.last_in is None:
                text += (
                    f"; nothing at all has come from {self.url} since the client opened: check the address, "
                    f"the model (--model / model=, now {self.model.name}) and that the camera is on"
                )
            elif (silent := link.silent_for()) >= timeout_s:
                text += f"; nothing has come from the device for {silent:.1f} s"
        verdict = self.identity.verdict
        if isinstance(exc, (TimeoutError, DeviceError)) and verdict.status == identity.MISMATCH:
            text += f"; {verdict.message}"
        elif isinstance(exc, DeviceError) and not isinstance(exc, DecodeError):
            text += model_hint(self.model.name)
        if text == str(exc):
            return exc
        new = copy.copy(exc)  # keeps `request` (and a DecodeError's `answer`)
        new.args = (text,)
        return new

    # -- frames from the catalog ----------------------------------------------------------------

    def commands(self) -> list[CommandSpec]:
        """The catalog commands this model supports."""
        return self.dialect.supported(self.model)

    def spec(self, ident: str) -> CommandSpec:
        """The catalog command `ident` (identifier or name), if this model supports it."""
        return self._builder.spec(ident)

    def build(self, ident: str, *, read: bool = False, dst: str | None = None, **values: object) -> Frame:
        """The frame `request()` would send (values in API units and signs), validated."""
        return self._builder.build(ident, values, read=read, dst=dst)

    def build_from(
        self, ident: str, values: Mapping[str, object], *, read: bool = False, dst: str | None = None
    ) -> Frame:
        """`build()` with the values in a mapping."""
        return self._builder.build(ident, values, read=read, dst=dst)


def model_hint(model: str) -> str:
    """What a refusal adds while the device's model is not known to be wrong."""
    return f"; if the device is not a {model}, pass the right --model (connect(model=...))"
