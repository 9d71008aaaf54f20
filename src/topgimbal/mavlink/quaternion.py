"""Euler angles <-> quaternions for MAVLink's gimbal messages: topgimbal.geo owns them
(geo/quaternion.py); the names stay importable from here."""

from __future__ import annotations

from ..geo.earth import wrap180
from ..geo.quaternion import Euler, Quaternion, from_euler_deg, is_valid, to_euler_deg

__all__ = ["Euler", "Quaternion", "from_euler_deg", "is_valid", "to_euler_deg", "wrap180"]
