"""`topgimbal sim --media DIR`: the simulated camera's card. Each photo (CAP) becomes one JPEG per
lens, rendered from the scene at the moment of capture, with EXIF / XMP of what the camera was fed
(exif.py); each recording (REC start .. stop) an MP4 of the scene.

Names: TOPOTEK as its CAP / REC feedback names them (§五.1, §五.2): `snap_<lens>_<index>.jpeg`, lens
0 the visible and 1 the thermal (the RTSP stream numbers), recordings `stream_0_<index>.mp4` (the
camera writes .h264; we write MP4 so any player opens it). SkyDroid documents no names (a
decision): `IMG_<index>.jpg` (visible), `IMG_<index>_T.jpg` (thermal), `VID_<index>.mp4`, index
4 digits. The index is the camera's photo / recording counter, as in the feedback's file index.

The picture's time is the camera's clock (what TIM / UTC set, moved on); a camera whose clock was
never set dates its files from 1970-01-01 plus its uptime, as a real one does. Bounded: the files
in DIR stay under `max_bytes` (oldest dropped first, one log line each time), a recording stops
adding frames after `MAX_RECORD_S`, and at most `MAX_PENDING` photos wait to be written (more are
dropped with a log line)."""

from __future__ import annotations

import asyncio
import datetime
import io
import logging
import os
import threading
from collections.abc import Iterable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING

from ..clock import monotonic
from ..sim.state import NO_CLOCK_EPOCH
from .exif import PhotoMeta, Pose, focal_lengths, tag_jpeg
from .lens import MEDIA_NAME, StreamSpec, photo_names, recording_name, streams_for
from .render import Renderer
from .snapshot import SceneState, capture

if TYPE_CHECKING:
    from ..sim.simulator import Simulator

log = logging.getLogger("topgimbal.sim")

DEFAULT_MAX_BYTES = 256 * 1024 * 1024
PHOTO_SIZE_PX = {"visible": (1280, 720), "thermal": (640, 512)}
RECORD_SIZE_PX = (640, 360)
RECORD_FPS = 10.0
MAX_RECORD_S = 600.0
MAX_PENDING = 8
SENSOR_WIDTH_MM = {"visible": 6.17, "thermal": 7.68}  # assumed (1/2.3" visible, 640 x 12 um thermal)
MAKES = {"topotek": "TOPOTEK", "skydroid": "SkyDroid"}


@dataclass(frozen=True)
class Shot:
    """Everything a photo needs, taken on the simulator's thread at the moment of capture."""

    index: int
    scene: SceneState
    meta: PhotoMeta


