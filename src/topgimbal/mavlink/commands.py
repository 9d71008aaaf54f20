"""COMMAND_LONG / COMMAND_INT in, exactly one true COMMAND_ACK out.

A handler is a coroutine that does the work through the camera client and returns only when
the camera confirmed it (the client raises otherwise). The dispatcher turns what happened into
the MAVLink result: returned -> ACCEPTED; the handler's own refusal -> DENIED / UNSUPPORTED /
TEMPORARILY_REJECTED; the camera's error frame, a timeout or a lost link -> FAILED, with
`result_param2` saying which (and a STATUSTEXT with the camera's words). A handler still running
after `progress_after_s` gets MAV_RESULT_IN_PROGRESS acks (every second) until it ends.

Retransmissions (same sender, message type, command and parameters; COMMAND_LONG
`confirmation` > 0, see `Command.retransmits`) never act twice: one in progress is answered
IN_PROGRESS, one just finished gets its final ack again.
Work in flight and remembered results are bounded: in total and per peer (fairness.py), and
commands registered `local` (no camera traffic) are answered whatever the load."""

from __future__ import annotations

import asyncio
import logging
from collections import OrderedDict
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from ..clock import monotonic
from ..errors import (
    DeviceError,
    FieldValueError,
    ModelMismatchError,
    RequestTimeoutError,
    TransportError,
    UnsupportedError,
)
from ..links.mav import mavlink
from ..logthrottle import ThrottledLog
from ..timeouts import stop_tasks
from .command import (
    ACCEPTED,
    BRIDGE_ERROR,
    CAMERA_ERROR,
    CAMERA_LINK_DOWN,
    CAMERA_TIMEOUT,
    CAMERA_WRONG_MODEL,
    CANCELLED,
    DENIED,
    FAILED,
    IN_PROGRESS,
    RESULT_NAMES,
    TEMPORARILY_REJECTED,
    UNSUPPORTED,
    Accepts,
    Command,
    CommandRefusedError,
    Handler,
    Outcome,
    denied,
    rejected,
    unsupported,
)
from .fairness import MAX_INFLIGHT, MAX_INFLIGHT_PER_PEER, RESERVED_FOR_IDLE_PEERS, InflightLimits
from .node import Component
from .statustext import send_statustext

if TYPE_CHECKING:
    from ..links.mav import MAVLinkMessage

log = logging.getLogger("topgimbal.mavlink")

REMEMBER_RESULTS = 128
RETRANSMIT_WINDOW_S = 3.0
BUSY_LOG_EVERY_S = 10.0  # a flood of commands is one warning per this period, not one per command
WRONG_MODEL_LOG_EVERY_S = 10.0  # commands refused because the camera is another model: one line per period


@dataclass
class _Done:
    t: float
    result: int
    param2: int
    confirmation: int = 0


