"""Video in the web console: the relay's routes and the picture's controls.

    GET  /api/video                 lenses, their picture size and field of view, relay states
    GET  /video/<lens>.mjpg         the live picture (multipart JPEG)
    GET  /video/<lens>/whep         whether the lens plays over WebRTC now ({"ready", "codec", "why"})
    POST /video/<lens>/whep         WebRTC (WHEP): an SDP offer in, 201 + the answer (webrtc.py)
    DELETE /video/<lens>/whep/<id>  end that WebRTC session
    POST /api/video/point           {"lens", "x", "y"}: point at that spot (fractions of the picture)
    POST /api/video/track           {"lens", "x0", "y0", "x1", "y1"}: track what the box holds
    POST /api/video/zoom            {"direction": "in" | "out"}: one zoom step

`attach(console)` is the console's one hook: with a simulator it starts the simulator's RTSP
streams (free loopback ports); with a real camera it relays the model's documented RTSP URLs at
the camera's address. Without the video extra it logs why and the console runs without video.
The console passes its origin check in; its token middleware already guards every route.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
from typing import TYPE_CHECKING, Any

from ..timeouts import within
from .lens import StreamSpec, VideoError, View, hfov_at, host_of, stream_urls, streams_for, tracking_requests, wrap180
from .webconsole_io import OriginCheck, VideoHost, error_response, fraction_of, lens_of, shown_url

if TYPE_CHECKING:  # named for the type checker only: aiohttp is imported by the routes when they run
    from aiohttp import web

    from .relay import Relay
    from .simvideo import SimVideo
    from .webrtc import WhepServer

log = logging.getLogger("topgimbal.video.console")

BOUNDARY = "topgimbalframe"
ZOOM_STEP_S = 0.3  # one wheel notch runs the zoom motor this long
# The console's own simulated camera renders at this rate: it shares one process (and, on a
# small machine, the CPU) with the console and the relay; 15 fps halves the cost of 30 (see
# docs/video.md) and still shows motion. `topgimbal sim --video` keeps the camera's 30 fps.
CONSOLE_SIM_FPS = 15.0
VIEWER_STALL_S = 10.0  # a viewer that takes no picture for this long is dropped (it holds a place)


class ConsoleVideo:
    def __init__(self, console: VideoHost, *, origin_ok: OriginCheck | None = None) -> None:
        from .relay import Relay

        self.console = console
        self.origin_ok = origin_ok or (lambda request: True)
        self.specs: dict[str, StreamSpec] = {s.lens: s for s in streams_for(console.model or "C12")}
        self.sim_video: SimVideo | None = None
        self.relays: dict[str, Relay] = {}
        self.whep: WhepServer | None = None  # None: aiortc is not installed (the page plays MJPEG)
        self._zoom_task: asyncio.Task[None] | None = None
        self._relay_cls: type[Relay] = Relay

    async def start(self) -> ConsoleVideo:
        if self.console.sim is not None:
            from .simvideo import SimVideo, VideoOptions

            opts = VideoOptions(port=0, fps=CONSOLE_SIM_FPS)
            self.sim_video = await SimVideo(self.console.sim, opts).start()
            urls = dict(self.sim_video.urls)
        else:
            model, url = self.console.model, self.console.url
            given = dict(self.console.video_urls)
            if not model or not (url or len(given) == len(self.specs)):
                raise VideoError("the console has no camera URL and model to take the video from")
            missing = [lens for lens in self.specs if lens not in given]
            # the documented URLs at the camera's address (on --video-port, keeping their spacing)
            documented = stream_urls(model, host_of(url), port=self.console.video_port) if missing and url else {}
            urls = {lens: given.get(lens) or documented[lens] for lens in self.specs}
        self.relays = {lens: self._relay_cls(lens, url) for lens, url in urls.items()}
        from .webrtc import WhepServer, available

        if available():
            self.whep = WhepServer(urls)
        else:
            log.info("console video: WebRTC is off (pip install 'topgimbal[webrtc]'); the page plays MJPEG")
        return self

    async def close(self) -> None:
        if self.whep is not None:
            await self.whep.close()
        for r in self.relays.values():
            await r.close()
        if self.sim_video is not None:
            await self.sim_video.stop()
            self.sim_video = None

    # -- routes ------------------------------------------------------------------------------------

    def add_routes(self, app: web.Application) -> None:
        app.router.add_get("/api/video", self.info)
        app.router.add_get("/video/{lens}.mjpg", self.mjpeg)
        app.router.add_get("/video/{lens}/whep", self.whep_ready)
        app.router.add_post("/video/{lens}/whep", self.whep_offer)
        app.router.add_delete("/video/{lens}/whep/{session}", self.whep_delete)
        app.router.add_post("/api/video/point", self.point)
        app.router.add_post("/api/video/track", self.track)
        app.router.add_post("/api/video/zoom", self.zoom)

    async def info(self, request: web.Request) -> web.StreamResponse:
        from aiohttp import web

        lenses = []
        for lens, relay in self.relays.items():
            s = self.specs[lens]
            lenses.append(
                {
                    "lens": lens,
                    "hfov_deg": s.hfov_deg,
                    "url": shown_url(relay.url),
                    **relay.status(),
                    "size": list(relay.size or s.size),
                    "webrtc": self.whep.status(lens) if self.whep is not None else None,
                }
            )
        state = self.console.cam.state if self.console.cam is not None else None
        att = state.attitude if state is not None else None
        rec = state.recording if state is not None else None
        return web.json_response(
            {
                "model": self.console.model,
                "lenses": lenses,
                "zoom_x": self._zoom_x(),
                "attitude": None if att is None else {k: getattr(att, k) for k in ("yaw_deg", "pitch_deg", "roll_deg")},
                "recording": bool(rec.value) if rec is not None else False,
            }
        )

    async def mjpeg(self, request: web.Request) -> web.StreamResponse:
        from aiohttp import web

        from .relay import RelayFullError

        relay = self.relays.get(request.match_info["lens"])
        if relay is None:
            return error_response(404, f"no such lens; this camera has: {', '.join(self.relays)}")
        # The console's own page (a same-origin request: the guard refused other sites' pages)
        # may take the places kept for the operator.
        own_page = request.headers.get("Sec-Fetch-Site", "").strip().lower() == "same-origin"
        pictures = relay.pictures_for_viewer(operator=own_page)
        try:
            first = await pictures.__anext__()
        except RelayFullError as exc:
            return error_response(503, str(exc))
        except StopAsyncIteration:
            return error_response(503, "the console is stopping")
        resp = web.StreamResponse(
            headers={
                "Content-Type": f"multipart/x-mixed-replace; boundary={BOUNDARY}",
                "Cache-Control": "no-store",
            }
        )
        try:
            await resp.prepare(request)
            jpeg = first
            while True:
                head = f"--{BOUNDARY}\r\nContent-Type: image/jpeg\r\nContent-Length: {len(jpeg)}\r\n\r\n"
                # A viewer that stops reading (a frozen tab, a stalled proxy) would hold its
                # place among the MAX_VIEWERS forever: past VIEWER_STALL_S it is dropped.
                await within(resp.write(head.encode() + jpeg + b"\r\n"), VIEWER_STALL_S)
                jpeg = await pictures.__anext__()
        except asyncio.TimeoutError:
            log.warning(
                "video %s: a viewer (%s) took no picture for %.0f s: dropping it",
                relay.name, request.remote, VIEWER_STALL_S,
            )  # fmt: skip
            if request.transport is not None:
                request.transport.close()
        except (ConnectionError, StopAsyncIteration, asyncio.CancelledError):
            pass  # the viewer left (aiohttp says "Connection lost" as a plain ConnectionError)
        finally:
            await pictures.aclose()
        return resp

    async def whep_offer(self, request: web.Request) -> web.StreamResponse:
        """WHEP: the SDP offer in the body (application/sdp), 201 with the answer and Location."""
        from aiohttp import web

        from .webrtc import MAX_OFFER_BYTES, WebRtcError

        if self.whep is None:
            return error_response(
                501, "WebRTC is off on this console (pip install 'topgimbal[webrtc]'): use the MJPEG stream"
            )
        if not self.origin_ok(request):
            return error_response(403, "cross-origin request refused")
        if request.content_type != "application/sdp":
            return error_response(415, "the body must be an SDP offer (Content-Type: application/sdp)")
        if request.content_length is None or request.content_length > MAX_OFFER_BYTES:
            return error_response(413, f"an offer is at most {MAX_OFFER_BYTES} bytes, with a Content-Length")
        try:
            offer = (await request.read()).decode("utf-8")
        except UnicodeDecodeError:
            return error_response(400, "the offer is not UTF-8 text")
        lens = request.match_info["lens"]
        sock = request.transport.get_extra_info("sockname") if request.transport is not None else None
        try:
            # An Origin (checked above: the console's own) is the page's fetch; a WHEP player sends none
            page = "Origin" in request.headers
            sid, answer = await self.whep.answer(lens, offer, sock[0] if sock else None, page=page)
        except WebRtcError as exc:
            return error_response(exc.status, str(exc))
        return web.Response(status=201, text=answer, content_type="application/sdp",
                            headers={"Location": f"{request.path}/{sid}", "Cache-Control": "no-store"})  # fmt: skip

    async def whep_ready(self, request: web.Request) -> web.StreamResponse:
        """200 {"ready": bool, "codec", "why"}: the page asks before it offers (no failed request)."""
        from aiohttp import web

        from .webrtc import WebRtcError

        if self.whep is None:
            return web.json_response({"ready": False, "codec": None, "why": "WebRTC is off on this console"})
        try:
            return web.json_response(await self.whep.ready(request.match_info["lens"]))
        except WebRtcError as exc:
            return error_response(exc.status, str(exc))

    async def whep_delete(self, request: web.Request) -> web.StreamResponse:
        from aiohttp import web

        if self.whep is None:
            return error_response(404, "WebRTC is off on this console")
        if not self.origin_ok(request):
            return error_response(403, "cross-origin request refused")
        ended = await self.whep.end(request.match_info["session"], why="ended by the client (DELETE)")
        return web.Response(status=200) if ended else error_response(404, "no such WebRTC session")

    async def _body(self, request: web.Request) -> dict[str, object] | web.Response:
        if not self.origin_ok(request):
            return error_response(403, "cross-origin request refused")
        try:
            body = await request.json()
        except Exception:
            return error_response(400, "the body must be JSON")
        if not isinstance(body, dict):
            return error_response(400, "the body must be a JSON object")
        return body

    def _zoom_x(self) -> float:
        sim = self.console.sim
        if sim is not None:
            return float(sim.camera.zoom_x)
        z = getattr(self.console.cam.state, "zoom", None) if self.console.cam is not None else None
        try:
            return max(1.0, float(z.value)) if z is not None else 1.0
        except (TypeError, ValueError):
            return 1.0

    async def point(self, request: web.Request) -> web.StreamResponse:
        from aiohttp import web

        body = await self._body(request)
        if not isinstance(body, dict):
            return body
        try:
            lens, x, y = lens_of(body, self.specs), fraction_of(body, "x"), fraction_of(body, "y")
        except VideoError as exc:
            return error_response(400, str(exc))
        cam = self.console.cam
        if cam is None:
            return error_response(503, "no camera")
        att = cam.state.attitude
        if att is None:
            with contextlib.suppress(Exception):
                att = await cam.get_attitude()
        if att is None:
            return error_response(503, "the camera has not reported its attitude yet")
        spec = self.specs[lens]
        w, h = self.relays[lens].size or spec.size
        view = View(att.yaw_deg, att.pitch_deg, att.roll_deg, hfov_at(spec.hfov_deg, self._zoom_x()), w, h)
        az, el = view.angles_at(x * w, y * h)
        lo, hi = cam.model.yaw_range_deg
        yaw = min(hi, max(lo, att.yaw_deg + wrap180(az - att.yaw_deg)))
        plo, phi = cam.model.pitch_range_deg
        pitch = min(phi, max(plo, el))
        try:
            await cam.set_angles(yaw, pitch)
        except Exception as exc:
            return error_response(502, f"the camera refused: {exc}")
        return web.json_response({"yaw_deg": round(yaw, 3), "pitch_deg": round(pitch, 3)})

    async def track(self, request: web.Request) -> web.StreamResponse:
        from aiohttp import web

        body = await self._body(request)
        if not isinstance(body, dict):
            return body
        try:
            lens_of(body, self.specs)
            x0, y0, x1, y1 = (fraction_of(body, k) for k in ("x0", "y0", "x1", "y1"))
        except VideoError as exc:
            return error_response(400, str(exc))
        cam = self.console.cam
        if cam is None:
            return error_response(503, "no camera")
        try:
            requests = tracking_requests(cam.dialect, cam.model, x0, y0, x1, y1)
        except VideoError as exc:
            return error_response(409, str(exc))
        try:
            for ident, values in requests:
                await cam.request(ident, **values)
        except Exception as exc:
            return error_response(502, f"the camera refused: {exc}")
        return web.json_response({"requests": [{"id": i, **v} for i, v in requests]})

    async def zoom(self, request: web.Request) -> web.StreamResponse:
        from aiohttp import web

        body = await self._body(request)
        if not isinstance(body, dict):
            return body
        direction = body.get("direction")
        if direction not in ("in", "out"):
            return error_response(400, "direction must be 'in' or 'out'")
        cam = self.console.cam
        if cam is None:
            return error_response(503, "no camera")
        try:
            if cam.model.optical_zoom_max > 1.0:
                await cam.zoom(direction)
                if self._zoom_task is not None:
                    self._zoom_task.cancel()
                self._zoom_task = asyncio.get_running_loop().create_task(self._zoom_stop(cam))
            else:
                z = self._zoom_x()
                await cam.zoom(max(1.0, min(cam.model.digital_zoom_max, round(z) + (1 if direction == "in" else -1))))
        except Exception as exc:
            return error_response(502, f"the camera refused: {exc}")
        return web.json_response({"direction": direction})

    async def _zoom_stop(self, cam: Any) -> None:
        await asyncio.sleep(ZOOM_STEP_S)
        with contextlib.suppress(Exception):
            await cam.zoom("stop")


async def attach(console: VideoHost, app: web.Application, origin_ok: OriginCheck | None = None) -> ConsoleVideo | None:
    """Start video for a console and mount its routes on `app` (before the app starts)."""
    try:
        import av  # noqa: F401
        import numpy  # noqa: F401
        import PIL  # noqa: F401
    except ImportError as exc:
        log.warning("console video is off: the video extra is not installed (%s)", exc)
        return None
    try:
        video = await ConsoleVideo(console, origin_ok=origin_ok).start()
    except VideoError as exc:
        log.warning("console video is off: %s", exc)
        return None
    video.add_routes(app)
    return video
