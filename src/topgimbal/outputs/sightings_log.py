"""A JSON Lines log of where the camera looks (`topgimbal mavlink --sightings FILE`): one line a
second with the time, the vehicle, the optical axis, the field of view, the located target and the
picture's corners, for looking back at a flight (a GIS, pandas, `jq`).

Bounded and safe to leave running: lines are appended and flushed one at a time (a crash loses at
most the line being written); the file stops growing at `max_bytes` (one warning, then no more
lines: the log never fills a disk); a number that is not finite is written as null (JSON has no
NaN); while nothing is known (no vehicle position yet) nothing is written. An existing file is
appended to, never truncated. Fed a `Sighting`, like every output: it knows no MAVLink."""

from __future__ import annotations

import asyncio
import contextlib
import logging
import math
import os
import stat
from collections.abc import Callable
from pathlib import Path
from typing import IO, Any

from ..clock import wall_time
from ..errors import TopGimbalError
from ..jsonl import line
from .sighting import Sighting

log = logging.getLogger("topgimbal.outputs")

PERIOD_S = 1.0
MAX_BYTES = 1 << 30  # 1 GiB: some 2.5 million lines, a month of flying at one a second


class SightingsLogError(TopGimbalError, ValueError):
    """A log file that cannot be appended to (what was wrong, and what is allowed)."""


def check_path(path: str) -> None:
    """SightingsLogError unless `path` is a regular file, or a new file in an existing directory,
    that this process may write: nothing is created here (a bad command line leaves no file)."""
    p = Path(path)
    try:
        st = p.stat()
    except FileNotFoundError:
        parent = p.parent if str(p.parent) else Path(".")
        if not parent.is_dir():
            raise SightingsLogError(f"sightings {path!r}: the directory {str(parent)!r} does not exist") from None
        if not os.access(parent, os.W_OK):
            raise SightingsLogError(f"sightings {path!r}: the directory {str(parent)!r} is not writable") from None
        return
    except OSError as exc:
        raise SightingsLogError(f"sightings {path!r}: {exc.strerror or exc}") from None
    if not stat.S_ISREG(st.st_mode):
        raise SightingsLogError(f"sightings {path!r}: not a regular file (a new or existing file is allowed)")
    if not os.access(p, os.W_OK):
        raise SightingsLogError(f"sightings {path!r}: not writable")


def _num(v: float, digits: int) -> float | None:
    return round(v, digits) if math.isfinite(v) else None


def record(s: Sighting, wall_s: float) -> dict[str, Any]:
    """One line's JSON object: degrees and metres as the names say, altitudes above mean sea level."""

    def point(f: Any) -> dict[str, Any] | None:
        if f is None or not (math.isfinite(f.lat_deg) and math.isfinite(f.lon_deg)):
            return None
        return {k: (_num(v, 7) if isinstance(v, float) else v) for k, v in f.as_dict().items()}

    return {
        "time_s": round(wall_s, 3),  # Unix time
        "vehicle": {
            "lat_deg": _num(s.vehicle_lat_deg, 7),
            "lon_deg": _num(s.vehicle_lon_deg, 7),
            "alt_m": _num(s.vehicle_alt_m, 2),
        },
        "axis": {
            "azimuth_deg": _num(s.azimuth_deg, 3),
            "elevation_deg": _num(s.elevation_deg, 3),
            "roll_deg": _num(s.roll_deg, 3),
        },
        "fov": {"hfov_deg": _num(s.hfov_deg, 3), "vfov_deg": _num(s.vfov_deg, 3)},
        "target": point(s.target),
        "corners": [point(c) for c in s.corners],
    }


class SightingsLog:
    """Appends `record(source())` to `path` every `period_s` from `run()` until `close()`."""

    def __init__(
        self,
        path: str,
        source: Callable[[], Sighting | None],
        *,
        period_s: float = PERIOD_S,
        max_bytes: int = MAX_BYTES,
        wall: Callable[[], float] = wall_time,
    ) -> None:
        self.path, self.source, self.period_s, self.max_bytes, self.wall = path, source, period_s, max_bytes, wall
        self.lines = 0  # written by this log
        self.full = False
        self._file: IO[bytes] | None = None

    def write_once(self) -> bool:
        """One line now, if the source knows where the camera looks and the file has room."""
        if self.full:
            return False
        s = self.source()
        if s is None:
            return False
        if self._file is None:
            self._file = open(self.path, "ab")  # noqa: SIM115  # kept open until close()
        data = (line(record(s, self.wall())) + "\n").encode()
        if self._file.tell() + len(data) > self.max_bytes:
            self.full = True
            log.warning("sightings %s: reached %d bytes: no more lines are written", self.path, self.max_bytes)
            return False
        self._file.write(data)
        self._file.flush()
        self.lines += 1
        return True

    async def run(self) -> None:
        """Until cancelled; the file is closed when it ends."""
        try:
            while True:
                try:
                    self.write_once()
                except OSError as exc:  # a full disk, a file removed under us: say it, stop this output only
                    log.warning("sightings %s: %s: no more lines are written", self.path, exc.strerror or exc)
                    return
                await asyncio.sleep(self.period_s)
        finally:
            self.close()

    def close(self) -> None:
        if self._file is not None:
            with contextlib.suppress(OSError):
                self._file.close()
            self._file = None
