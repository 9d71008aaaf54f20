"""A camera the console reaches through a `topgimbal zenoh` server (`--zenoh ENDPOINT`).

`SharedRemote` is the SDK's `RemoteClient` on the console's one Zenoh session (a session per
camera would cost threads and sockets per camera); it also keeps the server's last `state`
sample (recording, SD card, version) for the overview. `RemoteHub` is the console's `Hub` for it:
the same ops and pushes, minus what Zenoh does not carry. Frames stay on the Zenoh server, so the
traffic pane and the pcap download are unavailable for such a camera (said in `hello` and in the
status, with the reason); the raw-frame op works (`send_raw` is one of the served methods). The
server's own client watches the camera's link and publishes it, so the console sends no link
checks of its own through Zenoh."""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
import time
from typing import Any, cast

from ..client import CameraAPI
from ..client.remote import RemoteClient
from ..client.remote_keys import key
from .hub import Hub
from .pages import PageHub

log = logging.getLogger(__name__)

INFO_TIMEOUT_S = 5.0  # the served camera's `info` query when it appears
NOT_CARRIED = (
    "frames are not carried over Zenoh: the `topgimbal zenoh` server keeps its camera's traffic "
    "(watch it there, e.g. with `topgimbal console --url` on the camera)"
)
UNAVAILABLE = {"traffic": NOT_CARRIED, "pcap": NOT_CARRIED}


class SharedRemote(RemoteClient):
    """A RemoteClient on a session the console owns (opened and closed by `ZenohCameras`)."""

    def __init__(self, name: str, session: Any, endpoints: tuple[str, ...]) -> None:
        query = "&".join(f"connect={e}" for e in endpoints) or "mode=peer"
        super().__init__(f"zenoh/{name}?{query}")
        self.shared_session = session
        self.served_state: dict[str, Any] = {}
        self.served = False

    async def open(self) -> SharedRemote:
        # RemoteClient.open, minus opening a session (RemoteClient cannot be handed one)
        self._loop = asyncio.get_running_loop()
        self.session = self.shared_session
        self.info = await self._query_json(key(self.name, "info"), None, INFO_TIMEOUT_S)
        from ..protocol import get_model

        served = str(self.info.get("model", ""))
        if served:
            self.dialect, self.model = get_model(served)
        self._subs.append(self.session.declare_subscriber(key(self.name, "link"), self._on_link_sample))
        self._subs.append(self.session.declare_subscriber(key(self.name, "state"), self._on_state_sample))
        self.served = True
        self._set_link(True, "served")
        return self

    async def close(self) -> None:
        if self.closed:
            return
        self.closed = True
        for s in self._subs:
            with contextlib.suppress(Exception):
                s.undeclare()
        self._subs.clear()
        self.session = None  # the console's session: closed by its owner

    def _on_state_sample(self, sample: Any) -> None:
        super()._on_state_sample(sample)
        try:
            data = json.loads(sample.payload.to_bytes())
        except (ValueError, AttributeError):
            return
        if isinstance(data, dict) and self._loop is not None and not self._loop.is_closed():
            with contextlib.suppress(RuntimeError):
                self._loop.call_soon_threadsafe(self._keep_state, data)

    def _keep_state(self, data: dict[str, Any]) -> None:
        self.served_state = data

    def gone(self, reason: str) -> None:
        """Its liveliness token went away (the server stopped serving it, or the server is gone)."""
        self.served = False
        self._set_link(False, reason)

    def back(self) -> None:
        self.served = True
        up = self.served_state.get("up", True)
        self._set_link(bool(up), "served again" if up else str(self.served_state.get("reason", "")))


class RemoteHub(Hub):
    """`Hub` for a `SharedRemote`: no traffic subscription and no link checks (see the module)."""

    source = "zenoh"

    def __init__(self, cam: SharedRemote, *, attitude_hz: float = 50.0) -> None:
        # a CameraAPI but for feed/feed_from (the console feeds nothing to a remote camera)
        super().__init__(cast(CameraAPI, cam), url=cam.url, attitude_hz=attitude_hz)
        self.remote = cam

    async def start(self) -> None:
        self._unsubscribe.append(self.cam.on_link_change(self._on_link_change))
        if not self.cam.link_state.get("up", True):
            self._on_link_change(False, str(self.cam.link_state.get("reason") or "the link is down"))
        await PageHub.start(self)

    async def _keepalive_loop(self) -> None:
        """None: the Zenoh server's own client watches the camera's link and publishes it."""

    async def _attitude_loop(self) -> None:
        """Hub's loop, also counting a sample as something heard from the camera."""
        while True:
            try:
                async for att in self.cam.attitude(self.attitude_hz):
                    self.attitude = {
                        "yaw": float(att.yaw_deg),
                        "pitch": float(att.pitch_deg),
                        "roll": float(att.roll_deg),
                        "t": float(att.wall or time.time()),
                    }
                    self.last_in = time.time()
                    self._attitude_seq += 1
                    self.clear_error("attitude")
            except asyncio.CancelledError:
                raise
            except Exception as exc:
                self._background_failure(exc, "the attitude stream", "attitude")
            await asyncio.sleep(1.0)

    def link_status(self) -> dict[str, Any]:
        out = super().link_status()
        if out["link"] == "waiting" and self.remote.served:  # a model without a stream: served is heard
            out["link"] = "up"
        return out

    def _sync_recording(self) -> None:
        super()._sync_recording()
        rec = self.remote.served_state.get("recording")
        if isinstance(rec, bool) and rec != self.recording:
            self.recording = rec
            self.recording_since = time.time() if rec else None

    def status(self) -> dict[str, Any]:
        out = super().status()
        st = self.remote.served_state
        if self.version is None and isinstance(st.get("version"), str):
            self.version = st["version"]
        return {**out, "unavailable": UNAVAILABLE, "served": self.remote.served}

    def hello(self) -> dict[str, Any]:
        return {**super().hello(), "unavailable": UNAVAILABLE}


__all__ = ["NOT_CARRIED", "UNAVAILABLE", "RemoteHub", "SharedRemote"]
