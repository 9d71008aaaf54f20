"""D and M class camera functions: recording, photos, SD card, zoom, focus, digital zoom, day/night,
time, versions, model name, UID."""

from __future__ import annotations

from datetime import datetime
from typing import TYPE_CHECKING, Any

from ...protocol import Message
from ..dispatch import Ctx, Refuse, handles
from ..state import FOCUS_POS_MAX, PHOTO_MB, ZOOM_POS_MAX
from .common import fields, setting

if TYPE_CHECKING:
    from ..device import Device


@handles("REC")
def rec(dev: Device, msg: Message, ctx: Ctx) -> dict[str, Any] | None:
    cam = dev.camera
    if msg.frame.rw == "r":
        return {"state": "recording" if cam.recording else "stopped"}
    action = fields(msg)["action"]
    start = {"start": True, "stop": False, "toggle": not cam.recording}[action]
    if start and not cam.recording:
        if not cam.sd_present or cam.sd_remaining_mb <= 0:
            raise Refuse("no SD card / card full")
        cam.recording = True
        cam.record_started = ctx.now
        cam.record_index += 1
        dev.dirty = True
    elif not start:
        cam.recording = False
    if dev.dialect.name == "topotek":
        # §五.1: #tpDUAwREC11xxxxxxxx (started) / 00xxxxxxxx (stopped), file stream_0_<idx>.h264
        return {"state": "started" if cam.recording else "stopped", "file_index": cam.record_index}
    return None


@handles("CAP")
def cap(dev: Device, msg: Message, ctx: Ctx) -> dict[str, Any] | None:
    cam = dev.camera
    if not cam.sd_present or cam.sd_remaining_mb < PHOTO_MB:
        raise Refuse("no SD card / card full")
    cam.photos_taken += 1
    cam.photo_index += 1
    cam.sd_used_mb += PHOTO_MB
    dev.dirty = True
    if dev.dialect.name == "topotek":
        return {"state": "taken", "file_index": cam.photo_index}
    return None


@handles("SDC")
def sdc(dev: Device, msg: Message, ctx: Ctx) -> dict[str, Any]:
    cam = dev.camera
    if dev.dialect.name == "topotek":
        # §五.5: NNNNN = no card
        if not cam.sd_present:
            return {"capacity_mb": None}
        which = fields(msg).get("which", "remaining")
        return {"capacity_mb": min(0xFFFFF, cam.sd_total_mb if which == "total" else cam.sd_remaining_mb)}
    # SkyDroid §4.4: remaining and total, all zero = no card
    if not cam.sd_present:
        return {"remaining_mb": 0, "total_mb": 0}
    return {"remaining_mb": min(0xFFFFF, cam.sd_remaining_mb), "total_mb": min(0xFFFFF, cam.sd_total_mb)}


def zmp_report(dev: Device, ctx: Ctx) -> None:
    """TOPOTEK §三.4: magnification and zoom position go out after each zoom change."""
    if dev.dialect.name != "topotek":
        return
    cam = dev.camera
    ctx.notify(
        dev.dialect.notification(
            "ZMP", src="M", dst=ctx.host, magnification_x=min(99.9, cam.optical_zoom_x), zoom_pos=round(cam.zoom_pos)
        )
    )


@handles("ZMC")
def zmc(dev: Device, msg: Message, ctx: Ctx) -> None:
    cam = dev.camera
    action = fields(msg)["action"]
    was = cam.zoom_dir
    cam.zoom_dir = {"stop": 0, "zoom_in": 1, "zoom_out": -1}[action]
    if cam.optical_zoom_max <= 1.0:
        cam.zoom_dir = 0  # fixed lens: accepted, nothing moves
    dev._zoom_peer = (ctx.peer, ctx.host)
    if action == "stop" and was:
        dev.dirty = True
        zmp_report(dev, ctx)


@handles("FCC")
def fcc(dev: Device, msg: Message, ctx: Ctx) -> None:
    cam = dev.camera
    action = fields(msg)["action"]
    if action in ("focus_plus", "focus_minus"):
        cam.focus_dir = 1 if action == "focus_plus" else -1
        cam.autofocus = False
    elif action == "stop":
        cam.focus_dir = 0
    else:
        cam.focus_dir = 0
        cam.autofocus = action.startswith("auto")


@handles("ZFP")
def zfp(dev: Device, msg: Message, ctx: Ctx) -> None:
    f = fields(msg)
    cam = dev.camera
    cam.zoom_dir = 0
    cam.zoom_pos = float(max(0, min(ZOOM_POS_MAX, f["zoom_pos"]))) if cam.optical_zoom_max > 1 else 0.0
    if f.get("focus_pos") is None:
        cam.autofocus = True
    else:
        cam.focus_pos = float(max(0, min(FOCUS_POS_MAX, f["focus_pos"])))
    dev.dirty = True
    zmp_report(dev, ctx)


