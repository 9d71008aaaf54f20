"""The console's own periodic queries stay out of the traffic pane's default view even when the
camera answers them late (after the poll gave up): protocol frames carry no request id, so the hub
counts what a poll sent and what came back, and a late answer a finished poll was owed is still the
poll's; the operator's own query of the same command afterwards is not. Virtual time (looptime): the
simulator holds every request's answer past the client's timeout."""

from __future__ import annotations

import asyncio
from typing import Any

import pytest

import topgimbal
from topgimbal.console.hub import Hub
from topgimbal.sim import FaultPlan, Simulator

pytestmark = pytest.mark.virtual

LATE_S = 3.5  # every answer to a request comes this late: after the client gave up (3 attempts x 1 s)


@pytest.mark.looptime
async def test_a_polls_late_answers_stay_hidden_and_the_operators_do_not() -> None:
    sim = await Simulator("C12", faults=FaultPlan(late_reply_s=LATE_S)).start(udp=[])
    url = sim.listen_memory("hub-polls")
    try:
        async with topgimbal.connect(
            url, model="C12", timeout_s=1.0, retries=2, link_timeout_s=30.0, late_window_s=LATE_S + 1.0
        ) as cam:
            hub = Hub(cam, sd_interval_s=3600.0)
            seen: list[tuple[str, bool]] = []
            record = hub.record

            def spy(direction: str, frame: Any, message: Any, **marks: Any) -> dict[str, Any]:
                if getattr(frame, "ident", None) == "SDC":
                    seen.append((direction, bool(marks.get("poll"))))
                    print(asyncio.get_running_loop().time(), direction, frame)
                return record(direction, frame, message, **marks)

            hub.record = spy  # type: ignore[method-assign]
            unsubscribe = cam.on_traffic(hub._on_traffic)
            try:
                assert await hub.refresh_sd(poll=True) is None  # every attempt timed out
                polled = list(seen)
                assert [d for d, _ in polled].count("out") == 3 and all(poll for _, poll in polled)
                await asyncio.sleep(LATE_S + 1.0)  # the three late answers come in
                late = seen[len(polled) :]
                assert [d for d, _ in polled + late].count("in") == 3, seen
                assert all(poll for _, poll in late), f"a poll's late answer shown as the operator's: {seen}"
                # the operator's own query afterwards (a patient one): its frames are not polls
                mark = len(seen)
                await cam.request("SDC", read=True, timeout_s=LATE_S + 1.0, retries=0)
                await asyncio.sleep(0.1)
                mine = seen[mark:]
                assert [d for d, _ in mine] == ["out", "in"] and not any(poll for _, poll in mine), mine
            finally:
                unsubscribe()
    finally:
        await sim.stop()
