"""Where the vehicle and the target are, for the operator (issue 41.9): `GET api/where` and the
page's "Where" rows in the Laser range & target panel.

The vehicle's fix comes, first found:
- `feeds`: what this console's client feeds the camera (a fresh `cam.feed(...)` fix: a program or a
  bridge sharing the client);
- `autopilot`: the autopilot's GLOBAL_POSITION_INT heard on `--autopilot HOST:PORT`
  (autopilot.py), the target placed on flat ground at its home altitude;
- `camera`: with `--sim`, what the simulated camera was fed: by a bridge (its autopilot's
  GLOBAL_POSITION_INT and heading), ArduPilot's own camera driver, or the page's vehicle rows.
  The simulator's flat ground is at altitude 0 (the fed ALT is the height above it).
The target is where the camera's axis meets the ground from that fix: `cam.locate()` (the SDK's
geolocation, the same core as the bridge's CAMERA_FOV_STATUS). A camera's own target solution
(TOPOTEK §8.7, after a laser measurement) is still shown from its reports as before.

The answer is cached for CACHE_S (a locate asks the camera for its attitude: several pages polling
cost the camera one pair of queries, not one per page)."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import TYPE_CHECKING, Any

from ..clock import monotonic
from ..errors import TopGimbalError
from ..geo.earth import wrap360

if TYPE_CHECKING:
    from ..sim import Simulator
    from .autopilot import AutopilotListener

CACHE_S = 0.5


@dataclass(frozen=True)
class VehiclePlace:
    """Where the console puts the vehicle, and who says so (by role: autopilot.vehicle.VehicleFix is
    what an autopilot said, client.feeds.FedPosition what a user fed the camera)."""

    lat_deg: float
    lon_deg: float
    alt_m: float  # MSL (the simulator: above its flat ground)
    heading_deg: float | None  # true, 0..360
    source: str  # "feeds", "autopilot" or "camera"
    ground_alt_m: float | None  # the flat ground the target is placed on (None: not known here)


def vehicle_fix(cam: Any, sim: Simulator | None, autopilot: AutopilotListener | None = None) -> VehiclePlace | None:
    """The vehicle's fix from the first source that has one (module docstring), or None."""
    feeds: Any = getattr(cam, "feeds", None)
    fix = getattr(feeds, "fix", None)
    if fix is not None and feeds.fix_fresh():
        heading = None if fix.heading_deg is None else wrap360(fix.heading_deg)
        return VehiclePlace(fix.lat_deg, fix.lon_deg, fix.alt_m, heading, "feeds", None)
    heard = autopilot.fix() if autopilot is not None else None
    if heard is not None:
        p = heard.position
        return VehiclePlace(p.lat_deg, p.lon_deg, p.alt_m, heard.heading_deg, "autopilot", heard.home_alt_m)
    if sim is None:
        return None
    from ..sim.world import pose_of

    state = sim.device.state
    pos = state.position
    if pos.lat_deg is None or pos.lon_deg is None or pos.alt_m is None:
        return None
    heading = wrap360(pose_of(state.gimbal, pos).vehicle_yaw_deg)
    ground = 0.0 if state.terrain is None else None
    return VehiclePlace(pos.lat_deg, pos.lon_deg, pos.alt_m, heading, "camera", ground)


async def where(cam: Any, sim: Simulator | None, autopilot: AutopilotListener | None = None) -> dict[str, Any]:
    """{"vehicle": fix or null, "target": located point or null, "why": what is missing}."""
    fix = vehicle_fix(cam, sim, autopilot)
    if fix is None:
        why = "no vehicle position: feed one (a bridge, the SDK's feed(), --autopilot) or set it in the vehicle rows"
        return {"vehicle": None, "target": None, "why": why}
    vehicle = {k: v for k, v in asdict(fix).items() if k != "ground_alt_m"}
    if fix.heading_deg is None:
        return {"vehicle": vehicle, "target": None, "why": "no vehicle heading"}
    if fix.ground_alt_m is None:
        return {"vehicle": vehicle, "target": None, "why": "no ground altitude known to this console"}
    locate = getattr(cam, "locate", None)
    if locate is None:
        return {"vehicle": vehicle, "target": None, "why": "this camera's client cannot locate"}
    try:
        hit = await locate(
            position=(fix.lat_deg, fix.lon_deg, fix.alt_m), heading_deg=fix.heading_deg, ground_alt_m=fix.ground_alt_m
        )
    except TopGimbalError as exc:
        return {"vehicle": vehicle, "target": None, "why": f"cannot locate: {exc}"}
    if hit is None or not math.isfinite(hit.lat_deg):
        return {"vehicle": vehicle, "target": None, "why": "the camera looks above the horizon"}
    target = hit.as_dict()
    return {"vehicle": vehicle, "target": target, "why": ""}


class WhereCache:
    """One answer per CACHE_S for all the pages of a camera."""

    def __init__(self) -> None:
        self._at = -math.inf
        self._answer: dict[str, Any] | None = None

    async def get(self, cam: Any, sim: Simulator | None, autopilot: AutopilotListener | None) -> dict[str, Any]:
        now = monotonic()
        if self._answer is None or now - self._at >= CACHE_S:
            self._answer, self._at = await where(cam, sim, autopilot), now
        return self._answer
