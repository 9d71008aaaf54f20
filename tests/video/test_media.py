"""The simulated card (`sim --media`): photos rendered at capture with the camera's clock and what it
was fed, recordings as MP4, a size cap, the HTTP server and `topgimbal media`, and `topgimbal
geotag` for photos that were not fed. Tags are read back with exiftool and exifread."""

from __future__ import annotations

import asyncio
import contextlib
import datetime
import io
import json
import os
import shutil
import struct
import subprocess
import urllib.error
import urllib.request
from collections.abc import AsyncIterator
from pathlib import Path
from typing import Any

import pytest

import topgimbal
from topgimbal.cli.main import main
from topgimbal.sim import Simulator
from topgimbal.video.media import MediaStore
from topgimbal.video.media_http import MediaServer
from waiting import until

pytestmark = [
    pytest.mark.external,
    pytest.mark.skipif(shutil.which("exiftool") is None, reason="make exiftool-deps installs exiftool"),
]

UTC = datetime.timezone.utc


async def eventually(check: Any, timeout: float = 20.0, what: str = "condition") -> None:
    await until(what, check, bound_s=timeout)  # tests/waiting.py


def exiftool(*paths: Path) -> list[dict[str, Any]]:
    out = subprocess.run(["exiftool", "-j", "-n", "-G", *map(str, paths)], capture_output=True, text=True, timeout=60)
    data: list[dict[str, Any]] = json.loads(out.stdout)
    return data


@contextlib.asynccontextmanager
async def simulator(model: str) -> AsyncIterator[Simulator]:
    sim = Simulator(model)
    await sim.start(udp=[("127.0.0.1", 0)])  # loopback, a free port
    try:
        yield sim
    finally:
        await sim.stop()


def files(d: Path) -> list[str]:
    return sorted(p.name for p in d.iterdir() if not p.name.endswith(".part"))


async def test_an_unfed_camera_dates_its_photos_1970_and_writes_no_gps(tmp_path):
    async with simulator("C12") as sim:
        store = MediaStore(sim, tmp_path).start()
        async with topgimbal.connect(sim.url, model="C12", timeout_s=1, check_model=False) as cam:
            await cam.photo()
            await eventually(lambda: files(tmp_path) == ["IMG_0001.jpg", "IMG_0001_T.jpg"], what="both lenses")
        await store.stop()
    tags = exiftool(tmp_path / "IMG_0001.jpg", tmp_path / "IMG_0001_T.jpg")
    for t in tags:
        assert t["EXIF:DateTimeOriginal"].startswith("1970:01:01")
        assert not any(k.startswith("EXIF:GPS") and k not in ("EXIF:GPSVersionID",) for k in t)
        assert t["EXIF:Make"] == "SkyDroid" and t["EXIF:Model"] == "C12"
    assert tags[0]["File:ImageWidth"] == 1280 and tags[1]["File:ImageWidth"] == 640  # visible, thermal


async def test_a_recording_is_an_mp4_and_the_card_keeps_under_its_cap(tmp_path):
    async with simulator("SIP") as sim:
        store = MediaStore(sim, tmp_path, max_bytes=150_000).start()
        async with topgimbal.connect(sim.url, model="SIP", timeout_s=1, check_model=False) as cam:
            await cam.start_recording()
            await asyncio.sleep(1.0)
            await cam.stop_recording()
            await eventually(lambda: "stream_0_1.mp4" in files(tmp_path), 30.0, "the recording")
            for _ in range(3):
                await cam.photo()
            await eventually(lambda: "snap_0_3.jpeg" in files(tmp_path) and "snap_1_3.jpeg" in files(tmp_path))
        await store.stop()
    names = files(tmp_path)
    assert "stream_0_1.mp4" not in names and "snap_0_1.jpeg" not in names  # the oldest went first
    assert sum((tmp_path / n).stat().st_size for n in names) <= 150_000


async def test_the_card_drops_by_capture_order_when_photos_land_out_of_order(tmp_path):
    """Photos are written on worker threads: a later shot's file can land first (a newer mtime on
    the older shot). Pruning goes by when each was taken; files already on the card go before."""
    (tmp_path / "snap_0_7.jpeg").write_bytes(b"x" * 1000)  # from an earlier session
    async with simulator("SIP") as sim:
        store = MediaStore(sim, tmp_path, max_bytes=10_000_000).start()
        store._on_capture("photo", 1)
        store._on_capture("photo", 2)
        await store.stop()
        first, second = tmp_path / "snap_0_1.jpeg", tmp_path / "snap_0_2.jpeg"
        (tmp_path / "snap_0_7.jpeg").touch()  # the oldest, with the newest mtime
        stamp = second.stat().st_mtime
        os.utime(first, (stamp + 5, stamp + 5))  # the first shot "landed" last
        sizes = {n: (tmp_path / n).stat().st_size for n in files(tmp_path)}
        store.max_bytes = sum(sizes.values()) - 1000 - sizes["snap_0_1.jpeg"] - sizes["snap_1_1.jpeg"]
        store.prune()
    assert sorted(files(tmp_path)) == ["snap_0_2.jpeg", "snap_1_2.jpeg"]


