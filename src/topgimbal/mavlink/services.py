"""What every component of the bridge answers, whatever its role: its heartbeat,
MAV_CMD_REQUEST_MESSAGE (and the legacy request commands), and message intervals
(MAV_CMD_SET_MESSAGE_INTERVAL / GET_MESSAGE_INTERVAL) for the messages it streams.

Roles add *providers* (message id -> coroutine returning the messages to send after the ack;
it may ask the camera first) and *streams* (periodic messages with a default and a maximum rate).
Several roles may share one component (gimbal device + gimbal manager)."""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Awaitable, Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from ..links.mav import mav_id, mavlink, msg_id
from ..timeouts import stop_tasks
from .commands import Command, Dispatcher, Outcome, denied, unsupported
from .node import Component

if TYPE_CHECKING:
    from ..links.mav import MAVLinkMessage

log = logging.getLogger("topgimbal.mavlink")

Provider = Callable[[Command], Awaitable[list[Any]]]
Producer = Callable[[], "Any | None"]

MAV_CMD_REQUEST_MESSAGE = mav_id("MAV_CMD_REQUEST_MESSAGE")
MAV_CMD_SET_MESSAGE_INTERVAL = mav_id("MAV_CMD_SET_MESSAGE_INTERVAL")
MAV_CMD_GET_MESSAGE_INTERVAL = mav_id("MAV_CMD_GET_MESSAGE_INTERVAL")
MAV_AUTOPILOT_INVALID = mav_id("MAV_AUTOPILOT_INVALID")  # HEARTBEAT's autopilot: a component, not a vehicle
# Messages every component answers from what the bridge already knows (no camera traffic): a
# REQUEST_MESSAGE for one is answered whatever the command load (fairness.py).
LOCAL_MESSAGES = frozenset(
    msg_id(n)
    for n in ("CAMERA_INFORMATION", "GIMBAL_MANAGER_INFORMATION", "GIMBAL_MANAGER_STATUS", "GIMBAL_DEVICE_INFORMATION",
              "GIMBAL_DEVICE_ATTITUDE_STATUS")
)  # fmt: skip
MAX_MESSAGE_ID = 2**24 - 1  # MAVLink 2 message ids are 24 bits
# Legacy request commands -> (message id, which parameter carries the message's index).
LEGACY_REQUESTS: dict[int, tuple[int, int | None]] = {
    mav_id("MAV_CMD_REQUEST_CAMERA_INFORMATION"): (msg_id("CAMERA_INFORMATION"), None),
    mav_id("MAV_CMD_REQUEST_CAMERA_SETTINGS"): (msg_id("CAMERA_SETTINGS"), None),
    mav_id("MAV_CMD_REQUEST_STORAGE_INFORMATION"): (msg_id("STORAGE_INFORMATION"), None),
    mav_id("MAV_CMD_REQUEST_CAMERA_CAPTURE_STATUS"): (msg_id("CAMERA_CAPTURE_STATUS"), None),
    mav_id("MAV_CMD_REQUEST_CAMERA_IMAGE_CAPTURE"): (msg_id("CAMERA_IMAGE_CAPTURED"), 1),  # param1: image index
    mav_id("MAV_CMD_REQUEST_VIDEO_STREAM_INFORMATION"): (msg_id("VIDEO_STREAM_INFORMATION"), 1),  # param1: stream id
    mav_id("MAV_CMD_REQUEST_VIDEO_STREAM_STATUS"): (msg_id("VIDEO_STREAM_STATUS"), 1),
}
# The legacy requests whose param1 0 means "no" (param1 1: send it); the others' param1 is an index.
LEGACY_YES_NO = frozenset(c for c, (_, index_param) in LEGACY_REQUESTS.items() if index_param is None)


@dataclass
class Stream:
    msgid: int
    producer: Producer | None
    default_hz: float
    max_hz: float
    hz: float = 0.0
    task: asyncio.Task[None] | None = None

    @property
    def period_s(self) -> float:
        return 1.0 / self.hz if self.hz > 0 else 0.0


