"""Where the vehicle was, and when, from a log: the client's traffic log (JSONL: the LAT / LON /
ALT / AZI / GPS frames a host fed the camera, the gimbal attitude answers, the CAP answers with
their file index) or a MAVLink telemetry log (.tlog: GLOBAL_POSITION_INT, ATTITUDE, and
MAV_CMD_IMAGE_START_CAPTURE's CAMERA_IMAGE_CAPTURED).

`Track.at(t)` interpolates the position linearly between the two samples around `t` (UTC seconds);
before the first or after the last sample it holds that sample for at most `max_gap_s` (a host
feeds a position every so often: the camera would have had that one); further out, or across a
gap longer than `max_gap_s`, there is no position (never a guess).

Positions a log holds that no place has are dropped, never written into a photo: MAVLink's "unknown"
(INT32_MAX in lat / lon), 0, 0 (what an autopilot sends before its first fix), and anything outside
+-90 / +-180 degrees or not finite.

Each capture keeps which camera it came from (`Capture`): the MAVLink component that sent
CAMERA_IMAGE_CAPTURED, the vendor and model that component's CAMERA_INFORMATION named, the file its
`file_url` names; for a traffic log (one camera) the log's model. geotag_cmd.py matches a photo only
to its own camera's captures."""

from __future__ import annotations

import bisect
import json
import math
import os
import stat
import struct
from dataclasses import dataclass, field
from pathlib import Path

from ..client.signs import map_message
from ..client.traffic import read_log
from ..errors import InputError, TopGimbalError
from ..protocol import get_dialect, get_model

MAX_HEADER_CHARS = 64 * 1024  # a traffic log's header line (the rest is read record by record)
POSITION_ROLES = {"latitude": "lat_deg", "longitude": "lon_deg", "altitude": "alt_m"}


class TrackError(TopGimbalError, ValueError):
    """A log that holds no track (not a log, or no position in it)."""


class LogFileError(InputError, ValueError):
    """--log names no regular file (a FIFO, a device): refused unread, exit 2."""


@dataclass(frozen=True)
class Sample:
    t: float  # UTC seconds
    lat_deg: float
    lon_deg: float
    alt_m: float


def valid_position(lat_deg: float, lon_deg: float) -> bool:
    """A place on Earth: finite, within +-90 / +-180, and not 0, 0 (no fix yet)."""
    if not (math.isfinite(lat_deg) and math.isfinite(lon_deg)):
        return False
    if abs(lat_deg) > 90.0 or abs(lon_deg) > 180.0:
        return False
    return not (lat_deg == 0.0 and lon_deg == 0.0)


@dataclass(frozen=True)
class Capture:
    """One photo the log says was taken, and by which camera (None: the log does not say)."""

    t: float  # UTC seconds the log heard it
    index: int  # the photo's file index (CAP feedback; CAMERA_IMAGE_CAPTURED.image_index + 1)
    compid: int | None = None  # the MAVLink component that sent it
    vendor: str | None = None  # lower case: "topotek", "skydroid"
    model: str | None = None  # as CAMERA_INFORMATION / the traffic log's header names it
    file_name: str | None = None  # the last part of CAMERA_IMAGE_CAPTURED.file_url

    def camera(self) -> str:
        parts = [f"component {self.compid}" if self.compid is not None else "", self.model or ""]
        return " ".join(p for p in parts if p) or "the logged camera"


@dataclass
class Track:
    samples: list[Sample] = field(default_factory=list)
    poses: list[tuple[float, float, float, float]] = field(default_factory=list)  # (t, yaw, pitch, roll) gimbal
    capture_list: list[Capture] = field(default_factory=list)
    max_gap_s: float = 10.0
    dropped_positions: int = 0  # samples that were no place (module docstring)

    @property
    def captures(self) -> dict[int, float]:
        """File index -> UTC seconds, for a log of one camera (the last capture of each index)."""
        return {c.index: c.t for c in self.capture_list}

    def captures_of(self, index: int) -> list[Capture]:
        return [c for c in self.capture_list if c.index == index]

    def cameras(self) -> set[int | None]:
        """The components captures came from (None for a traffic log's one camera)."""
        return {c.compid for c in self.capture_list}

    def add_sample(self, sample: Sample) -> None:
        if valid_position(sample.lat_deg, sample.lon_deg) and math.isfinite(sample.alt_m):
            self.samples.append(sample)
        else:
            self.dropped_positions += 1

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
    head = _head(path)
    track = _from_traffic(path) if head.lstrip().startswith(b"{") else _from_tlog(path)
    if not track.samples:
        raise TrackError(f"{path}: no vehicle position in this log (LAT/LON/ALT frames or GLOBAL_POSITION_INT)")
    track.samples.sort(key=lambda s: s.t)
    track.poses.sort()
    return track


