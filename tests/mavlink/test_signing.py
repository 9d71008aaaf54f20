"""MAVLink 2 signing (`topgimbal mavlink --signing-key FILE`, issue 27): with a key the bridge
signs what it sends and acts only on commands signed with the same key; unsigned, wrongly signed
and MAVLink 1 commands are refused with one log line per peer. Peers are pymavlink codecs."""

from __future__ import annotations

import asyncio
import hashlib
import logging
from pathlib import Path
from typing import Any

import pytest
from pymavlink.dialects.v20 import common as ml

from topgimbal.cli.main import main
from topgimbal.links.signing import SigningKeyError, key_from_bytes, load_key, sign_outgoing

from .conftest import Peer, eventually

pytestmark = pytest.mark.loopback

GIMBAL = 154
KEY = hashlib.sha256(b"topgimbal test passphrase").digest()


def signed_peer(key: bytes, sysid: int = 255, compid: int = 190) -> Peer:
    p = Peer(sysid, compid)
    sign_outgoing(p.mav, key)
    return p


@pytest.mark.external
def test_the_key_file_forms(tmp_path: Path) -> None:
    assert key_from_bytes(KEY.hex().encode() + b"\n") == KEY
    assert key_from_bytes(KEY.hex().upper().encode()) == KEY
    raw = bytes(range(32))
    assert key_from_bytes(raw) == raw
    # A passphrase: its SHA-256, as MAVProxy's `signing setup` and QGC make the key.
    assert key_from_bytes(b"topgimbal test passphrase\n") == KEY
    assert key_from_bytes(b"topgimbal test passphrase") == KEY
    for bad in (b"", b"\n\n", b"   ", b"\xff\xfe\x00"):
        with pytest.raises(SigningKeyError):
            key_from_bytes(bad)
    f = tmp_path / "key"
    f.write_text(KEY.hex())
    assert load_key(f) == KEY
    with pytest.raises(SigningKeyError, match="not a file"):
        load_key(tmp_path)
    with pytest.raises(SigningKeyError, match="not a file"):
        load_key(tmp_path / "missing")
    (tmp_path / "big").write_bytes(b"x" * 5000)
    with pytest.raises(SigningKeyError, match="longer than"):
        load_key(tmp_path / "big")


def test_a_bad_key_file_is_a_usage_error(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    empty = tmp_path / "empty.key"
    empty.write_text("")
    for path in (str(empty), str(tmp_path / "missing.key")):
        with pytest.raises(SystemExit) as exc:
            main(["mavlink", "--url", "udp://127.0.0.1:9", "--model", "C12", "--mavlink", "udpin:127.0.0.1:0",
                  "--signing-key", path])  # fmt: skip
        assert exc.value.code == 2
        err = capsys.readouterr().err
        assert "--signing-key" in err and "passphrase" in err


async def _answer(peer: Peer, value: float, timeout: float = 3.0) -> Any:
    """A gimbal command from `peer` and its final ack (None when none came)."""
    fut = asyncio.ensure_future(peer.wait("COMMAND_ACK", lambda m: m.target_system == peer.mav.srcSystem
                                          and m.command == ml.MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW
                                          and m.result != ml.MAV_RESULT_IN_PROGRESS, timeout))  # fmt: skip
    await asyncio.sleep(0)
    peer.command(GIMBAL, ml.MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW, value, 10, float("nan"), float("nan"))
    try:
        return await fut
    except asyncio.TimeoutError:
        return None


async def test_with_a_key_only_correctly_signed_commands_are_acted_on(
    rig_factory: Any, caplog: pytest.LogCaptureFixture
) -> None:
    caplog.set_level(logging.WARNING, "topgimbal.mavlink")
    rig = await rig_factory("C12", signing_key=KEY)
    port = rig.bridge.addresses[0][1]
    good = await signed_peer(KEY, sysid=201).connect(port)
    wrong = await signed_peer(hashlib.sha256(b"another passphrase").digest(), sysid=202).connect(port)
    unsigned = await Peer(sysid=203).connect(port)
    try:
        ack = await _answer(good, -20)
        assert ack is not None and ack.result == ml.MAV_RESULT_ACCEPTED
        # Before: the bridge acted on all three (and on frames with a bogus signature).
        for peer in (wrong, unsigned, unsigned, wrong):
            assert await _answer(peer, -30, timeout=1.5) is None
        assert rig.bridge.node.unsigned_in >= 4
        assert (await _answer(good, -25)).result == ml.MAV_RESULT_ACCEPTED
        lines = [r.getMessage() for r in caplog.records if "refusing" in r.getMessage()]
        # One line per peer (the rig's own unsigned peer sent a heartbeat too), saying why.
        assert sum("wrongly signed" in x and "system 202" in x for x in lines) == 1, lines
        assert sum("unsigned" in x and "system 203" in x for x in lines) == 1, lines
        # What the bridge sends is signed with the key: a parser holding it accepts it, one
        # holding another key refuses it.
        checker, other = ml.MAVLink(None), ml.MAVLink(None)
        checker.signing.secret_key = KEY
        other.signing.secret_key = hashlib.sha256(b"another passphrase").digest()
        other.robust_parsing = True
        heartbeat = await good.wait("HEARTBEAT")
        frame = bytes(heartbeat.get_msgbuf())
        assert frame[2] & 0x01, "the signed flag is set"
        assert [m.get_type() for m in checker.parse_buffer(frame) or []] == ["HEARTBEAT"]
        assert [m.get_type() for m in other.parse_buffer(frame) or []] == ["BAD_DATA"]
    finally:
        for p in (good, wrong, unsigned):
            p.close()


def keep_sent(peer: Peer) -> tuple[list[bytes], Any]:
    """From now on every datagram `peer` sends is also kept (to replay one); (the kept datagrams,
    the transport's own sendto, which sends without keeping)."""
    sent: list[bytes] = []
    original = peer.transport.sendto  # type: ignore[union-attr]

    def keep(data: bytes, *a: Any) -> None:
        sent.append(bytes(data))
        original(data, *a)

    peer.transport.sendto = keep  # type: ignore[union-attr,method-assign]
    return sent, original


async def test_a_replayed_signed_command_is_refused(rig_factory: Any) -> None:
    rig = await rig_factory("C12", signing_key=KEY)
    good = await signed_peer(KEY, sysid=201).connect(rig.bridge.addresses[0][1])
    try:
        sent, original = keep_sent(good)
        assert (await _answer(good, -15)).result == ml.MAV_RESULT_ACCEPTED
        before = rig.bridge.node.unsigned_in
        original(sent[-1])  # the same signed frame again: its timestamp is not newer
        await eventually(lambda: rig.bridge.node.unsigned_in > before, 5, "the replay refused")
        assert rig.bridge.node.unsigned_in == before + 1
    finally:
        good.close()
