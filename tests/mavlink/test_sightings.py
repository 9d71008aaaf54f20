"""`topgimbal mavlink --sightings FILE` (issue 44's example of a new output: outputs/sightings_log.py,
its glue mavlink/features/sightings.py and one name in features.ORDER): the JSON Lines it writes,
its bounds and refusals (pure), the flag through BridgeConfig.features (pure), and the bridge on
the virtual rig logging where the camera looks once an autopilot says where the vehicle is."""

from __future__ import annotations

import asyncio
import json
import math
from pathlib import Path
from typing import Any

import pytest
from pymavlink.dialects.v20 import common as ml

from topgimbal.cli.main import build_parser
from topgimbal.cli.mavlink_cmd import build_config
from topgimbal.errors import InputError
from topgimbal.geo import Fix
from topgimbal.mavlink.bridge_config import BridgeConfig, BridgeConfigError
from topgimbal.outputs.sighting import Sighting
from topgimbal.outputs.sightings_log import SightingsLog, SightingsLogError, check_path, record

from .virtual import MemPeer

pytestmark = pytest.mark.virtual

NAN = float("nan")


def sighting(lat: float = 47.0, target: Fix | None = None) -> Sighting:
    corner = Fix(47.001, 8.0, 400.0, 150.0, "flat", 3.0, 10.0, -40.0)
    return Sighting(lat, 8.0, 500.0, 10.0, -40.0, 0.0, 60.0, 34.0, target, [corner, None, corner, None])


def test_a_record_is_json_with_null_for_what_is_not_finite() -> None:
    r = record(sighting(target=Fix(NAN, NAN, NAN, NAN, "flat", NAN, 10.0, -40.0)), 1_700_000_000.25)
    text = json.dumps(r, allow_nan=False)  # raises on a NaN left in
    back = json.loads(text)
    assert back["time_s"] == 1_700_000_000.25
    assert back["vehicle"] == {"lat_deg": 47.0, "lon_deg": 8.0, "alt_m": 500.0}
    assert back["axis"]["azimuth_deg"] == 10.0 and back["axis"]["elevation_deg"] == -40.0
    assert back["target"] is None  # a ray that meets no ground is no point
    assert back["corners"][0]["lat_deg"] == 47.001 and back["corners"][1] is None
    assert record(sighting(lat=NAN), 0.0)["vehicle"]["lat_deg"] is None


def test_the_log_appends_one_line_per_write_and_stops_at_its_bound(tmp_path: Path, caplog: Any) -> None:
    path = tmp_path / "s.jsonl"
    path.write_text('{"earlier": true}\n')  # an existing file is appended to, never truncated
    known: list[Sighting | None] = [None]
    log = SightingsLog(str(path), lambda: known[0], max_bytes=1200, wall=lambda: 5.0)
    assert log.write_once() is False  # nothing known yet: nothing written
    known[0] = sighting()
    written = 0
    while log.write_once():
        written += 1
    log.close()
    lines = path.read_text().splitlines()
    assert lines[0] == '{"earlier": true}' and len(lines) == 1 + written == 1 + log.lines
    assert written >= 2 and path.stat().st_size <= 1200
    assert all(json.loads(x)["vehicle"]["lat_deg"] == 47.0 for x in lines[1:])
    assert log.full and "reached 1200 bytes" in caplog.text
    assert log.write_once() is False  # full stays full


def test_a_path_that_cannot_be_a_log_is_refused_and_nothing_is_created(tmp_path: Path) -> None:
    with pytest.raises(SightingsLogError, match=r"directory .* does not exist"):
        check_path(str(tmp_path / "no" / "s.jsonl"))
    with pytest.raises(SightingsLogError, match="not a regular file"):
        check_path(str(tmp_path))
    with pytest.raises(SightingsLogError, match="not a regular file"):
        check_path("/dev/null")
    check_path(str(tmp_path / "new.jsonl"))
    assert not (tmp_path / "new.jsonl").exists()


BASE = ["mavlink", "--url", "udp://127.0.0.1:5000", "--model", "C12", "--mavlink", "udpin:127.0.0.1:0"]


def test_the_flag_lands_in_features_and_a_bad_one_names_the_flag(tmp_path: Path) -> None:
    parse = build_parser().parse_args
    built = build_config(parse([*BASE, "--sightings", str(tmp_path / "s.jsonl")]))
    assert built.features == {"sightings": str(tmp_path / "s.jsonl")}
    assert build_config(parse(BASE)).features == {}
    with pytest.raises(InputError, match=r"^--sightings .*does not exist"):
        build_config(parse([*BASE, "--sightings", str(tmp_path / "no" / "s.jsonl")]))
    assert not (tmp_path / "no").exists()


def test_a_python_config_with_an_unknown_feature_is_refused() -> None:
    config = BridgeConfig(
        url="udp://127.0.0.1:5000", model="C12", endpoints=["udpin:127.0.0.1:0"], features={"nope": 1}
    )
    with pytest.raises(BridgeConfigError, match=r"unknown feature 'nope' \(these take options here: sightings\)"):
        config.check()


@pytest.mark.looptime
async def test_the_bridge_logs_where_the_camera_looks_once_the_vehicle_is_known(
    vrig_maker: Any, tmp_path: Path
) -> None:
    path = tmp_path / "sightings.jsonl"
    vrig = await vrig_maker("C12", features={"sightings": str(path)})
    vrig.sim.gimbal.angle("pitch", -45.0)
    await asyncio.sleep(3.0)  # no vehicle position yet: no line
    assert not path.exists() or path.read_text() == ""
    autopilot = await MemPeer(sysid=1, compid=1).join(vrig.link)
    try:
        for _ in range(6):  # as an autopilot streams them
            autopilot.send(ml.MAVLink_attitude_message(0, 0.0, 0.0, 0.0, 0, 0, 0))
            autopilot.send(ml.MAVLink_global_position_int_message(0, 470000000, 80000000, 600000, 100000, 0, 0, 0, 0))
            await asyncio.sleep(0.5)
    finally:
        autopilot.close()
    lines = [json.loads(x) for x in path.read_text().splitlines()]
    assert 2 <= len(lines) <= 4  # once a second while the fix was fresh
    last = lines[-1]
    assert last["vehicle"] == {"lat_deg": 47.0, "lon_deg": 8.0, "alt_m": 600.0}
    assert math.isclose(last["axis"]["elevation_deg"], -45.0, abs_tol=0.5)
    # 100 m above home at -45 deg: the image centre is on flat ground ~100 m north
    assert last["target"] is not None and math.isclose(last["target"]["range_m"], 141.4, abs_tol=2.0)
    assert last["target"]["lat_deg"] > 47.0


@pytest.mark.looptime
async def test_the_log_closes_its_file_when_its_loop_is_stopped(tmp_path: Path) -> None:
    log = SightingsLog(str(tmp_path / "s.jsonl"), sighting, period_s=1.0)
    task = asyncio.ensure_future(log.run())
    await asyncio.sleep(2.5)  # three lines: at 0, 1 and 2 s
    assert log._file is not None and not log._file.closed
    task.cancel()
    with pytest.raises(asyncio.CancelledError):
        await task
    assert log._file is None and log.lines == 3
    assert len((tmp_path / "s.jsonl").read_text().splitlines()) == 3
