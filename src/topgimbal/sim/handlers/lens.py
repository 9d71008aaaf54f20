"""M class and digital zoom: zoom motor, focus, optical magnification, digital zoom, day / night.
A zoom change is reported by the model's zoom-report command where it has one (TOPOTEK ZMP)."""

from __future__ import annotations

from typing import Any

from ...protocol import Frame, Message
from ...protocol.fields import Enum, OneOf
from ..context import Request, SimState
from ..state import FOCUS_POS_MAX, ZOOM_POS_MAX
from .common import fields

# Digital zoom steps, by token name. TOPOTEK §五.14: 0A / 0B step 0.5x (`step_in` / `step_out`, also
# in the client forms both dialects take); SkyDroid §4.7: 0A / 0B one step of its 1x..4x table.
# Idempotent `zoom_in` / `zoom_out` / `stop` (TOPOTEK 0C..0E) run the zoom until stopped.
DIGITAL_STEP_X = {"step_in": 0.5, "step_out": -0.5, "zoom_in": 1.0, "zoom_out": -1.0}
DIGITAL_RUN = {"zoom_in": 1, "zoom_out": -1, "stop": 0}


def zoom_report(state: SimState, host: str) -> Frame | None:
    """The model's zoom report (TOPOTEK §三.4 ZMP), or None when it has none."""
    spec = state.dialect.by_role("zoom_report", state.model)
    if spec is None:
        return None
    cam = state.camera
    return state.dialect.notification(
        spec.ident,
        src=spec.address,
        dst=host,
        magnification_x=min(99.9, cam.optical_zoom_x),
        zoom_pos=round(cam.zoom_pos),
    )


def _notify_zoom(state: SimState, req: Request) -> None:
    frame = zoom_report(state, req.host)
    if frame is not None:
        req.notify(frame)


def zoom_control(state: SimState, msg: Message, req: Request) -> None:
    cam = state.camera
    action = fields(msg)["action"]
    was = cam.zoom_dir
    cam.zoom_dir = {"stop": 0, "zoom_in": 1, "zoom_out": -1}[action]
    if cam.optical_zoom_max <= 1.0:
        cam.zoom_dir = 0  # fixed lens: accepted, nothing moves
    state.zoom_host = (req.peer, req.host)
    if action == "stop" and was:
        state.dirty = True
        _notify_zoom(state, req)


def focus_control(state: SimState, msg: Message, req: Request) -> None:
    cam = state.camera
    action = fields(msg)["action"]
    cam.focus_dir = {"focus_plus": 1, "focus_minus": -1}.get(action, 0)
    if action in ("focus_plus", "focus_minus"):
        cam.autofocus = False
    elif action != "stop":
        cam.autofocus = action.startswith("auto")


def zoom_focus_position(state: SimState, msg: Message, req: Request) -> None:
    f = fields(msg)
    cam = state.camera
    cam.zoom_dir = 0
    cam.zoom_pos = float(max(0, min(ZOOM_POS_MAX, f["zoom_pos"]))) if cam.optical_zoom_max > 1 else 0.0
    if f.get("focus_pos") is None:
        cam.autofocus = True
    else:
        cam.focus_pos = float(max(0, min(FOCUS_POS_MAX, f["focus_pos"])))
    state.dirty = True
    _notify_zoom(state, req)


def zoom_position(state: SimState, msg: Message, req: Request) -> dict[str, Any]:
    return {"zoom_pos": round(state.camera.zoom_pos)}


def focus_position(state: SimState, msg: Message, req: Request) -> dict[str, Any]:
    return {"focus_pos": round(state.camera.focus_pos)}


def magnification(state: SimState, msg: Message, req: Request) -> dict[str, Any] | None:
    cam = state.camera
    if req.frame.rw == "r":
        return {"magnification_x": cam.optical_zoom_x}
    cam.zoom_dir = 0
    cam.set_magnification(float(fields(msg)["magnification_x"]))
    state.dirty = True
    _notify_zoom(state, req)
    return None


def day_night(state: SimState, msg: Message, req: Request) -> None:
    mode = fields(msg)["mode"]
    cam = state.camera
    cam.day_night = ("night" if cam.day_night == "day" else "day") if mode == "toggle" else mode
    state.dirty = True


def _token(msg: Message, name: str, value: object) -> tuple[str, bool] | None:
    """(name, idempotent) when `value` is a token of the field's enum, else None (a number)."""
    assert msg.form is not None
    codec = msg.form.field(name).codec
    table = codec.tokens if isinstance(codec, OneOf) else codec
    if not isinstance(value, str) or not isinstance(table, Enum):
        return None
    entry = table.lookup(value)
    return None if entry is None else (entry.name, entry.idempotent)


def digital_zoom(state: SimState, msg: Message, req: Request) -> dict[str, Any] | None:
    """Every DZM form of both dialects, told apart by their fields: the image (`lens` / `image`),
    then a zoom (a table value like `3x`, a number, a step or a run token) or a magnification."""
    cam = state.camera
    if req.frame.rw == "r":
        return _digital_zoom_answer(state, msg)
    f = fields(msg)
    # image code 01 is the thermal image in every form; what codes beyond 01 select is unknown
    # (errata E30): the simulator zooms the visible image for them
    thermal = f.get("lens", f.get("image")) == "thermal" or f.get("image_code") == 1
    current = cam.thermal_digital_zoom_x if thermal else cam.digital_zoom_x
    if "magnification_x" in f or "ratio_x" in f:
        target = float(f["magnification_x"] if "magnification_x" in f else f["ratio_x"])
    else:
        z = f["zoom"]
        token = _token(msg, "zoom", z)
        if token is None:
            target = float(z)
        elif token[0].endswith("x"):  # the SkyDroid table: 1x..4x
            target = float(token[0][:-1])
        elif token[1] and token[0] in DIGITAL_RUN:
            cam.digital_zoom_dir = DIGITAL_RUN[token[0]]
            return None
        else:
            target = (round(current) if token[0].startswith("zoom") else current) + DIGITAL_STEP_X[token[0]]
    target = round(max(1.0, min(cam.digital_zoom_max, target)), 1)
    if thermal:
        cam.thermal_digital_zoom_x = target
    else:
        cam.digital_zoom_x = target
    state.dirty = True
    return None


def _digital_zoom_answer(state: SimState, msg: Message) -> dict[str, Any]:
    """From the answer form's state keys: a table value (SkyDroid 1x..4x) or magnifications."""
    assert msg.spec is not None
    cam = state.camera
    out: dict[str, Any] = {}
    for f in msg.spec.forms_for("r", "response")[0].fields:
        x = cam.thermal_digital_zoom_x if f.state_key == "zoom.thermal_digital_x" else cam.digital_zoom_x
        if isinstance(f.codec, Enum):
            names = [v.name for v in f.codec.plain_values()]
            want = f"{max(1, round(x))}x"
            out[f.name] = want if want in names else names[-1]
        else:
            out[f.name] = min(x, 9.9)
    return out
