"""Targets in the simulated world (sim/targets.py), the truth file, and drawing them."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from topgimbal.sim import FakeClock
from topgimbal.sim.device import Device
from topgimbal.sim.targets import TargetSpecError, load, parse_spec
from topgimbal.sim.truth import truth_record
from topgimbal.video.render import Renderer
from topgimbal.video.snapshot import capture

from .conftest import LOOP

pytestmark = pytest.mark.loopback


def test_a_spec_moves_at_its_true_angular_speed_and_hides_in_its_intervals() -> None:
    t = parse_spec("name=car,bearing=10,elevation=-5,speed=10,heading=0,hide=3-3.5+8-9")
    assert t.name == "car" and t.at(0) == (10.0, -5.0)
    az, el = t.at(2.0)
    # 20 degrees of arc along the parallel at -5 degrees elevation: a little more than 20 of bearing
    assert el == -5.0 and 30.0 < az < 30.2
    assert [t.visible(s) for s in (2.9, 3.0, 3.4, 3.5, 8.5, 9.0)] == [True, False, False, True, False, True]
    up = parse_spec("elevation=0,speed=5,heading=90")
    assert up.at(2) == pytest.approx((0.0, 10.0))
    back = parse_spec("bearing=0,speed=10,span=20")
    assert back.at(1)[0] == pytest.approx(10.0) and back.at(3)[0] == pytest.approx(10.0)  # back again


@pytest.mark.parametrize(
    ("spec", "words"),
    [
        ("bearing=x", "bearing: expected a number"),
        ("colour=red", "unknown key(s) colour"),
        ("elevation=95", "elevation"),
        ("hide=5-2", "START < END"),
        ("speed", "expected key=value"),
        ("size=0", "size"),
    ],
)
def test_bad_specs_say_what_is_wrong(spec: str, words: str) -> None:
    with pytest.raises(TargetSpecError, match=None) as err:
        parse_spec(spec)
    assert words in str(err.value)


def test_a_json_file_holds_a_list_and_names_must_differ(tmp_path: Path) -> None:
    f = tmp_path / "targets.json"
    f.write_text(json.dumps([{"name": "a", "bearing": 5, "hide": [[1, 2]]}, {"name": "b", "speed": 3}]))
    a, b = load([str(f)])
    assert (a.name, a.bearing_deg, a.hidden, b.speed_deg_s) == ("a", 5.0, ((1.0, 2.0),), 3.0)
    with pytest.raises(TargetSpecError, match="must differ"):
        load([str(f), "name=a"])
    f.write_text("{not json")
    with pytest.raises(TargetSpecError, match="not JSON"):
        load([str(f)])
    with pytest.raises(TargetSpecError, match="target file"):
        load([str(tmp_path / "missing.json")])


def test_truth_gives_targets_gimbal_zoom_and_tracking() -> None:
    clock = FakeClock()
    dev = Device("SIP", clock=clock)
    dev.state.targets = (parse_spec("name=t1,bearing=0,elevation=0,speed=10,hide=1-2"),)
    clock.advance(0.5)
    r = truth_record(dev, wall_s=12.0)
    assert r["t"] == 0.5 and r["wall"] == 12.0 and r["tracking"] == "stopped" and r["box"] is None
    (tg,) = r["targets"]
    assert tg["name"] == "t1" and tg["bearing_deg"] == pytest.approx(5.0) and tg["visible"]
    assert tg["x"] > 0.5 and tg["y"] == pytest.approx(0.5)  # right of centre, on the horizon
    clock.advance(1.0)
    assert not truth_record(dev)["targets"][0]["visible"]


def test_targets_are_drawn_dark_in_visible_and_hot_in_thermal() -> None:
    clock = FakeClock()
    dev = Device("SIP", clock=clock)
    dev.state.targets = (parse_spec("bearing=0,elevation=10,size=4,contrast=1,temp=80"),)
    state = capture(dev, wall_s=0.0)
    assert len(state.targets) == 1
    vis = np.asarray(Renderer("visible", 640, 360, 56.0).render(state)).astype(int)
    plain = np.asarray(Renderer("visible", 640, 360, 56.0).render(capture(Device("SIP", clock=clock)))).astype(int)
    x, y = 320, 180 - round(180 / np.tan(np.radians(28.0)) * np.tan(np.radians(10.0)) * 320 / 180)
    assert vis[y, x].max() < 30 and plain[y, x].min() > 100  # a dark disc on the bright sky
    th = np.asarray(Renderer("thermal", 640, 512, 32.0).render(state)).astype(int)
    ty = 256 - round(320 / np.tan(np.radians(16.0)) * np.tan(np.radians(10.0)))
    assert th[ty, 320].min() > 200  # white hot: the 80 °C target is near white on the cold sky
    dev.state.targets = (parse_spec("bearing=0,elevation=10,size=4,hide=0-5"),)
    assert capture(dev, wall_s=0.0).targets == ()  # hidden: not drawn


SIM = [sys.executable, "-m", "topgimbal.cli.main", "sim", "--model", "C12", "--udp", f"{LOOP}:0"]


@pytest.mark.integration
def test_sim_cli_takes_targets_and_writes_truth_at_50_hz(tmp_path: Path) -> None:
    truth = tmp_path / "truth.jsonl"
    proc = subprocess.Popen(
        [*SIM, "--target", "name=a,bearing=3,speed=10", "--target", "name=b,elevation=-10", "--truth", str(truth)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert proc.stdout is not None
        assert proc.stdout.readline().startswith("udp://127.0.0.1:")
        for _ in range(100):  # until a second or so of truth is there
            if truth.exists() and truth.stat().st_size > 12000:
                break
            time.sleep(0.2)
    finally:
        proc.send_signal(signal.SIGTERM)
        assert proc.wait(10) == 0
    lines = [json.loads(line) for line in truth.read_text().splitlines()]
    assert [t["name"] for t in lines[-1]["targets"]] == ["a", "b"]
    span = lines[-1]["t"] - lines[0]["t"]
    # paced at 50 Hz: never more records than periods went by (a writer made late by a loaded machine
    # catches up in a burst, so no gap is a wiring check; the pacing itself is proved on looptime in
    # tests/sim/test_truth_pacing.py)
    assert len(lines) >= 10 and len(lines) <= span * 50 + 2, (len(lines), span)
    a0, a1 = lines[0]["targets"][0]["bearing_deg"], lines[-1]["targets"][0]["bearing_deg"]
    assert a1 - a0 == pytest.approx(10 * span, abs=0.01)


def test_sim_cli_refuses_a_bad_target(capsys: pytest.CaptureFixture[str]) -> None:
    from topgimbal.cli.main import main

    assert main(["sim", "--udp", f"{LOOP}:0", "--target", "bearing=1,colour=red"]) != 0
    assert "colour" in capsys.readouterr().err