class MediaStore:
    def __init__(
        self, sim: Simulator, directory: str | os.PathLike[str], *, max_bytes: int = DEFAULT_MAX_BYTES
    ) -> None:
        self.sim = sim
        self.dir = Path(directory)
        self.dir.mkdir(parents=True, exist_ok=True)
        self.max_bytes = int(max_bytes)
        self.streams: list[StreamSpec] = list(streams_for(sim.device.model))
        self.written: list[Path] = []
        self.dropped = 0
        self._pending = 0
        self._lock = threading.Lock()
        self._recorder: _Recorder | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        # Capture order by file name: photos are written on worker threads and can land out of
        # order, so the age that pruning goes by is when the shot was taken, not the file's mtime.
        self._taken: dict[str, int] = {}
        self._shots = 0

    def start(self) -> MediaStore:
        self._loop = asyncio.get_running_loop()
        self.sim.device.state.capture_listeners.append(self._on_capture)
        return self

    async def stop(self) -> None:
        listeners = self.sim.device.state.capture_listeners
        if self._on_capture in listeners:
            listeners.remove(self._on_capture)
        if self._recorder is not None:
            rec, self._recorder = self._recorder, None
            await asyncio.to_thread(rec.finish)
        while self._pending:
            await asyncio.sleep(0.02)

    # -- on the simulator's thread ---------------------------------------------------------------

    def _on_capture(self, event: str, index: int) -> None:
        try:
            if event == "photo":
                self._photo(index)
            elif event == "record_start":
                self._record_start(index)
            elif event == "record_stop" and self._recorder is not None:
                rec, self._recorder = self._recorder, None
                threading.Thread(target=rec.finish, name="media-record-finish", daemon=True).start()
        except Exception:  # the camera goes on whatever happens to its card
            log.exception("media: %s %d not stored", event, index)

    def shot_meta(self) -> PhotoMeta:
        device = self.sim.device
        pos = device.state.position
        clock = device.camera_time()
        if clock is None:  # a camera with a clock never set: its factory date, as a real one shows
            clock = NO_CLOCK_EPOCH + datetime.timedelta(seconds=max(0.0, device.now - device.camera.booted_at))
        v = device.gimbal.vehicle
        has_fix = pos.lat_deg is not None and pos.lon_deg is not None
        return PhotoMeta(
            make=MAKES.get(device.dialect.name, device.dialect.name),
            model=device.model.name,
            time=clock.replace(tzinfo=None),  # exif.py keeps the fraction in SubSecTimeOriginal
            lat_deg=pos.lat_deg if has_fix else None,
            lon_deg=pos.lon_deg if has_fix else None,
            alt_m=pos.alt_m if has_fix else None,
            flight=Pose(v.yaw, v.pitch, v.roll),
        )

    def _photo(self, index: int) -> None:
        if self._pending >= MAX_PENDING:
            self.dropped += 1
            log.warning("media: photo %d not stored: %d photos are still being written", index, self._pending)
            return
        scene = capture(self.sim.device)
        # The world pose (sim/world.py) holds the heading however it came (AZI or a vehicle
        # attitude), so the scene's earth yaw and the flight pose already include it.
        meta = replace(self.shot_meta(), gimbal=Pose(scene.yaw_deg, scene.pitch_deg, scene.roll_deg))
        self._note_taken(photo_names(self.sim.device.dialect.name, index, [s.lens for s in self.streams]).values())
        self._pending += 1
        assert self._loop is not None
        fut = self._loop.run_in_executor(None, self._write_photo, Shot(index, scene, meta))
        fut.add_done_callback(self._photo_done)

    def _note_taken(self, names: Iterable[str]) -> None:
        with self._lock:
            self._shots += 1
            for name in names:
                self._taken[name] = self._shots

    def _photo_done(self, fut: asyncio.Future[None]) -> None:
        self._pending -= 1
        if not fut.cancelled() and fut.exception() is not None:
            log.warning("media: photo not stored: %s", fut.exception())

    def _record_start(self, index: int) -> None:
        if self._recorder is not None:
            return
        spec = self.streams[0]
        name = recording_name(self.sim.device.dialect.name, index)
        self._note_taken([name])
        assert self._loop is not None
        self._recorder = _Recorder(self, self.dir / name, spec, self._loop)
        self._recorder.start()

    # -- on worker threads -----------------------------------------------------------------------

    def _write_photo(self, shot: Shot) -> None:
        names = photo_names(self.sim.device.dialect.name, shot.index, [s.lens for s in self.streams])
        for spec in self.streams:
            w, h = PHOTO_SIZE_PX.get(spec.lens, PHOTO_SIZE_PX["visible"])
            zoom = shot.scene.zoom_x if spec.lens == "visible" else shot.scene.thermal_zoom_x
            picture = Renderer(spec.lens, w, h, spec.hfov_deg).render(shot.scene)
            buf = io.BytesIO()
            picture.convert("RGB").save(buf, "JPEG", quality=85)
            focal, focal35 = focal_lengths(spec.hfov_deg, zoom, SENSOR_WIDTH_MM.get(spec.lens, 6.17))
            meta = replace(shot.meta, focal_mm=focal, focal_35mm=focal35, zoom_x=zoom, width_px=w, height_px=h)
            path = self.dir / names[spec.lens]
            tmp = path.with_name(path.name + ".part")
            tmp.write_bytes(tag_jpeg(buf.getvalue(), meta))
            self._store(tmp, path)

    def _store(self, tmp: Path, path: Path) -> None:
        os.replace(tmp, path)
        with self._lock:
            self.written.append(path)
        self.prune()

    def prune(self) -> None:
        """Drop the oldest files until DIR is under its cap."""
        with self._lock:
            files = [p for p in self.dir.iterdir() if p.is_file() and MEDIA_NAME.match(p.name)]
            # Files already on the card before this store are older than any it took (by mtime
            # among themselves); its own go by capture order.
            files.sort(key=lambda p: (1, self._taken[p.name], 0.0) if p.name in self._taken
                       else (0, 0, p.stat().st_mtime))  # fmt: skip
            if len(self._taken) > 2 * len(files) + 1000:  # names deleted by hand: keep the map bounded
                on_card = {p.name for p in files}
                self._taken = {n: i for n, i in self._taken.items() if n in on_card}
            total = sum(p.stat().st_size for p in files)
            gone: list[str] = []
            while total > self.max_bytes and len(files) > 1:
                oldest = files.pop(0)
                total -= oldest.stat().st_size
                oldest.unlink(missing_ok=True)
                self._taken.pop(oldest.name, None)
                gone.append(oldest.name)
            if gone:
                log.warning("media: %s over its %d bytes: dropped %s", self.dir, self.max_bytes, ", ".join(gone))


class _Recorder:
    """Renders the visible lens into an MP4 at RECORD_FPS until `finish()` (or MAX_RECORD_S)."""

    def __init__(self, store: MediaStore, path: Path, spec: StreamSpec, loop: asyncio.AbstractEventLoop) -> None:
        self.store, self.path, self.spec, self.loop = store, path, spec, loop
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="media-record", daemon=True)
        self.frames = 0

    def start(self) -> None:
        self._thread.start()

    def finish(self) -> None:
        self._stop.set()
        self._thread.join(30.0)

    def _scene(self) -> SceneState | None:
        fut = asyncio.run_coroutine_threadsafe(self._take(), self.loop)
        try:
            return fut.result(5.0)
        except Exception:
            return None

    async def _take(self) -> SceneState:
        return capture(self.store.sim.device, self.frames)

    def _run(self) -> None:
        import av

        w, h = RECORD_SIZE_PX
        tmp = self.path.with_name(self.path.name + ".part")
        try:
            renderer = Renderer(self.spec.lens, w, h, self.spec.hfov_deg)
            with av.open(str(tmp), "w", format="mp4") as out:
                stream = out.add_stream("libx264", rate=int(RECORD_FPS))
                stream.width, stream.height, stream.pix_fmt = w, h, "yuv420p"
                stream.options = {"preset": "ultrafast"}
                started = monotonic()
                while not self._stop.wait(0 if self.frames == 0 else 1.0 / RECORD_FPS):
                    if monotonic() - started > MAX_RECORD_S:
                        log.warning("media: %s reached %g s: no more frames", self.path.name, MAX_RECORD_S)
                        break
                    scene = self._scene()
                    if scene is None:
                        continue
                    frame = av.VideoFrame.from_image(renderer.render(scene).convert("RGB"))
                    for packet in stream.encode(frame):
                        out.mux(packet)
                    self.frames += 1
                for packet in stream.encode():
                    out.mux(packet)
            self._stop.wait()
            self.store._store(tmp, self.path)
        except Exception:
            log.exception("media: recording %s not stored", self.path.name)
