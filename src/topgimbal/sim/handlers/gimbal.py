"""G class: control codes, rate and angle commands, attitude answers and streams, motors, the
vehicle's attitude, tracking. Values are in the API sign convention (the device maps wire signs).
Which command does what comes from its catalog role; which axes it moves from its fields' `axis`."""

from __future__ import annotations

from typing import Any

from ...protocol import Frame, Message
from ..context import Reply, Request, SimState
from ..physics import AXES, wrap180
from ..streams import ReportFn, Stream
from ..tracker import POINT_BOX
from .common import fields

NUDGE_FRACTION = 0.5  # PTZ up/down/left/right move at this fraction of the model's rate limit
TRIM_STEP_DEG = 0.1
# A missed stop (the stop_coasts quirk) lets the gimbal run on for a time drawn from this range,
# from the device's seeded generator: the same seed and commands always coast the same way.
COAST_S = (0.15, 0.5)


def axis_fields(msg: Message) -> list[tuple[str, str]]:
    """(axis, field name) of the request's gimbal-axis fields, from the catalog's metadata."""
    assert msg.form is not None
    return [(f.axis, f.name) for f in msg.form.fields if f.axis]


def halt(state: SimState, req: Request, axes: tuple[str, ...] = AXES) -> None:
    """A stop of `axes`. With the stop_coasts quirk the first stop of a move is missed for a short
    while (the gimbal keeps its speed); a repeated stop halts it at once."""
    g = state.gimbal
    moving = any(g.axis(a).mode == "rate" and g.axis(a).rate_cmd for a in axes)
    if state.quirks.get("stop_coasts") and moving and state.coast_until is None:
        state.coast_until = req.now + state.rng.uniform(*COAST_S)
        state.coast_axes = axes
        return
    state.coast_until, state.coast_axes = None, ()
    for a in axes:
        if g.axis(a).mode == "rate":
            g.rate(a, 0.0)


def control(state: SimState, msg: Message, req: Request) -> None:
    """Control codes (PTZ): each dialect's table names them alike."""
    g = state.gimbal
    action = fields(msg)["action"]
    nudge = state.model.max_rate_deg_s * NUDGE_FRACTION
    if action == "stop":
        halt(state, req)
        return
    state.coast_until = None
    if action in ("up", "down"):
        g.rate("pitch", nudge if action == "up" else -nudge)
    elif action in ("left", "right"):
        g.rate("yaw", nudge if action == "right" else -nudge)
    elif action == "center":
        g.center()
    elif action in ("follow", "lock"):
        g.set_mode(action)
        state.dirty = True
    elif action == "toggle_follow_lock":
        g.set_mode("lock" if g.mode == "follow" else "follow")
        state.dirty = True
    elif action.startswith("calibrate"):
        g.calibrations += 1
        g.center()
    elif action == "look_down":
        g.angle("pitch", max(-90.0, state.model.pitch_range_deg[0]))
        g.angle("yaw", 0.0)
    elif action.startswith("mount_"):
        g.mount = action.removeprefix("mount_")
        state.dirty = True
    elif action.startswith("trim_"):
        if action == "trim_clear":
            g.trims = {"x": 0.0, "y": 0.0, "z": 0.0}
        else:
            axis, sign = action[5], (1 if action.endswith("plus") else -1)
            g.trims[axis] = round(g.trims[axis] + sign * TRIM_STEP_DEG, 3)
        state.dirty = True


def rates(state: SimState, msg: Message, req: Request) -> None:
    f = fields(msg)
    moved = axis_fields(msg)
    if all(not f[name] for _, name in moved):
        halt(state, req, tuple(axis for axis, _ in moved))
        return
    state.coast_until = None
    for axis, name in moved:
        state.gimbal.rate(axis, float(f[name]))


def angles(state: SimState, msg: Message, req: Request) -> None:
    assert msg.spec is not None
    f = fields(msg)
    frame = "earth" if msg.spec.role == "earth_angle" else "body"
    state.coast_until = None
    for axis, name in axis_fields(msg):
        speed = f.get("speed_deg_s", f.get(f"{axis}_speed_deg_s"))
        state.gimbal.angle(axis, float(f[name]), None if speed is None else float(speed), frame)


def reported(state: SimState, earth: bool) -> tuple[float, float, float]:
    """The attitude a frame carries: the earth frame (TOPOTEK GIC / GIA); else TOPOTEK's GAC the
    encoders (its document: body frame), SkyDroid's GAC pitch and roll from the horizon (physics.py)."""
    if earth:
        return state.gimbal.earth()
    return state.gimbal.body() if state.dialect.name == "topotek" else state.gimbal.horizon()


def attitude(state: SimState, earth: bool) -> dict[str, float]:
    y, p, r = reported(state, earth)
    return {"yaw_deg": round(y, 2), "pitch_deg": round(p, 2), "roll_deg": round(r, 2)}


def body_attitude(state: SimState, msg: Message, req: Request) -> dict[str, Any]:
    return attitude(state, earth=False)


def earth_attitude(state: SimState, msg: Message, req: Request) -> dict[str, Any]:
    return attitude(state, earth=True)


