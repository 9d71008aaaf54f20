"""`topgimbal console --autopilot HOST:PORT`: the autopilot's fix for the operator (issue 41.9).

The console listens on a UDP port for the autopilot's MAVLink stream (a MAVLink router's or the
autopilot's own output to that port, as a ground station receives it) and keeps the newest
GLOBAL_POSITION_INT, read as the bridge reads it (autopilot.vehicle.fix_of: one VehicleFix):
position, altitude above mean sea level, home altitude (altitude minus the height above home: the
flat ground the target is placed on) and heading (`hdg`, else the newest ATTITUDE's yaw). It only reads: nothing is sent, to the autopilot or to the camera (a bridge
feeds the camera). A fix older than STALE_S is not shown; what is not MAVLink is dropped and
counted. Shown by `api/where` and the page's Vehicle row (where.py)."""

from __future__ import annotations

import asyncio
import logging
import math
from typing import Any, cast

from ..autopilot.vehicle import VehicleFix, fix_of
from ..clock import monotonic
from ..errors import TopGimbalError
from ..geo.earth import wrap360

log = logging.getLogger(__name__)

STALE_S = 3.0  # a fix older than this is not the vehicle's position any more


class AutopilotAddressError(TopGimbalError, ValueError):
    """An --autopilot address that cannot be listened on as given."""


def listen_address(text: str) -> tuple[str, int]:
    """HOST:PORT (IPv6 in brackets) to listen on for the autopilot; PORT 0: any free port."""
    host, sep, port = text.rpartition(":")
    host = host.strip("[]")
    if not sep or not host or not port.isdigit() or not 0 <= int(port) <= 65535:
        raise AutopilotAddressError(f"--autopilot {text!r}: expected HOST:PORT to listen on, e.g. 127.0.0.1:14550")
    return host, int(port)


class AutopilotListener(asyncio.DatagramProtocol):
    """The newest fix heard on one UDP port."""

    def __init__(self) -> None:
        from pymavlink.dialects.v20 import common

        self._mav = common.MAVLink(None)
        self._mav.robust_parsing = True  # garbage is skipped, not raised
        self._fix: VehicleFix | None = None
        self._yaw: tuple[float, int, float] | None = None  # (time, sysid, degrees) from ATTITUDE
        self.transport: asyncio.DatagramTransport | None = None
        self.dropped = 0

    @classmethod
    async def listen(cls, host: str, port: int) -> AutopilotListener:
        loop = asyncio.get_running_loop()
        _, proto = await loop.create_datagram_endpoint(cls, local_addr=(host, port))
        return proto

    @property
    def address(self) -> tuple[str, int]:
        assert self.transport is not None
        host, port = self.transport.get_extra_info("sockname")[:2]
        return str(host), int(port)

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        self.transport = cast(asyncio.DatagramTransport, transport)

    def datagram_received(self, data: bytes, addr: Any) -> None:
        try:
            messages = self._mav.parse_buffer(data) or []
        except Exception:  # a malformed packet from anyone: dropped, counted
            self.dropped += 1
            return
        for m in messages:
            kind = m.get_type()
            if kind in ("BAD_DATA", "UNKNOWN"):
                self.dropped += 1
            elif kind == "ATTITUDE":
                self._yaw = (monotonic(), m.get_srcSystem(), wrap360(math.degrees(m.yaw)))
            elif kind == "GLOBAL_POSITION_INT" and (m.lat or m.lon):  # 0, 0: no fix yet
                self._position(m)

    def _position(self, m: Any) -> None:
        yaw, now = self._yaw, monotonic()
        fresh_yaw = yaw is not None and yaw[1] == m.get_srcSystem() and now - yaw[0] <= STALE_S
        self._fix = fix_of(m, now, yaw[2] if yaw is not None and fresh_yaw else None)

    def fix(self) -> VehicleFix | None:
        """The newest fix, None when there is none or it is stale."""
        if self._fix is None or monotonic() - self._fix.t > STALE_S:
            return None
        return self._fix

    def close(self) -> None:
        if self.transport is not None:
            self.transport.close()
