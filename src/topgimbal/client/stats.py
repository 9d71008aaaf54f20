"""Link counters: what the engine and the link monitor saw. `as_dict()` is JSON-able and is what the
console and `monitor` show."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass
class LinkStats:
    frames_in: int = 0
    frames_out: int = 0
    bytes_in: int = 0
    bytes_out: int = 0
    requests: int = 0
    replies: int = 0
    timeouts: int = 0
    retries: int = 0
    late_replies: int = 0  # answers to attempts of requests that had already finished
    duplicates: int = 0  # copies of an answer already taken
    stray_replies: int = 0  # look like answers but fit no attempt (another program's, a report)
    ambiguous: int = 0  # could answer the live request or an earlier one: never taken
    deferred: int = 0  # requests that waited for an earlier request's attempts to run out
    errors: int = 0  # ERE frames
    bad_frames: int = 0
    link_losses: int = 0
    rtt_ms_last: float | None = None
    rtt_ms_avg: float | None = None
    rtt_ms_min: float | None = None
    connected: bool = False

    def add_rtt(self, rtt_s: float) -> None:
        ms = rtt_s * 1000.0
        self.rtt_ms_last = ms
        # exponential average: a link's recent behaviour matters more than its history
        self.rtt_ms_avg = ms if self.rtt_ms_avg is None else self.rtt_ms_avg * 0.9 + ms * 0.1
        self.rtt_ms_min = ms if self.rtt_ms_min is None else min(self.rtt_ms_min, ms)

    def as_dict(self) -> dict[str, float | int | bool | None]:
        d = dict(self.__dict__)
        for k in ("rtt_ms_last", "rtt_ms_avg", "rtt_ms_min"):
            if d[k] is not None:
                d[k] = round(d[k], 3)
        return d
