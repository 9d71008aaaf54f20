"""RTP push: a camera's RTSP stream re-sent as plain RTP over UDP (what QGroundControl and the
ArduPilot companion images play on port 5600), without decoding or encoding anything.

A reader thread demuxes the RTSP stream with PyAV (access units in Annex B form, no decoder) and
re-packetizes each one with `rtp.Packetizer` (RFC 6184 / RFC 7798) to one UDP target. A UDP
receiver has no SDP (QGC's pipeline is `udpsrc ! application/x-rtp,encoding-name=H264 ! ...`), so
the parameter sets (SPS/PPS, and VPS for H.265) are put in front of every keyframe that does not
carry them already: a receiver that joins late decodes from the next keyframe. The parameter sets
come from the stream itself (in-band, the newest win) and from its SDP (the container's extradata).

Bounds: nothing is queued (each access unit is sent as it is read; a UDP send that fails is
counted and logged once a minute); the source is reopened every RETRY_S while it fails.
"""

from __future__ import annotations

import logging
import random
import socket
import threading
from dataclasses import dataclass
from typing import TYPE_CHECKING
from urllib.parse import urlsplit

from ..clock import MonotonicFn, monotonic
from ..logthrottle import ThrottledLog
from .lens import VideoError
from .rtp import CLOCK_HZ, PAYLOAD_TYPE, Packetizer, nal_type, parameter_sets, split_nals

if TYPE_CHECKING:
    from av.container import InputContainer

log = logging.getLogger("topgimbal.video.rtp_push")

RETRY_S = 1.0
READ_TIMEOUT_S = 3.0
# The parameter sets a decoder needs before a keyframe, per codec, in the order they are sent.
NEEDED = {"h264": ("sps", "pps"), "h265": ("vps", "sps", "pps")}
# NAL unit types that start a decodable picture: H.264 IDR; H.265 IRAP (BLA, IDR, CRA).
KEY_NALS = {"h264": frozenset({5}), "h265": frozenset(range(16, 22))}
CODEC_NAMES = {"h264": "h264", "hevc": "h265", "h265": "h265"}
# Demuxer options for the lowest delay: no input buffer, little probing (the SDP has what is needed).
OPEN_OPTIONS = {
    "fflags": "nobuffer",
    "flags": "low_delay",
    "max_delay": "0",
    "analyzeduration": "0",
    "probesize": "32",
    "reorder_queue_size": "0",
}


def parse_udp_target(text: str) -> tuple[str, int]:
    """`udp://HOST:PORT` (IPv6 in brackets) as (host, port); a VideoError says what is expected."""
    try:
        parts = urlsplit(text)
        port = parts.port
    except ValueError:
        port = None
        parts = None
    if parts is None or parts.scheme != "udp" or not parts.hostname or port is None or not 1 <= port <= 65535:
        raise VideoError(f"{text!r} is not udp://HOST:PORT (port 1..65535; QGroundControl listens on 5600)")
    if parts.path not in ("", "/") or parts.query:
        raise VideoError(f"{text!r}: udp://HOST:PORT takes no path or query")
    return parts.hostname, port


def advertised_uri(port: int) -> str:
    """What VIDEO_STREAM_INFORMATION says of an RTP/UDP stream: the port a ground station listens
    on (QGC's form: udp://0.0.0.0:PORT; the bridge pushes to the station, which binds the port)."""
    return f"udp://0.0.0.0:{port}"


def is_keyframe(codec: str, nals: list[bytes]) -> bool:
    keys = KEY_NALS[codec]
    return any(nal_type(codec, n) in keys for n in nals)


class ParamSetInserter:
    """Puts the newest parameter sets in front of every keyframe that lacks them (pure)."""

    def __init__(self, codec: str, extradata: bytes | None = None) -> None:
        self.codec = codec
        self.params: dict[str, bytes] = {}
        self.inserted = 0  # keyframes that needed them
        if extradata and (extradata.startswith(b"\x00\x00\x01") or extradata.startswith(b"\x00\x00\x00\x01")):
            self.params.update(parameter_sets(codec, split_nals(extradata)))

    def nals(self, annexb: bytes) -> list[bytes]:
        """The NAL units to send for one access unit."""
        nals = split_nals(annexb)
        found = parameter_sets(self.codec, nals)
        self.params.update(found)
        if not is_keyframe(self.codec, nals):
            return nals
        missing = [k for k in NEEDED[self.codec] if k not in found]
        if not missing:
            return nals
        self.inserted += 1
        return [self.params[k] for k in NEEDED[self.codec] if k in self.params and k not in found] + nals


@dataclass
class PushStats:
    pictures: int = 0
    keyframes: int = 0
    packets: int = 0
    bytes: int = 0
    send_errors: int = 0
    opens: int = 0


