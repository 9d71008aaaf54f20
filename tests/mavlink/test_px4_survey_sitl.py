"""A survey flown by PX4 SITL with the bridge's camera (issue 42): the mission QGroundControl's
survey makes, uploaded with pymavlink: three 150 m transects 40 m apart, DO_SET_CAM_TRIGG_DIST 20 m
with param3 1 (the first photo at once) after each transect's first waypoint and 0 after its last,
flown at 9 m/s (MPC_XY_CRUISE) at 30 m. PX4 triggers by distance (TRIG_MODE 4, TRIG_INTERFACE 3);
the bridge is on its gimbal-mode and onboard payload links (test_px4_sitl.py). Checked: photos =
PX4's triggers (CAMERA_TRIGGER), no duplicate, spacing within 10 % of 20 m, each photo's position
within 1 m of PX4's at the shutter, none in the turns (every photo on a transect). Runs only where
PX4_SITL points at PX4's `px4` SITL binary; skipped (not passed) elsewhere."""

from __future__ import annotations

import asyncio
import bisect
import itertools
import math
import shutil
import tempfile
import time
from collections.abc import Awaitable, Callable
from contextlib import AbstractAsyncContextManager
from pathlib import Path
from typing import Any

import pytest
from pymavlink.dialects.v20 import common as ml

from topgimbal.geo.aim import Geodetic, offset_m
from topgimbal.geo.earth import ned_up_to_geodetic

from .test_px4_sitl import SITL, _free_instance, gcs_streams, payload_links, px4_sitl
from .test_sitl import AUTOPILOT, Gcs, until

pytestmark = pytest.mark.external

DISTANCE_M = 20.0
TRANSECTS = 3
LENGTH_M = 150.0
SPACING_M = 40.0
ALT_M = 30.0
SPEED_M_S = 9.0
PARAMS = {"MNT_MODE_IN": "4", "MNT_MODE_OUT": "2", "TRIG_MODE": "4", "TRIG_INTERFACE": "3",
          "MPC_XY_CRUISE": str(SPEED_M_S), "COM_RC_IN_MODE": "4", "MAV_SYS_ID": "1"}  # fmt: skip
FLY_S = 240.0
ON_LINE_M = 3.0  # a photo this far off its transect's line, or beyond its ends, is in a turn


def _place(home: Geodetic, north_m: float, east_m: float) -> Geodetic:
    """`north_m`, `east_m` from `home` in its tangent plane on the WGS84 ellipsoid, at home's height."""
    lat, lon, _ = ned_up_to_geodetic((home.lat_deg, home.lon_deg, home.alt_m), north_m, east_m, 0.0)
    return Geodetic(lat, lon, home.alt_m)


def _position_at(track: list[tuple[float, Any]], t: float) -> Geodetic:
    """PX4's position at `t` (our clock), interpolated between the fixes heard around it."""
    i = bisect.bisect_left([w for w, _ in track], t)
    assert 0 < i < len(track), "no GLOBAL_POSITION_INT around that time"
    (ta, a), (tb, b) = track[i - 1], track[i]
    w = (t - ta) / (tb - ta) if tb > ta else 1.0
    return Geodetic((a.lat + w * (b.lat - a.lat)) / 1e7, (a.lon + w * (b.lon - a.lon)) / 1e7, a.alt / 1000.0)


def _speed_at(track: list[tuple[float, Any]], t: float) -> float:
    i = min(max(1, bisect.bisect_left([w for w, _ in track], t)), len(track) - 1)
    m = track[i][1]
    return math.hypot(m.vx, m.vy) / 100.0


def transects(home: Geodetic) -> list[tuple[Geodetic, Geodetic]]:
    """Lawnmower lines north-south, 20 m north of home, SPACING_M apart eastwards."""
    lines = []
    for j in range(TRANSECTS):
        a, b = _place(home, 20.0, j * SPACING_M), _place(home, 20.0 + LENGTH_M, j * SPACING_M)
        lines.append((a, b) if j % 2 == 0 else (b, a))
    return lines


