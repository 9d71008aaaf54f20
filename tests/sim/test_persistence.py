"""Persistent settings across restarts; atomic writes."""

from __future__ import annotations

import asyncio
import json
import os
from datetime import datetime
from pathlib import Path

import pytest

from topgimbal.protocol import all_models
from topgimbal.sim import Simulator, persist
from topgimbal.sim.persist import StateFileError
from topgimbal.sim.state import NetworkState

from .conftest import LOOP, UdpClient, req

pytestmark = pytest.mark.loopback


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


# -- malformed state files: one clear line naming the file and the key, never a traceback -----------


def _doc(state: object) -> str:
    return json.dumps({"format": persist.FORMAT, "version": persist.VERSION, "state": state})


GOOD = Simulator("C12").device.snapshot()


def _with(path: str, value: str) -> str:
    """GOOD as JSON text with the value at a dotted path replaced by raw JSON text."""
    marker = "__REPLACE_ME__"
    state = json.loads(json.dumps(GOOD))  # the snapshot is plain JSON (a time as ISO text)
    *parents, last = path.split(".")
    node = state
    for key in parents:
        node = node[key]
    node[last] = marker
    return _doc(state).replace(f'"{marker}"', value)


MALFORMED = [
    ("{not json", "is not valid JSON (Expecting property name"),
    ("", "is not valid JSON (Expecting value at line 1 column 1"),
    ("[1, 2]", "is not a topgimbal simulator state file"),
    (json.dumps({"format": persist.FORMAT, "version": 1, "state": [1]}), "'state' must be an object, got a list"),
    (json.dumps({"format": persist.FORMAT, "version": 1, "state": {}, "extra": 1}), "unknown key 'extra'"),
    (json.dumps({"format": persist.FORMAT, "version": 2, "state": {}}), "has version 2; this simulator reads 1"),
    (_with("camera.zoom_pos", "Infinity"), "camera.zoom_pos is Infinity (not a finite number); expected a finite"),
    (_with("camera.zoom_pos", "NaN"), "camera.zoom_pos is NaN (not a finite number)"),
    (_with("camera.sd_used_mb", "1e400"), "camera.sd_used_mb is 1e400 (not a finite number)"),
    (_with("uid", "9" * 400), "uid is 999999999999999999999999... (an integer of 400 digits)"),
    (_with("uid", str(1 << 64)), "uid is an integer; expected an integer within +-2**63"),
    (_with("settings", "[]"), "settings is a list; expected an object"),
    (_with("settings.IMG", '"ironbow"'), "settings.IMG is text; expected an object"),
    (_with("settings.IMG.palette", "7"), "settings.IMG.palette is an integer; expected text"),
    (_with("camera.record_index", '"3"'), "camera.record_index is text; expected an integer"),
    (_with("camera.record_index", "2.5"), "camera.record_index is a number; expected an integer"),
    (_with("camera.sd_present", "1"), "camera.sd_present is an integer; expected true or false"),
    (_with("camera.photo_index", "true"), "camera.photo_index is true; expected an integer"),
    (_with("gimbal.trims.x", "{}"), "gimbal.trims.x is an object; expected a number"),
    (_with("camera.bogus", "1"), "unknown key 'camera.bogus'; known here: bitrate_kbps"),
    (_with("settings.TSM", "{}"), "unknown key 'settings.TSM'"),
    (_with("settings.TIM.time", '"yesterday"'), "settings.TIM.time is 'yesterday'; expected a time as ISO 8601"),
    (
        _with("settings.TIM.time", '"2026-13-45T99:00:00"'),
        "settings.TIM.time is '2026-13-45T99:00:00'; expected a time",
    ),  # a setting the C12 does not have
    (_with("network.ip", json.dumps("x" * 5000)), "network.ip is text; expected text of at most 4096"),
    (_with("model", '"SIP"'), "belongs to a SIP simulator, this one is a C12"),
    ("[" * 100_000 + "]" * 100_000, "nests more than 64 levels deep (line 1)"),
    (_with("settings.IMG", "[" * 60 + "]" * 60), "settings.IMG is a list; expected an object"),
]