class Dispatcher:
    MESSAGES: tuple[str, ...] = ("COMMAND_LONG", "COMMAND_INT")  # what on_message reads (node.on)

    def __init__(
        self,
        *,
        progress_after_s: float = 0.25,
        progress_every_s: float = 1.0,
        timeout_s: float = 30.0,
        max_inflight: int = MAX_INFLIGHT,
    ) -> None:
        self.progress_after_s = progress_after_s
        self.progress_every_s = progress_every_s
        self.timeout_s = timeout_s
        self.max_inflight = max_inflight
        # Per-peer bounds scaled to a smaller total (tests); the defaults are fairness.py's.
        self.limits = InflightLimits(
            max_inflight,
            min(MAX_INFLIGHT_PER_PEER, max_inflight),
            RESERVED_FOR_IDLE_PEERS * max_inflight // MAX_INFLIGHT,
        )
        self._local: dict[tuple[int, int], Accepts] = {}
        self._handlers: dict[tuple[int, int], Handler] = {}
        self._accepts: dict[tuple[int, int], Accepts] = {}
        self._components: dict[int, Component] = {}
        self._inflight: dict[tuple[Any, ...], asyncio.Task[None]] = {}
        self._done: OrderedDict[tuple[Any, ...], _Done] = OrderedDict()
        self.counts: dict[str, int] = {}
        self.busy_rejected = 0  # commands refused because max_inflight were running
        self.busy_log = ThrottledLog(log, BUSY_LOG_EVERY_S)
        self.refusal_log = ThrottledLog(log, WRONG_MODEL_LOG_EVERY_S)

    def register(
        self,
        component: Component,
        command: int,
        handler: Handler,
        *,
        accepts: Accepts | None = None,
        local: bool | Accepts = False,
    ) -> None:
        """`accepts`: for a broadcast (target component 0), whether this component answers this
        command at all (REQUEST_MESSAGE for a message the component does not send: stay quiet).
        `local` (or a predicate on the command): the handler needs no camera traffic; it takes no
        in-flight place and is answered whatever the load."""
        self._components[component.compid] = component
        self._handlers[(component.compid, command)] = handler
        if local:
            self._local[(component.compid, command)] = local if callable(local) else (lambda _c: True)
        if accepts is not None:
            self._accepts[(component.compid, command)] = accepts

    def add_component(self, component: Component) -> None:
        self._components[component.compid] = component

    def handles(self, compid: int, command: int) -> bool:
        return (compid, command) in self._handlers

    def on_message(self, m: MAVLinkMessage) -> None:
        if m.get_type() not in ("COMMAND_LONG", "COMMAND_INT"):
            return
        cmd = Command.from_message(m)
        comp_any = next(iter(self._components.values()), None)
        if comp_any is None or cmd.target_system not in (0, comp_any.sysid):
            return
        if cmd.target_component == 0:
            # Broadcast: only components that handle the command answer (no chorus of UNSUPPORTED).
            targets = [c for c in self._components.values() if self._answers_broadcast(c.compid, cmd)]
        else:
            c = self._components.get(cmd.target_component)
            targets = [c] if c is not None else []
        for comp in targets:
            self._accept(comp, Command(**{**cmd.__dict__, "target_component": comp.compid}))

    def _answers_broadcast(self, compid: int, cmd: Command) -> bool:
        if not self.handles(compid, cmd.command):
            return False
        accepts = self._accepts.get((compid, cmd.command))
        return accepts is None or accepts(cmd)

    def _accept(self, comp: Component, cmd: Command) -> None:
        key = cmd.key()
        if key in self._inflight:
            self._ack(comp, cmd, IN_PROGRESS, progress=255)
            return
        now = monotonic()
        self._forget_old(now)
        done = self._done.get(key)
        if done is not None and cmd.retransmits(done.confirmation):
            done.confirmation = max(done.confirmation, cmd.confirmation)
            self._ack(comp, cmd, done.result, param2=done.param2)  # a retransmission: the same answer
            return
        handler = self._handlers.get((comp.compid, cmd.command))
        if handler is None:
            self._finish(comp, cmd, Outcome(UNSUPPORTED))
            return
        peer = cmd.peer if cmd.peer is not None else (cmd.src_system, cmd.src_component)
        is_local = self._local.get((comp.compid, cmd.command))
        local = is_local is not None and is_local(cmd)
        if not local:
            why = self.limits.refusal(peer)
            if why is not None:
                self._busy(cmd, why)
                self._ack(comp, cmd, TEMPORARILY_REJECTED)
                return
            self.limits.take(peer)
        task = asyncio.ensure_future(self._run(comp, cmd, handler))
        self._inflight[key] = task

        def ended(_t: asyncio.Task[None]) -> None:
            self._inflight.pop(key, None)
            if not local:
                self.limits.give_back(peer)

        task.add_done_callback(ended)

    def _busy(self, cmd: Command, why: str = "") -> None:
        self.busy_rejected += 1
        left_out = self.busy_log.allow("busy")
        if left_out is None:
            return
        since = left_out + 1  # this one too
        log.warning("%s: command %d from %d/%d (%s) TEMPORARILY_REJECTED "
                    "(%d rejected since the last such line, %d in all)", why, cmd.command,
                    cmd.src_system, cmd.src_component, _peer_text(cmd.peer), since, self.busy_rejected)  # fmt: skip

    async def _run(self, comp: Component, cmd: Command, handler: Handler) -> None:
        work = asyncio.ensure_future(handler(cmd))
        progress_at = self.progress_after_s
        deadline = monotonic() + self.timeout_s
        try:
            while True:
                done, _ = await asyncio.wait({work}, timeout=progress_at)
                if done:
                    break
                if monotonic() >= deadline:
                    work.cancel()
                    break
                self._ack(comp, cmd, IN_PROGRESS, progress=255)
                progress_at = self.progress_every_s
            outcome = self._outcome(cmd, work)
        except asyncio.CancelledError:
            work.cancel()
            raise
        self._finish(comp, cmd, outcome)

    def _outcome(self, cmd: Command, work: asyncio.Future[Outcome | None]) -> Outcome:
        # not done: cancelled at the deadline just now (a task is cancelled only once it runs again;
        # asking it for its exception then raised InvalidStateError: no final ack, the place kept)
        if work.cancelled() or not work.done():
            return Outcome(FAILED, BRIDGE_ERROR, text=f"command {cmd.command} took longer than {self.timeout_s:g} s")
        exc = work.exception()
        if exc is None:
            return work.result() or Outcome()
        if isinstance(exc, CommandRefusedError):
            return Outcome(exc.result, text=str(exc))
        if isinstance(exc, UnsupportedError):
            return Outcome(UNSUPPORTED, text=str(exc))
        if isinstance(exc, FieldValueError):
            return Outcome(DENIED, text=str(exc))
        if isinstance(exc, DeviceError):
            return Outcome(FAILED, CAMERA_ERROR, text=f"camera refused: {exc}")
        if isinstance(exc, RequestTimeoutError):
            return Outcome(FAILED, CAMERA_TIMEOUT, text=f"camera did not answer: {exc}")
        if isinstance(exc, TransportError):
            return Outcome(FAILED, CAMERA_LINK_DOWN, text=f"camera link down: {exc}")
        if isinstance(exc, ModelMismatchError):
            # Expected, not a fault of the bridge: the camera is another model than declared (it
            # was logged once as an error when found). One throttled line, no traceback.
            self.refusal_log.warning("wrong_model", "command %d from %d/%d refused: %s", cmd.command, cmd.src_system,
                                     cmd.src_component, exc)  # fmt: skip
            return Outcome(FAILED, CAMERA_WRONG_MODEL, text=str(exc), logged=True)
        log.error("command %d failed in the bridge", cmd.command, exc_info=exc)
        return Outcome(FAILED, BRIDGE_ERROR, text=f"bridge error: {type(exc).__name__}: {exc}")

    def _finish(self, comp: Component, cmd: Command, outcome: Outcome) -> None:
        self._ack(comp, cmd, outcome.result, param2=outcome.param2)
        name = RESULT_NAMES.get(outcome.result, str(outcome.result))
        self.counts[name] = self.counts.get(name, 0) + 1
        if outcome.text and outcome.result != ACCEPTED:
            if not outcome.logged:
                log.info("command %d from %d/%d to %s: %s (%s)", cmd.command, cmd.src_system, cmd.src_component,
                         comp.name, name, outcome.text)  # fmt: skip
            if outcome.result == FAILED:  # the command first: what failed, then why
                statustext(comp, f"{command_name(cmd.command)} failed: {outcome.text}", severity=3)
        self._done[cmd.key()] = _Done(monotonic(), outcome.result, outcome.param2, cmd.confirmation)
        while len(self._done) > REMEMBER_RESULTS:
            self._done.popitem(last=False)
        for msg in outcome.after:
            comp.send(msg)

    def forget_system(self, sysid: int) -> None:
        """A system rebooted (reboots.py): its next commands are new orders, not retransmissions
        of what it sent before, even if identical (its capture sequence starts again at 1)."""
        for k in [k for k in self._done if k[0] == sysid]:
            del self._done[k]

    def _forget_old(self, now: float) -> None:
        while self._done:
            k, d = next(iter(self._done.items()))
            if now - d.t <= RETRANSMIT_WINDOW_S:
                break
            del self._done[k]

    def _ack(self, comp: Component, cmd: Command, result: int, *, progress: int = 0, param2: int = 0) -> None:
        comp.send(mavlink().MAVLink_command_ack_message(
            cmd.command, result, progress, param2, cmd.src_system, cmd.src_component))  # fmt: skip

    async def close(self) -> None:
        await stop_tasks(list(self._inflight.values()), "commands in flight")  # bounded