class RtpPush:
    """One RTSP source pushed to one UDP target. `start()` runs the reader thread; `stop()` ends it."""

    def __init__(
        self,
        source_url: str,
        target: str,
        *,
        name: str = "video",
        transport: str = "tcp",
        clock: MonotonicFn = monotonic,
    ) -> None:
        self.source_url = source_url
        self.target = parse_udp_target(target)
        self.target_url = target
        self.name = name
        self.transport = transport
        self.clock = clock
        self.state = "idle"
        self.error: str | None = None
        self.codec: str | None = None
        self.params: dict[str, bytes] = {}  # the newest parameter sets (for an SDP file)
        self.stats = PushStats()
        self.ssrc = random.getrandbits(32)
        self._rtp_offset = random.getrandbits(32)
        self._seq = random.getrandbits(16)
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._sock: socket.socket | None = None
        self._send_log = ThrottledLog(log, 60.0, lambda: self.clock())

    def start(self) -> RtpPush:
        family = socket.AF_INET6 if ":" in self.target[0] else socket.AF_INET
        try:
            info = socket.getaddrinfo(self.target[0], self.target[1], family, socket.SOCK_DGRAM)
        except OSError as exc:
            raise VideoError(f"{self.target_url}: {exc.strerror or exc}") from None
        self._addr = info[0][4]
        self._sock = socket.socket(info[0][0], socket.SOCK_DGRAM)
        self._stop.clear()
        self._thread = threading.Thread(target=self._run, name=f"topgimbal-rtp-push-{self.name}", daemon=True)
        self._thread.start()
        log.info("video %s: pushing %s as RTP to %s", self.name, self.source_url, self.target_url)
        return self

    def stop(self, timeout_s: float = 5.0) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout_s)
        if self._sock is not None:
            self._sock.close()
        self.state = "idle"

    # -- the reader (thread) -----------------------------------------------------------------------

    def _run(self) -> None:
        import av

        while not self._stop.is_set():
            self.state = "connecting" if self.stats.pictures == 0 else "reconnecting"
            try:
                container = av.open(
                    self.source_url,
                    options={**OPEN_OPTIONS, "rtsp_transport": self.transport},
                    timeout=READ_TIMEOUT_S,
                )
            except Exception as exc:  # any failure to open is a state to report, not a crash
                self._failed(str(exc))
                continue
            self.stats.opens += 1
            try:
                self._pump(container)
                self._failed("the stream ended")
            except Exception as exc:
                self._failed(str(exc))
            finally:
                container.close()

    def _failed(self, why: str) -> None:
        if self._stop.is_set():
            return
        if self.error != why:
            log.warning("video %s: %s: %s; retrying every %.0f s", self.name, self.source_url, why, RETRY_S)
        self.error = why
        self.state = "reconnecting"
        self._stop.wait(RETRY_S)

    def _pump(self, container: InputContainer) -> None:
        stream = container.streams.video[0] if container.streams.video else None
        if stream is None:
            raise VideoError("the source has no video stream")
        codec = CODEC_NAMES.get(stream.codec_context.name)
        if codec is None:
            raise VideoError(f"the source's codec is {stream.codec_context.name}: RTP push takes H.264 or H.265")
        self.codec = codec
        inserter = ParamSetInserter(codec, stream.codec_context.extradata)
        self.params = inserter.params
        packetizer = Packetizer(codec, self.ssrc, self._seq)
        tb = stream.time_base
        for packet in container.demux(stream):
            if self._stop.is_set():
                return
            data = bytes(packet)
            if not data:
                continue
            if packet.pts is not None and tb is not None:
                rtp_time = int(packet.pts * tb * CLOCK_HZ)
            else:
                rtp_time = int(self.clock() * CLOCK_HZ)
            nals = inserter.nals(data)
            au = b"".join(b"\x00\x00\x00\x01" + n for n in nals)
            self.state, self.error = "playing", None
            self.stats.pictures += 1
            if is_keyframe(codec, nals):
                self.stats.keyframes += 1
            self._send(packetizer.packets(au, (rtp_time + self._rtp_offset) & 0xFFFFFFFF))
        self._seq = packetizer.seq  # a reopened source continues the sequence numbers

    def _send(self, packets: list[bytes]) -> None:
        sock = self._sock
        if sock is None:
            return
        for p in packets:
            try:
                sock.sendto(p, self._addr)
            except OSError as exc:  # nobody listening (ICMP refused), a full buffer: UDP drops it
                self.stats.send_errors += 1
                if self._send_log.allow("send") is not None:
                    log.warning("video %s: sending RTP to %s: %s (%d failed sends in all)",
                                self.name, self.target_url, exc.strerror or exc, self.stats.send_errors)  # fmt: skip
                continue
            self.stats.packets += 1
            self.stats.bytes += len(p)


def sdp_for(codec: str, port: int, params: dict[str, bytes] | None = None, *, host: str = "127.0.0.1") -> str:
    """An SDP file for players that want one (ffmpeg/ffplay `-protocol_whitelist file,udp,rtp -i
    x.sdp`, VLC): the stream on `port`, payload type 96."""
    from .rtp import sdp

    text = sdp(codec, params or {}, host=host, name="topgimbal RTP push")
    ip = "IP6" if ":" in host else "IP4"
    text = text.replace(f"m=video 0 RTP/AVP {PAYLOAD_TYPE}", f"m=video {port} RTP/AVP {PAYLOAD_TYPE}")
    return text.replace(f"c=IN {ip} {'::' if ip == 'IP6' else '0.0.0.0'}", f"c=IN {ip} {host}")
