"""`mavlink --record DIR`: the camera's video as MPEG-TS with a MISB ST 0601 KLV data stream.

The video packets are copied as they come (PyAV remux: no decoding, no re-encoding), from the
first keyframe on (FFmpeg's MPEG-TS muxer puts the stream's parameter sets in front of a keyframe
that lacks them, so a file opens decodable); next to
them, at most KLV_HZ times a second, one ST 0601 packet (klv.py) of what the bridge knows at that
moment, stamped with the video packet's presentation time. FFmpeg's MPEG-TS muxer carries a KLV
stream asynchronously (stream type 0x06, private PES, with the KLVA registration descriptor:
MISB ST 1402's "asynchronous carriage"), which is what ffprobe reports as codec `klv`, tag `KLVA`.

Runs in its own thread (PyAV's demuxer blocks). Bounded: a file stops at MAX_FILE_BYTES (logged);
the recording reconnects to the stream after RETRY_S when it ends or fails.

Never silent about the files: a file that cannot be written (a full disk, a read-only or vanished
folder) is a WARNING naming the file, the error and what is kept (what was written so far stays:
an MPEG-TS is playable up to its last packet); an attempt that wrote nothing leaves no empty file;
attempts after write failures back off to RETRY_MAX_S; a vanished folder is made again. Each file
name is taken with an exclusive create, so two recorders in one folder never share one."""

from __future__ import annotations

import contextlib
import logging
import os
import threading
import time
from collections.abc import Callable, Mapping
from fractions import Fraction
from pathlib import Path
from typing import Any

from ..clock import wall_time
from .klv import packet

log = logging.getLogger("topgimbal.mavlink")

KLV_HZ = 5.0
MAX_FILE_BYTES = 2 * 1024**3  # one file, then the recording stops (and says so)
RETRY_S = 2.0
RETRY_MAX_S = 60.0  # after write failures in a row, the next attempt waits up to this long
MAX_NAME_TRIES = 1000  # file names tried in one second (topgimbal-<time>-<n>.ts) before giving up
KLV_TIME_BASE = Fraction(1, 90000)

Sample = Callable[[], "Mapping[int, float | None] | None"]


class RecordWriteError(OSError):
    """The recording's file cannot be written (the stream itself may be fine)."""


class RecordDirError(ValueError):
    """The record directory is not a directory that can be made and written (the message starts with
    the field, `record DIR: ...`; the CLI writes it as `--record`)."""


def check_directory(directory: str | Path) -> Path:
    """DIR made (with its parents) and written to (a probe file made and removed), or
    RecordDirError saying why not."""
    d = Path(directory)
    if d.exists() and not d.is_dir():
        raise RecordDirError(f"record {d}: not a directory; give a directory (each recording is a file "
                             "topgimbal-<UTC time>-<n>.ts in it)")  # fmt: skip
    try:
        d.mkdir(parents=True, exist_ok=True)
        probe = d / f".topgimbal-probe-{os.getpid()}"
        probe.write_bytes(b"")
        probe.unlink()
    except OSError as exc:
        raise RecordDirError(
            f"record {d}: cannot write there ({exc.strerror or exc}); give a writable directory"
        ) from None
    return d


def reserve(directory: Path, stamp: str) -> Path:
    """A new file DIR/topgimbal-<stamp>-<n>.ts, created empty with O_EXCL (RecordWriteError if none)."""
    for n in range(MAX_NAME_TRIES):
        dst = directory / f"topgimbal-{stamp}-{n}.ts"
        try:
            os.close(os.open(dst, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644))
            return dst
        except FileExistsError:
            continue
        except OSError as exc:
            raise RecordWriteError(exc.errno, f"cannot make {dst}: {exc.strerror or exc}") from None
    raise RecordWriteError(f"{MAX_NAME_TRIES} recordings named topgimbal-{stamp}-*.ts already in {directory}")


class _Sink:
    """The file PyAV writes through: FFmpeg's own writer keeps a write error to itself (a full
    disk went unnoticed), so every write is ours and its first error is kept for the caller."""

    def __init__(self, dst: Path) -> None:
        self.dst = dst
        self.bytes = 0
        self.error: OSError | None = None
        try:
            self.file = open(dst, "wb", buffering=0)  # noqa: SIM115 - closed by close()
        except OSError as exc:
            raise RecordWriteError(f"cannot open {dst}: {exc.strerror or exc}") from None

    def write(self, data: bytes) -> int:
        try:
            n = self.file.write(data) or 0
        except OSError as exc:
            self.error = self.error or exc
            raise
        self.bytes += n
        return n

    def check(self) -> None:
        if self.error is not None:
            raise RecordWriteError(f"cannot write {self.dst}: {self.error.strerror or self.error}")

    def close(self) -> None:
        self.file.close()


