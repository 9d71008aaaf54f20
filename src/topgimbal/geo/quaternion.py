"""Euler angles <-> quaternions, as MAVLink's gimbal messages use them. Pure math (geo owns the
rotations: frames.py's matrices and these quaternions; mavlink/quaternion.py re-exports them).

MAVLink's gimbal quaternion is (w, x, y, z), Hamilton convention, rotation from the reference
frame to the gimbal's FRD frame, Euler order 3-2-1 (yaw, then pitch, then roll). Its signs match
topgimbal's API convention: yaw right-positive, pitch up-positive, roll right-positive."""

from __future__ import annotations

import math
from typing import NamedTuple

Quaternion = tuple[float, float, float, float]


class Euler(NamedTuple):
    roll_deg: float
    pitch_deg: float
    yaw_deg: float


def from_euler_deg(roll_deg: float, pitch_deg: float, yaw_deg: float) -> Quaternion:
    r, p, y = (math.radians(a) / 2.0 for a in (roll_deg, pitch_deg, yaw_deg))
    cr, sr, cp, sp, cy, sy = math.cos(r), math.sin(r), math.cos(p), math.sin(p), math.cos(y), math.sin(y)
    return (
        cr * cp * cy + sr * sp * sy,
        sr * cp * cy - cr * sp * sy,
        cr * sp * cy + sr * cp * sy,
        cr * cp * sy - sr * sp * cy,
    )


def is_valid(q: Quaternion | list[float]) -> bool:
    """MAVLink marks "no attitude" with NaN (or an all-zero quaternion)."""
    if len(q) != 4 or any(math.isnan(v) or math.isinf(v) for v in q):
        return False
    return sum(v * v for v in q) > 1e-6


def to_euler_deg(q: Quaternion | list[float]) -> Euler:
    """Euler angles (degrees, yaw in -180..180) of a quaternion; it need not be normalised."""
    w, x, y, z = q
    n = math.sqrt(w * w + x * x + y * y + z * z)
    if n == 0 or math.isnan(n):
        raise ValueError("not a rotation: the quaternion is zero or NaN")
    w, x, y, z = w / n, x / n, y / n, z / n
    roll = math.atan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
    sinp = max(-1.0, min(1.0, 2.0 * (w * y - z * x)))
    pitch = math.asin(sinp)
    yaw = math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    return Euler(math.degrees(roll), math.degrees(pitch), math.degrees(yaw))
