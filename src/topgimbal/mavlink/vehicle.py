"""What the bridge hears about vehicles on the MAVLink network: our own vehicle's position and
attitude (for ROI, earth-frame set-points, photo positions, CAMERA_FOV_STATUS) and other systems'
positions (MAV_CMD_DO_SET_ROI_SYSID). Bounded: at most MAX_SYSTEMS remembered, our own vehicle
always among them.

Our vehicle's attitude comes from AUTOPILOT_STATE_FOR_GIMBAL_DEVICE (preferred: what an autopilot
sends its MAVLink gimbal, about 50 Hz; ArduPilot sends no ATTITUDE on a gimbal's port unless
MAVn_EXTRA1 is set) or ATTITUDE; the heading, failing both, from GLOBAL_POSITION_INT hdg."""

from __future__ import annotations

import math
from collections import OrderedDict
from dataclasses import dataclass
from typing import TYPE_CHECKING

from ..clock import monotonic
from .geo import Position
from .quaternion import is_valid, to_euler_deg

if TYPE_CHECKING:
    from ._mav import MAVLinkMessage

MAX_SYSTEMS = 32
STALE_S = 3.0

Attitude = tuple[float, float, float]  # roll_deg, pitch_deg, yaw_deg


@dataclass(frozen=True)
class Fix:
    position: Position
    relative_alt_m: float
    heading_deg: float | None
    t: float

    @property
    def home_alt_m(self) -> float:
        return self.position.alt_m - self.relative_alt_m


class Vehicles:
    def __init__(self, sysid: int, own_compids: set[int]) -> None:
        self.sysid = sysid
        self.own = own_compids
        self._fixes: OrderedDict[int, Fix] = OrderedDict()
        # Our vehicle's attitude: (roll, pitch, yaw degrees, t) per source message type.
        self._attitude: dict[str, tuple[Attitude, float]] = {}

    def on_message(self, m: MAVLinkMessage) -> None:
        kind = m.get_type()
        src = m.get_srcSystem()
        if kind == "GLOBAL_POSITION_INT":
            hdg = None if m.hdg == 65535 else m.hdg / 100.0
            fix = Fix(Position(m.lat / 1e7, m.lon / 1e7, m.alt / 1000.0), m.relative_alt / 1000.0, hdg, monotonic())
            self._fixes[src] = fix
            self._fixes.move_to_end(src)
            if len(self._fixes) > MAX_SYSTEMS:
                # The least recently heard other system goes; never our own vehicle (on a network
                # of more than MAX_SYSTEMS vehicles it used to be evicted between its own updates).
                oldest = next(k for k in self._fixes if k != self.sysid)
                del self._fixes[oldest]
            return
        if src != self.sysid or m.get_srcComponent() in self.own:
            return
        if kind == "AUTOPILOT_STATE_FOR_GIMBAL_DEVICE":
            # q: the vehicle's attitude, earth frame (NED) to body, Hamilton (w, x, y, z); NaN or
            # zero when the autopilot has none. Addressed to its gimbal; another gimbal's copy
            # carries the same attitude, so the target does not matter.
            if is_valid(list(m.q)):
                e = to_euler_deg(list(m.q))
                self._attitude[kind] = ((e.roll_deg, e.pitch_deg, e.yaw_deg), monotonic())
        elif kind == "ATTITUDE":
            values = (m.roll, m.pitch, m.yaw)
            if all(math.isfinite(v) for v in values):
                roll, pitch, yaw = (math.degrees(v) for v in values)
                self._attitude[kind] = ((roll, pitch, yaw), monotonic())

    def fix(self, sysid: int | None = None) -> Fix | None:
        f = self._fixes.get(self.sysid if sysid is None else sysid)
        if f is None or monotonic() - f.t > STALE_S:
            return None
        return f

    def attitude_deg(self) -> tuple[float, float, float] | None:
        """Our vehicle's (roll_deg, pitch_deg, yaw_deg), earth frame (yaw from North, clockwise;
        -180..180), from AUTOPILOT_STATE_FOR_GIMBAL_DEVICE (preferred) or ATTITUDE heard within
        STALE_S; None when neither was."""
        now = monotonic()
        for kind in ("AUTOPILOT_STATE_FOR_GIMBAL_DEVICE", "ATTITUDE"):
            got = self._attitude.get(kind)
            if got is not None and now - got[1] <= STALE_S:
                return got[0]
        return None

    @property
    def yaw_deg(self) -> float | None:
        """Our vehicle's heading (attitude_deg()'s yaw, else GLOBAL_POSITION_INT hdg), if heard lately."""
        att = self.attitude_deg()
        if att is not None:
            return att[2]
        f = self.fix()
        return f.heading_deg if f is not None else None
