"""Frames the device sends on its own: attitude streams, temperature and range reports, and the
ZMP report when the zoom motor stops at an end."""

from __future__ import annotations

from collections.abc import Hashable
from typing import TYPE_CHECKING

from ...protocol import Frame
from ..dispatch import Ctx
from .camera import zmp_report
from .gimbal import attitude
from .ranging import result_frames
from .thermal import tmp_report

if TYPE_CHECKING:
    from ..device import Device, Stream


def stream_frame(dev: Device, s: Stream) -> Frame | None:
    if s.ident == "GAC":
        # SkyDroid §3.3.2.2 and TOPOTEK §四.3.4: GAC answers, sent unasked (#TPGUCrGAC...)
        return dev.report("GAC", src="G", dst=s.host, rw="r", **attitude(dev, earth=False))
    if s.ident == "GIA":
        # What ArduPilot reads: GIA frames whose first 12 data characters are yaw, pitch, roll.
        return dev.report("GIA", src="G", dst=s.host, rw="r", **attitude(dev, earth=True))
    if s.ident == "TMP":
        return tmp_report(dev, s.host)  # type: ignore[no-any-return]
    if s.ident == "LRF":
        frames = result_frames(dev, s.host)
        for extra in frames[1:]:
            dev._extra.append((extra, s.peer))
        return frames[0]
    return None


def pending_reports(dev: Device) -> list[tuple[Frame, Hashable]]:
    out = list(dev._extra)
    dev._extra.clear()
    if "zoom_stopped" in dev.camera.events:
        dev.camera.events.clear()
        if dev._zoom_peer is not None:
            peer, host = dev._zoom_peer
            ctx = Ctx(peer, Frame("#TP", host, "M", "w", "ZMC", b"00"), dev.now)
            zmp_report(dev, ctx)
            out += [(f, peer) for f in ctx.notes]
    return out
