"""A survey flown by ArduPilot SITL with the bridge's camera (issue 42): the ArduPilot counterpart of
test_px4_survey_sitl.py. The mission QGroundControl's survey makes, uploaded with pymavlink
(MISSION_ITEM_INT): takeoff to 30 m, three 150 m transects 40 m apart, DO_SET_CAM_TRIGG_DIST 20 m
with param3 1 (the first photo at once) after each transect's first waypoint and 0 after its last,
flown at 9 m/s (WPNAV_SPEED 900), then RTL. ArduPilot triggers the bridge as a MAVLink camera
(`CAM1_TYPE 6`, MAVLinkCamV2: MAV_CMD_IMAGE_START_CAPTURE on SERIAL2), set up as test_sitl.py does
(a first short boot saves CAM1_TYPE and calibrates the accelerometers). Checked: photos taken =
ArduPilot's triggers (CAMERA_FEEDBACK) = the bridge's records (CAMERA_IMAGE_CAPTURED from its camera
component, heard through ArduPilot), no duplicate, the spacing of the photos' geotags within 10 % of
20 m, each geotag within 1 m of ArduPilot's position at the shutter (GLOBAL_POSITION_INT,
interpolated), none in the turns (each photo within 3 m of its transect's line and within its ends).
Runs only where ARDUPILOT_SITL points at an `arducopter` SITL binary; skipped (not passed) elsewhere.
The figures are printed (`pytest -s`)."""

from __future__ import annotations

import asyncio
import contextlib
import itertools
import math
import tempfile
import time
from collections.abc import AsyncIterator
from pathlib import Path
from typing import Any

import pytest
from pymavlink.dialects.v20 import ardupilotmega
from pymavlink.dialects.v20 import common as ml

from topgimbal.geo import LocalFrame
from topgimbal.geo.aim import Geodetic, offset_m

from .test_px4_survey_sitl import (
    ALT_M,
    DISTANCE_M,
    LENGTH_M,
    SPACING_M,
    SPEED_M_S,
    TRANSECTS,
    _position_at,
    _speed_at,
    fly_printing,
    upload,
)
from .test_sitl import (
    AUTOPILOT,
    BOOT_S,
    CAMERA,
    SITL,
    Gcs,
    _connect,
    _free_instance,
    _free_port,
    first_boot,
    stop_sitl,
    until,
)

pytestmark = pytest.mark.external

# the same mission as PX4's survey: 3 transects x 150 m, 40 m apart, a photo every 20 m, 30 m up, 9 m/s
# test_sitl.py's setup (the quad, the MAVLink gimbal on SERIAL2) and the survey's speed
PARAMS = f"""\
FRAME_CLASS 1
FRAME_TYPE 1
MNT1_TYPE 6
SERIAL2_PROTOCOL 2
WPNAV_SPEED {SPEED_M_S * 100:g}
"""
CAM_TYPE = 6  # MAVLinkCamV2: a MAVLink camera (protocol v2), triggered with MAV_CMD_IMAGE_START_CAPTURE
FLY_S = 240.0  # from MISSION_START to the last transect's end: about 90 s at 9 m/s
ARM_S = 150.0  # the EKF needs a while after boot before ArduPilot agrees to arm
ON_LINE_M = 3.0  # a photo this far off its transect's line, or beyond its ends, is in a turn
SPACING_GOAL = 0.10  # of DISTANCE_M
POSITION_GOAL_M = 1.0


def transects(home: Geodetic) -> list[tuple[Geodetic, Geodetic]]:
    """Lawnmower lines north-south, from 20 m north of home, SPACING_M apart eastwards (points on
    the WGS84 ellipsoid: topgimbal.geo's tangent frame at home)."""
    frame = LocalFrame(home)
    lines = []
    for j in range(TRANSECTS):
        a, b = frame.to_geodetic(20.0, j * SPACING_M, 0.0), frame.to_geodetic(20.0 + LENGTH_M, j * SPACING_M, 0.0)
        lines.append((a, b) if j % 2 == 0 else (b, a))
    return lines


