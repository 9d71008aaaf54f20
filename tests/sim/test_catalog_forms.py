"""Every request form of every model, with real values from the catalog's metadata (factory values,
range ends, every table value), gets the reply a device gives: the echo, or an answer the catalog's
response form decodes carrying what the state holds. The error frame and silence are expected only
where the profile says the model refuses or drops the request, and each such case says why."""

from __future__ import annotations

from collections import Counter
from typing import Any

import pytest

from topgimbal.protocol import REQUEST, RESPONSE, CommandSpec, DeviceModel, Dialect, Form, Frame, all_models
from topgimbal.protocol.commands import factory_values
from topgimbal.protocol.fields import Enum, OneOf
from topgimbal.protocol.fields.enums import KEEP_NAMES
from topgimbal.protocol.signs import flip, resolve_signs
from topgimbal.sim import FakeClock
from topgimbal.sim.device import Device
from topgimbal.sim.handlers import camera, system, thermal
from topgimbal.sim.handlers.common import setting

from .conftest import frames
from .samples import same, samples

pytestmark = pytest.mark.virtual

MODELS = sorted(all_models())
# Handlers of stored settings (a write stores, a query answers what is stored).
STORED = (setting, camera.video_output, camera.bitrate, thermal.temperature_range, system.address)
COUNTS: Counter[str] = Counter()
WHY: Counter[str] = Counter()  # each reason for an error frame or silence, and how often


def build(model: str) -> Device:
    """A fresh device, set up so that what the catalog offers can happen: video output running
    (the needs_video_output quirk holds camera commands back until then: its own test covers it)
    and something in rangefinder range (20 m below, looked at 30 degrees down: 40 m)."""
    dev = Device(model, clock=FakeClock())
    dev.camera.video_output = True
    dev.position.alt_m = 20.0
    dev.gimbal.pitch_axis.pos = -30.0
    return dev


def request_forms(dialect: Dialect, model: DeviceModel) -> list[tuple[CommandSpec, Form, str]]:
    """(command, request form, destination) for everything a host may send this model."""
    out = []
    for spec in dialect.supported(model):
        for form in spec.forms:
            if form.direction == REQUEST:
                for dst in (spec.address, *spec.addresses):
                    out.append((spec, form, dst))
    return out


def refusal(dev: Device, spec: CommandSpec, form: Form, values: dict[str, Any]) -> str | None:
    """Why the model answers this request with the error frame, from its profile (None: it does not)."""
    m = dev.model
    for (ident, name), (lo, hi) in m.limits.items():
        v = values.get(name)
        if ident == spec.ident and isinstance(v, (int, float)) and not lo <= v <= hi:
            return f"{name}={v} is outside the {m.name}'s limit {lo:g}..{hi:g} (profile limits)"
    if spec.role == "temperature" and not m.thermal:
        return f"the {m.name} profile has no thermal camera"
    return None


def silence(dev: Device, spec: CommandSpec, form: Form) -> str | None:
    """Why the model sends nothing back (None: it answers)."""
    m, q = dev.model, dev.quirks
    if q["ignored_commands"] and spec.ident in m.ignored:
        return f"the {m.name} firmware drops {spec.ident} (profile ignored, quirk ignored_commands)"
    if form.rw == "w" and q["no_motion_echo"] and spec.ident in m.no_echo:
        return f"the {m.name} does not echo motion commands (profile no_echo, quirk no_motion_echo)"
    return None


def decoded(dev: Device, reply: Frame, request: Frame) -> dict[str, Any]:
    msg = dev.dialect.decode(reply)
    assert msg.fields is not None and msg.form is not None, (request, reply, msg.error)
    assert msg.form.direction == RESPONSE and reply.ident == request.ident and reply.rw == request.rw
    assert (reply.src, reply.dst) == (request.dst, request.src), (request, reply)
    return msg.fields


def expected_answer(dev: Device, spec: CommandSpec, request: Frame) -> dict[str, Any] | None:
    """What a fresh device's answer carries, by role, from the catalog and the profile."""
    role, m = spec.role, dev.model
    if role in ("version", "model_name", "hardware_version"):
        text = m.identity.get(f"{role}@{request.dst}") or m.identity[role]
        return {spec.forms_for("r", RESPONSE)[0].fields[0].name: text}
    if role in ("attitude", "earth_attitude"):  # on the wire: the model's signs apply
        return flip(spec, {"yaw_deg": 0.0, "pitch_deg": -30.0, "roll_deg": 0.0}, resolve_signs(m))
    if role == "range":
        return {"distance_m": 40.0}
    if role in ("attitude_stream", "earth_attitude_stream", "motors"):
        return {"state": "off" if role != "motors" else "on"}
    if dev.table[spec.ident] in STORED:
        return factory_values(spec)  # a stored setting, fresh from the factory: the catalog's values
    return None


