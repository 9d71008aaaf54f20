"""A minimal read-only MAVLink FTP server (FILE_TRANSFER_PROTOCOL) for the camera definitions:
what a ground station on a link without IP needs to fetch an `mftp://` cam_definition_uri.

OpenFileRO, ReadFile, BurstReadFile, TerminateSession, ResetSessions, ListDirectory and
CalcFileCRC32 over the files it was given (names at the root, `/sip-thermal.xml`); every other
opcode is NAKed (UnknownCommand, or FileProtected for writes). Sessions belong to their peer (the
link and address a request came from, and its system and component): one peer can neither read,
close nor reset another's, and replies go to the requester only (not to every peer: no
amplification). Bounded: at most MAX_SESSIONS open files per peer (the peer's oldest is closed for
a new one; a session number is the client's, echoed) and MAX_ALL_SESSIONS in all (the oldest of
all closed), a burst of at most BURST_PACKETS packets. A
payload too short or a path that is not text is NAKed, never raised. `answer()` is pure
(bytes in, bytes out) and tested with pymavlink's codec; `FtpServer` puts it on a component."""

from __future__ import annotations

import struct
import zlib
from collections import OrderedDict
from collections.abc import Hashable
from typing import TYPE_CHECKING

from ..links.base import link_peer
from ..links.mav import mavlink

if TYPE_CHECKING:
    from ..links.mav import MAVLinkMessage
    from .node import Component

HEADER = struct.Struct("<HBBBBBBI")  # seq, session, opcode, size, req_opcode, burst_complete, padding, offset
MAX_DATA = 239
PAYLOAD = 251
MAX_SESSIONS = 4  # per peer
MAX_ALL_SESSIONS = 64  # all peers together
BURST_PACKETS = 32
(OP_TERMINATE, OP_RESET, OP_LIST, OP_OPEN_RO, OP_READ, OP_CRC32, OP_BURST) = (1, 2, 3, 4, 5, 14, 15)  # fmt: skip
WRITE_OPS = frozenset({6, 7, 8, 9, 10, 11, 12, 13})
OP_ACK, OP_NAK = 128, 129
ERR_FAIL, ERR_SIZE, ERR_SESSION, ERR_NO_SESSIONS, ERR_EOF, ERR_UNKNOWN, ERR_PROTECTED, ERR_NOT_FOUND = (
    1, 3, 4, 5, 6, 7, 9, 10)  # fmt: skip


def _pack(seq: int, session: int, opcode: int, req: int, offset: int, data: bytes, burst_complete: int = 0) -> bytes:
    head = HEADER.pack(seq & 0xFFFF, session, opcode, len(data), req, burst_complete, 0, offset)
    return (head + data).ljust(PAYLOAD, b"\0")


class FtpFiles:
    """The files and open sessions of one server: the pure protocol."""

    def __init__(self, files: dict[str, bytes]) -> None:
        self.files = dict(files)
        self.sessions: OrderedDict[tuple[Hashable, int], str] = OrderedDict()  # (owner, session) -> file

    def _path(self, data: bytes) -> str | None:
        try:
            text = data.split(b"\0", 1)[0].decode("utf-8")
        except UnicodeDecodeError:
            return None
        return text.strip().lstrip("/").removeprefix("@MAV_ROOT/")

    def answer(self, request: bytes, owner: Hashable = None) -> list[bytes]:
        """The reply payloads (each PAYLOAD bytes) to one request payload from `owner` (the peer:
        its sessions are its own); [] when it is too short to have a sequence number to answer."""
        if len(request) < HEADER.size:
            return []
        seq, session, op, size, _req, _bc, _pad, offset = HEADER.unpack_from(request)
        data = bytes(request[HEADER.size : HEADER.size + min(size, MAX_DATA)])
        reply = seq + 1

        def nak(err: int) -> list[bytes]:
            return [_pack(reply, session, OP_NAK, op, offset, bytes([err]))]

        def ack(payload: bytes = b"") -> list[bytes]:
            return [_pack(reply, session, OP_ACK, op, offset, payload)]

        if op == OP_RESET:
            for k in [k for k in self.sessions if k[0] == owner]:
                del self.sessions[k]
            return ack()
        if op == OP_TERMINATE:
            self.sessions.pop((owner, session), None)
            return ack()
        if op in WRITE_OPS:
            return nak(ERR_PROTECTED)
        if op == OP_LIST:
            path = self._path(data)
            if path is None or path not in ("", "."):
                return nak(ERR_NOT_FOUND)
            entries = [f"F{name}\t{len(body)}".encode() + b"\0" for name, body in sorted(self.files.items())]
            listing = b""
            for e in entries[offset:]:
                if len(listing) + len(e) > MAX_DATA:
                    break
                listing += e
            return ack(listing) if listing else nak(ERR_EOF)
        if op in (OP_OPEN_RO, OP_CRC32):
            path = self._path(data)
            body = self.files.get(path) if path is not None else None
            if body is None:
                return nak(ERR_NOT_FOUND)
            if op == OP_CRC32:
                return ack(struct.pack("<I", zlib.crc32(body)))
            # The session is the client's number, echoed (ArduPilot's server does so; MAVProxy routes
            # replies by it; QGC and pymavlink adopt whatever the reply says).
            self.sessions.pop((owner, session), None)
            mine = [k for k in self.sessions if k[0] == owner]
            for k in mine[: max(0, len(mine) - MAX_SESSIONS + 1)]:
                del self.sessions[k]  # this peer's oldest
            while len(self.sessions) >= MAX_ALL_SESSIONS:
                self.sessions.popitem(last=False)
            self.sessions[(owner, session)] = path  # type: ignore[assignment]
            return ack(struct.pack("<I", len(body)))
        if op in (OP_READ, OP_BURST):
            name = self.sessions.get((owner, session))
            if name is None:
                return nak(ERR_SESSION)
            body = self.files[name]
            if offset >= len(body):
                return nak(ERR_EOF)
            chunk = max(1, min(size or MAX_DATA, MAX_DATA))
            if op == OP_READ:
                return ack(body[offset : offset + chunk])
            burst: list[bytes] = []
            at = offset
            while at < len(body) and len(burst) < BURST_PACKETS:
                part = body[at : at + chunk]
                last = at + len(part) >= len(body) or len(burst) == BURST_PACKETS - 1
                burst.append(_pack(reply + len(burst), session, OP_ACK, op, at, part, 1 if last else 0))
                at += len(part)
            return burst
        return nak(ERR_UNKNOWN)


class FtpServer:
    """FtpFiles on a component: answers FILE_TRANSFER_PROTOCOL addressed to it."""

    MESSAGES: tuple[str, ...] = ("FILE_TRANSFER_PROTOCOL",)  # what on_message reads (node.on)

    def __init__(self, comp: Component, files: dict[str, str]) -> None:
        self.comp = comp
        self.proto = FtpFiles({k: v.encode("utf-8") for k, v in files.items()})

    def on_message(self, m: MAVLinkMessage) -> None:
        if m.get_type() != "FILE_TRANSFER_PROTOCOL":
            return
        if m.target_system != self.comp.sysid or m.target_component != self.comp.compid:
            return
        origin = link_peer(m)
        owner = (origin, m.get_srcSystem(), m.get_srcComponent())
        for payload in self.proto.answer(bytes(m.payload), owner):
            reply = mavlink().MAVLink_file_transfer_protocol_message(
                0, m.get_srcSystem(), m.get_srcComponent(), list(payload))  # fmt: skip
            if origin is None:  # not through a node (a dispatcher fed directly): as before
                self.comp.send(reply)
            else:
                self.comp.send_to(reply, origin)
