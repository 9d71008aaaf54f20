"""G class: PTZ codes, speed and angle commands, attitude queries and streams, motors, vehicle
attitude input, tracking. Values are in the API sign convention (the device maps wire signs)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from ...protocol import Message
from ..dispatch import Ctx, Refuse, Reply, handles
from ..physics import wrap180
from .common import fields

if TYPE_CHECKING:
    from ..device import Device

NUDGE_FRACTION = 0.5  # PTZ up/down/left/right move at this fraction of the model's rate limit
TRIM_STEP_DEG = 0.1


def axis_fields(msg: Message) -> list[tuple[str, str]]:
    """(axis, field name) of the request's gimbal-axis fields, from the catalog's metadata."""
    assert msg.form is not None
    return [(f.axis, f.name) for f in msg.form.fields if f.axis]


@handles("PTZ")
def ptz(dev: Device, msg: Message, ctx: Ctx) -> None:
    g = dev.gimbal
    action = fields(msg)["action"]
    nudge = dev.model.max_rate_deg_s * NUDGE_FRACTION
    if action == "stop":
        g.stop()
    elif action in ("up", "down"):
        g.rate("pitch", nudge if action == "up" else -nudge)
    elif action in ("left", "right"):
        g.rate("yaw", nudge if action == "right" else -nudge)
    elif action == "center":
        g.center()
    elif action in ("follow", "lock"):
        g.set_mode(action)
        dev.dirty = True
    elif action == "toggle_follow_lock":
        g.set_mode("lock" if g.mode == "follow" else "follow")
        dev.dirty = True
    elif action.startswith("calibrate"):
        g.calibrations += 1
        g.center()
    elif action == "look_down":
        g.angle("pitch", max(-90.0, dev.model.pitch_range_deg[0]))
        g.angle("yaw", 0.0)
    elif action in ("mount_hanging", "mount_inverted"):
        g.mount = action.removeprefix("mount_")
        dev.dirty = True
    elif action.startswith("trim_"):
        if action == "trim_clear":
            g.trims = {"x": 0.0, "y": 0.0, "z": 0.0}
        else:
            axis, sign = action[5], (1 if action.endswith("plus") else -1)
            g.trims[axis] = round(g.trims[axis] + sign * TRIM_STEP_DEG, 3)
        dev.dirty = True
    else:  # pragma: no cover - every catalog value is handled above
        raise Refuse(f"PTZ {action}")


@handles("GSY", "GSP", "GSR", "GSM", "RPS", "YPR")
def rates(dev: Device, msg: Message, ctx: Ctx) -> None:
    f = fields(msg)
    for axis, name in axis_fields(msg):
        dev.gimbal.rate(axis, float(f[name]))


@handles("GAY", "GAP", "GAR", "GAM", "GIY", "GIP", "GIR", "GIM")
def angles(dev: Device, msg: Message, ctx: Ctx) -> None:
    f = fields(msg)
    ident = msg.frame.ident
    frame = "earth" if ident.startswith("GI") else "body"
    for axis, name in axis_fields(msg):
        speed = f.get("speed_deg_s", f.get(f"{axis}_speed_deg_s"))
        dev.gimbal.angle(axis, float(f[name]), None if speed is None else float(speed), frame)


def attitude(dev: Device, earth: bool) -> dict[str, Any]:
    y, p, r = dev.gimbal.earth() if earth else dev.gimbal.body()
    return {
        "yaw_deg": round(y, 2),
        "pitch_deg": round(p, 2),
        "roll_deg": round(r, 2),
    }


@handles("GAC")
def gac(dev: Device, msg: Message, ctx: Ctx) -> dict[str, Any]:
    return attitude(dev, earth=False)


@handles("GIC")
def gic(dev: Device, msg: Message, ctx: Ctx) -> dict[str, Any]:
    return attitude(dev, earth=True)


@handles("GAA")
def gaa(dev: Device, msg: Message, ctx: Ctx) -> dict[str, Any] | None:
    f = fields(msg)
    if msg.frame.rw == "r":
        return {"state": "on" if dev.subscribed(ctx.peer, "GAC") else "off"}
    if "rate_hz" in f:  # SkyDroid: 1..100 Hz, 0 = off
        dev.subscribe(ctx, "GAC", float(f["rate_hz"]))
    else:
        dev.subscribe(ctx, "GAC", dev.topotek_stream_hz if f["state"] == "on" else 0.0)
    return None


@handles("GIA")
def gia(dev: Device, msg: Message, ctx: Ctx) -> dict[str, Any] | None:
    f = fields(msg)
    if msg.frame.rw == "r":
        return {"state": "on" if dev.subscribed(ctx.peer, "GIA") else "off"}
    dev.subscribe(ctx, "GIA", dev.topotek_stream_hz if f["state"] == "on" else 0.0)
    return None


@handles("GMS")
def gms(dev: Device, msg: Message, ctx: Ctx) -> dict[str, Any] | None:
    if msg.frame.rw == "r":
        return {"state": "on" if dev.gimbal.motors_on else "off"}
    dev.gimbal.set_motors(fields(msg)["state"] == "on")
    return None


@handles("FAE")
def fae(dev: Device, msg: Message, ctx: Ctx) -> None:
    dev.vehicle_input = fields(msg)["state"] == "on"


@handles("FAI")
def fai(dev: Device, msg: Message, ctx: Ctx) -> None:
    """SkyDroid C12 vehicle attitude (the document gives GAC's convention: yaw right, pitch up)."""
    f = fields(msg)
    if dev.vehicle_input:
        v = dev.gimbal.vehicle
        v.yaw = wrap180(f["yaw_deg"])
        v.pitch = float(f["pitch_deg"])
        v.roll = float(f["roll_deg"])


@handles("UAV")
def uav(dev: Device, msg: Message, ctx: Ctx) -> None:
    """TOPOTEK vehicle attitude struct: yaw 0..360; its pitch is down-positive on the wire, which
    the field's sign metadata already undid (fields arrive in the API convention)."""
    f = fields(msg)
    v = dev.gimbal.vehicle
    v.yaw = wrap180(f["yaw_deg"])
    v.pitch = float(f["pitch_deg"])
    v.roll = float(f["roll_deg"])
    dev.position.speed_m_s = float(f["speed_m_s"])


@handles("VER")
def ver(dev: Device, msg: Message, ctx: Ctx) -> dict[str, Any]:
    if dev.dialect.name == "topotek":
        return {"serial": dev.serial}  # G class: serial number (14 characters)
    return {"version": VERSIONS.get(dev.model.name, "V1.0.0")}


# The real C12 answers 010502 (and with a wrong length character; see quirks).
VERSIONS = {"C12": "010502", "C10": "V1.2.0", "C10Pro": "V1.2.0", "C13": "V1.1.0", "C20": "V1.0.3"}


@handles("SUM")
def sum_(dev: Device, msg: Message, ctx: Ctx) -> None:
    dev.camera.tracking = (
        "tracking" if fields(msg)["action"] == "confirm" and dev.camera.tracking != "stopped" else "stopped"
    )


@handles("GOT")
def got(dev: Device, msg: Message, ctx: Ctx) -> None:
    dev.camera.tracking = "tracking"


@handles("TRC")
def trc(dev: Device, msg: Message, ctx: Ctx) -> dict[str, Any] | Reply | None:
    cam = dev.camera
    if msg.frame.rw == "r":
        return {"reserved": "30", "state": cam.tracking}
    cam.tracking = "waiting" if fields(msg)["action"] == "start" else "stopped"
    return None


@handles("LOC")
def loc(dev: Device, msg: Message, ctx: Ctx) -> None:
    if dev.camera.tracking == "stopped":
        dev.camera.tracking = "waiting"
    f = fields(msg)
    if f["width_px"] > 0 and f["height_px"] > 0:
        dev.camera.tracking = "tracking"