def mission(home: Geodetic) -> list[Any]:
    """As QGroundControl uploads a survey to ArduPilot: item 0 is home (ArduPilot keeps its own),
    then the takeoff, the transects with their trigger distances, and RTL."""
    glob, rel, miss = ml.MAV_FRAME_GLOBAL, ml.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, ml.MAV_FRAME_MISSION
    items: list[tuple[int, int, list[float], Geodetic | None, float]] = [
        (ml.MAV_CMD_NAV_WAYPOINT, glob, [0] * 4, home, home.alt_m),
        (ml.MAV_CMD_NAV_TAKEOFF, rel, [0] * 4, None, ALT_M),
    ]
    for a, b in transects(home):
        items += [(ml.MAV_CMD_NAV_WAYPOINT, rel, [0] * 4, a, ALT_M),
                  (ml.MAV_CMD_DO_SET_CAM_TRIGG_DIST, miss, [DISTANCE_M, 0, 1, 0], None, 0.0),
                  (ml.MAV_CMD_NAV_WAYPOINT, rel, [0] * 4, b, ALT_M),
                  (ml.MAV_CMD_DO_SET_CAM_TRIGG_DIST, miss, [0, 0, 0, 0], None, 0.0)]  # fmt: skip
    items.append((ml.MAV_CMD_NAV_RETURN_TO_LAUNCH, miss, [0] * 4, None, 0.0))
    out = []
    for seq, (cmd, frame, p, where, z) in enumerate(items):
        x, y = (round(where.lat_deg * 1e7), round(where.lon_deg * 1e7)) if where else (0, 0)
        out.append(ml.MAVLink_mission_item_int_message(*AUTOPILOT, seq, frame, cmd, 0, 1, *p, x, y, z, 0))
    return out


@contextlib.asynccontextmanager
async def ardupilot_sitl(work: Path, bridge_port: int) -> AsyncIterator[Gcs]:
    """ArduCopter SITL with its SERIAL2 on the bridge and a ground station on its SERIAL0, set up
    as test_sitl.py's `_run` does and for the reasons it gives: a first short boot saves CAM1_TYPE
    and CAM2_TYPE (from a defaults file they do not stick) and calibrates the accelerometers, then
    the real boot. SITL's output in `work`/sitl.log, its tail printed when the body fails."""
    (work / "survey.parm").write_text(PARAMS)
    log_path = work / "sitl.log"
    instance = _free_instance()

    async def start(base: int, *extra: str) -> asyncio.subprocess.Process:
        with open(log_path, "ab") as out:
            return await asyncio.create_subprocess_exec(
                str(SITL), "--model", "quad", "--speedup", "1", "--defaults", str(work / "survey.parm"),
                "-I", str(instance), "--base-port", str(base), *extra,
                cwd=work, stdout=out, stderr=asyncio.subprocess.STDOUT,
            )  # fmt: skip

    await first_boot(start)
    base = _free_port()
    proc = await start(base, "--serial2", f"tcpclient:127.0.0.1:{bridge_port}")
    gcs: Gcs | None = None
    try:
        gcs = await _connect(proc, base)
        # ArduPilot's own messages (CAMERA_FEEDBACK) are in its dialect, not in common: test_sitl's
        # parser would drop them as bad data. Swapped before anything but SITL's banner is read.
        gcs.mav = ardupilotmega.MAVLink(None, srcSystem=255, srcComponent=190)
        gcs.mav.robust_parsing = True
        yield gcs
    except BaseException:
        with contextlib.suppress(OSError):
            print("--- SITL output, last 4000 bytes ---\n" + log_path.read_bytes()[-4000:].decode("utf-8", "replace"))
        if gcs is not None:
            print("--- the autopilot's STATUSTEXTs ---\n" + "\n".join(t for _, t in gcs.texts[-40:]))
        raise
    finally:
        if gcs is not None:
            await gcs.close()
        await stop_sitl(proc)


