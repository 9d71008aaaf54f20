"""What the bridge hears about vehicles on the MAVLink network: our own vehicle's position and
heading (for ROI, earth-frame yaw, photo positions, CAMERA_FOV_STATUS) and other systems'
positions (MAV_CMD_DO_SET_ROI_SYSID). Bounded: at most MAX_SYSTEMS remembered, our own vehicle
always among them."""

from __future__ import annotations

import math
import time
from collections import OrderedDict
from dataclasses import dataclass
from typing import TYPE_CHECKING

from .geo import Position
from .quaternion import is_valid, to_euler_deg

if TYPE_CHECKING:
    from ._mav import MAVLinkMessage

MAX_SYSTEMS = 32
STALE_S = 3.0


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
        self._yaw: tuple[float, float] | None = None  # (deg, t) from our vehicle's ATTITUDE
        self._att: tuple[tuple[float, float, float], float] | None = None  # ((roll, pitch, yaw) deg, t): ATTITUDE
        self._att_q: tuple[tuple[float, float, float], float] | None = (
            None  # the same from AUTOPILOT_STATE_FOR_GIMBAL_DEVICE
        )

    def on_message(self, m: MAVLinkMessage) -> None:
        kind = m.get_type()
        src = m.get_srcSystem()
        if kind == "GLOBAL_POSITION_INT":
            hdg = None if m.hdg == 65535 else m.hdg / 100.0
            fix = Fix(
                Position(m.lat / 1e7, m.lon / 1e7, m.alt / 1000.0), m.relative_alt / 1000.0, hdg, time.monotonic()
            )
            self._fixes[src] = fix
            self._fixes.move_to_end(src)
            if len(self._fixes) > MAX_SYSTEMS:
                # The least recently heard other system goes; never our own vehicle (on a network
                # of more than MAX_SYSTEMS vehicles it used to be evicted between its own updates).
                oldest = next(k for k in self._fixes if k != self.sysid)
                del self._fixes[oldest]
        elif (
            kind == "ATTITUDE" and src == self.sysid and m.get_srcComponent() not in self.own and not math.isnan(m.yaw)
        ):
            self._yaw = (math.degrees(m.yaw), time.monotonic())
            if not (math.isnan(m.roll) or math.isnan(m.pitch)):
                self._att = ((math.degrees(m.roll), math.degrees(m.pitch), math.degrees(m.yaw)), time.monotonic())
        elif kind == "AUTOPILOT_STATE_FOR_GIMBAL_DEVICE" and self._own_vehicle(m) and is_valid(list(m.q)):
            e = to_euler_deg(list(m.q))
            self._att_q = ((e.roll_deg, e.pitch_deg, e.yaw_deg), time.monotonic())

    def fix(self, sysid: int | None = None) -> Fix | None:
        f = self._fixes.get(self.sysid if sysid is None else sysid)
        if f is None or time.monotonic() - f.t > STALE_S:
            return None
        return f

    def _own_vehicle(self, m: MAVLinkMessage) -> bool:
        return bool(m.get_srcSystem() == self.sysid and m.get_srcComponent() not in self.own)

    def attitude_deg(self) -> tuple[float, float, float] | None:
        """Our vehicle's (roll, pitch, yaw) in degrees, if heard lately: AUTOPILOT_STATE_FOR_GIMBAL_DEVICE's
        quaternion preferred, else ATTITUDE; None when neither is fresh."""
        now = time.monotonic()
        for att in (self._att_q, self._att):
            if att is not None and now - att[1] <= STALE_S:
                return att[0]
        return None

    @property
    def yaw_deg(self) -> float | None:
        """Our vehicle's heading (ATTITUDE yaw, else GLOBAL_POSITION_INT hdg), if heard lately."""
        now = time.monotonic()
        if self._yaw is not None and now - self._yaw[1] <= STALE_S:
            return self._yaw[0]
        f = self.fix()
        return f.heading_deg if f is not None else None
