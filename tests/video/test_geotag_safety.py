"""`topgimbal geotag` never writes a wrong answer: a photo is matched only to its own camera's
captures in a log of several cameras (or refused, naming --camera-compid), positions that are no
place are dropped, and files it must not write are refused or written through in place."""

from __future__ import annotations

import datetime
import io
import os
import stat
import struct
import subprocess
import sys
from pathlib import Path

import pytest
from PIL import Image

import topgimbal
from topgimbal.cli.main import main
from topgimbal.video.exif import IFD_EXIF, IFD_GPS, TAG_ORIGINAL, PhotoMeta, tag_jpeg

pytestmark = pytest.mark.loopback

UTC = datetime.timezone.utc
T0 = datetime.datetime(2025, 5, 4, 10, 0, 0, tzinfo=UTC)
LAT0 = 47.0
NORTH_PER_S = 5e-5  # degrees of latitude per second of flight (about 5.6 m/s)


def _mav(compid: int):  # type: ignore[no-untyped-def]
    from pymavlink.dialects.v20 import common as ml

    return ml, ml.MAVLink(None, srcSystem=1, srcComponent=compid)


def _record(t: float, packet: bytes) -> bytes:
    return struct.pack(">Q", int(t * 1e6)) + packet


def write_tlog(
    path: Path,
    *,
    captures: list[tuple[int, int, float, str]] = (),  # type: ignore[assignment]  # (compid, file index, s after T0, file_url)
    info: dict[int, tuple[str, str]] | None = None,  # compid -> (vendor, model)
    lat_e7: list[int] | None = None,
    lon_e7: list[int] | None = None,
    seconds: int = 30,
) -> None:
    """A flight north at NORTH_PER_S, positions at 5 Hz, and the cameras' captures."""
    ml, ap = _mav(1)
    out: list[tuple[float, bytes]] = []
    for i in range(seconds * 5):
        t = T0.timestamp() + i * 0.2
        lat = lat_e7[i] if lat_e7 is not None else int((LAT0 + i * 0.2 * NORTH_PER_S) * 1e7)
        lon = lon_e7[i] if lon_e7 is not None else int(8.5e7)
        msg = ml.MAVLink_global_position_int_message(i * 200, lat, lon, 500_000, 0, 0, 0, 0, 0)
        out.append((t, msg.pack(ap)))
    for compid, (vendor, model) in (info or {}).items():
        ml, cam = _mav(compid)
        msg = ml.MAVLink_camera_information_message(
            0, list(vendor.encode().ljust(32, b"\0")), list(model.encode().ljust(32, b"\0")),
            0, 0.0, 0.0, 0.0, 0, 0, 0, 0, 0, b"", 0, 0)  # fmt: skip
        out.append((T0.timestamp(), msg.pack(cam)))
    for compid, index, after_s, url in captures:
        ml, cam = _mav(compid)
        msg = ml.MAVLink_camera_image_captured_message(
            0, 0, 0, 0, 0, 0, 0, [1.0, 0.0, 0.0, 0.0], index - 1, 1, url.encode())  # fmt: skip
        out.append((T0.timestamp() + after_s, msg.pack(cam)))
    out.sort(key=lambda r: r[0])
    path.write_bytes(b"".join(_record(t, p) for t, p in out))


def photo(path: Path, taken: datetime.datetime | None, make: str = "", model: str = "") -> Path:
    buf = io.BytesIO()
    Image.new("RGB", (16, 8)).save(buf, "JPEG")
    path.write_bytes(tag_jpeg(buf.getvalue(), PhotoMeta(make=make, model=model,
                                                        time=taken.replace(tzinfo=None) if taken else None)))  # fmt: skip
    return path


def gps_lat(path: Path) -> float | None:
    with Image.open(path) as img:
        gps = img.getexif().get_ifd(IFD_GPS)
    if 2 not in gps:
        return None
    d, m, s = (float(v) for v in gps[2])
    return d + m / 60 + s / 3600


def original(path: Path) -> str | None:
    with Image.open(path) as img:
        v = img.getexif().get_ifd(IFD_EXIF).get(TAG_ORIGINAL)
    return str(v) if v is not None else None


def lat_at(after_s: float) -> float:
    return LAT0 + after_s * NORTH_PER_S


# -- 35.1: captures of another camera ------------------------------------------------------------


