"""Errors that say what happened: a lost photo, a silent device, an acknowledgement that does not
carry the data sent (in-memory fake device, no sockets)."""

from __future__ import annotations

import pytest

import topgimbal
from topgimbal.errors import DeviceError, RequestTimeoutError

pytestmark = pytest.mark.virtual


async def test_a_lost_photo_says_it_may_have_been_taken_and_how_to_check(fake):
    url = fake.start_memory()
    fake.handler = lambda f: None if f.ident == "CAP" else fake.default(f)
    async with topgimbal.connect(url, model="C12", timeout_s=0.1, retries=3, check_model=False) as cam:
        with pytest.raises(RequestTimeoutError) as err:
            await cam.photo()
    text = str(err.value)
    assert "may or may not have been taken" in text and "never sent twice" in text
    assert "SD card" in text and "CAP feedback" in text
    assert [f.ident for f in fake.received] == ["CAP"]


async def test_a_silent_device_says_so_in_words(fake):
    url = fake.start_memory()
    fake.muted = True
    async with topgimbal.connect(url, model="C12", timeout_s=0.05, retries=0) as cam:
        with pytest.raises(RequestTimeoutError) as err:
            await cam.identify()
    assert "nothing at all has come from" in str(err.value) and "memory://" in str(err.value)


async def test_an_acknowledgement_with_other_data_is_a_device_error_showing_it(fake):
    url = fake.start_memory()
    d = fake.dialect

    def clamp(frame):  # a device that echoes another angle than the one it was sent
        if frame.ident == "GAY":
            return [d.encode("GAY", yaw_deg=45.0).swapped().to_bytes()]
        return fake.default(frame)

    fake.handler = clamp
    async with topgimbal.connect(url, model="C12", timeout_s=0.3) as cam:
        with pytest.raises(DeviceError) as err:
            await cam.set_angles(yaw_deg=10)
    assert "does not carry the data sent" in str(err.value) and "#TPGU6wGAY1194" in str(err.value)


def test_the_console_can_type_its_camera_as_camera_api():
    from topgimbal.client import CameraAPI

    assert {"attitude", "request", "set_angles", "photo", "on_link_change"} <= set(dir(CameraAPI))