async def test_mp4_plays(tmp_path):
    async with simulator("C12") as sim:
        store = MediaStore(sim, tmp_path).start()
        async with topgimbal.connect(sim.url, model="C12", timeout_s=1, check_model=False) as cam:
            await cam.start_recording()
            await asyncio.sleep(1.0)
            await cam.stop_recording()
            await eventually(lambda: "VID_0001.mp4" in files(tmp_path), 30.0, "the recording")
        await store.stop()
    import av

    with av.open(str(tmp_path / "VID_0001.mp4")) as f:
        frames = sum(1 for _ in f.decode(video=0))
    assert frames >= 3


async def test_http_lists_and_serves_only_media_files_and_media_get_fetches_them(tmp_path, capsys):
    card, out = tmp_path / "card", tmp_path / "out"
    out.mkdir()
    async with simulator("SIP") as sim:
        store = MediaStore(sim, card).start()
        (card / "secret.txt").write_text("not media")
        server = MediaServer(card).start()
        try:
            async with topgimbal.connect(sim.url, model="SIP", timeout_s=1, check_model=False) as cam:
                await cam.photo()
                await eventually(lambda: len(files(card)) == 3, what="two photos")
            for bad in ("secret.txt", "..%2Fsecret.txt", "snap_0_9.jpeg"):
                with pytest.raises(urllib.error.HTTPError) as err:
                    urllib.request.urlopen(server.url + bad, timeout=10)
                assert err.value.code == 404
            assert await asyncio.to_thread(main, ["media", "list", server.url]) == 0
            listed = capsys.readouterr().out
            assert "snap_0_1.jpeg" in listed and "snap_1_1.jpeg" in listed and "secret" not in listed
            rc = await asyncio.to_thread(main, ["media", "get", server.url, "-o", str(out)])
            assert rc == 0
            assert (out / "snap_0_1.jpeg").read_bytes() == (card / "snap_0_1.jpeg").read_bytes()
            rc = await asyncio.to_thread(main, ["media", "get", server.url, "snap_0_9.jpeg", "-o", str(out)])
            assert rc == 1 and "404" in capsys.readouterr().err
        finally:
            server.stop()
            await store.stop()


async def test_geotag_tags_unfed_photos_from_a_traffic_log(tmp_path, capsys):
    """One client fed a SIP (its traffic log holds the LAT/LON/ALT frames); a C12 given only the time
    took the photos. `geotag` finds each photo's position in the log by its DateTimeOriginal."""
    card, log = tmp_path / "card", tmp_path / "traffic.jsonl"
    lat, lon, alt = 52.5200066, 13.4049540, 34.5
    async with simulator("SIP") as sip, simulator("C12") as c12:
        store = MediaStore(c12, card).start()
        async with (
            topgimbal.connect(sip.url, model="SIP", timeout_s=1, check_model=False, log_path=str(log)) as fed,
            topgimbal.connect(c12.url, model="C12", timeout_s=1, check_model=False) as unfed,
        ):
            await unfed.feed(time_utc=datetime.datetime.now(UTC))  # the time only: no position
            for _ in range(30):  # 3 s of fixes, 10 Hz feeds
                await fed.feed(lat, lon, alt, 90.0)
                await asyncio.sleep(0.1)
                if _ == 15:
                    await unfed.photo()
            await eventually(lambda: len(files(card)) == 2, what="the photos")
        await store.stop()
    (card / "broken.jpg").write_bytes(b"\xff\xd8\xff\xe1\x00")  # a bad file among them
    before = exiftool(card / "IMG_0001.jpg")[0]
    assert "EXIF:GPSLatitude" not in before
    rc = await asyncio.to_thread(main, ["geotag", str(card), "--log", str(log)])
    err = capsys.readouterr().err
    assert rc == 1 and "broken.jpg" in err and "2 of 3 photos tagged" in err
    for t in exiftool(card / "IMG_0001.jpg", card / "IMG_0001_T.jpg"):
        assert abs(t["Composite:GPSLatitude"] - lat) < 1e-5 and abs(t["Composite:GPSLongitude"] - lon) < 1e-5
        assert abs(t["EXIF:GPSAltitude"] - alt) < 1.0
        assert t["EXIF:DateTimeOriginal"] == before["EXIF:DateTimeOriginal"]  # kept
    import exifread

    with (card / "IMG_0001.jpg").open("rb") as f:
        ex = exifread.process_file(f, details=False)
    assert str(ex["GPS GPSLatitudeRef"]) == "N" and str(ex["Image Model"]) == "C12"


