"""RTP packetisation of H.264 (RFC 6184) and H.265 (RFC 7798), and the SDP that describes them.
Pure: bytes in, packets out."""

from __future__ import annotations

import base64
import re
import struct
from collections.abc import Iterator

PAYLOAD_TYPE = 96
CLOCK_HZ = 90000
MAX_PAYLOAD = 1400  # fits a 1500-byte Ethernet MTU with IP, UDP and RTP headers

_START = re.compile(b"\x00\x00\x01")


def split_nals(annexb: bytes) -> list[bytes]:
    """The NAL units of an Annex B byte string (3- or 4-byte start codes)."""
    out = []
    starts = [m.end() for m in _START.finditer(annexb)]
    for i, s in enumerate(starts):
        end = starts[i + 1] - 3 if i + 1 < len(starts) else len(annexb)
        nal = annexb[s:end]
        if i + 1 < len(starts) and nal.endswith(b"\x00"):
            nal = nal.rstrip(b"\x00")  # the zero byte of a 4-byte start code (trailing_zero_8bits)
        if nal:
            out.append(nal)
    return out


def nal_type(codec: str, nal: bytes) -> int:
    return (nal[0] >> 1) & 0x3F if codec == "h265" else nal[0] & 0x1F


def parameter_sets(codec: str, nals: list[bytes]) -> dict[str, bytes]:
    """The parameter sets among some NAL units: sps/pps (H.264), vps/sps/pps (H.265)."""
    names = {32: "vps", 33: "sps", 34: "pps"} if codec == "h265" else {7: "sps", 8: "pps"}
    return {names[nal_type(codec, n)]: n for n in nals if nal_type(codec, n) in names}


def payloads(codec: str, nal: bytes, max_payload: int = MAX_PAYLOAD) -> Iterator[bytes]:
    """RTP payloads for one NAL unit: the NAL itself, or fragmentation units when it is too big."""
    if len(nal) <= max_payload:
        yield nal
        return
    if codec == "h265":
        t = (nal[0] >> 1) & 0x3F
        header = bytes([(nal[0] & 0x81) | (49 << 1), nal[1]])
        body, first = nal[2:], True
        step = max_payload - 3
        for i in range(0, len(body), step):
            last = i + step >= len(body)
            fu = (0x80 if first else 0) | (0x40 if last else 0) | t
            yield header + bytes([fu]) + body[i : i + step]
            first = False
        return
    indicator = (nal[0] & 0xE0) | 28  # FU-A
    t = nal[0] & 0x1F
    body, first = nal[1:], True
    step = max_payload - 2
    for i in range(0, len(body), step):
        last = i + step >= len(body)
        fu = (0x80 if first else 0) | (0x40 if last else 0) | t
        yield bytes([indicator, fu]) + body[i : i + step]
        first = False


class Packetizer:
    """RTP packets for one receiver: its own sequence numbers, one SSRC."""

    def __init__(self, codec: str, ssrc: int, seq: int = 0) -> None:
        self.codec = codec
        self.ssrc = ssrc & 0xFFFFFFFF
        self.seq = seq & 0xFFFF

    def packets(self, annexb: bytes, rtp_time: int) -> list[bytes]:
        """Every packet of one access unit; the marker bit is set on its last one."""
        chunks = [p for nal in split_nals(annexb) for p in payloads(self.codec, nal)]
        out = []
        for i, chunk in enumerate(chunks):
            marker = 0x80 if i == len(chunks) - 1 else 0
            header = struct.pack("!BBHII", 0x80, marker | PAYLOAD_TYPE, self.seq, rtp_time & 0xFFFFFFFF, self.ssrc)
            out.append(header + chunk)
            self.seq = (self.seq + 1) & 0xFFFF
        return out


def sdp(codec: str, params: dict[str, bytes], *, host: str = "127.0.0.1", session_id: int = 1, name: str = "") -> str:
    """A session description for one video track whose control URL is `trackID=0`."""
    b64 = {k: base64.b64encode(v).decode() for k, v in params.items()}
    if codec == "h265":
        fmtp = f"sprop-vps={b64.get('vps', '')};sprop-sps={b64.get('sps', '')};sprop-pps={b64.get('pps', '')}"
        rtpmap = "H265/90000"
    else:
        sps = params.get("sps", b"\x67\x42\xc0\x1f")
        profile = sps[1:4].hex().upper() if len(sps) >= 4 else "42C01F"
        fmtp = f"packetization-mode=1;profile-level-id={profile};sprop-parameter-sets={b64.get('sps', '')},{b64.get('pps', '')}"
        rtpmap = "H264/90000"
    ip = "IP6" if ":" in host else "IP4"
    lines = [
        "v=0",
        f"o=- {session_id} 1 IN {ip} {host}",
        f"s={name or 'topgimbal simulated camera'}",
        f"c=IN {ip} {'::' if ip == 'IP6' else '0.0.0.0'}",
        "t=0 0",
        "a=control:*",
        "a=range:npt=0-",
        f"m=video 0 RTP/AVP {PAYLOAD_TYPE}",
        f"a=rtpmap:{PAYLOAD_TYPE} {rtpmap}",
        f"a=fmtp:{PAYLOAD_TYPE} {fmtp}",
        "a=control:trackID=0",
    ]
    return "\r\n".join(lines) + "\r\n"
