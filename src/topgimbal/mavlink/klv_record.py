"""`mavlink --record DIR`: the camera's video as MPEG-TS with a MISB ST 0601 KLV data stream.

The video packets are copied as they come (PyAV remux: no decoding, no re-encoding); next to
them, at most KLV_HZ times a second, one ST 0601 packet (klv.py) of what the bridge knows at that
moment, stamped with the video packet's presentation time. FFmpeg's MPEG-TS muxer carries a KLV
stream asynchronously (stream type 0x06, private PES, with the KLVA registration descriptor:
MISB ST 1402's "asynchronous carriage"), which is what ffprobe reports as codec `klv`, tag `KLVA`.

Runs in its own thread (PyAV's demuxer blocks). Bounded: a file stops at MAX_FILE_BYTES (logged);
the recording reconnects to the stream after RETRY_S when it ends or fails."""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable, Mapping
from fractions import Fraction
from pathlib import Path

from ..clock import wall_time
from .klv import packet

log = logging.getLogger("topgimbal.mavlink")

KLV_HZ = 5.0
MAX_FILE_BYTES = 2 * 1024**3  # one file, then the recording stops (and says so)
RETRY_S = 2.0
KLV_TIME_BASE = Fraction(1, 90000)

Sample = Callable[[], "Mapping[int, float | None] | None"]


def remux(
    src: str, dst: Path, sample: Sample, stop: threading.Event, *, max_bytes: int = MAX_FILE_BYTES,
    open_options: Mapping[str, str] | None = None,
) -> tuple[int, int]:  # fmt: skip
    """Copy `src`'s first video stream into the MPEG-TS `dst` with a KLV stream from `sample()`
    (None: nothing to say now) until the source ends, `stop` is set or `max_bytes` is reached.
    Returns (video packets, KLV packets) written."""
    import av

    inp = av.open(src, options=dict(open_options or {}), timeout=5.0)
    try:
        vin = inp.streams.video[0]
        out = av.open(str(dst), "w", format="mpegts")
        try:
            vout = out.add_stream_from_template(vin)
            kout = out.add_data_stream("klv")
            videos = klvs = 0
            last_klv = -1
            period = int(90000 / KLV_HZ)
            for pkt in inp.demux(vin):
                if stop.is_set():
                    break
                if pkt.dts is None or pkt.pts is None:
                    continue  # the demuxer's flush packet
                tb = pkt.time_base
                pts = pkt.pts
                pkt.stream = vout
                out.mux(pkt)
                videos += 1
                t = int(pts * tb / KLV_TIME_BASE)
                if t >= last_klv + period:  # also keeps KLV time strictly increasing (B-frames)
                    values = sample()
                    if values is not None:
                        k = av.Packet(packet(int(wall_time() * 1e6), values))
                        k.stream = kout
                        k.time_base = KLV_TIME_BASE
                        k.pts = k.dts = t
                        out.mux(k)
                        klvs += 1
                        last_klv = t
                if dst.stat().st_size >= max_bytes:
                    log.warning("recording %s: %d bytes reached, stopped (MAX_FILE_BYTES)", dst, max_bytes)
                    stop.set()
                    break
            return videos, klvs
        finally:
            out.close()
    finally:
        inp.close()


class Recorder:
    """Records `url` into DIR/topgimbal-<UTC time>.ts in a thread until `close()`."""

    def __init__(self, url: str, directory: str | Path, sample: Sample) -> None:
        self.url = url
        self.dir = Path(directory)
        self.dir.mkdir(parents=True, exist_ok=True)
        self.sample = sample
        self.stop = threading.Event()
        self.files: list[Path] = []
        self.thread = threading.Thread(target=self._run, name="topgimbal-record", daemon=True)

    def start(self) -> None:
        self.thread.start()

    def _run(self) -> None:
        while not self.stop.is_set():
            stamp = time.strftime("%Y%m%dT%H%M%SZ", time.gmtime(wall_time()))
            dst = self.dir / f"topgimbal-{stamp}-{len(self.files)}.ts"
            try:
                self.files.append(dst)
                videos, klvs = remux(
                    self.url,
                    dst,
                    self.sample,
                    self.stop,
                    open_options={"rtsp_transport": "tcp"} if self.url.startswith("rtsp") else None,
                )
                log.info("recorded %s: %d video and %d KLV packets", dst, videos, klvs)
            except Exception as exc:  # the stream is not up yet, or went away: try again
                log.info("recording %s: %s", self.url, exc)
            self.stop.wait(RETRY_S)

    def close(self) -> None:
        self.stop.set()
        self.thread.join(timeout=10.0)
