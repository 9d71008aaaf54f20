"""Where each of the camera's feeds comes from, for the operator (`topgimbal mavlink --status`,
`Bridge.info()["feeds"]`): the position, the vehicle attitude, the heading and the UTC time that the
bridge takes from the autopilot (vehicle.py, mavlink/camera_feed.py) and hands to the camera, its geotags,
earth-frame yaw and CAMERA_FOV_STATUS.

For each feed: the MAVLink message in use, the system/component that sent it, its measured rate
and age; or `none` and why (nothing heard from an autopilot, asked and not answered, not asked,
heard but empty: no GPS fix or time yet, a NaN attitude; stale). The preference order and the
staleness are those of the code that uses the messages (vehicle.Vehicles, camera_feed), so the
status names the message that code takes.

Pure: messages and times go in, a dict comes out; the clock is the caller's. Bounded: one record
per watched message (four), each with at most RATE_SAMPLES arrival times."""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from ..geo.quaternion import is_valid
from .vehicle import STALE_S, TIME_STALE_S  # a fix, an attitude, a SYSTEM_TIME older than these is not used

if TYPE_CHECKING:
    from ..links.mav import MAVLinkMessage

RATE_SAMPLES = 16  # arrival times kept per message for its rate
HDG_UNKNOWN = 65535

# feed -> the messages that can carry it, preferred first (vehicle.Vehicles' order)
FEEDS: dict[str, tuple[str, ...]] = {
    "position": ("GLOBAL_POSITION_INT",),
    "attitude": ("AUTOPILOT_STATE_FOR_GIMBAL_DEVICE", "ATTITUDE"),
    "heading": ("AUTOPILOT_STATE_FOR_GIMBAL_DEVICE", "ATTITUDE", "GLOBAL_POSITION_INT"),
    "time": ("SYSTEM_TIME",),
}
WATCHED = frozenset(name for names in FEEDS.values() for name in names)


@dataclass
class Heard:
    """One message as last heard from our vehicle."""

    source: str  # "SYS/COMP"
    last: float  # when it was last heard
    arrivals: deque[float] = field(default_factory=lambda: deque(maxlen=RATE_SAMPLES))
    empty: dict[str, str] = field(default_factory=dict)  # feed -> why the last one carried nothing for it
    usable: dict[str, float] = field(default_factory=dict)  # feed -> when one last carried it

    def rate_hz(self) -> float | None:
        a = self.arrivals
        if len(a) < 2 or a[-1] <= a[0]:
            return None
        return (len(a) - 1) / (a[-1] - a[0])


def _empty_for(m: MAVLinkMessage) -> dict[str, str | None]:
    """For each feed this message can carry: None when it carries it, else why not."""
    kind = m.get_type()
    if kind == "GLOBAL_POSITION_INT":
        no_fix = "no GPS fix yet (lat, lon 0, 0)" if m.lat == 0 and m.lon == 0 else None
        return {"position": no_fix, "heading": "no heading in it (hdg unknown)" if m.hdg == HDG_UNKNOWN else None}
    if kind == "AUTOPILOT_STATE_FOR_GIMBAL_DEVICE":
        why = None if is_valid(list(m.q)) else "no attitude in it (q NaN or zero)"
        return {"attitude": why, "heading": why}
    if kind == "ATTITUDE":
        why = None if all(math.isfinite(v) for v in (m.roll, m.pitch, m.yaw)) else "no attitude in it (NaN)"
        return {"attitude": why, "heading": why}
    if kind == "SYSTEM_TIME":
        return {"time": None if int(m.time_unix_usec) > 0 else "no GPS time yet (time_unix_usec 0)"}
    return {}


class FeedSources:
    def __init__(self) -> None:
        self.heard: dict[str, Heard] = {}

    def on_message(self, m: MAVLinkMessage, now: float) -> None:
        """A message from our vehicle (the caller filters by system and own components)."""
        kind = m.get_type()
        if kind not in WATCHED:
            return
        h = self.heard.get(kind)
        source = f"{m.get_srcSystem()}/{m.get_srcComponent()}"
        if h is None or h.source != source:  # another sender: its own rate
            h = self.heard[kind] = Heard(source, now)
        h.last = now
        h.arrivals.append(now)
        for feed, why in _empty_for(m).items():
            if why is None:
                h.usable[feed] = now
                h.empty.pop(feed, None)
            else:
                h.empty[feed] = why

    def report(self, now: float, *, autopilot: str | None, asked: dict[str, int], asking: bool) -> dict[str, Any]:
        """{feed: {"message", "source", "rate_hz", "age_s", "none"}}: `none` is None when the feed
        has a source, else why it has none. `autopilot`: "SYS/COMP" of the autopilot heard (None:
        none yet); `asked`: how many times each message was asked for; `asking`: whether the
        bridge asks for what is missing (False: --no-request-streams)."""
        out: dict[str, Any] = {}
        for feed, names in FEEDS.items():
            stale_s = TIME_STALE_S if feed == "time" else STALE_S
            out[feed] = self._one(feed, names, now, stale_s) or {
                "message": None, "source": None, "rate_hz": None, "age_s": None,
                "none": self._why_none(feed, names, now, stale_s, autopilot, asked, asking),
            }  # fmt: skip
        return out

    def _one(self, feed: str, names: tuple[str, ...], now: float, stale_s: float) -> dict[str, Any] | None:
        for name in names:
            h = self.heard.get(name)
            used = h.usable.get(feed) if h is not None else None
            if h is None or used is None or now - used > stale_s:
                continue
            rate = h.rate_hz()
            return {"message": name, "source": h.source, "rate_hz": None if rate is None else round(rate, 1),
                    "age_s": round(now - h.last, 2), "none": None}  # fmt: skip
        return None

    def _why_none(
        self, feed: str, names: tuple[str, ...], now: float, stale_s: float,
        autopilot: str | None, asked: dict[str, int], asking: bool,
    ) -> str:  # fmt: skip
        heard = [(name, self.heard[name]) for name in names if name in self.heard]
        for name, h in heard:  # heard lately, but empty for this feed
            if now - h.last <= stale_s and feed in h.empty:
                return f"{name} from {h.source}: {h.empty[feed]}"
        if heard:  # heard once, not lately
            name, h = max(heard, key=lambda nh: nh[1].last)
            return f"{name} from {h.source} last heard {now - h.last:.1f} s ago"
        wanted = " or ".join(names)
        if autopilot is None:
            return f"no {wanted}: no autopilot heard on the MAVLink links"
        times = sum(asked.get(name, 0) for name in names)
        if times:
            return f"no {wanted} from the autopilot {autopilot}, asked {times} times"
        if not asking and any(name in ("GLOBAL_POSITION_INT", "SYSTEM_TIME") for name in names):
            return f"no {wanted} from the autopilot {autopilot}, not asked (--no-request-streams)"
        return f"no {wanted} from the autopilot {autopilot}"