@pytest.mark.skipif(
    not SITL, reason="ARDUPILOT_SITL is not set to an arducopter SITL binary: the ArduPilot survey cannot be flown"
)
async def test_ardupilot_flies_a_survey_one_photo_per_trigger(rig_factory: Any) -> None:
    assert SITL is not None and Path(SITL).is_file(), f"ARDUPILOT_SITL={SITL!r} is not a file"
    work = Path(tempfile.mkdtemp(prefix="ardupilot-survey-"))
    # the bridge as test_sitl.py has it: a tcpin link for the autopilot's SERIAL2 (SITL connects to it)
    r = await rig_factory(CAMERA, role="device", endpoints=["udpin:127.0.0.1:0", "tcpin:127.0.0.1:0"])
    _, bridge_port = r.bridge.addresses[1]
    await fly_printing(ardupilot_sitl(work, bridge_port), lambda g, rows: _fly(r, g, rows), work)


async def _fly(r: Any, g: Gcs, rows: list[str]) -> None:
    sim = r.sim
    camera = r.bridge.cameras[0]  # the lens ArduPilot found first: the one it triggers
    seen: list[Any] = []
    kinds = {"MISSION_REQUEST_INT", "MISSION_REQUEST", "MISSION_ACK", "MISSION_ITEM_REACHED"}
    track: list[tuple[float, Any]] = []  # ArduPilot's GLOBAL_POSITION_INT, all of the flight (Gcs keeps 30 s)
    feedback: list[tuple[float, Any]] = []  # ArduPilot's CAMERA_FEEDBACK: one per trigger
    captured: list[tuple[float, Any]] = []  # the bridge's CAMERA_IMAGE_CAPTURED, heard through ArduPilot

    def heard(m: Any) -> None:
        kind, src = m.get_type(), (m.get_srcSystem(), m.get_srcComponent())
        if kind == "CAMERA_IMAGE_CAPTURED" and src == (camera.comp.node.sysid, camera.comp.compid):
            captured.append((time.monotonic(), m))
        elif src != AUTOPILOT:
            return
        elif kind in kinds:
            seen.append(m)
        elif kind == "CAMERA_FEEDBACK" and m.cam_idx == 0:
            # CAM1's (the mission's camera); each trigger makes ArduPilot send one for every
            # camera instance, CAM2's with nothing in it
            feedback.append((time.monotonic(), m))
        elif kind == "GLOBAL_POSITION_INT":
            track.append((time.monotonic(), m))

    g.mav.set_callback(heard)
    arrivals: dict[int, float] = {}  # ArduPilot's photo requests as the bridge got them, by sequence number

    def requested(m: Any) -> None:
        if m.get_type() == "COMMAND_LONG" and m.command == ml.MAV_CMD_IMAGE_START_CAPTURE:
            arrivals.setdefault(round(m.param4), time.monotonic())

    r.bridge.node.subscribe(requested)
    t_boot = time.monotonic()
    # ArduPilot's MAVLinkCamV2 finds the camera ("Camera: ..."): until then a trigger has nowhere to go
    await until(lambda: bool(g.texts_since(0.0, "Camera: ")), BOOT_S, '"Camera:" from the autopilot')
    boot_s = time.monotonic() - t_boot
    ack = await g.command(ml.MAV_CMD_SET_MESSAGE_INTERVAL, ml.MAVLINK_MSG_ID_GLOBAL_POSITION_INT, 1e6 / 20)
    assert ack.result == ml.MAV_RESULT_ACCEPTED, ack  # our truth at each shutter, 20 Hz
    await until(lambda: g.position is not None and g.position.lat != 0, 60, "a position from the autopilot")
    wpnav_speed = await g.param("WPNAV_SPEED")
    cam_type = await g.param("CAM1_TYPE")
    assert (wpnav_speed, cam_type) == (SPEED_M_S * 100, CAM_TYPE), (wpnav_speed, cam_type)
    home = g.place
    items = mission(home)
    await upload(g, items, seen)
    shutters: list[float] = []
    sim.device.state.capture_listeners.append(
        lambda event, index: shutters.append(time.monotonic()) if event == "photo" else None
    )
    taken0, index0 = sim.camera.photos_taken, camera.image_count
    ack = await g.command(ml.MAV_CMD_DO_SET_MODE, ml.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, 4)  # GUIDED
    assert ack.result == ml.MAV_RESULT_ACCEPTED, ack
    t_arm = time.monotonic()
    while (await g.command(ml.MAV_CMD_COMPONENT_ARM_DISARM, 1)).result != ml.MAV_RESULT_ACCEPTED:
        assert time.monotonic() - t_arm < ARM_S, "ArduPilot refused to arm: " + "; ".join(t for _, t in g.texts[-5:])
        await asyncio.sleep(3.0)
    arm_s = time.monotonic() - t_arm
    ack = await g.command(ml.MAV_CMD_MISSION_START, 0, 0)  # AUTO, the mission from its first item
    assert ack.result == ml.MAV_RESULT_ACCEPTED, ack
    t_start = time.monotonic()
    last_wp = len(items) - 3  # the last transect's last waypoint
    await until(lambda: any(m.get_type() == "MISSION_ITEM_REACHED" and m.seq >= last_wp for m in seen), FLY_S,
                "the last transect flown")  # fmt: skip
    fly_s = time.monotonic() - t_start
    await asyncio.sleep(5.0)  # the last record heard, and no trigger after the last transect (on the way home)
    rows.append(f"times (s): boot to \"Camera:\" {boot_s:.1f}, arming {arm_s:.1f}, mission start to the last "
                f"transect's end {fly_s:.1f}; WPNAV_SPEED {wpnav_speed:g}, CAM1_TYPE {cam_type:g}")  # fmt: skip

    taken = sim.camera.photos_taken - taken0
    triggers = sorted({m.img_idx for _, m in feedback})
    records = {m.image_index: m for _, m in captured if m.image_index >= index0}
    repeated = len([1 for _, m in captured if m.image_index >= index0]) - len(records)
    kept = {i: m for i, m in camera.images.items() if i >= index0}  # the bridge's own, in this process
    photos = [records[i] for i in sorted(records)]
    where = [Geodetic(m.lat / 1e7, m.lon / 1e7, home.alt_m) for m in photos]
    assert len(shutters) == taken, (len(shutters), taken)
    paired = shutters[-len(where) :] if where else []
    # each geotag against ArduPilot's position at its shutter
    errors_m = [math.hypot(*offset_m(_position_at(track, t), p)[:2]) for p, t in zip(where, paired, strict=False)]
    # each photo on a transect (none in the turns): across and along its line
    lines = transects(home)
    fit: list[tuple[int, float, float] | None] = []
    for p in where:
        fits = []
        for j, (a, b) in enumerate(lines):
            an, ae, _ = offset_m(a, p)
            bn, be, _ = offset_m(a, b)
            length = math.hypot(bn, be)
            along, across = (an * bn + ae * be) / length, (an * be - ae * bn) / length
            if abs(across) <= ON_LINE_M and -ON_LINE_M <= along <= length + ON_LINE_M:
                fits.append((j, along, across))
        fit.append(fits[0] if fits else None)
    off_line = [photos[i].image_index for i, f in enumerate(fit) if f is None]
    per_line = [[i for i, f in enumerate(fit) if f is not None and f[0] == j] for j in range(TRANSECTS)]
    # spacing: the distance between consecutive geotags on the same transect; the same at
    # ArduPilot's position at each trigger (CAMERA_FEEDBACK) and at each shutter (its own track)
    gaps = [math.hypot(*offset_m(where[i], where[k])[:2]) for line in per_line for i, k in itertools.pairwise(line)]
    truth = [_position_at(track, t) for t in paired]
    true_gaps = [
        math.hypot(*offset_m(truth[i], truth[k])[:2]) for line in per_line for i, k in itertools.pairwise(line)
    ]
    fed = [Geodetic(m.lat / 1e7, m.lng / 1e7, home.alt_m) for _, m in sorted(feedback, key=lambda f: f[1].img_idx)]
    trigger_gaps = [
        d for d in (math.hypot(*offset_m(a, b)[:2]) for a, b in itertools.pairwise(fed)) if d < 1.5 * DISTANCE_M
    ]
    # how far the vehicle went from ArduPilot's trigger (CAMERA_FEEDBACK's position) to the shutter
    lag_m = [math.hypot(*offset_m(f, t)[:2]) for f, t in zip(fed, truth, strict=False)]
    # and how long it took: the record's UTC at the shutter less CAMERA_FEEDBACK's at the trigger
    # (both ArduPilot's GPS time; the bridge dates a photo from ArduPilot's SYSTEM_TIME)
    stamps = [m.time_usec for _, m in sorted(feedback, key=lambda f: f[1].img_idx)]
    lag_s = [(m.time_utc - u) / 1e6 for m, u in zip(photos, stamps, strict=False)]
    # the two parts of that time: ArduPilot's trigger to its request at the bridge (SERIAL2), and the
    # request to the shutter (the bridge and the camera); CAMERA_FEEDBACK's img_idx is the request's
    # sequence number (param4)
    link_s, camera_s = [], []
    for (_, fb), shutter in zip(sorted(feedback, key=lambda f: f[1].img_idx), paired, strict=False):
        got = arrivals.get(fb.img_idx)
        utc = camera.utc_at(got) if got is not None and camera.utc_at is not None else None
        link_s.append(utc - fb.time_usec / 1e6 if utc is not None else math.nan)
        camera_s.append(shutter - got if got is not None else math.nan)

    rows.append(
        "photo | transect | along (m) | across (m) | geotag error (m) | speed (m/s) | trigger to shutter (m, s) | "
        "trigger to request at the bridge, request to shutter (s)"
    )
    for i, m in enumerate(photos):
        f = fit[i]
        line = f"{f[0] + 1} | {f[1]:.1f} | {f[2]:+.2f}" if f is not None else "in a turn | - | -"
        err = f"{errors_m[i]:.2f}" if i < len(errors_m) else "-"
        speed = f"{_speed_at(track, paired[i]):.1f}" if i < len(paired) else "-"
        lag = f"{lag_m[i]:.2f}, {lag_s[i]:.3f}" if i < min(len(lag_m), len(lag_s)) else "-"
        parts = f"{link_s[i]:.3f}, {camera_s[i]:.3f}" if i < len(link_s) else "-"
        rows.append(f"{m.image_index} | {line} | {err} | {speed} | {lag} | {parts}")

    def span(values: list[float]) -> str:
        return f"{min(values):.2f} to {max(values):.2f}" if values else "none"

    rows.append("ArduPilot survey | figure")
    rows.append(f"photos taken / ArduPilot's triggers (CAMERA_FEEDBACK) / bridge records (heard; kept) | "
                f"{taken} / {len(triggers)} / {len(records)}; {len(kept)}")  # fmt: skip
    rows.append(f"repeated records / photos in the turns | {repeated} / {len(off_line)} {off_line}")
    rows.append(f"photos per transect | {[len(line) for line in per_line]}")
    rows.append(f"spacing of the geotags (m) | {span(gaps)} (goal {DISTANCE_M:g} +- {SPACING_GOAL:.0%})")
    rows.append(f"spacing at ArduPilot's triggers / at its positions at the shutters (m) | {span(trigger_gaps)} / "
                f"{span(true_gaps)}")  # fmt: skip
    rows.append(f"geotag error against ArduPilot's position at the shutter (m) | max {max(errors_m, default=math.nan):.2f}, "
                f"median {sorted(errors_m)[len(errors_m) // 2] if errors_m else math.nan:.2f}")  # fmt: skip
    rows.append(f"trigger to shutter (m travelled; s) | {span(lag_m)}; {span(lag_s)}")
    rows.append(f"trigger to request at the bridge; request to shutter (s) | {span(link_s)}; {span(camera_s)}")

    assert taken == len(triggers) == len(records) == len(kept), "photos = triggers = records"
    assert len(feedback) == len(triggers) and repeated == 0, "a trigger or a record twice"
    assert len(paired) == len(where) == TRANSECTS * (int(LENGTH_M // DISTANCE_M) + 1), (len(where), len(paired))
    assert off_line == [] and all(per_line), off_line
    assert all(abs(gap - DISTANCE_M) <= SPACING_GOAL * DISTANCE_M for gap in gaps), gaps
    assert max(errors_m) <= POSITION_GOAL_M, errors_m
