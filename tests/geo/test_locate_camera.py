"""`cam.locate()` and `topgimbal locate` against a simulator on the synthetic DEM: `locate --laser`
agrees with the simulated laser (whose truth is the simulator's own march over the model), and
without the laser the terrain alone lands within the same metres; the blocking facade the same."""

from __future__ import annotations

import json
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from topgimbal import Gimbal
from topgimbal.cli.main import main
from topgimbal.geo import Attitude, Geodetic, LocalFrame, Pointing, View, ray
from topgimbal.sim import BackgroundSimulator

from .brute import BruteCaster
from .conftest import LAT0, LON0

pytestmark = [pytest.mark.loopback, pytest.mark.integration]

POS = (LAT0 - 0.003, LON0 + 0.002, 560.0)
HEADING = 30.0


@pytest.fixture(scope="module")
def bg(dem_path: Path) -> Iterator[BackgroundSimulator]:
    with BackgroundSimulator("SIP", seed=3, listen={"udp": [("127.0.0.1", 0)]}, terrain=dem_path) as sim:
        yield sim


def _run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def _truth(dem_path: Path, fix: dict[str, Any]) -> float:
    """The tests' own cast along the angles the camera reported for this fix (it may still settle
    by hundredths of a degree between two calls)."""
    g = fix["inputs"]["gimbal"]
    view = View(
        Geodetic(*POS), Attitude(yaw_deg=HEADING), Pointing(HEADING + g["yaw_deg"], g["pitch_deg"], earth_frame=True)
    )
    truth = BruteCaster(dem_path).cast(POS[0], POS[1], POS[2], ray(view), 1600, step_m=0.1)
    assert truth is not None
    return truth


def test_locate_with_the_laser_agrees_with_the_simulated_laser(
    bg: BackgroundSimulator, dem_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    base = ["--url", bg.url, "--model", "SIP"]
    assert _run(capsys, *base, "point", "25", "-35")[0] == 0
    time.sleep(0.5)  # let it settle: the laser measures after the attitude is read
    where = ["--position", ",".join(str(v) for v in POS), "--heading", str(HEADING), "--json"]
    code, out, err = _run(capsys, *base, "locate", "--terrain", str(dem_path), "--laser", *where)
    assert code == 0, err
    fix = json.loads(out)
    assert fix["source"] == "laser+terrain"
    laser = fix["inputs"]["laser_m"]
    # the truth: the tests' own cast along the angles the camera reached
    g = fix["inputs"]["gimbal"]
    view = View(
        Geodetic(*POS), Attitude(yaw_deg=HEADING), Pointing(HEADING + g["yaw_deg"], g["pitch_deg"], earth_frame=True)
    )
    truth = BruteCaster(dem_path).cast(POS[0], POS[1], POS[2], ray(view), 1600, step_m=0.1)
    assert truth is not None
    assert laser == pytest.approx(truth, abs=0.5)
    assert fix["range_m"] == pytest.approx(truth, abs=0.5)
    # the camera's own target solution (TOPOTEK §8.7, LAT/LON after the range) is the same place
    hit = LocalFrame(Geodetic(*POS)).to_local(fix["lat_deg"], fix["lon_deg"], POS[2])
    assert abs(hit[0]) > 10 or abs(hit[1]) > 10  # a real offset, not the vehicle's own position
    code, out, err = _run(capsys, *base, "locate", "--terrain", str(dem_path), *where)
    assert code == 0, err
    dem_only = json.loads(out)
    assert dem_only["source"] == "terrain" and dem_only["inputs"]["laser_m"] is None
    assert dem_only["range_m"] == pytest.approx(_truth(dem_path, dem_only), abs=0.5)
    code, out, err = _run(capsys, *base, "locate", "--ground-alt", "0", *where)
    assert code == 0 and json.loads(out)["source"] == "flat"


def test_locate_says_what_it_lacks(bg: BackgroundSimulator, capsys: pytest.CaptureFixture[str]) -> None:
    base = ["--url", bg.url, "--model", "SIP", "locate"]
    code, _, err = _run(capsys, *base, "--laser")
    assert code != 0 and "--position" in err
    code, _, err = _run(capsys, *base, "--position", "1,2,3", "--heading", "0")
    assert code != 0 and "--terrain" in err
    with pytest.raises(SystemExit):  # argparse's usage error
        _run(capsys, *base, "--position", "1,2", "--heading", "0", "--laser")
    assert "LAT,LON,ALT" in capsys.readouterr().err
    code, _, err = _run(capsys, *base, "--position", "1,2,3", "--heading", "0", "--terrain", "/nonexistent/dem.tif")
    assert code != 0 and "DEM" in err


def test_blocking_locate_from_the_fed_position(bg: BackgroundSimulator, dem_path: Path) -> None:
    with Gimbal(bg.url, "SIP") as cam:
        cam.point(-40.0, -25.0)
        time.sleep(0.5)  # let it settle: the two calls below read the attitude apart
        cam.feed(POS[0], POS[1], POS[2], HEADING)
        fix = cam.locate(terrain=str(dem_path), laser=True)
        assert fix is not None and fix.source in ("laser+terrain", "laser")
        dem = cam.locate(terrain=str(dem_path))
        assert dem is not None and dem.source == "terrain"
        assert dem.range_m == pytest.approx(fix.range_m, abs=0.6)
        assert dem.error_m > fix.error_m