def test_a_c12_photo_is_not_tagged_from_the_sips_capture_of_the_same_number(tmp_path, capsys):
    """The issue's flight: the SIP (component 102) took photos 6..8 at 2..4 s, the C12 its
    IMG_0006..8 at 10..12 s by its own (fed) clock. With the SIP's file_url in the log, the C12's
    photos are tagged from their own clock; DateTimeOriginal is kept."""
    log = tmp_path / "flight.tlog"
    write_tlog(log, captures=[(102, n, n - 4.0, f"http://127.0.0.1:8090/snap_0_{n}.jpeg") for n in (6, 7, 8)])
    photos = [photo(tmp_path / f"IMG_000{n}.jpg", T0 + datetime.timedelta(seconds=n + 4), "SkyDroid", "C12")
              for n in (6, 7, 8)]  # fmt: skip
    before = [original(p) for p in photos]
    assert main(["geotag", *map(str, photos), "--log", str(log)]) == 0
    for n, p, b in zip((6, 7, 8), photos, before, strict=True):
        lat = gps_lat(p)
        assert lat is not None and abs(lat - lat_at(n + 4)) < 2e-6, (p, lat)
        assert original(p) == b
    assert "3 of 3 photos tagged" in capsys.readouterr().err


def test_a_capture_the_photos_clock_contradicts_is_refused_naming_the_choice(tmp_path, capsys):
    """No file_url, no camera information: only the clock says capture 6 is not this photo's.
    Refused, naming --camera-compid (and --offset); the file is left as it was."""
    log = tmp_path / "flight.tlog"
    write_tlog(log, captures=[(102, 6, 2.0, "")])
    p = photo(tmp_path / "IMG_0006.jpg", T0 + datetime.timedelta(seconds=10), "SkyDroid", "C12")
    data = p.read_bytes()
    assert main(["geotag", str(p), "--log", str(log)]) == 1
    err = capsys.readouterr().err
    assert "--camera-compid 102" in err and "--offset" in err and "0 of 1 photos tagged" in err
    assert p.read_bytes() == data
    # The user says the number is right: component 102's capture 6 is used.
    assert main(["geotag", str(p), "--log", str(log), "--camera-compid", "102"]) == 0
    lat = gps_lat(p)
    assert lat is not None and abs(lat - lat_at(2.0)) < 2e-6


def test_two_cameras_with_the_same_number_are_ambiguous_until_one_is_chosen(tmp_path, capsys):
    """Both cameras took a photo 6; the photo's clock was never set and the log names no camera:
    refused. --camera-compid picks one; then the never-set clock gets that capture's time."""
    log = tmp_path / "flight.tlog"
    write_tlog(log, captures=[(100, 6, 5.0, ""), (102, 6, 20.0, "")])
    p = photo(tmp_path / "IMG_0006.jpg", datetime.datetime(1970, 1, 1, 0, 5, tzinfo=UTC))
    assert main(["geotag", str(p), "--log", str(log)]) == 1
    err = capsys.readouterr().err
    assert "--camera-compid" in err and "100" in err and "102" in err
    assert gps_lat(p) is None and original(p) == "1970:01:01 00:05:00"
    assert main(["geotag", str(p), "--log", str(log), "--camera-compid", "100"]) == 0
    lat = gps_lat(p)
    assert lat is not None and abs(lat - lat_at(5.0)) < 2e-6
    assert original(p) == (T0 + datetime.timedelta(seconds=5)).strftime("%Y:%m:%d %H:%M:%S")


def test_camera_information_tells_the_cameras_apart(tmp_path):
    """The log's CAMERA_INFORMATION names each component's vendor: a SkyDroid photo whose clock was
    never set takes the SkyDroid component's capture, not the TOPOTEK's."""
    log = tmp_path / "flight.tlog"
    info = {100: ("SkyDroid", "C12"), 102: ("TOPOTEK", "SIP")}
    write_tlog(log, captures=[(100, 6, 5.0, ""), (102, 6, 20.0, "")], info=info)
    p = photo(tmp_path / "IMG_0006.jpg", None, "SkyDroid", "C12")
    assert main(["geotag", str(p), "--log", str(log)]) == 0
    lat = gps_lat(p)
    assert lat is not None and abs(lat - lat_at(5.0)) < 2e-6
    q = photo(tmp_path / "snap_0_6.jpeg", None)  # TOPOTEK's naming, no EXIF make
    assert main(["geotag", str(q), "--log", str(log)]) == 0
    lat = gps_lat(q)
    assert lat is not None and abs(lat - lat_at(20.0)) < 2e-6


