"""What the bridge hears about vehicles on the MAVLink network: our own vehicle's position and
attitude (for ROI, earth-frame set-points, photo positions, CAMERA_FOV_STATUS) and other systems'
positions (MAV_CMD_DO_SET_ROI_SYSID). Bounded: at most MAX_SYSTEMS remembered, our own vehicle
always among them.

Our vehicle's attitude comes from AUTOPILOT_STATE_FOR_GIMBAL_DEVICE (preferred: what an autopilot
sends its MAVLink gimbal, about 50 Hz; ArduPilot sends no ATTITUDE on a gimbal's port unless
MAVn_EXTRA1 is set) or ATTITUDE; the heading, failing both, from GLOBAL_POSITION_INT hdg."""

from __future__ import annotations

import math
from collections import OrderedDict, deque
from dataclasses import dataclass
from typing import TYPE_CHECKING

from ..clock import monotonic
from ..geo.earth import metres_per_degree, wrap180
from ..geo.frames import Geodetic
from ..geo.quaternion import is_valid, to_euler_deg

if TYPE_CHECKING:
    from ..links.mav import MAVLinkMessage

MAX_SYSTEMS = 32
STALE_S = 3.0
TIME_STALE_S = 5.0  # a SYSTEM_TIME older than this is not handed on (the offset is kept by the feeds)
# A heading is carried forward at the vehicle's yaw rate for at most this long: between two
# AUTOPILOT_STATE_FOR_GIMBAL_DEVICE (50 Hz) a turning vehicle moves on, and the camera must be
# told where the heading is now, not where it was 20 ms ago. Beyond this, the rate is not trusted.
EXTRAPOLATE_S = 0.5
YAW_RATE_SMOOTHING = 0.3  # weight of a new heading difference in the smoothed yaw rate
# Our own vehicle's recent fixes, to place a photo where the vehicle was at the shutter (issue 32:
# the last fix heard lags 4-5.5 m at 10 m/s). 64 fixes: 6 s at 10 Hz.
HISTORY_FIXES = 64
POSITION_EXTRAPOLATE_S = 1.0  # past the last fix, carried forward at its velocity this long at most

Attitude = tuple[float, float, float]  # roll_deg, pitch_deg, yaw_deg


@dataclass(frozen=True)
class VehicleFix:
    """Our vehicle as its autopilot last said (GLOBAL_POSITION_INT): where it is, its height over
    home, heading, velocity and when (by role: geo.Fix is a located ground point, client.feeds.FedPosition
    what a user feeds the camera)."""

    position: Geodetic
    relative_alt_m: float
    heading_deg: float | None
    t: float
    velocity_ned_m_s: tuple[float, float, float] = (0.0, 0.0, 0.0)

    @property
    def home_alt_m(self) -> float:
        return self.position.alt_m - self.relative_alt_m


NO_HEADING = 65535  # GLOBAL_POSITION_INT.hdg when the autopilot does not know it


def fix_of(m: MAVLinkMessage, t: float, heading_deg: float | None = None) -> VehicleFix:
    """A GLOBAL_POSITION_INT as a VehicleFix heard at `t`; `heading_deg` stands in for an unknown
    `hdg` (the console takes the newest ATTITUDE's yaw). The one reading of that message, for the
    bridge and the console alike."""
    hdg = heading_deg if m.hdg == NO_HEADING else m.hdg / 100.0
    velocity = (m.vx / 100.0, m.vy / 100.0, m.vz / 100.0)
    where = Geodetic(m.lat / 1e7, m.lon / 1e7, m.alt / 1000.0)
    return VehicleFix(where, m.relative_alt / 1000.0, hdg, t, velocity)