def plain(form: Form, name: str, value: Any) -> bool:
    """Whether `value` is a value of its own (not a toggle, a relative step or "keep")."""
    codec = form.field(name).codec
    table = codec.tokens if isinstance(codec, OneOf) else codec
    if isinstance(table, Enum) and isinstance(value, str):
        entry = table.lookup(value)
        return entry is not None and entry.idempotent and entry.name not in KEEP_NAMES
    return True


def read_back(dev: Device, spec: CommandSpec, form: Form, values: dict[str, Any]) -> dict[str, Any]:
    """What a query answers after this write, for the fields both carry: what was written, except
    where the role says the device holds something else (its own limits)."""
    m = dev.model
    if spec.role == "optical_zoom":  # the lens stops at its ends
        return {"magnification_x": min(m.optical_zoom_max, max(1.0, values["magnification_x"]))}
    if spec.role == "digital_zoom":
        x = values.get("magnification_x", values.get("zoom"))
        if isinstance(x, str) and x.endswith("x"):
            x = float(x[:-1])
        if not isinstance(x, (int, float)):
            return {}  # a step or a run: relative to where it was
        x = round(min(m.digital_zoom_max, max(1.0, x)), 1)
        names = {f.name for f in spec.forms_for("r", RESPONSE)[0].fields}
        if "zoom" in names:  # SkyDroid: its 1x..4x table
            return {"zoom": f"{round(x)}x"}
        thermal = values.get("lens", values.get("image")) == "thermal"
        return {"thermal_zoom_x" if thermal else "visible_zoom_x": x}
    return {k: v for k, v in values.items() if plain(form, k, v)}


def send(dev: Device, request: Frame) -> list[Frame]:
    out: list[Frame] = []
    for o in dev.receive("host", request.to_bytes()):
        out += frames(o.data)
    COUNTS["frames"] += 1
    return out


def check(dev: Device, spec: CommandSpec, form: Form, dst: str, values: dict[str, Any], *, back: bool) -> None:
    d, m = dev.dialect, dev.model
    request = d.encode(spec.ident, read=form.rw == "r", form=form.title, src=m.host_address, dst=dst, **values)
    replies = send(dev, request)
    why = refusal(dev, spec, form, values)
    if why is not None:
        assert [f.ident for f in replies] == ["ERE"], (m.name, request, why, replies)
        COUNTS["refused"] += 1
        WHY[why] += 1
        return
    why = silence(dev, spec, form)
    if why is not None:
        assert replies == [], (m.name, request, why, replies)
        COUNTS["silent"] += 1
        WHY[why] += 1
        return
    assert replies and replies[0].ident == spec.ident, (m.name, request, replies)
    first = replies[0]
    if form.rw == "r":
        got = decoded(dev, first, request)
        want = expected_answer(dev, spec, request) if not back else None
        for name, value in (want or {}).items():
            codec = next(f.codec for f in dev.dialect.decode(first).form.fields if f.name == name)  # type: ignore[union-attr]
            assert same(codec, value, got[name]), (m.name, request, first, name, value, got)
        COUNTS["answered"] += 1
        return
    rule = m.echo_rules.get(spec.ident)
    if rule is None:
        assert first.to_bytes() == request.swapped().to_bytes(), (m.name, request, first)
    else:
        msg = d.decode(first)
        assert msg.form is not None and msg.form.title == rule, (m.name, request, first, msg)
    COUNTS["echoed"] += 1
    query = spec.forms_for("r", REQUEST)
    if not back or not query or query[0].const is None:
        return
    codecs = {f.name: f.codec for f in spec.forms_for("r", RESPONSE)[0].fields}
    want = {k: v for k, v in read_back(dev, spec, form, values).items() if k in codecs}
    if want:
        asked = d.encode(spec.ident, read=True, src=m.host_address, dst=dst)
        answer = decoded(dev, send(dev, asked)[0], asked)
        for name, value in want.items():
            assert same(codecs[name], value, answer[name]), (m.name, request, name, value, answer)
            COUNTS["read back"] += 1


@pytest.mark.parametrize("model", MODELS)
def test_every_request_form_gets_the_reply_a_device_gives(model: str) -> None:
    reads, writes = build(model), build(model)
    forms = request_forms(reads.dialect, reads.model)
    for spec, form, dst in forms:
        dev = reads if form.rw == "r" else writes
        for values in samples(form):
            check(dev, spec, form, dst, values, back=form.rw == "w")
    COUNTS["forms"] += len(forms)
    COUNTS["models"] += 1


def test_counts_of_what_ran() -> None:
    """Runs after the per-model test (same module, in order): says how much of the catalog ran."""
    if COUNTS["models"] != len(MODELS):
        pytest.fail("run the whole module: the per-model test fills the counts")
    print(f"\ncatalog-driven simulator test: {dict(COUNTS)}")
    for why, n in sorted(WHY.items()):
        print(f"  {n:4d} x {why}")
    # Every request form of every model ran (7 models, 367 forms with their destinations when
    # this was written); most frames are answered, not refused or dropped.
    assert COUNTS["forms"] >= 360 and COUNTS["frames"] >= 1300
    assert COUNTS["refused"] + COUNTS["silent"] < COUNTS["frames"] / 10
