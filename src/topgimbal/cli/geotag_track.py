"""Where the vehicle was, and when, from a log: the client's traffic log (JSONL: the LAT / LON /
ALT / AZI / GPS frames a host fed the camera, the gimbal attitude answers, the CAP answers with
their file index) or a MAVLink telemetry log (.tlog: GLOBAL_POSITION_INT, ATTITUDE, and
MAV_CMD_IMAGE_START_CAPTURE's CAMERA_IMAGE_CAPTURED).

`Track.at(t)` interpolates the position linearly between the two samples around `t` (UTC seconds);
before the first or after the last sample it holds that sample for at most `max_gap_s` (a host
feeds a position every so often: the camera would have had that one); further out, or across a
gap longer than `max_gap_s`, there is no position (never a guess)."""

from __future__ import annotations

import bisect
import json
import math
import struct
from dataclasses import dataclass, field
from pathlib import Path

from ..client.signs import map_message
from ..client.traffic import read_log
from ..errors import TopGimbalError
from ..protocol import get_dialect, get_model

POSITION_ROLES = {"latitude": "lat_deg", "longitude": "lon_deg", "altitude": "alt_m"}


class TrackError(TopGimbalError, ValueError):
    """A log that holds no track (not a log, or no position in it)."""


@dataclass(frozen=True)
class Sample:
    t: float  # UTC seconds
    lat_deg: float
    lon_deg: float
    alt_m: float


@dataclass
class Track:
    samples: list[Sample] = field(default_factory=list)
    poses: list[tuple[float, float, float, float]] = field(default_factory=list)  # (t, yaw, pitch, roll) gimbal
    captures: dict[int, float] = field(default_factory=dict)  # photo file index -> UTC seconds of its CAP answer
    max_gap_s: float = 10.0

    def at(self, t: float) -> Sample | None:
        s = self.samples
        i = bisect.bisect_left([x.t for x in s], t)
        if i < len(s) and s[i].t == t:
            return s[i]
        if not s:
            return None
        if i == 0 or i == len(s):  # before the first / after the last: held within max_gap_s
            edge = s[0] if i == 0 else s[-1]
            return Sample(t, edge.lat_deg, edge.lon_deg, edge.alt_m) if abs(edge.t - t) <= self.max_gap_s else None
        a, b = s[i - 1], s[i]
        if b.t - a.t > self.max_gap_s:
            return None
        k = (t - a.t) / (b.t - a.t)
        return Sample(t, a.lat_deg + k * (b.lat_deg - a.lat_deg), a.lon_deg + k * (b.lon_deg - a.lon_deg),
                      a.alt_m + k * (b.alt_m - a.alt_m))  # fmt: skip

    def pose_at(self, t: float) -> tuple[float, float, float] | None:
        """The gimbal attitude heard last before `t` (within max_gap_s)."""
        i = bisect.bisect_right([p[0] for p in self.poses], t)
        if i == 0 or t - self.poses[i - 1][0] > self.max_gap_s:
            return None
        return self.poses[i - 1][1:]


def load_track(path: Path) -> Track:
    with path.open("rb") as fh:
        head = fh.read(64)
    track = _from_traffic(path) if head.lstrip().startswith(b"{") else _from_tlog(path)
    if not track.samples:
        raise TrackError(f"{path}: no vehicle position in this log (LAT/LON/ALT frames or GLOBAL_POSITION_INT)")
    track.samples.sort(key=lambda s: s.t)
    track.poses.sort()
    return track


def _from_traffic(path: Path) -> Track:
    with path.open(encoding="utf-8", errors="replace") as fh:
        try:
            header = json.loads(fh.readline())
        except ValueError:
            header = {}
    if not isinstance(header, dict) or "topgimbal_log" not in header:
        raise TrackError(f"{path}: not a topgimbal traffic log (no header line) nor a MAVLink .tlog")
    try:
        dialect, model = get_model(str(header.get("model") or "C12"))
    except TopGimbalError:
        dialect, model = get_dialect(str(header.get("dialect") or "skydroid")), None
    track = Track()
    current: dict[str, float] = {}
    for rec in read_log(path):
        m = dialect.decode(rec.frame)
        if m.fields is None or m.spec is None:
            continue
        role = m.spec.role
        if rec.direction == "out" and role in POSITION_ROLES and rec.frame.rw == "w":
            current[POSITION_ROLES[role]] = float(m.fields[POSITION_ROLES[role]])  # type: ignore[arg-type]
            if role == "altitude" and {"lat_deg", "lon_deg"} <= current.keys():
                track.samples.append(Sample(rec.t, current["lat_deg"], current["lon_deg"], current["alt_m"]))
        elif rec.direction == "out" and role == "vehicle_position":
            f = m.fields
            track.samples.append(Sample(rec.t, float(f["lat_deg"]), float(f["lon_deg"]), float(f["alt_m"])))  # type: ignore[arg-type]
        elif rec.direction == "in" and role == "attitude" and {"yaw_deg", "pitch_deg"} <= m.fields.keys():
            f = (map_message(m, model.wire_signs) if model is not None else m).fields or {}
            track.poses.append((rec.t, float(f["yaw_deg"]), float(f["pitch_deg"]), float(f.get("roll_deg", 0.0))))  # type: ignore[arg-type]
        elif rec.direction == "in" and role == "photo" and "file_index" in m.fields:
            track.captures[int(m.fields["file_index"])] = rec.t  # type: ignore[call-overload]
    return track


def _from_tlog(path: Path) -> Track:
    """A MAVLink .tlog: each record an 8-byte big-endian UTC microsecond stamp and one packet."""
    try:
        from pymavlink.dialects.v20 import common as ml
    except ImportError as exc:
        raise TrackError(f"reading a .tlog needs pymavlink (pip install 'topgimbal[mavlink]'): {exc}") from None
    data = path.read_bytes()
    parser = ml.MAVLink(None)
    parser.robust_parsing = True
    track = Track()
    i = 0
    while i + 8 < len(data):
        (usec,) = struct.unpack(">Q", data[i : i + 8])
        i += 8
        n = _packet_length(data, i)
        if n is None:
            i += 1 - 8  # not a record here: resynchronise byte by byte
            continue
        try:
            msgs = parser.parse_buffer(data[i : i + n]) or []
        except Exception:  # pymavlink raises its own errors on bad packets: skip the record
            msgs = []
        i += n
        t = usec / 1e6
        for m in msgs:
            kind = m.get_type()
            if kind == "GLOBAL_POSITION_INT" and (m.lat or m.lon):
                track.samples.append(Sample(t, m.lat / 1e7, m.lon / 1e7, m.alt / 1000.0))
            elif kind == "GIMBAL_DEVICE_ATTITUDE_STATUS" and not any(math.isnan(v) for v in m.q):
                from ..mavlink.quaternion import to_euler_deg

                e = to_euler_deg(list(m.q))
                track.poses.append((t, e.yaw_deg, e.pitch_deg, e.roll_deg))
            elif kind == "CAMERA_IMAGE_CAPTURED" and m.image_index >= 0:
                track.captures[int(m.image_index) + 1] = t
    return track


def _packet_length(data: bytes, i: int) -> int | None:
    if i >= len(data):
        return None
    if data[i] == 0xFD and i + 2 < len(data):  # MAVLink 2: header 10, checksum 2, signature 13 if flagged
        return 12 + data[i + 1] + (13 if data[i + 2] & 1 else 0)
    if data[i] == 0xFE and i + 1 < len(data):  # MAVLink 1: header 6, checksum 2
        return 8 + data[i + 1]
    return None