def attitude_report(ident: str, earth: bool) -> ReportFn:
    """A stream of `ident` frames carrying the attitude; while the gimbal holds still the same
    frame is sent again without encoding it anew."""

    def report(state: SimState, s: Stream) -> list[Frame]:
        y, p, r = reported(state, earth)
        key = (round(y, 2), round(p, 2), round(r, 2))
        if key != s.memo_key or not s.memo_frames:
            frame = state.report(ident, dst=s.host, rw="r", yaw_deg=key[0], pitch_deg=key[1], roll_deg=key[2])
            s.memo_key, s.memo_frames = key, [frame]
        return s.memo_frames

    return report


def _switch_stream(state: SimState, msg: Message, req: Request, ident: str, earth: bool) -> dict[str, Any] | None:
    """Attitude output on / off (TOPOTEK) or at a rate (SkyDroid, 0 = off), for the host that asked."""
    assert msg.spec is not None
    if req.frame.rw == "r":
        return {"state": "on" if state.streams.subscribed(req.peer, ident) else "off"}
    f = fields(msg)
    if "rate_hz" in f:
        asked = float(f["rate_hz"])
        rate = state.stream_rate(msg.spec.ident, asked) if asked > 0 else 0.0
    else:
        rate = state.stream_rate(msg.spec.ident, None) if f.get("state") == "on" else 0.0
    state.subscribe(req, ident, rate, attitude_report(ident, earth))
    return None


def attitude_stream(state: SimState, msg: Message, req: Request) -> dict[str, Any] | None:
    """GAA: streams the body-frame attitude command's frames (GAC)."""
    spec = state.dialect.require_role("attitude", state.model)
    return _switch_stream(state, msg, req, spec.ident, earth=False)


def earth_attitude_stream(state: SimState, msg: Message, req: Request) -> dict[str, Any] | None:
    """TOPOTEK GIA: the switch and the stream are one identifier; ArduPilot reads the stream."""
    assert msg.spec is not None
    return _switch_stream(state, msg, req, msg.spec.ident, earth=True)


def motors(state: SimState, msg: Message, req: Request) -> dict[str, Any] | None:
    if req.frame.rw == "r":
        return {"state": "on" if state.gimbal.motors_on else "off"}
    state.gimbal.set_motors(fields(msg)["state"] == "on")
    return None


def vehicle_attitude_enable(state: SimState, msg: Message, req: Request) -> None:
    state.vehicle_input = fields(msg)["state"] == "on"


def vehicle_attitude(state: SimState, msg: Message, req: Request) -> None:
    """The vehicle's attitude from the host (SkyDroid FAI after FAE; TOPOTEK UAV, whose pitch the
    field's own sign metadata already turned into the API convention)."""
    f = fields(msg)
    if not state.vehicle_input:
        return
    v = state.gimbal.vehicle
    state.vehicle_heard = True
    v.yaw = wrap180(f["yaw_deg"])
    v.pitch = float(f["pitch_deg"])
    v.roll = float(f["roll_deg"])
    if "speed_m_s" in f:
        state.position.speed_m_s = float(f["speed_m_s"])


# The camera's own tracker (sim/tracker.py) behind the tracking commands. What the documents leave
# open is decided in docs/errata.md (E41): a SkyDroid GOT point starts tracking at
# once (SUM 01 confirms it, SUM 00 stops); TOPOTEK's LOC box starts it (TRC 01 / 02 only arm), and
# a lost target reads back as TRC state 1 (waiting for a new box), the code the firmware has.
GOT_PICTURE = (1280.0, 720.0)  # the GOT fields' picture (the catalog's field ranges)
LOC_HALF_SPAN = 1000.0  # LOC: centre 0, edges -1000 / +1000 on each axis (video/lens.py)


def tracking_confirm(state: SimState, msg: Message, req: Request) -> None:
    if fields(msg)["action"] != "confirm":
        state.set_tracking("stopped")
    # A confirm keeps what GOT started; with nothing started there is nothing to confirm.


def tracking_target(state: SimState, msg: Message, req: Request) -> None:
    f = fields(msg)
    w, h = GOT_PICTURE
    state.start_tracking(req.now, (f["x_px"] / w, f["y_px"] / h, POINT_BOX, POINT_BOX * w / h))


def tracking(state: SimState, msg: Message, req: Request) -> dict[str, Any] | Reply | None:
    cam = state.camera
    if req.frame.rw == "r":
        return {"reserved": "30", "state": "waiting" if cam.tracking == "lost" else cam.tracking}
    state.set_tracking("waiting" if fields(msg)["action"] in ("start", "ready") else "stopped")
    return None


def tracking_box(state: SimState, msg: Message, req: Request) -> None:
    f = fields(msg)
    if f["width_px"] > 0 and f["height_px"] > 0:
        s = LOC_HALF_SPAN
        box = ((f["x_px"] / s + 1) / 2, (f["y_px"] / s + 1) / 2, f["width_px"] / (2 * s), f["height_px"] / (2 * s))
        state.start_tracking(req.now, box)
    elif state.camera.tracking == "stopped":
        state.set_tracking("waiting")
