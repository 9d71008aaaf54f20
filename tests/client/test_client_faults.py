"""Under the simulator's fault plans: queries end in the right answer or a clear timeout, no
toggle is applied twice, no reply is matched to the wrong request, nothing hangs. Bounded in
count (fixed iterations, fixed seeds) and time (short timeouts, an overall wait_for)."""

from __future__ import annotations

import asyncio

import pytest

import topgimbal
from topgimbal.errors import RequestTimeoutError
from topgimbal.sim import FaultPlan

pytestmark = [pytest.mark.loopback, pytest.mark.integration]

# late_window_s must exceed the longest delay the link can add (reorder hold 0.2 s on the way in,
# late 0.35 s and reorder hold 0.2 s on the way out):
# without transaction ids that is what tells a late answer from a fresh one.
HOSTILE = dict(drop=0.3, corrupt=0.1, duplicate=0.1, reorder=0.1, late_reply_s=0.35, late_reply_p=0.2)
PALETTES = ["white_hot", "ironbow", "rainbow", "black_hot"]
PALETTES_SIP = ["white_hot", "ironbow", "lava", "black_hot"]


# Virtual time (looptime, memory://) for the behaviour; real sockets in time as the smoke test.
VIRTUAL = [pytest.mark.looptime, pytest.mark.virtual]


@pytest.mark.parametrize(
    "model,kind",
    [
        pytest.param("C12", "memory", marks=VIRTUAL),
        pytest.param("SIP", "memory", marks=VIRTUAL),
        ("C12", "udp"),
        ("SIP", "tcp"),
    ],
)
async def test_queries_get_the_right_answer_or_a_clear_timeout(sim_factory, memory_sim, model, kind):
    faults = FaultPlan(**HOSTILE, direction="both")
    if kind == "memory":
        sim, url = await memory_sim(model, seed=11, faults=faults)
    else:
        sim = await sim_factory(model, seed=11, faults=faults)
        url = dict(sim.endpoints)[kind]
    palettes = PALETTES if model == "C12" else PALETTES_SIP
    outcomes = {"right": 0, "timeout": 0}

    async def body() -> None:
        async with topgimbal.connect(url, model=model, timeout_s=0.15, retries=6, late_window_s=1.0) as cam:
            for i in range(10):
                want = palettes[i % len(palettes)]
                try:
                    await cam.palette(want)  # absolute set-point: retried
                except RequestTimeoutError:
                    outcomes["timeout"] += 1
                    continue
                try:
                    got = await cam.palette()
                except RequestTimeoutError:
                    outcomes["timeout"] += 1
                    continue
                # a late or duplicated answer to an earlier query would name an earlier palette
                assert got == want, (i, got, want)
                outcomes["right"] += 1
            stats = cam.stats.as_dict()
        assert stats["retries"] > 0  # the faults really bit
        assert stats["late_replies"] + stats["duplicates"] + stats["stray_replies"] > 0

    await asyncio.wait_for(body(), 60)
    assert outcomes["right"] >= 4
    assert sum(sim.fault_counts["out"].values()) > 0


@pytest.mark.parametrize("kind", [pytest.param("memory", marks=VIRTUAL), "udp"])
async def test_toggles_and_photos_are_never_sent_twice(sim_factory, memory_sim, kind):
    # Faults on the device -> host side (a duplicated *request* would be the network's doing).
    faults = FaultPlan(**HOSTILE, direction="out")
    if kind == "memory":
        sim, url = await memory_sim("C12", seed=12, faults=faults)
    else:
        sim = await sim_factory("C12", seed=12, faults=faults)
        url = dict(sim.endpoints)["udp"]
    calls = {"toggle": 0, "photo": 0}

    async def body() -> None:
        async with topgimbal.connect(url, model="C12", timeout_s=0.1, retries=3, late_window_s=1.0) as cam:
            for _ in range(12):
                calls["toggle"] += 1
                with _maybe_timeout():
                    await cam.toggle_recording()
                calls["photo"] += 1
                with _maybe_timeout():
                    await cam.photo()

    await asyncio.wait_for(body(), 40)
    toggles = [f for f in sim.received if f.ident == "REC" and f.data == b"0A"]
    caps = [f for f in sim.received if f.ident == "CAP"]
    assert len(toggles) == calls["toggle"] and len(caps) == calls["photo"]
    assert sim.camera.photos_taken == calls["photo"]
    assert sim.camera.recording is (calls["toggle"] % 2 == 1)


class _maybe_timeout:  # noqa: N801 - a context manager used like a keyword
    def __enter__(self) -> None:
        return None

    def __exit__(self, et, e, tb) -> bool:
        return et is RequestTimeoutError


async def test_set_points_echo_matches_only_its_own_request(sim_factory):
    sim = await sim_factory("SIP", seed=13, faults=FaultPlan(**HOSTILE, direction="both"))
    url = dict(sim.endpoints)["udp"]
    seen: list[tuple[str, bytes, bytes]] = []

    async def body() -> None:
        async with topgimbal.connect(url, model="SIP", timeout_s=0.1, retries=5, late_window_s=1.0) as cam:
            for i in range(16):
                frame = cam.build("GAY", yaw_deg=float(i))
                try:
                    m = await cam.request("GAY", yaw_deg=float(i))
                except RequestTimeoutError:
                    continue
                seen.append((m.ident, m.frame.data, frame.data))

    await asyncio.wait_for(body(), 40)
    assert seen and all(reply == sent for _, reply, sent in seen)


async def test_late_replies_are_counted_and_dropped(sim_factory):
    sim = await sim_factory("C12", seed=14, faults=FaultPlan(late_reply_s=0.3, late_reply_p=0.5, direction="out"))
    url = dict(sim.endpoints)["udp"]

    async def body() -> dict:
        async with topgimbal.connect(url, model="C12", timeout_s=0.1, retries=0, late_window_s=1.0) as cam:
            want = [True, False] * 6
            for rec in want:
                with _maybe_timeout():
                    if rec:
                        await cam.start_recording()
                    else:
                        await cam.stop_recording()
                try:
                    assert await cam.recording() is sim.camera.recording
                except RequestTimeoutError:
                    pass
            await asyncio.sleep(0.4)  # let the last late replies arrive
            return cam.stats.as_dict()

    stats = await asyncio.wait_for(body(), 30)
    assert stats["timeouts"] > 0 and stats["late_replies"] > 0
