"""Persistent settings across restarts; atomic writes."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest

from topgimbal.sim import Simulator, persist
from topgimbal.sim.persist import StateFileError
from topgimbal.sim.state import NetworkState

from .conftest import LOOP, UdpClient, req


async def test_settings_survive_a_restart(tmp_path: Path) -> None:
    state = tmp_path / "cam.json"
    async with Simulator("SIP", state_file=state, listen={"udp": [(LOOP, 0)]}) as sim:
        c = UdpClient(sim.addresses["udp"][0])
        try:
            for msg in (
                req("SIP", "IPV", address="127.9.8.7"),
                req("SIP", "IMG", palette="ironbow"),
                req("SIP", "PTZ", action="lock"),
                req("SIP", "CAP", mode="visible"),
                req("SIP", "REC", action="start"),
                req("SIP", "REC", action="stop"),
            ):
                assert await c.request(msg)
        finally:
            c.close()
        assert json.loads(state.read_text())["state"]["network"]["ip"] == "127.9.8.7"  # written before stop
    again = Simulator("SIP", state_file=state)
    assert again.network.ip == "127.9.8.7"
    assert again.settings["IMG"]["palette"] == "ironbow"
    assert again.gimbal.mode == "lock"
    assert (again.camera.photo_index, again.camera.record_index) == (1, 1)
    assert again.camera.sd_remaining_mb < again.camera.sd_total_mb


def test_factory_reset_restores_defaults_and_persists(tmp_path: Path) -> None:
    state = tmp_path / "cam.json"
    sim = Simulator("C12", state_file=state)
    sim.device.receive("p", req("C12", "IPV", address="127.0.0.11"))
    sim.device.receive("p", req("C12", "RTF", action="factory_reset"))
    sim.flush()
    assert Simulator("C12", state_file=state).network.ip == NetworkState().ip  # the factory default


def test_a_crash_mid_write_leaves_the_old_file(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    state = tmp_path / "cam.json"
    persist.save(state, {"network": {"ip": "127.0.0.11"}})
    before = state.read_bytes()

    def crash(src: str, dst: str) -> None:
        raise OSError("killed")

    monkeypatch.setattr(os, "replace", crash)
    with pytest.raises(OSError):
        persist.save(state, {"network": {"ip": "127.0.0.12"}})
    assert state.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == ["cam.json"]  # no temporary left behind


def test_corrupt_or_foreign_file_is_a_clear_error(tmp_path: Path) -> None:
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    with pytest.raises(StateFileError, match="not valid JSON"):
        Simulator("C12", state_file=bad)
    bad.write_text('{"hello": 1}')
    with pytest.raises(StateFileError, match="not a topgimbal simulator state file"):
        Simulator("C12", state_file=bad)
