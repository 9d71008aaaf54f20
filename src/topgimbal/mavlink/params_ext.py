"""Camera settings over the extended parameter protocol (PARAM_EXT_*), as the camera definition
(`camdef`) lists them.

PARAM_EXT_REQUEST_LIST / REQUEST_READ answer PARAM_EXT_VALUE with what the camera says now where
the catalog has a query for the setting; where it has none, the last value the camera confirmed
through this bridge, else the catalog's factory value (a camera that cannot be asked cannot be
known better). PARAM_EXT_SET answers PARAM_EXT_ACK IN_PROGRESS at once and then the true result:
ACCEPTED only once the camera confirmed the write (the client's request returned: its echo carried
the value), VALUE_UNSUPPORTED for a value that is not an option or out of range, or a wrong type,
FAILED when the camera refused, did not answer or the link is down (a STATUSTEXT says why). A
setting of a command with several settings is written with the others' current values, read
first. At most MAX_INFLIGHT requests run at once; more are answered FAILED (a rate-limited log
line says so). A read of a setting whose read is already queued or running is not queued again:
the answer on its way (broadcast, like every PARAM_EXT_VALUE) serves it. A client's retransmissions
while a slow camera answers (MAVSDK resends every ~0.4 s) each cost a camera round trip otherwise,
and the queue they made sent answers ever later (MAVSDK then took the answers to its older
requests as wrong ones, failed its reads and, once, aborted)."""

from __future__ import annotations

import asyncio
import functools
import logging
import math
import struct
from typing import TYPE_CHECKING, Any

from ..camdef.definition import Setting
from ..errors import TopGimbalError
from ..links.mav import mavlink
from ..logtext import untrusted
from ..logthrottle import ThrottledLog
from .camera_link import CameraLink
from .commands import statustext

if TYPE_CHECKING:
    from ..links.mav import MAVLinkMessage
    from .node import Component

log = logging.getLogger("topgimbal.mavlink")

ACCEPTED, VALUE_UNSUPPORTED, FAILED, IN_PROGRESS = 0, 1, 2, 3  # PARAM_ACK
FORMATS = {1: "<B", 2: "<b", 3: "<H", 4: "<h", 5: "<I", 6: "<i", 7: "<Q", 8: "<q", 9: "<f", 10: "<d"}
MAX_INFLIGHT = 8
BUSY_LOG_EVERY_S = 10.0


class ParamValueError(TopGimbalError, ValueError):
    """A PARAM_EXT value this setting does not take (answered VALUE_UNSUPPORTED)."""


def encode_value(setting: Setting, value: float) -> bytes:
    fmt = FORMATS[setting.wire_type]
    return struct.pack(fmt, value if fmt == "<f" else int(value)).ljust(128, b"\0")


def decode_value(param_type: int, raw: bytes) -> float:
    fmt = FORMATS.get(param_type)
    if fmt is None:
        raise ParamValueError(f"parameter type {param_type} is not a number type (1..10)")
    value = struct.unpack(fmt, bytes(raw).ljust(128, b"\0")[: struct.calcsize(fmt)])[0]
    if not math.isfinite(value):
        raise ParamValueError("the value is not a finite number")
    return float(value)