def mission(home: Geodetic) -> list[Any]:
    rel, miss = ml.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, ml.MAV_FRAME_MISSION
    items: list[tuple[int, int, list[float], Geodetic | None]] = [(ml.MAV_CMD_NAV_TAKEOFF, rel, [0] * 4, home)]
    for a, b in transects(home):
        items += [(ml.MAV_CMD_NAV_WAYPOINT, rel, [0] * 4, a),
                  (ml.MAV_CMD_DO_SET_CAM_TRIGG_DIST, miss, [DISTANCE_M, 0, 1, 0], None),
                  (ml.MAV_CMD_NAV_WAYPOINT, rel, [0] * 4, b),
                  (ml.MAV_CMD_DO_SET_CAM_TRIGG_DIST, miss, [0, 0, 0, 0], None)]  # fmt: skip
    items.append((ml.MAV_CMD_NAV_RETURN_TO_LAUNCH, miss, [0] * 4, None))
    out = []
    for seq, (cmd, frame, p, where) in enumerate(items):
        x, y, z = (round(where.lat_deg * 1e7), round(where.lon_deg * 1e7), ALT_M) if where else (0, 0, 0.0)
        out.append(ml.MAVLink_mission_item_int_message(*AUTOPILOT, seq, frame, cmd, 0, 1, *p, x, y, z, 0))
    return out


async def upload(g: Gcs, items: list[Any], seen: list[Any]) -> None:
    seen.clear()
    g.send(ml.MAVLink_mission_count_message(*AUTOPILOT, len(items), 0))
    t0 = time.monotonic()
    sent: set[int] = set()
    while not any(m.get_type() == "MISSION_ACK" for m in seen):
        assert time.monotonic() - t0 < 30, f"mission upload: {len(sent)} of {len(items)} items asked for"
        for m in [m for m in seen if m.get_type() in ("MISSION_REQUEST_INT", "MISSION_REQUEST")]:
            seen.remove(m)
            g.send(items[m.seq])
            sent.add(m.seq)
        await asyncio.sleep(0.05)
    ack = next(m for m in seen if m.get_type() == "MISSION_ACK")
    assert ack.type == ml.MAV_MISSION_ACCEPTED and len(sent) == len(items), (ack.type, sorted(sent))


@pytest.mark.skipif(not SITL, reason="PX4_SITL is not set to PX4's px4 SITL binary: the survey cannot be flown")
async def test_px4_flies_a_survey_one_photo_per_trigger(rig_factory: Any) -> None:
    assert SITL is not None and Path(SITL).is_file(), f"PX4_SITL={SITL!r} is not a file"
    work = Path(tempfile.mkdtemp(prefix="px4-survey-"))
    instance = _free_instance()
    r = await rig_factory("C12", role="device", endpoints=payload_links(instance))
    await fly_printing(px4_sitl(work, instance, PARAMS), lambda g, rows: _fly(r, g, rows), work)


async def fly_printing(
    sitl: AbstractAsyncContextManager[Gcs], fly: Callable[[Gcs, list[str]], Awaitable[None]], work: Path
) -> None:
    """`fly` with the autopilot `sitl` starts; the figures it gathered are printed and the work
    directory removed, whether it passed or not (both surveys, PX4's and ArduPilot's)."""
    rows: list[str] = []
    try:
        async with sitl as g:
            await fly(g, rows)
    finally:
        print("\n".join(rows))
        shutil.rmtree(work, ignore_errors=True)


