"""The pointing tests' own angle wrap and percentile (virtual, real-time and SITL alike): written
here, not taken from topgimbal.geo, so that a fault in the product's wrap cannot hide in the score
that checks it."""

from __future__ import annotations


def wrap180(deg: float) -> float:
    return (deg + 180.0) % 360.0 - 180.0


def percentile(values: list[float], q: float) -> float:
    """The q-th percentile (0..100) of `values`, the nearest rank."""
    s = sorted(values)
    return s[min(len(s) - 1, round(q / 100.0 * (len(s) - 1)))]
