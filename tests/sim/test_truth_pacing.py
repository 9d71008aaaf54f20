"""The truth file's pacing on looptime's virtual clock: one record per period, on the period, as many
as the time allows (the loopback test of `sim --truth` checks the wiring, not the timing)."""

from __future__ import annotations

import asyncio
import itertools
import json
from pathlib import Path

import pytest

from topgimbal.sim import Simulator
from topgimbal.sim.truth import TRUTH_HZ, TruthWriter

pytestmark = pytest.mark.virtual


async def test_truth_is_written_at_its_rate(tmp_path: Path) -> None:
    sim = Simulator("C12", seed=1)
    writer = TruthWriter(sim.device, tmp_path / "truth.jsonl")
    await writer.start()
    await asyncio.sleep(1.0 + 0.5 / TRUTH_HZ)  # a second, and half a period so the count is exact
    await writer.stop()
    lines = [json.loads(line) for line in (tmp_path / "truth.jsonl").read_text().splitlines()]
    assert len(lines) == writer.lines == int(TRUTH_HZ) + 1  # one at the start, then one per period
    gaps = [b["t"] - a["t"] for a, b in itertools.pairwise(lines)]
    assert all(g == pytest.approx(1.0 / TRUTH_HZ, abs=1e-3) for g in gaps), gaps[:5]
