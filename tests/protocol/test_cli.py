"""`topgimbal decode`, `encode` and `catalog`: output forms scripts rely on."""

from __future__ import annotations

import io
import json
import subprocess
import sys

import pytest

from topgimbal.cli.main import main

pytestmark = pytest.mark.loopback


def run(
    argv: list[str],
    capsys: pytest.CaptureFixture[str],
    stdin: str | None = None,
    monkeypatch: pytest.MonkeyPatch | None = None,
) -> tuple[int, str, str]:
    if stdin is not None:
        assert monkeypatch is not None
        monkeypatch.setattr(sys, "stdin", io.StringIO(stdin))
    rc = main(argv)
    out, err = capsys.readouterr()
    return rc, out, err


def test_decode_json_has_the_documented_keys(capsys: pytest.CaptureFixture[str]) -> None:
    rc, out, _ = run(["decode", "--json", "#tpGPCrGACFF36ED5A0048DE"], capsys)
    rec = json.loads(out)
    assert rc == 0
    for key in (
        "frame",
        "ok",
        "error",
        "header",
        "src",
        "dst",
        "length",
        "rw",
        "id",
        "data",
        "checksum",
        "expected_checksum",
        "fields",
    ):
        assert key in rec
    assert rec["ok"] is True and rec["error"] is None and rec["dialect"] == "topotek"
    assert rec["fields"] == {"yaw_deg": -2.02, "pitch_deg": -47.74, "roll_deg": 0.72}


def test_decode_bad_checksum_names_expected(capsys: pytest.CaptureFixture[str]) -> None:
    rc, out, _ = run(["decode", "--json", "#TPUG6wGAYEF073288"], capsys)
    rec = json.loads(out)
    assert rc == 1 and rec["ok"] is False and "'48'" in rec["error"]
    assert rec["checksum"] == "88" and rec["expected_checksum"] == "48"
    assert rec["fields"] == {"yaw_deg": -43.45, "speed_deg_s": 5.0}  # still named, for debugging


def test_decode_stdin_one_json_object_per_line(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    lines = "#TPUG2wPTZ006A\n\n#tpDU3rVER0105025A\ngarbage\n"
    rc, out, _ = run(["decode", "--json", "--dialect", "skydroid"], capsys, lines, monkeypatch)
    recs = [json.loads(x) for x in out.splitlines()]
    assert [r["ok"] for r in recs] == [True, True, False]
    assert recs[0]["fields"] == {"action": "stop"}
    assert recs[1]["anomaly"] and recs[1]["fields"] == {"version": "010502"}
    assert "starts with '#'" in recs[2]["error"] and rc == 1


def test_decode_dialect_choice_changes_meaning(capsys: pytest.CaptureFixture[str]) -> None:
    _, out, _ = run(["decode", "--json", "--dialect", "topotek", "#TPUG2wPTZ0670"], capsys)
    assert json.loads(out)["fields"] == {"action": "lock"}
    _, out, _ = run(["decode", "--json", "--dialect", "skydroid", "#TPUG2wPTZ0670"], capsys)
    assert json.loads(out)["fields"] == {"action": "follow"}


def test_decode_hex_binary_frame(capsys: pytest.CaptureFixture[str]) -> None:
    from topgimbal.protocol import get_dialect

    frame = get_dialect("topotek").encode("UAV", yaw_deg=90, pitch_deg=-5, roll_deg=1, speed_m_s=3, path_angle_deg=0)
    rc, out, _ = run(["decode", "--json", "--hex", frame.to_bytes().hex()], capsys)
    rec = json.loads(out)
    assert rc == 0 and rec["fields"]["yaw_deg"] == 90.0 and rec["fields"]["pitch_deg"] == -5.0
    rc, out, _ = run(["decode", "--json", "--hex", "zz"], capsys)
    assert rc == 1 and "hex" in json.loads(out)["error"]


def test_decode_human_output(capsys: pytest.CaptureFixture[str]) -> None:
    rc, out, _ = run(["decode", "#TPUG6wGAYEF073248"], capsys)
    assert rc == 0 and "yaw_deg     = -43.45 deg" in out and "ok" in out.splitlines()[0]


def test_encode(capsys: pytest.CaptureFixture[str]) -> None:
    rc, out, _ = run(["encode", "GAY", "yaw_deg=-50", "speed_deg_s=5", "--dialect", "skydroid"], capsys)
    assert rc == 0 and out.strip() == "#TPUG6wGAYEC78324D"
    rc, out, _ = run(["encode", "GAC", "--read", "--dialect", "skydroid", "--json"], capsys)
    assert json.loads(out)["frame"] == "#TPUG2rGAC0032"
    rc, out, _ = run(["--model", "SIP", "encode", "REC", "action=toggle"], capsys)
    assert out.strip() == "#TPUD2wREC0A54"


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["encode", "GAY", "yaw_deg=-500", "--dialect", "skydroid"], "yaw_deg=-500.0 is not allowed: expected -90..90"),
        (["encode", "GAY", "yaw=-5", "--dialect", "skydroid"], "a field of GAY: yaw_deg, speed_deg_s"),
        (["encode", "GAY", "yaw_deg", "--dialect", "skydroid"], "NAME=VALUE"),
        (["encode", "QQQ", "--dialect", "skydroid"], "'QQQ' is not a command"),
        (["encode", "GAY", "yaw_deg=1"], "needs --dialect"),
        (["--model", "C20", "encode", "CAP"], "C20 does not support CAP"),
        (["encode", "PTZ", "action=spin", "--dialect", "topotek"], "action='spin'"),
    ],
)
def test_encode_errors_are_one_line_and_non_zero(
    argv: list[str], message: str, capsys: pytest.CaptureFixture[str]
) -> None:
    rc, out, err = run(argv, capsys)
    assert rc == 2 and out == ""  # refused before anything is sent: a usage error (issue 26, item 5)
    assert err.startswith("topgimbal: error: ") and message in err and err.count("\n") == 1