class Services:
    def __init__(self, comp: Component, dispatcher: Dispatcher, mav_type: int) -> None:
        self.comp = comp
        self.dispatcher = dispatcher
        self.mav_type = mav_type
        self.providers: dict[int, Provider] = {}
        self.streams: dict[int, Stream] = {}
        self.system_status = 4  # MAV_STATE_ACTIVE
        self._started = False
        dispatcher.add_component(comp)
        # Broadcast (component 0) requests are answered only by the components that send the
        # message: a gimbal must not answer UNSUPPORTED to a broadcast CAMERA_INFORMATION request.
        dispatcher.register(comp, MAV_CMD_REQUEST_MESSAGE, self._request_message,
                            accepts=lambda c: c.p(1) in self.providers,
                            local=lambda c: c.p(1) in LOCAL_MESSAGES)  # fmt: skip
        dispatcher.register(comp, MAV_CMD_SET_MESSAGE_INTERVAL, self._set_interval,
                            accepts=lambda c: c.p(1) in self.streams, local=True)  # fmt: skip
        dispatcher.register(comp, MAV_CMD_GET_MESSAGE_INTERVAL, self._get_interval,
                            accepts=lambda c: c.p(1) in self.streams, local=True)  # fmt: skip
        for cmd in LEGACY_REQUESTS:
            dispatcher.register(comp, cmd, self._legacy_request, accepts=self._provides_legacy)

    def _provides_legacy(self, cmd: Command) -> bool:
        return LEGACY_REQUESTS[cmd.command][0] in self.providers

    def provide(self, msgid: int, provider: Provider) -> None:
        self.providers[msgid] = provider

    def add_stream(self, msgid: int, producer: Producer | None, default_hz: float, max_hz: float) -> Stream:
        s = self.streams[msgid] = Stream(msgid, producer, default_hz, max_hz, default_hz)
        return s

    def heartbeat(self) -> MAVLinkMessage:
        return mavlink().MAVLink_heartbeat_message(self.mav_type, MAV_AUTOPILOT_INVALID, 0, 0, self.system_status, 3)

    def start(self) -> None:
        self._started = True
        for s in self.streams.values():
            self._restart(s)

    async def close(self) -> None:
        self._started = False
        await stop_tasks([s.task for s in self.streams.values() if s.task is not None], "message streams")
        for s in self.streams.values():
            s.task = None

    def _restart(self, s: Stream) -> None:
        if s.task is not None:
            s.task.cancel()
            s.task = None
        if self._started and s.producer is not None and s.hz > 0:
            s.task = asyncio.ensure_future(self._run_stream(s))

    async def _run_stream(self, s: Stream) -> None:
        while True:
            await asyncio.sleep(s.period_s)
            try:
                msg = s.producer() if s.producer is not None else None
            except Exception:
                log.exception("%s: stream %d failed", self.comp, s.msgid)
                continue
            if msg is not None:
                self.comp.send(msg)

    # -- command handlers ------------------------------------------------------------------------

    async def _request_message(self, cmd: Command) -> Outcome:
        return await self._answer(cmd.whole(1, "message id", 0, MAX_MESSAGE_ID), cmd)

    async def _legacy_request(self, cmd: Command) -> Outcome:
        msgid, index_param = LEGACY_REQUESTS[cmd.command]
        if cmd.command in LEGACY_YES_NO and cmd.p(1) == 0:
            return Outcome()  # param1 = 0: "do not send" (the legacy commands' way to stop)
        # Re-express as REQUEST_MESSAGE, whose param2 is the index.
        params = list(cmd.params)
        params[1] = cmd.p(index_param) if index_param is not None else 0.0
        return await self._answer(msgid, Command(**{**cmd.__dict__, "params": tuple(params)}))

    async def _answer(self, msgid: int, cmd: Command) -> Outcome:
        provider = self.providers.get(msgid)
        if provider is None:
            raise unsupported(f"{self.comp.name} does not provide message {msgid}")
        msgs = await provider(cmd)
        return Outcome(after=list(msgs))

    async def _set_interval(self, cmd: Command) -> Outcome:
        msgid, interval_us = cmd.whole(1, "message id", 0, MAX_MESSAGE_ID), cmd.finite(2, "interval in microseconds")
        s = self.streams.get(msgid)
        if s is None:
            raise unsupported(f"{self.comp.name} does not stream message {msgid}")
        if interval_us == -1:
            s.hz = 0.0
        elif interval_us == 0:
            s.hz = s.default_hz
        elif interval_us > 0:
            hz = 1e6 / interval_us
            if hz > s.max_hz:
                raise denied(f"message {msgid} at most {s.max_hz:g} Hz from {self.comp.name}")
            s.hz = hz
        else:
            raise denied(f"interval {interval_us:g} us: expected -1, 0 or a positive number")
        self._restart(s)
        return Outcome()

    async def _get_interval(self, cmd: Command) -> Outcome:
        msgid = cmd.whole(1, "message id", 0, MAX_MESSAGE_ID)
        s = self.streams.get(msgid)
        interval = 0 if s is None else -1 if s.hz <= 0 else int(1e6 / s.hz)
        return Outcome(after=[mavlink().MAVLink_message_interval_message(msgid, interval)])