@handles("ZOM")
def zom(dev: Device, msg: Message, ctx: Ctx) -> dict[str, Any]:
    return {"zoom_pos": round(dev.camera.zoom_pos)}


@handles("FOC")
def foc(dev: Device, msg: Message, ctx: Ctx) -> dict[str, Any]:
    return {"focus_pos": round(dev.camera.focus_pos)}


@handles("MUL")
def mul(dev: Device, msg: Message, ctx: Ctx) -> dict[str, Any] | None:
    cam = dev.camera
    if msg.frame.rw == "r":
        return {"magnification_x": cam.optical_zoom_x}
    cam.zoom_dir = 0
    cam.set_magnification(float(fields(msg)["magnification_x"]))
    dev.dirty = True
    zmp_report(dev, ctx)
    return None


@handles("IRC")
def irc(dev: Device, msg: Message, ctx: Ctx) -> None:
    mode = fields(msg)["mode"]
    cam = dev.camera
    cam.day_night = ("night" if cam.day_night == "day" else "day") if mode == "toggle" else mode
    dev.dirty = True


@handles("DZM")
def dzm(dev: Device, msg: Message, ctx: Ctx) -> dict[str, Any] | None:
    cam = dev.camera
    f = fields(msg)
    if dev.dialect.name == "skydroid":
        # §4.7: 01..04 = 1..4x, 0A / 0B = one step in / out
        if msg.frame.rw == "r":
            return {"zoom": f"{max(1, min(4, round(cam.digital_zoom_x)))}x"}
        z = f["zoom"]
        if z == "zoom_in":
            cam.digital_zoom_x = min(cam.digital_zoom_max, round(cam.digital_zoom_x) + 1.0)
        elif z == "zoom_out":
            cam.digital_zoom_x = max(1.0, round(cam.digital_zoom_x) - 1.0)
        else:
            cam.digital_zoom_x = min(cam.digital_zoom_max, float(z.rstrip("x")))
        dev.dirty = True
        return None
    # TOPOTEK §五.14: lens 0 visible / 1 thermal; 00..80 = 0.1x steps; 0A/0B = +-0.5x; 0C/0D/0E run/stop
    if msg.frame.rw == "r":
        return {"thermal_zoom_x": min(9.9, cam.thermal_digital_zoom_x), "visible_zoom_x": min(9.9, cam.digital_zoom_x)}
    z = f["zoom"]
    thermal = f["lens"] == "thermal"
    cur = cam.thermal_digital_zoom_x if thermal else cam.digital_zoom_x
    if isinstance(z, str):
        if z in ("zoom_in", "zoom_out", "stop"):
            cam.digital_zoom_dir = {"zoom_in": 1, "zoom_out": -1, "stop": 0}[z]
            return None
        cur = cur + (0.5 if z == "step_in" else -0.5)
    else:
        cur = float(z)
    cur = round(max(1.0, min(cam.digital_zoom_max, cur)), 1)
    if thermal:
        cam.thermal_digital_zoom_x = cur
    else:
        cam.digital_zoom_x = cur
    dev.dirty = True
    return None


@handles("BIT")
def bit(dev: Device, msg: Message, ctx: Ctx) -> dict[str, Any] | None:
    result = setting(dev, msg, ctx)
    dev.camera.bitrate_kbps = int(dev.settings["BIT"]["bitrate_kbps"])
    return result


@handles("TIM", "UTC")
def tim(dev: Device, msg: Message, ctx: Ctx) -> None:
    t = fields(msg)["time"]
    if isinstance(t, datetime):
        dev.camera.time_set = t
        dev.camera.time_set_at = ctx.now


@handles("VSN")
def vsn(dev: Device, msg: Message, ctx: Ctx) -> dict[str, Any]:
    # §三.8: the lens answers its version (M3326); §五.16: the system answers a short one. ArduPilot
    # reads "1.2.3" or "123".
    return {"version": "M3326" if msg.frame.dst == "M" else "1.2.3"}


@handles("PA2")
def pa2(dev: Device, msg: Message, ctx: Ctx) -> dict[str, Any]:
    return {"model": dev.model.name}


@handles("UID")
def uid(dev: Device, msg: Message, ctx: Ctx) -> dict[str, Any] | None:
    if msg.frame.rw == "r":
        return {"uid": dev.uid}
    dev.uid = int(fields(msg)["uid"])
    dev.settings["UID"]["uid"] = dev.uid
    dev.dirty = True
    return None