def test_catalog_lists_and_shows(capsys: pytest.CaptureFixture[str]) -> None:
    rc, out, _ = run(["catalog", "--dialect", "topotek", "--json"], capsys)
    ids = {r["id"] for r in json.loads(out)}
    assert rc == 0 and {"GIA", "YPR", "PA2", "LOC"} <= ids
    rc, out, _ = run(["catalog", "SDC", "--json"], capsys)
    entries = json.loads(out)
    assert {e["dialect"] for e in entries} == {"skydroid", "topotek"}


def test_console_script_is_installed() -> None:
    res = subprocess.run(
        [sys.executable, "-m", "topgimbal.cli.main", "decode", "#TPUG2wPTZ006A"],
        capture_output=True,
        text=True,
        check=False,
    )
    assert res.returncode == 0 and "gimbal_control" in res.stdout


def test_docs_protocol_md_is_generated_from_the_catalog() -> None:
    from pathlib import Path

    from topgimbal.tools.gendocs import render

    path = Path(__file__).resolve().parents[2] / "docs" / "protocol.md"
    assert path.read_text(encoding="utf-8") == render(), "run `make docs`"


def test_every_decode_record_has_the_same_keys(capsys: pytest.CaptureFixture[str]) -> None:
    from topgimbal.cli.protocol_cmds import RECORD_KEYS

    for argv in (
        ["decode", "--json", "#TPUG2wPTZ006A"],
        ["decode", "--json", "--hex", "zz"],
        ["decode", "--json", "é"],
    ):
        _, out, _ = run(argv, capsys)
        assert tuple(json.loads(out)) == RECORD_KEYS, argv


def test_decode_batch_reports_every_bad_line_and_goes_on(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """Issue 9: one odd line used to raise KeyError and lose the rest of the batch."""
    lines = [
        "#TPUG2wPTZ006A",  # good
        "#TPUG2xGAA0100",  # control x: bad frame, fields an "unknown form"
        "#TPUDDwQQQ00",  # not a frame (length)
        "#TPUD2rBIT0043",  # TOPOTEK only: the fallback decodes it
        "\x00\xff#",  # garbage
        "#tpUD3rXYZ123",  # short
        "#TPUG2wPTZ006A",  # good again
    ]
    rc, out, _ = run(["decode", "--json"], capsys, "\n".join(lines) + "\n", monkeypatch)
    recs = [json.loads(x) for x in out.splitlines()]
    assert len(recs) == len(lines) and rc == 1  # every line reported, and the batch says some failed
    assert recs[0]["ok"] and recs[-1]["ok"] and recs[0]["dialect"] == "skydroid"
    assert "unknown form" in recs[1]["fields_error"]
    assert recs[3]["ok"] and recs[3]["dialect"] == "topotek" and recs[3]["name"] == "bitrate"
    rc, _, _ = run(["decode", "#TPUG2wPTZ006A", "#TPUD2rBIT0043"], capsys)
    assert rc == 0


def test_decode_says_which_dialect_decoded_it(capsys: pytest.CaptureFixture[str]) -> None:
    rc, out, _ = run(["decode", "--dialect", "skydroid", "#TPUD2rBIT0043"], capsys)
    assert rc == 0 and "decoded by the topotek dialect" in out


def test_encode_picks_a_form_by_title(capsys: pytest.CaptureFixture[str]) -> None:
    rc, out, _ = run(["encode", "DZM", "zoom=2.5", "--dialect", "topotek", "--form", "zoom (2 characters)"], capsys)
    assert rc == 0 and out.strip() == "#TPUD2wDZM255B"
    rc, _, err = run(["encode", "GAC", "--read", "--header", "#Tp", "--dialect", "topotek"], capsys)
    assert rc == 2 and "#Tp frame has no r/w" in err