@pytest.mark.parametrize(("text", "message"), MALFORMED)
def test_every_malformed_state_file_is_one_clear_error(tmp_path: Path, text: str, message: str) -> None:
    bad = tmp_path / "cam.json"
    bad.write_text(text)
    with pytest.raises(StateFileError) as exc:
        Simulator("C12", state_file=bad)
    assert str(bad) in str(exc.value) and message in str(exc.value)
    assert "\n" not in str(exc.value)


def test_undecodable_and_oversized_files(tmp_path: Path) -> None:
    bad = tmp_path / "cam.json"
    bad.write_bytes(b'{"format": "\xff\xfe"}')
    with pytest.raises(StateFileError, match=r"is not UTF-8 text \(byte 12\)"):
        persist.load(bad)
    bad.write_bytes(b" " * (persist.MAX_BYTES + 1))
    with pytest.raises(StateFileError, match="a state file has at most 1048576"):
        persist.load(bad)


def test_cli_prints_one_line_for_a_bad_state_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from topgimbal.cli.main import main

    bad = tmp_path / "cam.json"
    bad.write_text(_with("camera.zoom_pos", "1e400"))
    assert main(["sim", "--udp", "127.0.0.1:0", "--state", str(bad)]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert f"state file {bad}: camera.zoom_pos is 1e400" in err


def _load_in_thread(path: Path) -> BaseException | None:
    """Load in a thread so that a hang is a failed assertion, not a stuck test run."""
    import threading

    box: list[BaseException | None] = []

    def run() -> None:
        try:
            persist.load(path)
            box.append(None)
        except BaseException as exc:  # handed to the test
            box.append(exc)

    t = threading.Thread(target=run, daemon=True)
    t.start()
    t.join(10)
    assert box, f"loading {path} hung"
    return box[0]


def test_non_regular_files_are_refused_without_hanging(tmp_path: Path) -> None:
    fifo = tmp_path / "fifo.json"
    os.mkfifo(fifo)
    for path, kind in ((fifo, "a FIFO"), (tmp_path, "a directory"), (Path("/dev/null"), "a character device")):
        exc = _load_in_thread(path)
        assert isinstance(exc, StateFileError) and f"state file {path} is {kind}, not a regular file" in str(exc)


def test_a_state_file_written_after_every_kind_of_change_loads_back(tmp_path: Path) -> None:
    """The check accepts everything the simulator itself writes (every model, changed settings)."""
    for model in sorted(all_models()):
        state = tmp_path / f"{model}.json"
        sim = Simulator(model, state_file=state)
        dev = sim.device
        for values in dev.settings.values():
            for name, value in values.items():
                if isinstance(value, (int, float)) and not isinstance(value, bool):
                    values[name] = value + 1
        dev.settings.get("TIM", {})["time"] = datetime(2026, 1, 2, 3, 4, 5)
        dev.settings.get("LAT", {})["lat_deg"] = -33.5
        dev.camera.sd_used_mb = 123.456
        dev.gimbal.trims["x"] = 1.5
        sim.flush(force=True)
        again = Simulator(model, state_file=state)
        assert again.device.snapshot() == json.loads(json.dumps(dev.snapshot()))  # JSON as it is


def test_stale_temporaries_of_our_pattern_are_removed_at_start(tmp_path: Path) -> None:
    state = tmp_path / "cam.json"
    persist.save(state, GOOD)
    ours = [tmp_path / ".cam.json.abcd_123.tmp", tmp_path / ".cam.json.zz99zz99.tmp"]
    others = [tmp_path / ".other.json.abcd1234.tmp", tmp_path / "cam.json.tmp", tmp_path / ".cam.json.x.tmp"]
    for p in ours + others:
        p.write_text("{")
    Simulator("C12", state_file=state)
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(["cam.json"] + [p.name for p in others])


# -- write-ahead: the reply to a change leaves only once the change is on disk ----------------------


class GatedWrites:
    """persist.write_atomic that waits for the test to open the gate, counting writes."""

    def __init__(self, monkeypatch: pytest.MonkeyPatch, fail: bool = False) -> None:
        import threading

        self.gate = threading.Event()
        self.writes = 0
        self.fail = fail
        real = persist.store.write_atomic

        def gated(path: str | Path, data: bytes) -> None:
            self.gate.wait(10)
            self.writes += 1
            if self.fail:
                raise OSError(28, "No space left on device")
            real(path, data)

        monkeypatch.setattr(persist.store, "write_atomic", gated)  # where GroupCommit finds it


async def test_a_reply_waits_for_its_write_and_writes_meanwhile_share_one(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    state = tmp_path / "cam.json"
    writes = GatedWrites(monkeypatch)
    async with Simulator("C12", state_file=state, listen={"udp": [(LOOP, 0)]}) as sim:
        c = UdpClient(sim.addresses["udp"][0])
        try:
            await c.request(req("C12", "IPV", address="127.0.0.1"), wait=0.3, count=1)  # held: gate shut
            assert not state.exists()
            for i in range(2, 7):  # five more changes while the first write is in flight
                await c.request(req("C12", "IPV", address=f"127.0.0.{i}"), wait=0.01)
            await c.request(req("C12", "REC", read=True), wait=0.01)  # must not overtake them
            assert await c.collect(wait=0.2) == []
            other = UdpClient(sim.addresses["udp"][0])  # another host is not held up by them
            try:
                [answer] = await other.request(req("C12", "REC", read=True), wait=5)
                assert answer.ident == "REC"
            finally:
                other.close()
            writes.gate.set()
            got = await c.collect(wait=5, count=7)
            assert [f.ident for f in got] == ["IPV"] * 6 + ["REC"]
            assert [f.data for f in got[:6]] == [f"127.0.0.{i}".encode() for i in range(1, 7)]
            assert writes.writes == 2  # one for the first change, one shared by the next five
            assert json.loads(state.read_text())["state"]["network"]["ip"] == "127.0.0.6"
        finally:
            c.close()


async def test_a_failed_write_withholds_the_reply(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    state = tmp_path / "cam.json"
    writes = GatedWrites(monkeypatch, fail=True)
    writes.gate.set()
    async with Simulator("C12", state_file=state, listen={"udp": [(LOOP, 0)]}) as sim:
        c = UdpClient(sim.addresses["udp"][0])
        try:
            assert await c.request(req("C12", "IPV", address="127.0.0.9"), wait=0.5) == []
            assert "write failed" in caplog.text and "No space left on device" in caplog.text
            writes.fail = False
            [echo] = await c.request(req("C12", "IMG", palette="rainbow"), wait=5)
            assert echo.ident == "IMG"
            saved = json.loads(state.read_text())["state"]
            assert saved["network"]["ip"] == "127.0.0.9" and saved["settings"]["IMG"]["palette"] == "rainbow"
        finally:
            c.close()
        monkeypatch.undo()


async def test_group_commit_bounds_what_it_holds(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    writes = GatedWrites(monkeypatch)
    state = {"n": 0}
    released: list[int] = []
    dropped: list[int] = []
    gc = persist.GroupCommit(tmp_path / "s.json", lambda: dict(state), released.extend, dropped.extend, max_held=3)
    for i in range(1, 11):
        state["n"] = i
        gc.submit([i], dirty=True)
    assert released == [] and dropped == [4, 5, 6, 7, 8, 9, 10] and gc.overflowed == 7
    writes.gate.set()
    await asyncio.wait_for(gc.drain(), 10)
    gc.close()
    assert released == [1, 2, 3] and writes.writes == 2
    assert json.loads((tmp_path / "s.json").read_text())["state"] == {"n": 10}  # every change is on disk
