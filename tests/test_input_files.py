"""Issue 43.7: files and numbers the user gives. Special files (/dev/zero, a FIFO) and JSON nested
100,000 deep are refused in one line with exit 2, never read for ever or ended in a traceback;
NaN, infinity, a JSON `true` as a number and a DEM beyond the Earth are refused (exit 2)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from topgimbal.cli.main import main

pytestmark = pytest.mark.loopback  # `sim` and `geotag` run in this process up to their checks


@pytest.fixture
def files(tmp_path: Path) -> dict[str, Path]:
    fifo = tmp_path / "targets.fifo"
    os.mkfifo(fifo)  # opened for reading, a FIFO blocks until a writer comes: none will
    deep = tmp_path / "deep.json"
    deep.write_text("[" * 100_000)
    true = tmp_path / "true.json"
    true.write_text('{"bearing": true}')
    log = tmp_path / "deep.jsonl"
    log.write_text('{"topgimbal_log": 1}\n' + "[" * 100_000 + "\n" + '{"dir": ' + "[" * 100_000 + "\n")
    photo = tmp_path / "a.jpg"
    photo.write_bytes(b"")
    return {"fifo": fifo, "deep": deep, "true": true, "log": log, "photo": photo}


def one_line_exit_2(argv: list[str], capsys: pytest.CaptureFixture[str]) -> str:
    try:
        code = main(argv)
    except SystemExit as exc:  # argparse's own refusal
        code = int(exc.code or 0)
    err = capsys.readouterr().err
    assert code == 2, (argv, code, err)
    lines = [x for x in err.splitlines() if x.strip()]
    assert lines and "Traceback" not in err and "RecursionError" not in err, err
    return lines[-1]


@pytest.mark.parametrize("which", ["/dev/zero", "fifo", "deep", "true"])
def test_sim_target_files(which: str, files: dict[str, Path], capsys: pytest.CaptureFixture[str]) -> None:
    path = which if which.startswith("/") else str(files[which])
    line = one_line_exit_2(["sim", "--model", "C12", "--udp", "127.0.0.1:0", "--target", path], capsys)
    expected = {"/dev/zero": "not a regular file", "fifo": "not a regular file", "deep": "nested more than 64",
                "true": "target bearing: expected a number, got true"}[which]  # fmt: skip
    assert expected in line, line


@pytest.mark.parametrize("which", ["/dev/zero", "fifo"])
def test_geotag_special_logs(which: str, files: dict[str, Path], capsys: pytest.CaptureFixture[str]) -> None:
    path = which if which.startswith("/") else str(files[which])
    line = one_line_exit_2(["geotag", "--log", path, str(files["photo"])], capsys)
    assert "not a regular file" in line, line


def test_a_geotag_log_nested_100000_deep_is_a_log_without_positions(
    files: dict[str, Path], capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["geotag", "--log", str(files["log"]), str(files["photo"])]) == 1  # as any log without positions
    err = capsys.readouterr().err
    assert "no vehicle position in this log" in err and "Traceback" not in err and len(err.splitlines()) == 1, err


def test_camera_files(files: dict[str, Path], capsys: pytest.CaptureFixture[str]) -> None:
    for path in ("/dev/zero", str(files["fifo"]), str(files["deep"])):
        line = one_line_exit_2(["zenoh", "--listen", "tcp/127.0.0.1:7447", "--cameras", path], capsys)
        assert "camera file" in line, line


@pytest.mark.parametrize(
    "argv",
    [
        ["track", "--video", "rtsp://127.0.0.1:9/x", "--box", "inf,0,0.1,0.1"],
        ["track", "--video", "rtsp://127.0.0.1:9/x", "--box", "0.1,0.1,nan,0.1"],
        ["track", "--video", "rtsp://127.0.0.1:9/x", "--box", "0.95,0.5,0.2,0.1"],  # past the picture's edge
        ["locate", "--position", "47,8,500", "--heading", "nan", "--ground-alt", "400"],
        ["locate", "--position", "47,8,500", "--heading", "inf", "--ground-alt", "400"],
        ["locate", "--position", "47,8,500", "--heading", "90", "--ground-alt", "nan"],
        ["locate", "--position", "47,8,nan", "--heading", "90", "--ground-alt", "400"],
    ],
)
def test_numbers_that_are_no_numbers(argv: list[str], capsys: pytest.CaptureFixture[str]) -> None:
    one_line_exit_2(["--url", "udp://127.0.0.1:9", "--model", "C12", *argv], capsys)


def test_a_dem_beyond_the_earth_or_special_is_refused_with_exit_2(
    tmp_path: Path, files: dict[str, Path], capsys: pytest.CaptureFixture[str]
) -> None:
    import rasterio
    from affine import Affine

    from topgimbal.errors import InputError
    from topgimbal.geo.dem import DemError, load_dem

    far = tmp_path / "far.tif"
    with rasterio.open(far, "w", driver="GTiff", width=4, height=4, count=1, dtype="float32", crs="EPSG:4326",
                       transform=Affine(0.001, 0.0, 8.0, 0.0, -0.001, 500.0)) as dst:  # fmt: skip
        dst.write(__import__("numpy").zeros((4, 4), dtype="float32"), 1)
    with pytest.raises(DemError, match=r"latitude 499\.996\.\.500.*-90\.\.90"):
        load_dem(far)
    with pytest.raises(DemError, match="not a regular file"):
        load_dem(files["fifo"])
    assert issubclass(DemError, InputError)  # the CLI's exit 2
    line = one_line_exit_2(["sim", "--model", "C12", "--udp", "127.0.0.1:0", "--terrain", str(far)], capsys)
    assert "latitude" in line, line


def test_sim_fault_plan_files(tmp_path: Path, files: dict[str, Path], capsys: pytest.CaptureFixture[str]) -> None:
    fifo = tmp_path / "plan.json"
    os.mkfifo(fifo)
    for path, expected in ((files["deep"], "nested more than 64"), (fifo, "not a regular file")):
        line = one_line_exit_2(["sim", "--model", "C12", "--udp", "127.0.0.1:0", "--faults", str(path)], capsys)
        assert expected in line, line


def test_pcap_from_a_log_nested_100000_deep(
    tmp_path: Path, files: dict[str, Path], capsys: pytest.CaptureFixture[str]
) -> None:
    code = main(["pcap", "from-log", str(files["log"]), "-o", str(tmp_path / "out.pcap")])
    err = capsys.readouterr().err
    assert code == 1 and "line 2: not JSON" in err and "Traceback" not in err, err  # the line named, the rest kept
