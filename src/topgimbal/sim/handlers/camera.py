"""Camera functions: recording, photos, SD card, video output and bitrate, time, identity. What a
reply carries comes from the catalog: the answer form's fields and their state keys, and the
profile's identity strings and echo rules."""

from __future__ import annotations

import re
from datetime import datetime
from typing import Any

from ...protocol import RESPONSE, Message
from ..context import RefusedError, Request, SimState
from ..state import PHOTO_MB
from .common import fields, setting


def recording(state: SimState, msg: Message, req: Request) -> dict[str, Any] | None:
    """Start / stop / toggle; the values are the TOPOTEK feedback (`echo_rules`), else echoed."""
    cam = state.camera
    if req.frame.rw == "r":
        return {"state": "recording" if cam.recording else "stopped"}
    action = fields(msg)["action"]
    start = {"start": True, "stop": False, "toggle": not cam.recording}[action]
    if start and not cam.recording:
        if not cam.sd_present or cam.sd_remaining_mb <= 0:
            raise RefusedError("no SD card / card full")
        cam.recording = True
        cam.record_started = req.now
        cam.record_index += 1
        state.dirty = True
        _tell(state, "record_start", cam.record_index)
    elif not start and cam.recording:
        cam.recording = False
        _tell(state, "record_stop", cam.record_index)
    # TOPOTEK §五.1: #tpDUAwREC11xxxxxxxx (started) / 00xxxxxxxx (stopped), file stream_0_<idx>.h264
    return {"state": "started" if cam.recording else "stopped", "file_index": cam.record_index}


def photo(state: SimState, msg: Message, req: Request) -> dict[str, Any]:
    cam = state.camera
    if not cam.sd_present or cam.sd_remaining_mb < PHOTO_MB:
        raise RefusedError("no SD card / card full")
    cam.photos_taken += 1
    cam.photo_index += 1
    cam.sd_used_mb += PHOTO_MB
    state.dirty = True
    _tell(state, "photo", cam.photo_index)
    return {"state": "taken", "file_index": cam.photo_index}


def _tell(state: SimState, event: str, index: int) -> None:
    for listener in list(state.capture_listeners):
        listener(event, index)


def sd_card(state: SimState, msg: Message, req: Request) -> dict[str, Any]:
    """Answered field by field from the answer form's state keys. No card: a field that has a
    "none" spelling says so (TOPOTEK NNNNN), the others read 0 (SkyDroid all zeros)."""
    assert msg.spec is not None
    cam = state.camera
    total = cam.sd_total_mb if cam.sd_present else 0
    which = fields(msg).get("which", "remaining")
    known = {
        "sd.remaining_mb": cam.sd_remaining_mb,
        "sd.total_mb": total,
        "sd.capacity_mb": total if which == "total" else cam.sd_remaining_mb,
    }
    out: dict[str, Any] = {}
    for f in msg.spec.forms_for("r", RESPONSE)[0].fields:
        none = getattr(f.codec, "none_tokens", ())
        value = known.get(f.state_key or "", 0)
        out[f.name] = None if none and not cam.sd_present else min(value, 16 ** (f.codec.width or 1) - 1)
    return out


def video_output(state: SimState, msg: Message, req: Request) -> dict[str, Any] | None:
    """VOM: a stored setting whose `output` switch starts or stops the video output."""
    result = setting(state, msg, req)
    assert msg.spec is not None
    state.camera.video_output = state.settings[msg.spec.ident].get("output", "on") == "on"
    return result


def bitrate(state: SimState, msg: Message, req: Request) -> dict[str, Any] | None:
    result = setting(state, msg, req)
    assert msg.spec is not None
    state.camera.bitrate_kbps = int(state.settings[msg.spec.ident]["bitrate_kbps"])
    return result


def set_time(state: SimState, msg: Message, req: Request) -> None:
    t = fields(msg)["time"]
    if isinstance(t, datetime):
        state.camera.time_set = t
        state.camera.time_set_at = req.now


def identity(state: SimState, msg: Message, req: Request) -> dict[str, Any]:
    """Version, model name, hardware version, serial number: the profile's identity strings (the
    serial number is the simulator's own per seed). The answer's one field gets the text."""
    spec = msg.spec
    assert spec is not None
    role = spec.role
    if role == "serial_number":
        text = state.serial
    else:
        text = state.identity(role, req.frame.dst) or (state.model.name if role == "model_name" else "")
    if not text:
        raise RefusedError(f"the {state.model.name} profile names no {role}")
    own = f"{role}@{req.frame.dst}" in state.model.identity  # another part's version (SIP lens)
    if role == "version" and state.quirks.get("version_digits_only") and not own:
        text = re.sub(r"\D", "", text) or text
    return {spec.forms_for("r", RESPONSE)[0].fields[0].name: text}


def uid(state: SimState, msg: Message, req: Request) -> dict[str, Any] | None:
    assert msg.spec is not None
    if req.frame.rw == "r":
        return {"uid": state.uid}
    state.uid = int(fields(msg)["uid"])
    state.settings.setdefault(msg.spec.ident, {})["uid"] = state.uid
    state.dirty = True
    return None
