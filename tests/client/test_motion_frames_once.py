"""A motion frame is built, and so range-checked, once: the frames validated before the first one
goes out are the frames sent (set_angles, rates, stop, point used to build each one twice, point's
angles were checked three times)."""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterator, Mapping
from typing import Any

import pytest

import topgimbal
from topgimbal.client import api_motion
from topgimbal.client.builder import FrameBuilder

pytestmark = [pytest.mark.looptime, pytest.mark.virtual]


@pytest.fixture
def builds(monkeypatch: pytest.MonkeyPatch) -> Iterator[Counter[tuple[str, str]]]:
    """Every write frame built, by (identifier, values)."""
    seen: Counter[tuple[str, str]] = Counter()
    real = FrameBuilder.build

    def counting(self: FrameBuilder, ident: str, values: Mapping[str, object], **kw: Any) -> Any:
        if not kw.get("read"):
            seen[(ident, repr(sorted(values.items())))] += 1
        return real(self, ident, values, **kw)

    monkeypatch.setattr(FrameBuilder, "build", counting)
    yield seen


@pytest.fixture
def axis_checks(monkeypatch: pytest.MonkeyPatch) -> Iterator[Counter[str]]:
    seen: Counter[str] = Counter()
    real = api_motion._check_axis

    def counting(core: Any, axis: str, value: float | None) -> None:
        if value is not None:
            seen[axis] += 1
        real(core, axis, value)

    monkeypatch.setattr(api_motion, "_check_axis", counting)
    yield seen


async def test_each_motion_frame_is_built_once(memory_sim: Any, builds: Counter[tuple[str, str]]) -> None:
    _sim, url = await memory_sim("C12")
    async with topgimbal.connect(url, model="C12") as cam:
        for call in (
            lambda: cam.set_angles(10.0, -20.0),
            lambda: cam.rates(3.0, -2.0),
            cam.stop,
        ):
            builds.clear()
            await call()
            assert builds and set(builds.values()) == {1}, dict(builds)


async def test_point_checks_and_builds_its_angles_once(
    memory_sim: Any, builds: Counter[tuple[str, str]], axis_checks: Counter[str]
) -> None:
    _sim, url = await memory_sim("C12")
    async with topgimbal.connect(url, model="C12") as cam:
        builds.clear()
        await cam.point(12.0, -8.0, tolerance_deg=1.0)
    assert axis_checks == {"yaw": 1, "pitch": 1}
    angle_frames = {k: n for k, n in builds.items() if "12.0" in k[1]}
    assert list(angle_frames.values()) == [1], dict(builds)
