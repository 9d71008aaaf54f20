"""The CLI on a model without attitude, and its exit statuses (issue 26, items 3 and 5).

`point` on a C13 (no attitude) sends the angles, waits the slew time from the model's ranges and
rates and says the position is not confirmed (was: exit 1 with "use set_angles()", a Python name);
`set_angles` is a CLI verb. Values refused before sending exit 2, like argparse's usage errors (was:
1, as for a dead camera)."""

from __future__ import annotations

import json
import time

import pytest

from topgimbal.cli.device_motion import default_speed_deg_s, slew_time_s
from topgimbal.cli.main import main
from topgimbal.protocol import get_model
from topgimbal.sim import BackgroundSimulator

pytestmark = [pytest.mark.loopback, pytest.mark.integration]


@pytest.fixture(scope="module")
def sims():
    with (
        BackgroundSimulator("C13", seed=26, listen={"udp": [("127.0.0.1", 0)]}) as c13,
        BackgroundSimulator("C12", seed=27, listen={"udp": [("127.0.0.1", 0)]}) as c12,
    ):
        yield {"C13": c13, "C12": c12}


def run(capsys, *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def test_point_moves_a_c13_there_and_says_it_is_unconfirmed(sims, capsys):
    bg = sims["C13"]
    bg.call(lambda s: (s.gimbal.angle("yaw", -80.0), s.gimbal.angle("pitch", 60.0)))  # far from the target
    code, out, err = run(capsys, "--url", bg.url, "--model", "C13", "point", "30", "-20", "--json")
    assert code == 0, err
    result = json.loads(out)
    assert result["confirmed"] is False and "not confirmed" in result["note"]
    assert (result["yaw_deg"], result["pitch_deg"]) == (30.0, -20.0)
    assert result["waited_s"] > 0
    yaw, pitch = bg.call(lambda s: (s.gimbal.yaw_deg, s.gimbal.pitch_deg))
    assert abs(yaw - 30) < 0.6 and abs(pitch + 20) < 0.6, (yaw, pitch)


def test_point_human_output_says_unconfirmed(sims, capsys):
    bg = sims["C13"]
    code, out, _ = run(capsys, "--url", bg.url, "--model", "C13", "point", "5", "5", "--wait", "0.2")
    assert code == 0
    assert "confirmed: False" in out and "not confirmed" in out and "set_angles()" not in out


def test_set_angles_is_a_cli_verb(sims, capsys):
    bg = sims["C13"]
    code, out, err = run(capsys, "--url", bg.url, "--model", "C13", "set_angles", "-10", "15", "--json")
    assert code == 0, err
    assert json.loads(out)["confirmed"] is False
    # unconfirmed: the CLI may return before the simulator's thread has handled the datagram
    for _ in range(200):
        target = bg.call(lambda s: (s.gimbal.axis("yaw").target, s.gimbal.axis("pitch").target))
        if target == pytest.approx((-10.0, 15.0)):
            break
        time.sleep(0.05)
    assert target == pytest.approx((-10.0, 15.0))


def test_the_slew_time_comes_from_the_profile():
    dialect, c13 = get_model("C13")
    speed = default_speed_deg_s(dialect, c13)
    assert 0 < speed <= c13.max_rate_deg_s
    # from anywhere in -90..90: 120 deg of yaw to reach 30 is the worst case
    assert slew_time_s(c13, {"yaw": 30.0, "pitch": -20.0}, speed) > 120 / speed
    assert slew_time_s(c13, {"yaw": 0.0, "pitch": 0.0}, speed) < slew_time_s(c13, {"yaw": 90.0}, speed)


@pytest.mark.parametrize(
    ("argv", "said"),
    [
        (["point", "200", "0"], "YAW=200.0"),
        (["point", "nan", "0"], "YAW=nan"),
        (["point", "3", "2", "--speed", "20"], "--speed=20.0"),
        (["point", "0", "-60"], "PITCH=-60.0"),
        (["set_angles", "0", "-60"], "PITCH=-60.0"),
    ],
)
def test_values_refused_before_sending_exit_2(sims, capsys, argv, said):
    bg = sims["C12"]
    code, out, err = run(capsys, "--url", bg.url, "--model", "C12", *argv)
    assert code == 2 and out == "" and said in err and err.startswith("topgimbal: error: ")
    # nothing that moves the gimbal was sent (the connection's own queries may have been)
    assert not bg.call(lambda s: [f for f in s.received if f.ident in ("GAM", "GAY", "GAP")])


def test_a_dead_camera_still_exits_1(capsys):
    import socket

    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.bind(("127.0.0.1", 0))
    try:
        url = f"udp://127.0.0.1:{s.getsockname()[1]}"
        code, _, err = run(capsys, "--url", url, "--model", "C12", "point", "3", "2", "--timeout", "0.05")
    finally:
        s.close()
    assert code == 1 and "nothing at all has come from" in err


def test_monitor_shows_the_sd_card_as_words_not_a_dict(sims, capsys):
    bg = sims["C12"]
    code, out, _ = run(capsys, "--url", bg.url, "--model", "C12", "monitor", "--count", "1")
    assert code == 0
    flat = " ".join(out.split())  # the table may wrap a long cell
    assert "present: True, remaining_mb: " in flat and "{'present'" not in out and "'total_mb'" not in out


def test_a_reply_prints_short(sims):
    """print(reply) showed about 3 KB of CommandSpec; now one line, as pymavlink's messages."""
    from topgimbal import Gimbal

    with Gimbal(sims["C12"].url, model="C12") as cam:
        reply = cam.request("REC", read=True)
    text = str(reply)
    assert text.startswith("<Message REC ") and "fields={'state':" in text and len(text) < 200
    assert "CommandSpec" not in text and "Form(" not in text