def remux(
    src: str, dst: Path, sample: Sample, stop: threading.Event, *, max_bytes: int = MAX_FILE_BYTES,
    open_options: Mapping[str, str] | None = None,
) -> tuple[int, int]:  # fmt: skip
    """Copy `src`'s first video stream into the MPEG-TS `dst` with a KLV stream from `sample()`
    (None: nothing to say now) until the source ends, `stop` is set or `max_bytes` is reached.
    Returns (video packets, KLV packets) written; RecordWriteError when `dst` cannot be written
    (what was written stays)."""
    import av

    inp = av.open(src, options=dict(open_options or {}), timeout=5.0)
    try:
        sink = _Sink(dst)
        out: Any = av.open(sink, "w", format="mpegts")
        try:
            counts = _copy(inp, out, sink, sample, stop, max_bytes)
        except BaseException:
            with contextlib.suppress(Exception):  # already failing: what was written stays
                out.close()
            sink.close()
            raise
        try:
            out.close()  # the trailer and FFmpeg's buffer: a full disk shows here too
        except Exception as exc:
            sink.error = sink.error or (exc if isinstance(exc, OSError) else OSError(str(exc)))
        sink.close()
        sink.check()
        return counts
    finally:
        inp.close()


def _copy(inp: Any, out: Any, sink: _Sink, sample: Sample, stop: threading.Event, max_bytes: int) -> tuple[int, int]:
    import av

    vin = inp.streams.video[0]
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
        if videos == 0 and not pkt.is_keyframe:
            continue  # a file opens at a keyframe: what comes before it decodes to nothing (or to grey)
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
        sink.check()
        if sink.bytes >= max_bytes:
            log.warning("recording %s: %d bytes reached, stopped (MAX_FILE_BYTES)", sink.dst, max_bytes)
            stop.set()
            break
    return videos, klvs


class Recorder:
    """Records `url` into DIR/topgimbal-<UTC time>-<n>.ts in a thread until `close()`."""

    def __init__(self, url: str, directory: str | Path, sample: Sample) -> None:
        self.url = url
        self.dir = check_directory(directory)
        self.sample = sample
        self.stop = threading.Event()
        self.files: list[Path] = []
        self.write_failures = 0  # in a row
        self.thread = threading.Thread(target=self._run, name="topgimbal-record", daemon=True)

    def start(self) -> None:
        self.thread.start()

    def _run(self) -> None:
        while not self.stop.is_set():
            self.stop.wait(self._attempt())

    def _attempt(self) -> float:
        """One file: its recording until the stream ends, fails, or the file cannot be written.
        Returns how long to wait before the next."""
        dst: Path | None = None
        try:
            if not self.dir.is_dir():
                log.warning("recording: the folder %s is gone: making it again", self.dir)
                try:
                    self.dir.mkdir(parents=True, exist_ok=True)
                except OSError as exc:
                    raise RecordWriteError(f"cannot make the folder {self.dir}: {exc.strerror or exc}") from None
            dst = reserve(self.dir, time.strftime("%Y%m%dT%H%M%SZ", time.gmtime(wall_time())))
            self.files.append(dst)
            options = {"rtsp_transport": "tcp"} if self.url.startswith("rtsp") else None
            videos, klvs = remux(self.url, dst, self.sample, self.stop, open_options=options)
            log.info("recorded %s: %d video and %d KLV packets", dst, videos, klvs)
            self.write_failures = 0
            return RETRY_S
        except RecordWriteError as exc:
            self.write_failures += 1
            wait_s = min(RETRY_MAX_S, RETRY_S * 2 ** (self.write_failures - 1))
            kept = self._keep(dst)
            log.warning("recording %s: %s; %s; trying a new file in %g s (%d write failures in a row)",
                        self.url, exc, kept, wait_s, self.write_failures)  # fmt: skip
            return wait_s
        except Exception as exc:  # the stream is not up yet, or went away: try again
            self._keep(dst)
            log.info("recording %s: %s", self.url, exc)
            return RETRY_S

    def _keep(self, dst: Path | None) -> str:
        """What is left of `dst` after a failure: an empty file is removed (nothing to play)."""
        if dst is None:
            return "no file made"
        try:
            size = dst.stat().st_size
        except OSError:
            size = 0
        if size:
            return f"{dst} kept ({size} bytes, playable up to there)"
        with contextlib.suppress(OSError):
            dst.unlink()
        with contextlib.suppress(ValueError):
            self.files.remove(dst)
        return "nothing written (no empty file left)"

    def close(self) -> None:
        self.stop.set()
        self.thread.join(timeout=10.0)
