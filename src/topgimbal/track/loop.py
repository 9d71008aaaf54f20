"""The companion tracking loop: the camera's video in, gimbal rates out.

    from topgimbal.track import CompanionTracker, TrackConfig, rtsp_frames
    async with topgimbal.connect("udp://127.0.0.1:5000", model="C10") as cam:
        tracker = CompanionTracker(cam, TrackConfig(box=(0.45, 0.45, 0.1, 0.1)))
        report = await tracker.run(rtsp_frames(cam.video_url()), duration_s=30)

Three tasks share one state: the attitude stream fills the attitude history; each picture goes
to the OpenCV tracker (in a worker thread) and its detection becomes an earth-frame direction with
the attitude *at the picture's capture time*; a timer at `rate_hz` turns the PI controller's rates
(control.py) into rate commands. A picture's capture time is the wall-clock stamp the simulator
burns into its pictures where there is one, else its arrival time minus the configured latency.
When the tracker loses the target the controller coasts on its prediction and each picture is
searched around where the target should be; after `reacquire_s` without it the loop stops the
gimbal and says "lost" (and keeps searching, so a target that comes back is taken up again).
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import math
import threading
from collections.abc import AsyncIterator, Callable
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

from ..clock import MonotonicFn, monotonic, wall_time
from ..geo.optics import PixelView, hfov_at
from ..protocol.streams import stream_for
from .control import AngleController, AttitudeHistory, Gains, PixelPGains, pixel_p_rates
from .vision import TrackerError, VisualTracker

if TYPE_CHECKING:
    import numpy as np

    from ..client import AsyncClient

log = logging.getLogger("topgimbal.track")

LAWS = ("pi", "pixel-p")
RATE_RESEND_S = 0.5  # a rate command is repeated this often even when unchanged
RATE_DEADBAND_DEG_S = 0.05


@dataclass(frozen=True)
class Picture:
    """One decoded picture and when the camera took it (this process's monotonic clock)."""

    image: np.ndarray
    t: float


@dataclass(frozen=True)
class TrackConfig:
    box: tuple[float, float, float, float] = (0.45, 0.45, 0.1, 0.1)  # x, y, width, height: picture fractions
    kind: str = "kcf"
    law: str = "pi"
    gains: Gains = field(default_factory=Gains)
    pixel_gains: PixelPGains = field(default_factory=PixelPGains)
    rate_hz: float = 50.0
    attitude_hz: float = 50.0
    reacquire_s: float = 2.0
    hfov_1x_deg: float | None = None  # None: the model profile's visible lens
    box_px: bool = False  # `box` is in pixels of the picture, not fractions

    def __post_init__(self) -> None:
        x, y, w, h = self.box
        if self.box_px:
            if min(x, y) < 0 or min(w, h) <= 0:
                raise TrackerError(f"box must be x,y,w,h pixels, w and h above 0 (got {self.box})")
        elif not (0 <= x < 1 and 0 <= y < 1 and 0 < w <= 1 and 0 < h <= 1 and x + w <= 1 and y + h <= 1):
            raise TrackerError(f"box must be x,y,w,h fractions of the picture within it (got {self.box})")
        if self.law not in LAWS:
            raise TrackerError(f"law must be one of {', '.join(LAWS)} (got {self.law!r})")
        if not 1 <= self.rate_hz <= 200:
            raise TrackerError(f"rate must be 1..200 Hz (got {self.rate_hz:g})")


@dataclass
class TrackReport:
    pictures: int = 0
    detections: int = 0
    losses: int = 0
    reacquired_after_s: list[float] = field(default_factory=list)
    state: str = "starting"


class CompanionTracker:
    def __init__(self, cam: AsyncClient, config: TrackConfig | None = None, *, clock: MonotonicFn = monotonic) -> None:
        self.cam = cam
        self.config = config or TrackConfig()
        self.clock = clock
        self.history = AttitudeHistory()
        # Never ask more than the gimbal can do: a saturated command only winds the loop up.
        limit = min(self.config.gains.max_rate_deg_s, float(cam.model.max_rate_deg_s))
        self.controller = AngleController(replace(self.config.gains, max_rate_deg_s=limit))
        self.vision = VisualTracker(self.config.kind)
        self.report = TrackReport()
        self.state = "starting"  # starting, tracking, searching, lost
        self._lost_at: float | None = None
        self._pixel_rates = (0.0, 0.0)
        self._sent: tuple[float, float, float] | None = None  # yaw, pitch rate and when
        lens = self.config.hfov_1x_deg
        self.hfov_1x_deg = lens if lens is not None else stream_for(cam.model, "visible").hfov_deg
        self.on_picture: Callable[[Picture, tuple[int, int, int, int] | None], None] | None = None

    def hfov_deg(self) -> float:
        z = self.cam.state.zoom
        value = z.value if z is not None else 1.0
        zoom = float(value) if isinstance(value, (int, float)) and value >= 1 else 1.0
        return hfov_at(self.hfov_1x_deg, zoom)

    async def run(self, pictures: AsyncIterator[Picture], duration_s: float | None = None) -> TrackReport:
        tasks = [
            asyncio.ensure_future(self._attitude()),
            asyncio.ensure_future(self._pictures(pictures)),
            asyncio.ensure_future(self._control()),
        ]
        try:
            if duration_s is None:
                await asyncio.gather(*tasks)
            else:
                done, _ = await asyncio.wait(tasks, timeout=duration_s, return_when=asyncio.FIRST_EXCEPTION)
                for t in done:
                    t.result()  # an error in a task ends the run with it
        finally:
            for t in tasks:
                t.cancel()
            for t in tasks:
                with contextlib.suppress(asyncio.CancelledError, Exception):
                    await t
            with contextlib.suppress(Exception):
                await self.cam.stop()
        self.report.state = self.state
        return self.report

    async def _attitude(self) -> None:
        async for att in self.cam.attitude(self.config.attitude_hz):
            self.history.add(att.t, att.yaw_deg, att.pitch_deg)

    async def _pictures(self, pictures: AsyncIterator[Picture]) -> None:
        async for pic in pictures:
            await self.picture(pic)

    async def picture(self, pic: Picture) -> None:
        """Handle one picture (the loop's `_pictures`, or a caller feeding pictures itself)."""
        self.report.pictures += 1
        h, w = pic.image.shape[:2]
        att = self.history.at(pic.t)
        if att is None:
            return  # no attitude yet: a detection could not be placed
        view = PixelView(att[0], att[1], 0.0, self.hfov_deg(), w, h)
        box: tuple[int, int, int, int] | None
        if self.state == "starting":
            x, y, bw, bh = self.config.box
            if not self.config.box_px:
                x, y, bw, bh = x * w, y * h, bw * w, bh * h
            await asyncio.to_thread(self.vision.start, pic.image, (x, y, bw, bh))
            box = self.vision.box
        elif self.vision.locked:
            box = await asyncio.to_thread(self.vision.update, pic.image)
        else:
            guess = self.controller.predict(pic.t)
            at = view.project(*guess) if guess is not None else None
            box = await asyncio.to_thread(self.vision.reacquire, pic.image, at) if at is not None else None
        if self.on_picture is not None:
            self.on_picture(pic, box)
        if box is None:
            self._missed(pic.t)
            return
        self.report.detections += 1
        cx, cy = self.vision.centre or (box[0] + box[2] / 2, box[1] + box[3] / 2)
        az, el = view.angles_at(cx, cy)
        if self.controller.target is None:
            # The first sighting: the target is where the picture was, moving as the gimbal was
            # moving (a gimbal panning with it holds it still in the picture), not at rest.
            self.controller.assume_velocity(*self.history.rate(pic.t))
        self.controller.observe(pic.t, az, el)
        f = view.focal_px
        self._pixel_rates = pixel_p_rates(
            (math.degrees(math.atan((cx - w / 2) / f)), math.degrees(math.atan((h / 2 - cy) / f))),
            self.config.pixel_gains,
        )
        if self.state in ("searching", "lost") and self._lost_at is not None:
            self.report.reacquired_after_s.append(pic.t - self._lost_at)
            log.info("track: re-acquired after %.2f s", pic.t - self._lost_at)
        self.state, self._lost_at = "tracking", None

    def _missed(self, t: float) -> None:
        if self.state in ("tracking", "starting"):
            self.state, self._lost_at = "searching", t
            self.report.losses += 1
            self._pixel_rates = (0.0, 0.0)
            log.info("track: target not in the picture; searching")
        elif self.state == "searching" and self._lost_at is not None and t - self._lost_at > self.config.reacquire_s:
            self.state = "lost"
            log.info("track: lost (not seen for %.1f s); gimbal stopped", self.config.reacquire_s)

    def rates_now(self) -> tuple[float, float]:
        if self.state in ("starting", "lost"):
            return 0.0, 0.0
        if self.config.law == "pixel-p":
            return self._pixel_rates
        now = self.clock()
        att = self.history.at(now)
        if att is None:
            return 0.0, 0.0
        return self.controller.command(now, att[0], att[1])

    def command_now(self) -> tuple[float, float] | None:
        """The rates to send now, or None: nothing is commanded before the target was first seen,
        so the gimbal goes on as it was (a rate 0 then would stop a pan that holds the target,
        issue 41.5)."""
        if self.state == "starting" or self.controller.target is None:
            return None
        return self.rates_now()

    async def _control(self) -> None:
        period = 1.0 / self.config.rate_hz
        while True:
            rates = self.command_now()
            if rates is None:
                await asyncio.sleep(period)
                continue
            yaw, pitch = rates
            now = self.clock()
            last = self._sent
            if (
                last is None
                or abs(yaw - last[0]) >= RATE_DEADBAND_DEG_S
                or abs(pitch - last[1]) >= RATE_DEADBAND_DEG_S
                or now - last[2] >= RATE_RESEND_S
            ):
                self._sent = (yaw, pitch, now)
                try:
                    # Not waiting for the echo: a control loop must not stall on one late answer
                    # (the command is sent again within RATE_RESEND_S anyway).
                    await self.cam.rates(yaw, pitch, wait_reply=False)
                except Exception as exc:  # a lost frame: the next period sends again
                    log.debug("track: rate command failed: %s", exc)
            await asyncio.sleep(period)


def capture_time(now: float, now_wall: float, stamp_ms: int | None, latency_s: float) -> float:
    """When a picture that arrives now was taken (monotonic): from its wall-clock stamp (ms) when it
    has one (the simulator's; same host, so the two clocks agree), else now minus the latency."""
    if stamp_ms is not None:
        return now - max(0.0, now_wall - stamp_ms / 1000.0)
    return now - latency_s


async def rtsp_frames(
    url: str, *, latency_s: float = 0.0, clock: MonotonicFn = monotonic, use_stamp: bool = True
) -> AsyncIterator[Picture]:
    """Pictures from an RTSP stream (video.frames in a thread; only the newest waits). The capture
    time is the simulator's burned-in stamp when the picture carries one (and `use_stamp`), else
    the arrival time minus `latency_s`."""
    from ..video.frames import frames
    from ..video.render import decode_stamp

    loop = asyncio.get_running_loop()
    queue: asyncio.Queue[Picture | BaseException | None] = asyncio.Queue(maxsize=2)
    stop = threading.Event()

    def put(item: Picture | BaseException | None) -> None:
        if queue.full():
            with contextlib.suppress(asyncio.QueueEmpty):
                queue.get_nowait()  # the newest picture wins: a late one is worth less
        queue.put_nowait(item)

    def reader() -> None:
        try:
            # Every picture is converted (the queue keeps only the newest): frames()' own lag cut-off
            # would drop all of them for good once a loaded machine decodes behind real time.
            for image in frames(url, max_lag_s=None):
                if stop.is_set():
                    return
                stamp = decode_stamp(image) if use_stamp else None
                t = capture_time(clock(), wall_time(), stamp, latency_s)
                loop.call_soon_threadsafe(put, Picture(image, t))
            loop.call_soon_threadsafe(put, None)
        except BaseException as exc:
            loop.call_soon_threadsafe(put, exc)

    thread = threading.Thread(target=reader, name="track-frames", daemon=True)
    thread.start()
    try:
        while True:
            item = await queue.get()
            if item is None:
                return
            if isinstance(item, BaseException):
                raise item
            yield item
    finally:
        stop.set()
