"""Traffic log (JSONL) written by the client, read back and replayed against a simulator."""

from __future__ import annotations

import json

import pytest

import topgimbal
from topgimbal.client import read_log

pytestmark = [pytest.mark.loopback, pytest.mark.integration]


async def test_log_and_replay(sim_factory, tmp_path):
    sim = await sim_factory("C12", seed=21)
    url = dict(sim.endpoints)["udp"]
    path = tmp_path / "session.jsonl"
    async with topgimbal.connect(url, model="C12", timeout_s=0.5, log_path=str(path)) as cam:
        traffic: list[tuple[str, str]] = []
        cam.on_traffic(lambda d, f, m: traffic.append((d, f.ident)))
        await cam.photo()
        await cam.start_recording()
        await cam.recording()
    lines = [json.loads(x) for x in path.read_text().splitlines()]
    assert lines[0]["topgimbal_log"] == 1 and lines[0]["model"] == "C12"
    body = lines[1:]
    assert {"t", "mono", "dir", "raw", "decoded"} <= set(body[0])
    assert [x["dir"] for x in body[:2]] == ["out", "in"]
    assert body[0]["raw"].startswith("#TPUD2wCAP") and body[0]["decoded"]["id"] == "CAP"
    assert ("out", "REC") in traffic and ("in", "REC") in traffic
    records = list(read_log(path))
    assert len(records) == len(body) and records[0].frame.ident == "CAP"

    # replay the host -> device frames into a fresh simulator: the same effects happen
    other = await sim_factory("C12", seed=22)
    async with topgimbal.connect(dict(other.endpoints)["udp"], model="C12", timeout_s=0.5) as cam:
        for r in records:
            if r.direction == "out":
                await cam.send_raw(r.frame)
    assert other.camera.photos_taken == 1 and other.camera.recording is True
