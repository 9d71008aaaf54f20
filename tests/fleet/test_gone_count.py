"""A call whose querier left is cancelled and counted once (`ServedCamera.gone`), though the
transport event and the poll may both see it before it ends (a fresh-clone run counted 5 for 4
calls). Pure: the camera's client is never connected, the calls are plain tasks."""

from __future__ import annotations

import asyncio

import pytest

from topgimbal.fleet import CameraSpec
from topgimbal.fleet.camera import ServedCamera

pytestmark = pytest.mark.virtual


async def test_a_cancelled_call_seen_twice_before_it_ends_is_gone_once() -> None:
    cam = ServedCamera(CameraSpec("a", "udp://127.0.0.1:9", "C12"), session=None)
    calls = [asyncio.ensure_future(asyncio.sleep(3600)) for _ in range(4)]
    for i, task in enumerate(calls):
        cam._call_querier[task] = (f"q{i % 2}", True)  # two queriers, each with its own transport
        task.add_done_callback(cam._call_done)
    cam._cancel_gone({"q1"})  # q0 left: the transport event ...
    cam._cancel_gone({"q1"})  # ... and the poll, before the cancelled calls have ended
    assert cam.gone == 2
    assert [t in cam._cancelled for t in calls] == [True, False, True, False]
    await asyncio.sleep(0)  # the cancelled calls end
    cam._cancel_gone(set())  # everyone left: the other two, once
    cam._cancel_gone(set())
    assert cam.gone == 4
    await asyncio.gather(*calls, return_exceptions=True)
    assert all(t.cancelled() for t in calls) and not cam._cancelled and not cam._calls