async def _fly(r: Any, g: Gcs, rows: list[str]) -> None:
    sim = r.sim
    seen: list[Any] = []
    kinds = {"MISSION_REQUEST_INT", "MISSION_REQUEST", "MISSION_ACK", "CAMERA_TRIGGER", "MISSION_ITEM_REACHED"}
    track: list[tuple[float, Any]] = []  # PX4's GLOBAL_POSITION_INT, all of the flight (Gcs keeps 12 s)

    def heard(m: Any) -> None:
        if m.get_srcSystem() != 1:
            return
        if m.get_type() in kinds:
            seen.append(m)
        elif m.get_type() == "GLOBAL_POSITION_INT" and m.get_srcComponent() == 1:
            track.append((time.monotonic(), m))

    g.mav.set_callback(heard)
    await until(lambda: g.position is not None and g.position.lat != 0, 120, "a GPS fix from PX4")
    await gcs_streams(g)
    home = g.place
    items = mission(home)
    await upload(g, items, seen)
    shutters: list[float] = []
    sim.device.state.capture_listeners.append(lambda event, index: shutters.append(time.monotonic()))
    taken0 = sim.camera.photos_taken
    for _ in range(30):  # PX4 arms once its estimator is ready
        if (await g.command(ml.MAV_CMD_COMPONENT_ARM_DISARM, 1)).result == ml.MAV_RESULT_ACCEPTED:
            break
        await asyncio.sleep(2.0)
    else:
        raise AssertionError("PX4 refused to arm for 60 s: " + "; ".join(t for _, t in g.texts[-5:]))
    ack = await g.command(ml.MAV_CMD_MISSION_START, 0, 0)
    assert ack.result == ml.MAV_RESULT_ACCEPTED, ack
    last_wp = len(items) - 3  # the last transect's last waypoint
    await until(lambda: any(m.get_type() == "MISSION_ITEM_REACHED" and m.seq >= last_wp for m in seen), FLY_S,
                "the last transect flown")  # fmt: skip
    await asyncio.sleep(3.0)
    triggers = [m for m in seen if m.get_type() == "CAMERA_TRIGGER"]
    taken = sim.camera.photos_taken - taken0
    records = dict(r.bridge.cameras[0].images)  # the bridge's CAMERA_IMAGE_CAPTURED records
    rows.append(f"survey: PX4 triggers {len(triggers)}, photos taken {taken}, bridge records {len(records)}")
    photos = [records[i] for i in sorted(records)]
    where = [Geodetic(m.lat / 1e7, m.lon / 1e7, home.alt_m) for m in photos]
    # geotags against PX4's position at each shutter
    errors_m = []
    for p, shutter in zip(where, shutters[-len(where) :], strict=True):
        n, e, _ = offset_m(_position_at(track, shutter), p)
        errors_m.append(math.hypot(n, e))
    # each photo on a transect (none in the turns), and the spacing along each
    per_line: dict[int, list[float]] = {}
    off_line = []
    for i, p in enumerate(where):
        fits = []
        for j, (a, b) in enumerate(transects(home)):
            an, ae, _ = offset_m(a, p)
            bn, be, _ = offset_m(a, b)
            along = (an * bn + ae * be) / LENGTH_M
            across = abs(an * be - ae * bn) / LENGTH_M
            if across <= ON_LINE_M and -ON_LINE_M <= along <= LENGTH_M + ON_LINE_M:
                fits.append((j, along))
        if not fits:
            off_line.append(i)
        else:
            per_line.setdefault(fits[0][0], []).append(fits[0][1])
    for i, (p, m, err) in enumerate(zip(where, photos, errors_m, strict=True)):
        fix = _position_at(track, shutters[-len(where) + i])
        rows.append(f"photo {m.image_index}: geotag error {err:.2f} m at {_speed_at(track, shutters[-len(where) + i]):.1f} "
                    f"m/s (PX4 {fix.lat_deg:.7f} {fix.lon_deg:.7f}, bridge {p.lat_deg:.7f} {p.lon_deg:.7f})")  # fmt: skip
    gaps = [b - a for line in per_line.values() for a, b in itertools.pairwise(sorted(line))]
    # the same from PX4's own position at each shutter: PX4's trigger spacing, without the geotags' errors
    truth = [_position_at(track, t) for t in shutters[-len(where) :]]
    true_gaps = [math.hypot(*offset_m(a, b)[:2]) for a, b in itertools.pairwise(truth)]
    true_gaps = [d for d in true_gaps if d < 1.5 * DISTANCE_M]  # not across a turn
    rows.append(f"spacing at PX4's own positions (m) min {min(true_gaps):.2f} max {max(true_gaps):.2f}")
    rows.append(f"photos per transect {[len(per_line.get(j, [])) for j in range(TRANSECTS)]}; off the lines "
                f"(in turns) {len(off_line)}; spacing (m) min {min(gaps):.2f} max {max(gaps):.2f}; "
                f"geotag error (m) max {max(errors_m):.2f}")  # fmt: skip
    assert taken == len(triggers) == len(records), "photos = triggers, no duplicate"
    assert len(per_line) == TRANSECTS and off_line == [], off_line
    assert all(abs(gap - DISTANCE_M) <= 0.1 * DISTANCE_M for gap in gaps), gaps
    assert max(errors_m) < 1.0, errors_m
