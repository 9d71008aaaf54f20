"""CLI details a new user trips over (issue 17, items 7, 8, 9; issue 15, a silent device): every
failure is a non-zero exit with words, options are checked and named, help shows the ranges, human
output has no Python reprs, a closed pipe is not an error, `raw` completes a frame."""

from __future__ import annotations

import json
import re
import socket
import subprocess
import sys

import pytest

from topgimbal.cli.main import build_parser, main
from topgimbal.protocol import dissect
from topgimbal.sim import BackgroundSimulator

pytestmark = [pytest.mark.loopback, pytest.mark.integration]


@pytest.fixture(scope="module")
def sims():
    with (
        BackgroundSimulator("C12", seed=41, listen={"udp": [("127.0.0.1", 0)]}) as c12,
        BackgroundSimulator("SIP", seed=42, listen={"udp": [("127.0.0.1", 0)]}) as sip,
    ):
        yield {"C12": c12, "SIP": sip}


@pytest.fixture
def silent_url():
    """A UDP port where nothing answers (bound, never read)."""
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.bind(("127.0.0.1", 0))
    yield f"udp://127.0.0.1:{s.getsockname()[1]}"
    s.close()


def run(capsys, *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


SILENT_COMMANDS = [
    ["info"],
    ["attitude"],
    ["point", "3", "2"],
    ["photo"],
    ["record", "status"],
    ["sd"],
    ["zoom", "in"],
    ["focus", "auto"],
    ["thermal", "palette"],
    ["net", "show"],
    ["raw", "#TPUD2rREC003E"],
    ["command", "REC", "--read"],
    ["stop"],
    ["center"],
    ["mode", "lock"],
    ["rate", "1"],
    ["monitor", "--count", "1"],
]


@pytest.mark.parametrize("command", SILENT_COMMANDS, ids=lambda c: c[0])
def test_every_command_against_a_silent_device_says_so(capsys, silent_url, command):
    code, out, err = run(capsys, "--url", silent_url, "--model", "C12", *command, "--timeout", "0.05", "--retries", "0")
    assert code == 1 and out == ""
    line = err.strip()
    assert line.startswith("topgimbal: error: ") and len(line.splitlines()) == 1
    assert "nothing at all has come from" in line and silent_url in line, line
    assert re.search(r"\[\d+\.\d s since the command started\]", line), line  # the true elapsed time


def test_without_model_a_silent_device_says_so(capsys, silent_url):
    code, _, err = run(capsys, "--url", silent_url, "info", "--timeout", "0.05")
    assert code == 1 and "did not identify itself" in err and "nothing at all came from" in err


def test_a_lost_photo_explains_itself(capsys, sims):
    bg = sims["C12"]
    # a photo whose acknowledgement never comes: the sim is fine, the wait is absurdly short
    code, _, err = run(capsys, "--url", silent_url_of(bg), "--model", "C12", "photo", "--timeout", "0.05")
    assert code == 1 and "may or may not have been taken" in err and "never sent twice" in err


def silent_url_of(bg) -> str:
    """The simulator's host with a port nothing listens on (the photo request goes nowhere)."""
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    return f"udp://127.0.0.1:{port}"


def test_range_without_a_distance_fails_and_says_why(capsys, sims):
    code, out, err = run(capsys, "--url", sims["SIP"].url, "--model", "SIP", "range")
    assert code == 1 and out == ""
    assert "no distance" in err and "ALT" in err and "command ALT alt_m=" in err
    base = ["--url", sims["SIP"].url, "--model", "SIP"]
    assert run(capsys, *base, "command", "ALT", "alt_m=100")[0] == 0  # what the message says to do
    assert run(capsys, *base, "point", "0", "-45", "--tolerance", "1")[0] == 0
    code, out, _ = run(capsys, *base, "range", "--json")
    assert code == 0 and 120 < json.loads(out)["range_m"] < 160  # 100 m / sin 45 deg


@pytest.mark.parametrize("value", ["0", "-1", "nan", "soon"])
def test_timeout_must_be_above_zero(capsys, value):
    with pytest.raises(SystemExit) as stop:
        main(["--url", "udp://127.0.0.1:9", "--model", "C12", "sd", "--timeout", value])
    assert stop.value.code == 2 and "--timeout" in capsys.readouterr().err


def test_point_errors_name_the_cli_option_and_help_shows_ranges(capsys, sims):
    code, _, err = run(capsys, "--url", sims["C12"].url, "--model", "C12", "point", "3", "2", "--speed", "20")
    assert code == 2 and "--speed=20" in err and "0..9.9 deg/s" in err and "yaw_speed_deg_s" not in err
    code, _, err = run(capsys, "--url", sims["C12"].url, "--model", "C12", "point", "300", "2")
    assert code == 2 and "YAW=300" in err and "-90..90" in err
    help_text = _help("point")
    assert "SIP: -150..150" in help_text and "-90..90" in help_text and "0..9.9 deg/s" in help_text


def _help(command: str) -> str:
    sub = next(a for a in build_parser()._actions if a.__class__.__name__ == "_SubParsersAction")
    return sub.choices[command].format_help()


def test_focus_help_and_errors_list_the_same_names(capsys, sims):
    help_names = re.search(r"focus: ([a-z_| ]+)", _help("focus")).group(1).split(" | ")
    code, _, err = run(capsys, "--url", sims["C12"].url, "--model", "C12", "focus", "sideways")
    assert code == 2
    listed = err.split("one of ", 1)[1].strip().split(", ")
    assert listed == help_names and "plus" in listed and "auto" in listed


def test_human_output_has_no_python_reprs(capsys, sims):
    bg = sims["C12"]
    code, out, _ = run(capsys, "--url", bg.url, "--model", "C12", "info")
    assert code == 0 and "None" not in out and "{" not in out and "'" not in out
    assert re.search(r"^link:\n  frames_in: \d+", out, re.M)
    code, out, _ = run(capsys, "--url", bg.url, "--model", "C12", "attitude")
    assert code == 0 and re.search(r"^t: \d{4}-\d\d-\d\d \d\d:\d\d:\d\d\.\d{3}$", out, re.M)
    code, out, _ = run(capsys, "--url", bg.url, "--model", "C12", "command", "REC", "--read")
    assert code == 0 and "error" not in out and "None" not in out


def test_raw_completes_a_frame_without_checksum_and_its_help_example_checks_out(capsys, sims):
    bg = sims["C12"]
    code, out, _ = run(capsys, "--url", bg.url, "--model", "C12", "raw", "#TPUD2rREC00", "--json")
    assert code == 0 and json.loads(out)["fields"] == {"state": "stopped"}
    examples = re.findall(r"'(#T[^']+)'", _help("raw").replace("\n", " "))
    full = [e for e in examples if len(e) > 12]
    assert full and all(dissect(e.encode()).ok for e in full)


def test_a_closed_pipe_is_not_an_error(sims):
    bg = sims["C12"]
    argv = [sys.executable, "-m", "topgimbal.cli.main", "--url", bg.url, "--model", "C12", "info", "--json"]
    proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    proc.stdout.close()  # the reader left before anything was written (`| head -0`)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 0 and b"Broken pipe" not in err, err
