"""The cameras a `topgimbal zenoh` server serves, found and followed by the console (`--zenoh ENDPOINT`).

One Zenoh session (client mode on the given endpoints, scouting off: client/zenoh_session.py; its
credentials, for a server with access control, from `config_file`, `--zenoh-config`)
subscribes to the fleet's liveliness tokens `topgimbal/<name>` with their history: a token that
appears is a camera to show (its `info` is asked, then it gets a `RemoteHub`); one that goes away
marks that camera LOST ("no longer served") and keeps it in the grid, so a page watching it says
what happened; the same name served again brings it back. When the console is full
(MAX_CAMERAS), a camera that is no longer served makes room for a new one; otherwise the newcomer
is left out, with a warning at most every `WARN_EVERY_S`."""

from __future__ import annotations

import asyncio
import contextlib
import logging
from collections.abc import Sequence
from typing import Any

from ..client.remote_keys import NAME_RE, ROOT
from ..clock import monotonic
from .cameras import Camera, CameraSet
from .remote_hub import RemoteHub, SharedRemote

log = logging.getLogger(__name__)

WARN_EVERY_S = 10.0
GONE_REASON = "no longer served on Zenoh (its liveliness token went away: the server stopped serving it or is gone)"


class ZenohCameras:
    def __init__(
        self, cameras: CameraSet, endpoints: Sequence[str], *, attitude_hz: float = 50.0, config_file: str | None = None
    ) -> None:
        self.cameras = cameras
        self.endpoints = tuple(endpoints)
        self.config_file = config_file  # user/password or TLS for an access-controlled server
        self.attitude_hz = attitude_hz
        self.session: Any = None
        self._sub: Any = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._opening: dict[str, asyncio.Task[None]] = {}
        self._alive: set[str] = set()  # names whose token is there now
        self._warned_at = 0.0
        self.left_out = 0  # newcomers not shown because the console was full

    async def start(self) -> None:
        from ..client.zenoh_session import open_session

        self._loop = asyncio.get_running_loop()
        self.session = await asyncio.to_thread(open_session, connect=self.endpoints, mode="client",
                                             config_file=self.config_file)  # fmt: skip
        self._sub = self.session.liveliness().declare_subscriber(f"{ROOT}/*", self._on_token, history=True)

    async def stop(self) -> None:
        """Stop following tokens (the cameras found stay until the console closes them)."""
        if self._sub is not None:
            with contextlib.suppress(Exception):
                self._sub.undeclare()
            self._sub = None
        for t in self._opening.values():
            t.cancel()
        for t in list(self._opening.values()):
            with contextlib.suppress(asyncio.CancelledError, Exception):
                await t

    async def close(self) -> None:
        """Close the session (after the cameras on it are closed)."""
        await self.stop()
        if self.session is not None:
            session, self.session = self.session, None
            with contextlib.suppress(Exception):
                await asyncio.to_thread(session.close)

    # -- tokens (called in a Zenoh thread) ---------------------------------------------------

    def _on_token(self, sample: Any) -> None:
        try:
            parts = str(sample.key_expr).split("/")
            alive = str(sample.kind).upper().endswith("PUT")
        except Exception:
            return
        if len(parts) != 2 or parts[0] != ROOT or not NAME_RE.fullmatch(parts[1]):
            return  # not a camera token of the fleet's layout
        loop = self._loop
        if loop is not None and not loop.is_closed():
            with contextlib.suppress(RuntimeError):
                loop.call_soon_threadsafe(self._seen, parts[1], alive)

    def _seen(self, name: str, alive: bool) -> None:
        (self._alive.add if alive else self._alive.discard)(name)
        cam = self.cameras.get(name)
        if cam is not None:
            if cam.source != "zenoh":
                self._warn(f"a camera named {name!r} is served on Zenoh, but this console already has a local "
                           "camera of that name: not shown")  # fmt: skip
                return
            remote = cam.cam
            assert isinstance(remote, SharedRemote)
            if alive and not remote.served:
                log.info("camera %s is served on Zenoh again", name)
                remote.back()
            elif not alive and remote.served:
                log.warning("camera %s: %s", name, GONE_REASON)
                remote.gone(GONE_REASON)
            return
        if alive and name not in self._opening:
            self._opening[name] = asyncio.create_task(self._open(name))

    async def _open(self, name: str) -> None:
        remote = SharedRemote(name, self.session, self.endpoints)
        try:
            await remote.open()
            if name not in self._alive:  # gone again while we asked
                await remote.close()
                return
            if not self._make_room(name):
                await remote.close()
                return
            hub = RemoteHub(remote, attitude_hz=self.attitude_hz)
            await hub.start()
            self.cameras.add(Camera(name, hub, "zenoh", remote.url, remote)).start_first_reads()
            log.info("camera %s (%s) found on Zenoh", name, remote.model.name)
        except asyncio.CancelledError:
            await remote.close()
            raise
        except Exception as exc:
            await remote.close()
            self._warn(f"camera {name!r} on Zenoh could not be opened: {exc}")
        finally:
            self._opening.pop(name, None)

    def _make_room(self, name: str) -> bool:
        if len(self.cameras) < self.cameras.max_cameras:
            return True
        gone = [c for c in self.cameras if c.source == "zenoh" and not c.served]
        if gone:
            oldest = min(gone, key=lambda c: c.added)
            self.cameras.remove(oldest.name)
            asyncio.create_task(oldest.close())  # noqa: RUF006 - closing; nothing waits for it
            log.info("camera %s (no longer served) makes room for %s", oldest.name, name)
            return True
        self.left_out += 1
        self._warn(f"camera {name!r} on Zenoh is not shown: this console shows at most "
                   f"{self.cameras.max_cameras} cameras ({self.left_out} left out so far)")  # fmt: skip
        return False

    def _warn(self, text: str) -> None:
        now = monotonic()
        if now - self._warned_at >= WARN_EVERY_S:
            self._warned_at = now
            log.warning("%s", text)
        else:
            log.debug("%s", text)


__all__ = ["GONE_REASON", "ZenohCameras"]