class Vehicles:
    MESSAGES: tuple[str, ...] = (
        "GLOBAL_POSITION_INT",
        "AUTOPILOT_STATE_FOR_GIMBAL_DEVICE",
        "ATTITUDE",
    )  # what on_message reads (node.on)

    def __init__(self, sysid: int, own_compids: set[int]) -> None:
        self.sysid = sysid
        self.own = own_compids
        self._fixes: OrderedDict[int, VehicleFix] = OrderedDict()
        # Our vehicle's attitude: (roll, pitch, yaw degrees, t) per source message type.
        self._attitude: dict[str, tuple[Attitude, float]] = {}
        # Our vehicle's yaw rate (deg/s, earth frame) and the autopilot's boot time of the last
        # AUTOPILOT_STATE_FOR_GIMBAL_DEVICE (to difference headings when it gives no rate).
        self.yaw_rate_deg_s: float = 0.0
        self._last_state: tuple[int, float] | None = None  # (time_boot_ms, yaw_deg)
        self._stamp = SenderClock()  # the autopilot's boot clock mapped onto ours
        self._attitude_stamped = 0.0  # when (our clock) the last AUTOPILOT_STATE's attitude was measured
        self._history: deque[VehicleFix] = deque(maxlen=HISTORY_FIXES)  # our vehicle's, oldest first, none at 0, 0

    def on_message(self, m: MAVLinkMessage) -> None:
        kind = m.get_type()
        src = m.get_srcSystem()
        if kind == "GLOBAL_POSITION_INT":
            now = monotonic()
            ours = src == self.sysid and m.get_srcComponent() not in self.own
            # Our vehicle's fix is dated when the autopilot measured it (its time_boot_ms on our
            # clock), not when it arrived: on a 4000 B/s payload link it comes tens of ms late, and
            # at 9 m/s each 0.1 s is 0.9 m on a photo's geotag. Other systems': their arrival.
            fix = fix_of(m, self._stamp.when(int(m.time_boot_ms) / 1000.0, now) if ours else now)
            h = self._history
            if ours and not (m.lat == 0 and m.lon == 0) and (not h or fix.t > h[-1].t):
                h.append(fix)  # (a copy heard on a second link is not newer: left out)
            self._fixes[src] = fix
            self._fixes.move_to_end(src)
            if len(self._fixes) > MAX_SYSTEMS:
                # The least recently heard other system goes; never our own vehicle (on a network
                # of more than MAX_SYSTEMS vehicles it used to be evicted between its own updates).
                oldest = next(k for k in self._fixes if k != self.sysid)
                del self._fixes[oldest]
            return
        if src != self.sysid or m.get_srcComponent() in self.own:
            return
        if kind == "AUTOPILOT_STATE_FOR_GIMBAL_DEVICE":
            # q: the vehicle's attitude, earth frame (NED) to body, Hamilton (w, x, y, z); NaN or
            # zero when the autopilot has none. Addressed to its gimbal; another gimbal's copy
            # carries the same attitude, so the target does not matter.
            if is_valid(list(m.q)):
                e = to_euler_deg(list(m.q))
                now = monotonic()
                # when the autopilot measured it, on our clock: a busy link or event loop delivers
                # it late, and a turning vehicle has moved on by then
                stamped = self._stamp.when(int(m.time_boot_us) / 1e6, now)
                self._attitude[kind] = ((e.roll_deg, e.pitch_deg, e.yaw_deg), now)
                self._attitude_stamped = stamped
                self._state_rate(m, e.yaw_deg)
        elif kind == "ATTITUDE":
            values = (m.roll, m.pitch, m.yaw)
            if all(math.isfinite(v) for v in values):
                roll, pitch, yaw = (math.degrees(v) for v in values)
                self._attitude[kind] = ((roll, pitch, yaw), monotonic())
                if "AUTOPILOT_STATE_FOR_GIMBAL_DEVICE" not in self._attitude and math.isfinite(m.yawspeed):
                    self.yaw_rate_deg_s = math.degrees(m.yawspeed)

    def _state_rate(self, m: MAVLinkMessage, yaw_deg: float) -> None:
        """The yaw rate from AUTOPILOT_STATE_FOR_GIMBAL_DEVICE: its angular_velocity_z (MAVLink 2
        extension) or feed_forward_angular_velocity_z where given, else the heading's change over
        the autopilot's own boot clock (not our arrival times, which jitter)."""
        boot_ms = int(m.time_boot_us) // 1000
        last, self._last_state = self._last_state, (boot_ms, yaw_deg)
        for field in ("angular_velocity_z", "feed_forward_angular_velocity_z"):
            v = getattr(m, field, float("nan"))
            if isinstance(v, float) and math.isfinite(v) and v != 0.0:
                self.yaw_rate_deg_s = math.degrees(v)
                return
        dt_ms = boot_ms - last[0] if last is not None else -1
        if last is None or dt_ms <= 0 or dt_ms > 500:
            if dt_ms != 0:  # a duplicate changes nothing; a gap or a reboot: no rate known
                self.yaw_rate_deg_s = 0.0
            return
        rate = wrap180(yaw_deg - last[1]) / (dt_ms / 1000.0)
        self.yaw_rate_deg_s += YAW_RATE_SMOOTHING * (rate - self.yaw_rate_deg_s)

    def fix(self, sysid: int | None = None) -> VehicleFix | None:
        f = self._fixes.get(self.sysid if sysid is None else sysid)
        if f is None or monotonic() - f.t > STALE_S:
            return None
        return f

    def position_at(self, t: float) -> VehicleFix | None:
        """Where our vehicle was at `t` (this clock): interpolated between the two fixes around it,
        or carried forward from the last one at its velocity (POSITION_EXTRAPOLATE_S at most; a
        fix older than STALE_S is none). Never a 0, 0 fix (what an autopilot sends before a fix)."""
        h = self._history
        if not h or t - h[-1].t > STALE_S:
            return None
        if t >= h[-1].t:
            return _moved(h[-1], min(t - h[-1].t, POSITION_EXTRAPOLATE_S), t)
        if t <= h[0].t:
            return h[0]
        for a, b in zip(h, list(h)[1:], strict=False):
            if a.t <= t <= b.t:
                w = (t - a.t) / (b.t - a.t) if b.t > a.t else 1.0
                pa, pb = a.position, b.position
                pos = Geodetic(pa.lat_deg + w * (pb.lat_deg - pa.lat_deg), pa.lon_deg + w * (pb.lon_deg - pa.lon_deg),
                               pa.alt_m + w * (pb.alt_m - pa.alt_m))  # fmt: skip
                rel = a.relative_alt_m + w * (b.relative_alt_m - a.relative_alt_m)
                return VehicleFix(pos, rel, b.heading_deg, t, b.velocity_ned_m_s)
        return h[-1]

    def attitude_deg(self) -> tuple[float, float, float] | None:
        """Our vehicle's (roll_deg, pitch_deg, yaw_deg), earth frame (yaw from North, clockwise;
        -180..180), from AUTOPILOT_STATE_FOR_GIMBAL_DEVICE (preferred) or ATTITUDE heard within
        STALE_S; None when neither was."""
        now = monotonic()
        for kind in ("AUTOPILOT_STATE_FOR_GIMBAL_DEVICE", "ATTITUDE"):
            got = self._attitude.get(kind)
            if got is not None and now - got[1] <= STALE_S:
                return got[0]
        return None

    @property
    def yaw_deg(self) -> float | None:
        """Our vehicle's heading (attitude_deg()'s yaw, else GLOBAL_POSITION_INT hdg), if heard lately.
        An attitude's yaw is carried forward to now at the vehicle's yaw rate (EXTRAPOLATE_S at most)."""
        got = self._heading_source()
        if got is not None:
            yaw, age_s = got
            return wrap180(yaw + self.yaw_rate_deg_s * age_s)
        f = self.fix()
        return f.heading_deg if f is not None else None

    def heading_age_s(self) -> float | None:
        """How far `yaw_deg` carries the attitude's heading forward now (s), None without one."""
        got = self._heading_source()
        return None if got is None else got[1]

    def _heading_source(self) -> tuple[float, float] | None:
        """(yaw_deg, age_s) of the attitude heard lately, AUTOPILOT_STATE_FOR_GIMBAL_DEVICE first."""
        now = monotonic()
        for kind in ("AUTOPILOT_STATE_FOR_GIMBAL_DEVICE", "ATTITUDE"):
            got = self._attitude.get(kind)
            if got is not None and now - got[1] <= STALE_S:
                # from when the autopilot measured it (AUTOPILOT_STATE's own clock), else from arrival
                measured = (
                    min(got[1], self._attitude_stamped) if kind == "AUTOPILOT_STATE_FOR_GIMBAL_DEVICE" else got[1]
                )
                return got[0][2], min(max(0.0, now - measured), EXTRAPOLATE_S)
        return None


