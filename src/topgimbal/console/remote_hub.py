"""A camera the console reaches through a `topgimbal zenoh` server (`--zenoh ENDPOINT`).

`SharedRemote` is the SDK's `RemoteClient` on the console's one Zenoh session (a session per
camera would cost threads and sockets per camera), handed to it with `session=`; its
`served_state` (the server's last `state` sample: recording, SD card, version) feeds the overview. `RemoteHub` is the console's `Hub` for it:
the same ops and pushes, minus what Zenoh does not carry. Frames stay on the Zenoh server, so the
traffic pane and the pcap download are unavailable for such a camera (said in `hello` and in the
status, with the reason); the raw-frame op works where the server allows it (`--allow-remote send_raw`). The
server's own client watches the camera's link and publishes it, so the console sends no link
checks of its own through Zenoh."""

from __future__ import annotations

import logging
from typing import Any, cast

from ..client import CameraAPI
from ..client.remote import RemoteClient
from ..clock import wall_time
from .hub import Hub
from .pages import PageHub

log = logging.getLogger(__name__)

NOT_CARRIED = (
    "frames are not carried over Zenoh: the `topgimbal zenoh` server keeps its camera's traffic "
    "(watch it there, e.g. with `topgimbal console --url` on the camera)"
)
UNAVAILABLE = {"traffic": NOT_CARRIED, "pcap": NOT_CARRIED}


class SharedRemote(RemoteClient):
    """A RemoteClient on the session the console owns (opened and closed by `ZenohCameras`)."""

    def __init__(self, name: str, session: Any, endpoints: tuple[str, ...]) -> None:
        query = "&".join(f"connect={e}" for e in endpoints) or "mode=peer"
        super().__init__(f"zenoh/{name}?{query}", session=session)
        self.served = False

    async def open(self) -> SharedRemote:
        await super().open()
        self.served = True
        return self

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
    samples_are_heard = True  # no traffic subscription here: an attitude sample is what is heard

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
            self.recording_since = wall_time() if rec else None

    def status(self) -> dict[str, Any]:
        out = super().status()
        st = self.remote.served_state
        if self.version is None and isinstance(st.get("version"), str):
            self.version = st["version"]
        return {**out, "unavailable": UNAVAILABLE, "served": self.remote.served}

    def hello(self) -> dict[str, Any]:
        return {**super().hello(), "unavailable": UNAVAILABLE}


__all__ = ["NOT_CARRIED", "UNAVAILABLE", "RemoteHub", "SharedRemote"]