def _head(path: Path) -> bytes:
    """The first bytes of a regular file (a FIFO or /dev/zero named as a log: refused, not read)."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_NOCTTY", 0))
    except IsADirectoryError:
        raise TrackError(f"{path}: a folder, not a log") from None
    with os.fdopen(fd, "rb") as fh:
        if not stat.S_ISREG(os.fstat(fh.fileno()).st_mode):
            raise LogFileError(f"{path}: not a regular file (a FIFO, a device or a socket): give a log file")
        return fh.read(64)


def _from_traffic(path: Path) -> Track:
    with path.open(encoding="utf-8", errors="replace") as fh:
        try:
            header = json.loads(fh.readline(MAX_HEADER_CHARS))
        except (ValueError, RecursionError):  # RecursionError: nested past Python's recursion
            header = {}
    if not isinstance(header, dict) or "topgimbal_log" not in header:
        raise TrackError(f"{path}: not a topgimbal traffic log (no header line) nor a MAVLink .tlog")
    try:
        dialect, model = get_model(str(header.get("model") or "C12"))
    except TopGimbalError:
        dialect, model = get_dialect(str(header.get("dialect") or "skydroid")), None
    track = Track()
    vendor = dialect.name.lower()
    model_name = model.name if model is not None else None
    current: dict[str, float] = {}
    for rec in read_log(path):
        m = dialect.decode(rec.frame)
        if m.fields is None or m.spec is None:
            continue
        role = m.spec.role
        if rec.direction == "out" and role in POSITION_ROLES and rec.frame.rw == "w":
            current[POSITION_ROLES[role]] = float(m.fields[POSITION_ROLES[role]])
            if role == "altitude" and {"lat_deg", "lon_deg"} <= current.keys():
                track.add_sample(Sample(rec.t, current["lat_deg"], current["lon_deg"], current["alt_m"]))
        elif rec.direction == "out" and role == "vehicle_position":
            f = m.fields
            track.add_sample(Sample(rec.t, float(f["lat_deg"]), float(f["lon_deg"]), float(f["alt_m"])))
        elif rec.direction == "in" and role == "attitude" and {"yaw_deg", "pitch_deg"} <= m.fields.keys():
            f = (map_message(m, model.wire_signs) if model is not None else m).fields or {}
            track.poses.append((rec.t, float(f["yaw_deg"]), float(f["pitch_deg"]), float(f.get("roll_deg", 0.0))))
        elif rec.direction == "in" and role == "photo" and "file_index" in m.fields:
            index = int(m.fields["file_index"])
            track.capture_list.append(Capture(rec.t, index, vendor=vendor, model=model_name))
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
    info: dict[int, tuple[str, str]] = {}  # component -> (vendor, model) from CAMERA_INFORMATION
    raw: list[tuple[float, int, int, str]] = []  # (t, index, component, file name)
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
            if kind == "GLOBAL_POSITION_INT":  # INT32_MAX = unknown, 0 / 0 = no fix: add_sample drops them
                track.add_sample(Sample(t, m.lat / 1e7, m.lon / 1e7, m.alt / 1000.0))
            elif kind == "GIMBAL_DEVICE_ATTITUDE_STATUS" and not any(math.isnan(v) for v in m.q):
                from ..mavlink.quaternion import to_euler_deg

                e = to_euler_deg(list(m.q))
                track.poses.append((t, e.yaw_deg, e.pitch_deg, e.roll_deg))
            elif kind == "CAMERA_IMAGE_CAPTURED" and m.image_index >= 0 and m.capture_result == 1:
                url = _text(m.file_url)
                raw.append((t, int(m.image_index) + 1, m.get_srcComponent(), url.rsplit("/", 1)[-1] if url else ""))
            elif kind == "CAMERA_INFORMATION":
                name = _text(m.model_name)
                name = name[: -len(" thermal")] if name.endswith(" thermal") else name  # the bridge's thermal lens
                info[m.get_srcComponent()] = (_text(m.vendor_name).split(" ")[0].lower(), name)
    for t, index, compid, file_name in raw:
        vendor, model = info.get(compid, (None, None))
        track.capture_list.append(Capture(t, index, compid, vendor or None, model or None, file_name or None))
    return track


def _text(value: object) -> str:
    """A MAVLink char / uint8 array field as text (pymavlink gives str or a list of ints)."""
    if isinstance(value, (list, tuple)):
        value = bytes(int(v) & 0xFF for v in value)
    if isinstance(value, (bytes, bytearray)):
        value = bytes(value).split(b"\0", 1)[0].decode("utf-8", "replace")
    return str(value).split("\0", 1)[0].strip()


def _packet_length(data: bytes, i: int) -> int | None:
    if i >= len(data):
        return None
    if data[i] == 0xFD and i + 2 < len(data):  # MAVLink 2: header 10, checksum 2, signature 13 if flagged
        return 12 + data[i + 1] + (13 if data[i + 2] & 1 else 0)
    if data[i] == 0xFE and i + 1 < len(data):  # MAVLink 1: header 6, checksum 2
        return 8 + data[i + 1]
    return None
