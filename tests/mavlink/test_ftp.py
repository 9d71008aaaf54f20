"""The camera definitions over MAVLink FTP (`mftp://`, for links without IP): pymavlink's own
mavftp client reads them through the bridge; the server's protocol is bounded and NAKs hostile
requests instead of raising."""

from __future__ import annotations

import asyncio
import struct
import zlib
from pathlib import Path
from typing import Any

import pytest
from pymavlink import mavftp, mavutil

from topgimbal.mavlink.ftp import BURST_PACKETS, HEADER, MAX_SESSIONS, OP_ACK, OP_NAK, PAYLOAD, FtpFiles

from .conftest import Rig
from .test_mavproxy import start_mavproxy

pytestmark = [pytest.mark.external, pytest.mark.integration]


def req(
    op: int, data: bytes = b"", *, seq: int = 7, session: int = 0, offset: int = 0, size: int | None = None
) -> bytes:
    return HEADER.pack(seq, session, op, len(data) if size is None else size, 0, 0, 0, offset) + data


def parse(reply: bytes) -> tuple[Any, ...]:
    seq, session, op, size, req_op, bc, _, offset = HEADER.unpack_from(reply)
    return seq, session, op, req_op, bc, offset, reply[HEADER.size : HEADER.size + size]


def test_protocol_reads_lists_and_refuses() -> None:
    body = bytes(range(256)) * 3
    ftp = FtpFiles({"a.xml": body})
    seq, session, op, req_op, _, _, data = parse(ftp.answer(req(4, b"/a.xml", session=3))[0])
    assert session == 3
    assert (seq, op, req_op) == (8, OP_ACK, 4) and struct.unpack("<I", data)[0] == len(body)
    burst = [parse(r) for r in ftp.answer(req(15, session=session, size=239))]
    assert b"".join(p[6] for p in burst) == body and [p[4] for p in burst] == [0, 0, 0, 1]  # burst_complete on the last
    assert [p[0] for p in burst] == [8, 9, 10, 11]
    assert parse(ftp.answer(req(5, session=session, offset=10, size=5))[0])[6] == body[10:15]
    assert parse(ftp.answer(req(5, session=session, offset=len(body), size=5))[0])[6] == bytes([6])  # EOF
    assert parse(ftp.answer(req(14, b"a.xml"))[0])[6] == struct.pack("<I", zlib.crc32(body))
    assert parse(ftp.answer(req(3, b"/"))[0])[6] == f"Fa.xml\t{len(body)}".encode() + b"\0"
    assert parse(ftp.answer(req(3, b"/", offset=1))[0])[6] == bytes([6])
    assert parse(ftp.answer(req(1, session=session))[0])[2] == OP_ACK
    assert parse(ftp.answer(req(5, session=session, size=5))[0])[6] == bytes([4])  # closed: InvalidSession
    # writes, unknown opcodes, missing files, a non-text path, a short payload
    for op, data, err in (
        (7, b"x", 9),
        (6, b"/b.xml", 9),
        (99, b"", 7),
        (4, b"/../etc/passwd", 10),
        (4, b"\xff\xfe", 10),
    ):
        reply = parse(ftp.answer(req(op, data))[0])
        assert reply[2] == OP_NAK and reply[6] == bytes([err])
    assert ftp.answer(b"\x01\x02") == []
    assert all(len(r) == PAYLOAD for r in ftp.answer(req(4, b"a.xml", size=255)))  # a size beyond the payload


def test_sessions_and_bursts_are_bounded() -> None:
    ftp = FtpFiles({"big": b"x" * 239 * (BURST_PACKETS + 5)})
    sessions = [parse(ftp.answer(req(4, b"big", session=n))[0])[1] for n in range(MAX_SESSIONS + 3)]
    assert sessions == list(range(MAX_SESSIONS + 3))  # the client's numbers, echoed
    assert len(ftp.sessions) == MAX_SESSIONS and [k[1] for k in ftp.sessions] == sessions[-MAX_SESSIONS:]
    burst = ftp.answer(req(15, session=sessions[-1], size=239))
    assert len(burst) == BURST_PACKETS and parse(burst[-1])[4] == 1


def _mavftp_get(port: int, path: str) -> tuple[bytes | None, int]:
    m = mavutil.mavlink_connection(f"udpout:127.0.0.1:{port}", source_system=255, source_component=190)
    try:
        m.mav.heartbeat_send(6, 8, 0, 0, 0)
        m.wait_heartbeat(timeout=10)
        ftp = mavftp.MAVFTP(m, 1, 101)
        got: dict[str, bytes] = {}
        ftp.cmd_get([path], callback=lambda fh: got.setdefault("data", fh.read()))
        result = ftp.process_ftp_reply("OpenFileRO", timeout=20)
        return got.get("data"), result.error_code
    finally:
        m.close()


async def test_pymavlink_mavftp_reads_the_definition_named_in_camera_information(rig_factory: Any) -> None:
    rig: Rig = await rig_factory("SIP", definition_http=None)
    info = await rig.peer.request(101, 259, "CAMERA_INFORMATION")
    assert info.cam_definition_uri == "mftp://[;comp=101]/sip-thermal.xml"
    data, err = await asyncio.to_thread(_mavftp_get, rig.bridge.addresses[0][1], "/sip-thermal.xml")  # type: ignore[index]
    assert err == 0 and data == rig.bridge.definition_files["sip-thermal.xml"].encode()


async def test_mavproxy_loads_the_definition_over_mavftp(rig_factory: Any, tmp_path: Path) -> None:
    rig: Rig = await rig_factory("C12", definition_http=None, silence_s=3.0, timeout_s=1.0)
    mp = await start_mavproxy(rig.bridge.addresses[0][1], tmp_path, modules="camera,ftp")  # type: ignore[index]
    try:
        await mp.wait(r"C12 thermal \(1:101\): loaded 2 settings", timeout=60)
        await mp.wait(r"C12 \(1:100\): loaded \d+ settings", timeout=30)
    finally:
        await mp.close()