def _peer_text(peer: Any) -> str:
    if isinstance(peer, tuple) and len(peer) == 2:
        return f"{peer[0]} {peer[1]}"
    return str(peer) if peer is not None else "?"


def statustext(comp: Component, text: str, severity: int = 6) -> None:
    """A STATUSTEXT from `comp` (severity: 3 error, 4 warning, 6 info); text longer than 50 bytes
    goes as MAVLink 2 chunks (statustext.py)."""
    send_statustext(comp, text, severity)


def command_name(command: int) -> str:
    """MAV_CMD_IMAGE_START_CAPTURE -> "IMAGE_START_CAPTURE"; the number where pymavlink has no name."""
    entry = mavlink().enums.get("MAV_CMD", {}).get(command)
    name = getattr(entry, "name", "") or ""
    return name.removeprefix("MAV_CMD_") or f"command {command}"


# What handlers import from here (command.py has them): kept importable from this module.
__all__ = [
    "ACCEPTED", "BRIDGE_ERROR", "CAMERA_ERROR", "CAMERA_LINK_DOWN", "CAMERA_TIMEOUT", "CAMERA_WRONG_MODEL",
    "CANCELLED", "DENIED", "FAILED", "IN_PROGRESS", "RESULT_NAMES", "RETRANSMIT_WINDOW_S",
    "TEMPORARILY_REJECTED", "UNSUPPORTED", "Accepts", "Command", "CommandRefusedError", "Dispatcher", "Handler",
    "Outcome", "command_name", "denied", "rejected", "statustext", "unsupported",
]  # fmt: skip
