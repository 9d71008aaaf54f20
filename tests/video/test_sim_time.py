"""One model of time for every model (issue 35.5): a photo's EXIF time (DateTimeOriginal plus
SubSecTimeOriginal) is the fed UTC time moved on, for the SIP (fed UTC, whole seconds) as for the
C12 (fed TIM, hundredths). It was ~1 s behind on the SIP: its frame cut the fraction."""

from __future__ import annotations

import asyncio
import datetime
from pathlib import Path

import pytest
from PIL import Image

import topgimbal
from topgimbal.clock import monotonic
from topgimbal.sim import Simulator
from topgimbal.video.exif import IFD_EXIF, TAG_ORIGINAL, TAG_SUBSEC_ORIGINAL
from topgimbal.video.media import MediaStore

pytestmark = pytest.mark.loopback

UTC = datetime.timezone.utc


def exif_time(path: Path) -> datetime.datetime:
    with Image.open(path) as img:
        sub = img.getexif().get_ifd(IFD_EXIF)
    t = datetime.datetime.strptime(str(sub[TAG_ORIGINAL]), "%Y:%m:%d %H:%M:%S")
    return t.replace(tzinfo=UTC) + datetime.timedelta(seconds=float("0." + str(sub.get(TAG_SUBSEC_ORIGINAL, "0"))))


@pytest.mark.parametrize("model", ["SIP", "C12"])
async def test_the_photo_time_is_the_fed_time(tmp_path: Path, model: str) -> None:
    sim = Simulator(model)
    await sim.start(udp=[("127.0.0.1", 0)])
    store = MediaStore(sim, tmp_path).start()
    given = datetime.datetime(2025, 6, 1, 12, 0, 0, 900_000, tzinfo=UTC)  # late in its second
    try:
        async with topgimbal.connect(sim.url, model=model, timeout_s=1, check_model=False) as cam:
            await cam.feed(time_utc=given)
            fed_at = monotonic()
            while cam.feeds.sent.get("UTC" if model == "SIP" else "TIM", 0) < 2:  # the clock set, and set again
                await asyncio.sleep(0.05)
            asked_at = monotonic()
            await cam.photo()
            answered_at = monotonic()
            while not any(p.suffix in (".jpg", ".jpeg") for p in tmp_path.iterdir()):
                await asyncio.sleep(0.05)
    finally:
        await store.stop()
        await sim.stop()
    photo = sorted(p for p in tmp_path.iterdir() if p.suffix in (".jpg", ".jpeg"))[0]
    # The photo was taken between the CAP request and its answer: its time is the fed time moved on
    # to that moment, give or take 0.1 s (the frame's way to the camera, EXIF's hundredths).
    earliest = given + datetime.timedelta(seconds=asked_at - fed_at - 0.1)
    latest = given + datetime.timedelta(seconds=answered_at - fed_at + 0.1)
    assert earliest <= exif_time(photo) <= latest, (earliest, exif_time(photo), latest)
