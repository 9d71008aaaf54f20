"""Projection for one rendered frame (render.py): world directions (x north, y east, z up) to
pixels of a pinhole camera, points and line segments, with segments that run behind the camera
clipped at its near plane and far ends pulled back into reach of the picture."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


def world_dir(az_deg: float, el_deg: float) -> tuple[float, float, float]:
    a, e = math.radians(az_deg), math.radians(el_deg)
    return (math.cos(e) * math.cos(a), math.cos(e) * math.sin(a), math.sin(e))


@dataclass
class Camera:
    """Projection for one frame: world vectors (x north, y east, z up) to pixels."""

    fwd: np.ndarray
    right: np.ndarray
    up: np.ndarray
    f: float
    width: int
    height: int
    near: float = 1e-3

    def radius_px(self, angle_deg: float) -> float:
        return self.f * math.tan(math.radians(angle_deg))

    def _cam(self, v: np.ndarray) -> np.ndarray:
        return np.stack([v @ self.right, v @ self.up, v @ self.fwd], axis=-1)

    def point(self, d: tuple[float, float, float]) -> tuple[float, float] | None:
        return self.points(np.array([d]))[0]

    def points(self, dirs: np.ndarray) -> list[tuple[float, float] | None]:
        c = self._cam(dirs)
        out: list[tuple[float, float] | None] = []
        for x, y, z in c:
            if z <= self.near:
                out.append(None)
            else:
                out.append((self.width / 2 + self.f * x / z, self.height / 2 - self.f * y / z))
        return out

    def segments(self, segs: np.ndarray) -> list[tuple[tuple[float, float], tuple[float, float]]]:
        """Project 3-D segments (S, 2, 3), clipped to the near plane: straight lines stay straight."""
        c = self._cam(segs)  # (S, 2, 3)
        out = []
        lim = 4.0 * max(self.width, self.height)
        for p, q in c:
            zp, zq = p[2], q[2]
            if zp <= self.near and zq <= self.near:
                continue
            if zp <= self.near or zq <= self.near:
                t = (self.near - zp) / (zq - zp)
                m = p + t * (q - p)
                p, q = (m, q) if zp <= self.near else (p, m)
            a = (self.width / 2 + self.f * p[0] / p[2], self.height / 2 - self.f * p[1] / p[2])
            b = (self.width / 2 + self.f * q[0] / q[2], self.height / 2 - self.f * q[1] / q[2])
            a, b = clip_far(a, b, lim, self.width, self.height)
            out.append((a, b))
        return out


def clip_far(a: tuple[float, float], b: tuple[float, float], lim: float, w: int, h: int) -> tuple:
    """Pull far-off endpoints in along the line (Pillow draws huge coordinates slowly)."""

    def pull(p: tuple[float, float], q: tuple[float, float]) -> tuple[float, float]:
        dx, dy = p[0] - w / 2, p[1] - h / 2
        n = max(abs(dx), abs(dy))
        if n <= lim:
            return p
        # Move p towards q until inside the box: param s on p + s (q - p).
        best = 0.0
        for coord, lo_hi in ((0, w / 2), (1, h / 2)):
            d = p[coord] - lo_hi
            dq = q[coord] - p[coord]
            if abs(d) > lim and dq != 0:
                s = (abs(d) - lim) / abs(dq)
                best = max(best, min(1.0, s))
        return (p[0] + best * (q[0] - p[0]), p[1] + best * (q[1] - p[1]))

    return pull(a, b), pull(b, a)
