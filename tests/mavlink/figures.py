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


def sender_delays(pairs: list[tuple[float, float]]) -> tuple[list[float], float]:
    """Each message's delay to us from (its sender's timestamp, our arrival time) pairs, both in
    seconds, judged after the fact: the sender's clock may run at another rate than ours (a SITL
    that is not quite real-time: PX4's ran 1.4 % slow here), so the arrival-less-stamp offset is a
    line plus each delay, not a constant plus each delay. The line goes through the smallest offset
    of the first half and of the second half of the record (the quickest deliveries). Returns the
    delays (>= 0) and the sender's clock rate against ours (1.0: the same)."""
    assert len(pairs) >= 4, "too few messages to judge their delays"
    offsets = [(sent, arrived - sent) for sent, arrived in pairs]
    half = len(offsets) // 2
    (s1, o1), (s2, o2) = min(offsets[:half], key=lambda p: p[1]), min(offsets[half:], key=lambda p: p[1])
    slope = (o2 - o1) / (s2 - s1) if s2 - s1 > 1.0 else 0.0
    delays = [max(0.0, o - (o1 + slope * (s - s1))) for s, o in offsets]
    return delays, 1.0 / (1.0 + slope)
