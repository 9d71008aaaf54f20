"""The bridge's ST 0601 packets as another reader uses them (issue 41 item 3): pymisb (Python >=
3.12, so in its own venv: `make misb-deps`) decodes them, and this test's player, in that
interpreter, composes the line of sight as ST 0601 defines it (platform heading, pitch, roll, tags
5-7, then sensor relative azimuth, elevation, roll, tags 18-20, each a Z-Y-X rotation), goes the
slant range (tag 21) along it from the sensor (tags 13-15) with pymap3d, and measures how far that
lands from the packet's own frame centre (tags 23/24). Platform roll and pitch up to +-20 deg."""

from __future__ import annotations

import json
import math
import random
import subprocess
import sys
from pathlib import Path

import pytest

from topgimbal.autopilot.vehicle import Fix
from topgimbal.geo import locate
from topgimbal.geo.aim import Geodetic
from topgimbal.mavlink.camera_link import AttitudeSample
from topgimbal.mavlink.camera_view import earth_view, st0601_values
from topgimbal.outputs.klv import packet

pytestmark = pytest.mark.external

ROOT = Path(__file__).resolve().parents[2]
MISB_PYTHON = ROOT / ".venv-misb" / "bin" / "python"

PLAYER = r"""
import json, math, sys
import numpy as np
import pymap3d
from pymisb.demux.engine import decode_packets

def zyx(yaw, pitch, roll):
    y, p, r = np.radians([yaw, pitch, roll])
    rz = np.array([[np.cos(y), -np.sin(y), 0], [np.sin(y), np.cos(y), 0], [0, 0, 1]])
    ry = np.array([[np.cos(p), 0, np.sin(p)], [0, 1, 0], [-np.sin(p), 0, np.cos(p)]])
    rx = np.array([[1, 0, 0], [0, np.cos(r), -np.sin(r)], [0, np.sin(r), np.cos(r)]])
    return rz @ ry @ rx

out = []
for pkt in decode_packets(open(sys.argv[1], "rb").read()):
    v = {k: float(x[1]) for k, x in pkt.MetadataList().items() if k not in (2,)}
    los = zyx(v[5], v[6], v[7]) @ zyx(v[18], v[19], v[20]) @ np.array([1.0, 0.0, 0.0])  # north, east, down
    az = math.degrees(math.atan2(los[1], los[0]))
    el = math.degrees(math.asin(-los[2]))
    lat, lon, h = pymap3d.aer2geodetic(az, el, v[21], v[13], v[14], v[15])
    e, n, _ = pymap3d.geodetic2enu(v[23], v[24], h, lat, lon, h)
    out.append(math.hypot(e, n))
print(json.dumps(out))
"""


def cases(n: int) -> list[bytes]:
    """Packets from the bridge's own code (camera_view.st0601_values, geo.locate on flat ground)."""
    rng = random.Random(41)
    packets = []
    while len(packets) < n:
        lat, lon = rng.uniform(-60, 60), rng.uniform(-180, 180)
        height = rng.uniform(150, 400)
        ground = rng.uniform(0, 1500)
        fix = Fix(Geodetic(lat, lon, ground + height), height, None, 0.0)
        heading = rng.uniform(0, 360)
        vatt = (rng.uniform(-20, 20), rng.uniform(-20, 20), heading)
        att = AttitudeSample(rng.uniform(-90, 90), rng.uniform(-60, -15), 0.0, 0.0)
        target = locate(earth_view(fix, att, heading, 60.0, 34.0), ground_alt_m=ground)
        assert target is not None
        values = st0601_values(fix, att, vatt, heading, 60.0, 34.0, target)
        packets.append(packet(1_764_300_000_000_000 + len(packets), values))
    return packets


def test_pymisb_line_of_sight_lands_on_the_frame_centre(tmp_path: Path) -> None:
    assert MISB_PYTHON.exists(), f"{MISB_PYTHON} missing: `make misb-deps` makes it (pymisb needs Python >= 3.12)"
    data = tmp_path / "st0601.klv"
    data.write_bytes(b"".join(cases(200)))
    run = subprocess.run([str(MISB_PYTHON), "-c", PLAYER, str(data)], capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr[-2000:]
    distances = sorted(json.loads(run.stdout))
    assert len(distances) == 200, "pymisb did not decode every packet"
    median, p95, top = distances[100], distances[round(0.95 * 199)], distances[-1]
    print(f"pymisb line of sight to the frame centre (platform roll/pitch up to +-20 deg): median {median:.3f} m, "
          f"p95 {p95:.3f} m, max {top:.3f} m", file=sys.stderr)  # fmt: skip
    assert top < 1.0, f"the ST 0601 line of sight lands {top:.2f} m from the frame centre"
    assert math.isfinite(median)