class ParamsExt:
    MESSAGES: tuple[str, ...] = (
        "PARAM_EXT_REQUEST_LIST",
        "PARAM_EXT_REQUEST_READ",
        "PARAM_EXT_SET",
    )  # what on_message reads (node.on)

    def __init__(self, comp: Component, cam: CameraLink, settings: list[Setting]) -> None:
        self.comp = comp
        self.cam = cam
        self.settings = {s.param: s for s in settings}
        self.order = [s.param for s in settings]
        self.known: dict[str, float] = {}  # what the camera said or confirmed last
        self.tasks: set[asyncio.Task[None]] = set()
        self.refused = 0
        self.reading: set[str] = set()  # settings whose read is queued or running
        self.coalesced = 0  # reads answered by the one already on its way
        self._busy_log = ThrottledLog(log, BUSY_LOG_EVERY_S)
        # One request at a time: answers leave in the order the requests came (MAVSDK's parameter
        # client takes an answer for another parameter than the one it asked as a failure).
        self._turn = asyncio.Lock()

    # -- messages ---------------------------------------------------------------------------------

    def on_message(self, m: MAVLinkMessage) -> None:
        kind = m.get_type()
        if kind not in ("PARAM_EXT_REQUEST_LIST", "PARAM_EXT_REQUEST_READ", "PARAM_EXT_SET") or not self.settings:
            return
        if m.target_system not in (0, self.comp.sysid) or m.target_component not in (0, self.comp.compid):
            return
        if kind == "PARAM_EXT_REQUEST_LIST":
            self._spawn(self._list(), None)
        elif kind == "PARAM_EXT_REQUEST_READ":
            param = self._param(m.param_id, m.param_index)
            if param is None:
                return
            if param in self.reading:
                self.coalesced += 1
                return
            task = self._spawn(self._read(param), None)
            if task is not None:
                self.reading.add(param)
                task.add_done_callback(functools.partial(self._read_done, param))
        else:
            param = self._param(m.param_id, -1)
            if param is None:
                return
            self.reading.discard(param)  # a read after this set is answered after it, not before
            raw = getattr(m, "_param_value_raw", None)
            if not isinstance(raw, (bytes, bytearray)):
                raw = str(m.param_value).encode("latin-1", "replace")
            self._spawn(self._set(param, int(m.param_type), bytes(raw)), param)

    def _read_done(self, param: str, _task: asyncio.Task[None]) -> None:
        self.reading.discard(param)

    def _param(self, param_id: Any, index: int) -> str | None:
        if 0 <= index < len(self.order):
            return self.order[index]
        name = param_id.decode("ascii", "replace") if isinstance(param_id, bytes) else str(param_id)
        name = name.split("\0", 1)[0]
        return name if name in self.settings else None

    def _spawn(self, work: Any, setting: str | None) -> asyncio.Task[None] | None:
        if len(self.tasks) >= MAX_INFLIGHT:
            work.close()
            self.refused += 1
            if self._busy_log.allow("busy") is not None:
                log.warning("%s: %d PARAM_EXT requests already running, refused %d", self.comp.name, MAX_INFLIGHT,
                            self.refused)  # fmt: skip
            if setting is not None:
                s = self.settings[setting]
                self._ack(s, self._known(s), FAILED)
            return None
        task = asyncio.ensure_future(self._in_turn(work))
        self.tasks.add(task)
        task.add_done_callback(self.tasks.discard)
        return task

    async def _in_turn(self, work: Any) -> None:
        async with self._turn:
            await work

    async def close(self) -> None:
        for t in list(self.tasks):
            t.cancel()
        await asyncio.gather(*self.tasks, return_exceptions=True)

    # -- reading ----------------------------------------------------------------------------------

    def _known(self, s: Setting) -> float:
        return self.known.get(s.param, s.default)

    async def read_command(self, ident: str) -> dict[str, Any]:
        """The camera's answer to the command's query (its fields in API values)."""
        m = await self.cam.call(lambda c: c.request(ident, read=True))
        return dict(m.fields or {})

    async def current(self, s: Setting, cache: dict[str, dict[str, Any]] | None = None) -> float:
        """The setting's value as the camera says it (readable), else as last known."""
        if s.readable:
            try:
                if cache is not None and s.ident in cache:
                    fields = cache[s.ident]
                else:
                    fields = await self.read_command(s.ident)
                    if cache is not None:
                        cache[s.ident] = fields
                value = s.from_api(fields.get(s.field))
                if value is not None:
                    self.known[s.param] = value
            except (TopGimbalError, OSError) as exc:
                log.info("%s: cannot read %s (%s): the last known value", self.comp.name, s.param, exc)
        return self._known(s)

    def _value_message(self, s: Setting, value: float) -> MAVLinkMessage:
        return mavlink().MAVLink_param_ext_value_message(
            s.param.encode(), encode_value(s, value), s.wire_type, len(self.order), self.order.index(s.param)
        )

    async def _list(self) -> None:
        cache: dict[str, dict[str, Any]] = {}
        for param in self.order:
            s = self.settings[param]
            self.comp.send(self._value_message(s, await self.current(s, cache)))

    async def _read(self, param: str) -> None:
        s = self.settings[param]
        self.comp.send(self._value_message(s, await self.current(s)))

    # -- writing ----------------------------------------------------------------------------------

    def _ack(self, s: Setting, value: float, result: int) -> None:
        self.comp.send(mavlink().MAVLink_param_ext_ack_message(
            s.param.encode(), encode_value(s, value), s.wire_type, result))  # fmt: skip

    async def _set(self, param: str, param_type: int, raw: bytes) -> None:
        s = self.settings[param]
        try:
            if param_type != s.wire_type:
                raise ParamValueError(f"{param} is {s.type} (type {s.wire_type}), not type {param_type}")
            value = decode_value(param_type, raw)
            api_value = s.to_api(value)
        except ValueError as exc:
            self._refuse(s, VALUE_UNSUPPORTED, str(exc))
            return
        self._ack(s, self._known(s), IN_PROGRESS)
        try:
            await self.write(s, api_value)
        except (TopGimbalError, OSError) as exc:
            self._refuse(s, FAILED, f"{param}: the camera did not confirm ({exc})")
            return
        self.known[param] = value
        self._ack(s, value, ACCEPTED)

    async def write(self, s: Setting, api_value: Any) -> None:
        """One camera write of the setting's command: the catalog defaults of the fixed fields, the
        current values of the other settings of the command (read first), the new value."""
        values: dict[str, Any] = dict(s.fixed)
        if s.siblings:
            current = await self.read_command(s.ident)
            for other in s.siblings:
                field = self.settings[other].field
                values[field] = current[field]
        values[s.field] = api_value
        await self.cam.call(lambda c: c.request(s.ident, **values))

    def _refuse(self, s: Setting, result: int, why: str) -> None:
        log.info("%s: PARAM_EXT_SET %s refused: %s", self.comp.name, untrusted(s.param), untrusted(why))
        statustext(self.comp, f"PARAM_EXT_SET {s.param}: {why}", severity=3 if result == FAILED else 4)
        self._ack(s, self._known(s), result)
