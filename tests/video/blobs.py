"""Finding the landmarks' bullseyes in a decoded picture: red blobs, by connected components."""

from __future__ import annotations

import numpy as np


def red_blobs(rgb: np.ndarray, min_pixels: int = 20) -> list[tuple[float, float, int]]:
    """(x, y, pixel count) of every connected blob of strong red, largest first."""
    r, g, b = (rgb[..., i].astype(np.int16) for i in range(3))
    mask = (r > 150) & (g < 90) & (b < 90)
    seen = np.zeros_like(mask)
    h, w = mask.shape
    blobs = []
    for y0, x0 in zip(*np.nonzero(mask), strict=False):
        if seen[y0, x0]:
            continue
        stack = [(y0, x0)]
        seen[y0, x0] = True
        pts = []
        while stack:
            y, x = stack.pop()
            pts.append((y, x))
            for dy, dx in ((1, 0), (-1, 0), (0, 1), (0, -1), (2, 0), (-2, 0), (0, 2), (0, -2)):
                yy, xx = y + dy, x + dx
                if 0 <= yy < h and 0 <= xx < w and mask[yy, xx] and not seen[yy, xx]:
                    seen[yy, xx] = True
                    stack.append((yy, xx))
        if len(pts) >= min_pixels:
            ys, xs = zip(*pts, strict=False)
            blobs.append((float(np.mean(xs)), float(np.mean(ys)), len(pts)))
    return sorted(blobs, key=lambda b: -b[2])


def nearest(blobs: list[tuple[float, float, int]], x: float, y: float) -> tuple[float, float, float]:
    """The blob nearest (x, y): its centre and its distance from (x, y)."""
    bx, by, _ = min(blobs, key=lambda b: (b[0] - x) ** 2 + (b[1] - y) ** 2)
    return bx, by, float(np.hypot(bx - x, by - y))