# -- 33.14: files geotag must not write, or must write through -----------------------------------


def _flight(tmp_path: Path) -> tuple[Path, datetime.datetime]:
    log = tmp_path / "flight.tlog"
    write_tlog(log)
    return log, T0 + datetime.timedelta(seconds=10)


def test_a_read_only_photo_is_refused_and_left_as_it_was(tmp_path, capsys):
    log, taken = _flight(tmp_path)
    p = photo(tmp_path / "a.jpg", taken)
    data = p.read_bytes()
    p.chmod(0o444)
    assert main(["geotag", str(p), "--log", str(log)]) == 1
    assert "read-only" in capsys.readouterr().err
    assert stat.S_IMODE(p.stat().st_mode) == 0o444 and p.read_bytes() == data


def test_the_mode_is_kept_a_symlink_is_written_through_and_hard_links_stay_one_file(tmp_path):
    log, taken = _flight(tmp_path)
    shared = photo(tmp_path / "shared.jpg", taken)
    shared.chmod(0o640)
    target = photo(tmp_path / "card.jpg", taken)
    link = tmp_path / "photos" / "link.jpg"
    link.parent.mkdir()
    link.symlink_to(target)
    twin = tmp_path / "photos" / "twin.jpg"
    hard = photo(tmp_path / "hard.jpg", taken)
    os.link(hard, twin)
    assert main(["geotag", str(shared), str(link), str(hard), "--log", str(log)]) == 0
    assert stat.S_IMODE(shared.stat().st_mode) == 0o640
    assert link.is_symlink() and os.readlink(link) == str(target)
    assert gps_lat(target) is not None and abs(gps_lat(target) - lat_at(10.0)) < 2e-6  # type: ignore[operator]
    assert os.path.samefile(hard, twin) and gps_lat(twin) is not None
    assert sorted(q.name for q in tmp_path.iterdir() if "geotag" in q.name) == []  # no temporary left


def test_a_fifo_named_jpg_is_reported_without_blocking_and_the_batch_goes_on(tmp_path):
    log, taken = _flight(tmp_path)
    fifo = tmp_path / "IMG_0002.jpg"
    os.mkfifo(fifo)
    good = photo(tmp_path / "IMG_0003.jpg", taken)
    env = dict(os.environ, PYTHONPATH=str(Path(topgimbal.__file__).parents[1]))
    try:  # today's code blocks in open(): the guard turns that into a failure, not a hung suite
        out = subprocess.run([sys.executable, "-m", "topgimbal.cli.main", "geotag", str(fifo), str(good), "--log", str(log)],
                             capture_output=True, text=True, timeout=120, env=env)  # fmt: skip
    except subprocess.TimeoutExpired:
        pytest.fail("geotag blocked on a FIFO")
    assert out.returncode == 1 and "IMG_0002.jpg: not a regular file" in out.stderr
    assert "1 of 2 photos tagged" in out.stderr and gps_lat(good) is not None


# -- 33.15: positions that are no place ------------------------------------------------------------


def test_unknown_and_impossible_positions_are_dropped(tmp_path, capsys):
    """MAVLink's "unknown" (INT32_MAX: 214.7 deg) and 0, 0 around the photo's time: the photo gets
    the position between the good samples on either side, never 214.7 or 0."""
    n = 30 * 5
    lat_e7 = [int((LAT0 + i * 0.2 * NORTH_PER_S) * 1e7) for i in range(n)]
    for i in range(45, 50):
        lat_e7[i] = 2**31 - 1
    lon_e7 = [int(8.5e7)] * n
    for i in range(50, 55):
        lat_e7[i] = lon_e7[i] = 0
    log = tmp_path / "flight.tlog"
    write_tlog(log, lat_e7=lat_e7, lon_e7=lon_e7)
    p = photo(tmp_path / "a.jpg", T0 + datetime.timedelta(seconds=10))
    assert main(["geotag", str(p), "--log", str(log)]) == 0
    lat = gps_lat(p)
    assert lat is not None and abs(lat - lat_at(10.0)) < 2e-6
    unknown = tmp_path / "unknown.tlog"
    write_tlog(unknown, lat_e7=[2**31 - 1] * n)
    q = photo(tmp_path / "b.jpg", T0 + datetime.timedelta(seconds=10))
    assert main(["geotag", str(q), "--log", str(unknown)]) == 1
    assert "no vehicle position" in capsys.readouterr().err and gps_lat(q) is None