def _tlog(path: Path, t0: float, seconds: int) -> None:
    from pymavlink.dialects.v20 import common as ml

    mav = ml.MAVLink(None, srcSystem=1, srcComponent=1)
    with path.open("wb") as f:
        for i in range(seconds * 5):
            t = t0 + i * 0.2
            lat = int((47.0 + i * 1e-5) * 1e7)  # moving north
            msg = ml.MAVLink_global_position_int_message(int(i * 200), lat, int(8.5 * 1e7), 500_000, 0, 0, 0, 0, 0)
            f.write(struct.pack(">Q", int(t * 1e6)) + msg.pack(mav))
            f.write(b"junk")  # a damaged record between good ones


def test_geotag_from_a_mavlink_tlog_matches_by_capture_time(tmp_path):
    from PIL import Image

    from topgimbal.video.exif import PhotoMeta, tag_jpeg

    t0 = datetime.datetime(2025, 5, 4, 10, 0, 0, tzinfo=UTC)
    _tlog(tmp_path / "flight.tlog", t0.timestamp(), 20)
    buf = io.BytesIO()
    Image.new("RGB", (32, 24)).save(buf, "JPEG")
    photo = tmp_path / "IMG_0007.jpg"
    taken = t0 + datetime.timedelta(seconds=10)
    photo.write_bytes(tag_jpeg(buf.getvalue(), PhotoMeta(make="X", model="Y", time=taken.replace(tzinfo=None))))
    assert main(["geotag", str(photo), "--log", str(tmp_path / "flight.tlog")]) == 0
    t = exiftool(photo)[0]
    assert abs(t["Composite:GPSLatitude"] - (47.0 + 50 * 1e-5)) < 1e-6  # 10 s = 50 samples north
    assert abs(t["EXIF:GPSAltitude"] - 500.0) < 1.0
    assert main(["geotag", str(photo), "--log", str(tmp_path / "flight.tlog")]) == 0  # has GPS: left alone
    late = tmp_path / "IMG_0008.jpg"
    late.write_bytes(tag_jpeg(buf.getvalue(), PhotoMeta(time=(t0 + datetime.timedelta(hours=1)).replace(tzinfo=None))))
    assert main(["geotag", str(late), "--log", str(tmp_path / "flight.tlog")]) == 1  # outside the flight: no guess
    assert "EXIF:GPSLatitude" not in exiftool(late)[0]


def test_geotag_reports_damaged_photos_and_goes_on(tmp_path, capsys):
    """Untrusted files: damaged EXIF, truncated pictures, not a JPEG. Each is tagged or reported in
    one line; nothing stops the batch."""
    import random

    from PIL import Image

    from topgimbal.video.exif import PhotoMeta, tag_jpeg

    t0 = datetime.datetime(2025, 5, 4, 10, 0, 0, tzinfo=UTC)
    _tlog(tmp_path / "flight.tlog", t0.timestamp(), 20)
    buf = io.BytesIO()
    Image.new("RGB", (32, 24)).save(buf, "JPEG")
    good = tag_jpeg(buf.getvalue(), PhotoMeta(time=(t0 + datetime.timedelta(seconds=5)).replace(tzinfo=None)))
    rng = random.Random(7)
    photos = tmp_path / "photos"
    photos.mkdir()
    for i in range(60):
        b = bytearray(good)
        for _ in range(rng.randint(1, 6)):
            j = rng.randrange(2, min(len(b), 300))
            b[j] = rng.randrange(256)
        (photos / f"p{i:02d}.jpg").write_bytes(bytes(b[: rng.randrange(20, len(b) + 1)]))
    (photos / "text.jpg").write_text("not a picture")
    (photos / "zz_good.jpg").write_bytes(good)
    rc = main(["geotag", str(photos), "--log", str(tmp_path / "flight.tlog")])
    err = capsys.readouterr().err
    assert rc == 1 and "text.jpg" in err and "Traceback" not in err
    assert f"of {62} photos tagged" in err
    assert abs(exiftool(photos / "zz_good.jpg")[0]["Composite:GPSLatitude"] - (47.0 + 25 * 1e-5)) < 1e-6
