"""Link counters: what the engine and the link monitor saw. `as_dict()` is JSON-able and is what the
console and `monitor` show."""

from __future__ import annotations

from dataclasses import dataclass, field, fields
from typing import TypeVar

T = TypeVar("T")


def _doc(default: T, text: str) -> T:
    """A counter's default with its description as data (`LinkStats.describe()`, docs/client.md)."""
    return field(default=default, metadata={"doc": text})


@dataclass(slots=True)  # one per client, written per frame: no __dict__ to miss in cache
class LinkStats:
    frames_in: int = _doc(0, "frames received, answers or not (a datagram may hold several)")
    frames_out: int = _doc(0, "frames sent, retries included")
    bytes_in: int = _doc(0, "bytes received")
    bytes_out: int = _doc(0, "bytes sent")
    requests: int = _doc(0, "requests made; a retry is not a new request")
    replies: int = _doc(0, "requests completed by the device's answer")
    timeouts: int = _doc(0, "requests that failed because no attempt was answered in time")
    retries: int = _doc(0, "attempts sent again after a timeout")
    late_replies: int = _doc(0, "answers to attempts of requests that had already finished")
    duplicates: int = _doc(0, "copies of an answer already taken")
    stray_replies: int = _doc(0, "frames that look like answers but fit no attempt (another program's, a report)")
    ambiguous: int = _doc(0, "answers that could be the live request's or an earlier one's: never taken")
    deferred: int = _doc(0, "requests that waited for an earlier request's attempts to run out")
    errors: int = _doc(0, "ERE frames, and echoes whose data is not what was sent")
    bad_frames: int = _doc(0, "damaged frames: bad checksum, garbage, a length the parser had to recover")
    link_losses: int = _doc(0, "times the link went down (silence, a closed TCP or serial link)")
    rtt_ms_last: float | None = _doc(
        None, "the last round trip, taken only when it is clear which attempt was answered, ms"
    )
    rtt_ms_avg: float | None = _doc(None, "round trip, exponential average (recent requests weigh more), ms")
    rtt_ms_min: float | None = _doc(None, "the fastest round trip seen, ms")
    connected: bool = _doc(False, "whether the link is up now")

    @classmethod
    def describe(cls) -> dict[str, str]:
        """Every counter's name and description, in `as_dict()` order."""
        return {f.name: f.metadata["doc"] for f in fields(cls)}

    def add_rtt(self, rtt_s: float) -> None:
        ms = rtt_s * 1000.0
        self.rtt_ms_last = ms
        # exponential average: a link's recent behaviour matters more than its history
        self.rtt_ms_avg = ms if self.rtt_ms_avg is None else self.rtt_ms_avg * 0.9 + ms * 0.1
        self.rtt_ms_min = ms if self.rtt_ms_min is None else min(self.rtt_ms_min, ms)

    def as_dict(self) -> dict[str, float | int | bool | None]:
        d = {f.name: getattr(self, f.name) for f in fields(self)}
        for k in ("rtt_ms_last", "rtt_ms_avg", "rtt_ms_min"):
            if d[k] is not None:
                d[k] = round(d[k], 3)
        return d