class SenderClock:
    """A sender's clock (its boot time, seconds) mapped onto ours. Our arrival time minus its
    timestamp is the clocks' offset plus the delivery delay, and the offset is not constant: a
    sender's clock may run at another rate than ours (a crystal's few ppm; a SITL that is not quite
    real-time, PX4's ran 1.2-1.4 % slow on a loaded machine). The smallest offset of each BUCKET_S
    second (the quickest delivery) is kept for the last BUCKETS; the line through the smallest of
    the older half and of the newer half is the offset at any timestamp, so a drifting clock is
    followed without lag. (A plain minimum over 10 s lagged a 1.2 % drift by up to 120 ms: a turning
    vehicle's heading was carried 85 ms too far forward, half a degree at 6 deg/s.) A timestamp going
    back (a reboot) starts afresh. Until the timestamps have shown that they keep time (over
    TRUSTED_AFTER_S their advance within TRUST_RATIO of ours), and whenever they stop doing so (a
    counter, a constant), the arrival time is the answer."""

    BUCKET_S = 1.0
    BUCKETS = 10
    MIN_SPAN_S = 2.0  # between the two points of the line
    MAX_SKEW = 0.05
    TRUSTED_AFTER_S = 1.0
    TRUST_RATIO = 0.5  # delays of a few hundred ms on a slow link move the early ratio this much

    def __init__(self) -> None:
        self._last_sent = -math.inf
        self._bucket_t = -math.inf
        self._mins: deque[tuple[float, float]] = deque(maxlen=self.BUCKETS)  # (sent_s, offset), oldest first
        self._first: tuple[float, float] | None = None  # (sent_s, arrived) of the first since a reset

    def when(self, sent_s: float, arrived: float) -> float:
        """When (our clock) the sender stamped `sent_s`; at most `arrived`."""
        if sent_s < self._last_sent - 1.0:
            self._mins.clear()
            self._first = None
        self._last_sent = sent_s
        if self._first is None:
            self._first = (sent_s, arrived)
        ours = arrived - self._first[1]
        trusted = ours >= self.TRUSTED_AFTER_S and abs((sent_s - self._first[0]) / ours - 1.0) <= self.TRUST_RATIO
        offset = arrived - sent_s
        if arrived - self._bucket_t > self.BUCKET_S or not self._mins:
            self._mins.append((sent_s, offset))
            self._bucket_t = arrived
        elif offset < self._mins[-1][1]:
            self._mins[-1] = (sent_s, offset)
        if not trusted:
            return arrived  # not yet known to be a clock, or not one
        return min(arrived, sent_s + self._offset_at(sent_s))

    def _offset_at(self, sent_s: float) -> float:
        mins = self._mins
        half = len(mins) // 2
        if half >= 2:
            s1, o1 = min(list(mins)[:half], key=lambda p: p[1])
            s2, o2 = min(list(mins)[half:], key=lambda p: p[1])
            if s2 - s1 >= self.MIN_SPAN_S:
                slope = (o2 - o1) / (s2 - s1)
                if abs(slope) <= self.MAX_SKEW:
                    return o2 + slope * (sent_s - s2)
        return min(o for _, o in mins)  # (a slope past MAX_SKEW: a jump, not a rate)


def _moved(f: VehicleFix, dt_s: float, t: float) -> VehicleFix:
    """`f` carried `dt_s` forward at its velocity (flat earth: metres over a second)."""
    vn, ve, vd = f.velocity_ned_m_s
    p = f.position
    m_lat, m_lon = metres_per_degree(p.lat_deg)
    lat = p.lat_deg + vn * dt_s / m_lat
    lon = wrap180(p.lon_deg + ve * dt_s / max(0.01 * m_lat, m_lon))
    return VehicleFix(
        Geodetic(lat, lon, p.alt_m - vd * dt_s), f.relative_alt_m - vd * dt_s, f.heading_deg, t, f.velocity_ned_m_s
    )


Fix = VehicleFix  # the name it had
