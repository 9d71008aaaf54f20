"""One or more valid frames for every form of every command in the catalog, with sample values
taken from each codec's own metadata (`protocol.examples`), and what the Python decoder makes of
them: the reference the Wireshark dissector is compared with."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from topgimbal.errors import TopGimbalError
from topgimbal.protocol import REQUEST, Dialect, Form, Frame, decode_any, guess_dialects, make_frame
from topgimbal.protocol.examples import example_values
from topgimbal.wire.ports import documented_ports

from .tshark import values

HOST = ("127.0.0.1", 40000)
ANY_PORT = ("127.0.0.1", 7777)  # documented for no dialect: the frame decides


@dataclass(frozen=True)
class FormFrame:
    dialect: str
    ident: str
    form_index: int  # position in spec.forms
    frame: Frame
    src: tuple[str, int]
    dst: tuple[str, int]
    expected: dict[str, Any]  # expected(frame, dialect): what tshark must show


def device_port(dialect: str) -> int:
    return min(p for (t, p), d in documented_ports().items() if d == dialect and t == "udp" and p != 9004)


def form_label(form: Form) -> str:
    return f"{form.rw} {form.direction} {form.title}" + (f" {form.role}" if form.role else "")


def expected(frame: Frame, prefer: Dialect | str | None) -> dict[str, Any]:
    """What the Python decoder makes of `frame` with `prefer` first (`decode_any`): Message.to_dict()
    plus the form's label and the dialects tried before the one that decoded it."""
    msg = decode_any(frame, prefer=prefer)
    out = msg.to_dict()
    out["form"] = form_label(msg.form) if msg.form else None
    first = (
        (prefer if isinstance(prefer, str) else prefer.name) if prefer is not None else guess_dialects(frame)[0].name
    )
    out["tried"] = [first] if msg.fields is not None and msg.dialect != first else []
    return out


def _value_sets(form: Form) -> list[dict[str, Any]]:
    if form.const is not None or not form.fields:
        return [{}]
    pools = [example_values(f.codec) for f in form.fields]
    n = max(len(p) for p in pools)
    return [{f.name: pool[i % len(pool)] for f, pool in zip(form.fields, pools, strict=True)} for i in range(n)]


def form_frames(d: Dialect, port: int | None = None) -> list[FormFrame]:
    """Frames of every form of every command of `d`, each between the host and the device on
    `port` (default: the dialect's documented port), with what decode_any prefers there."""
    out: list[FormFrame] = []
    device = ("127.0.0.1", port if port is not None else device_port(d.name))
    prefer = documented_ports().get(("udp", device[1]))
    for ident in sorted(d.commands):
        spec = d.commands[ident]
        for k, form in enumerate(spec.forms):
            for sample in _value_sets(form):
                try:
                    data = form.encode(sample, ident)
                except TopGimbalError:
                    continue
                host = d.host_addresses[0]
                src, dst = (host, spec.address) if form.direction == REQUEST else (spec.address, host)
                header = d.header_for(spec, len(data), dst)
                frame = make_frame(ident, data, src=src, dst=dst, rw=form.rw, header=header)
                a, b = (HOST, device) if form.direction == REQUEST else (device, HOST)
                out.append(FormFrame(d.name, ident, k, frame, a, b, expected(frame, prefer)))
    return out


def mismatches(node: dict[str, Any], expected: dict[str, Any]) -> list[str]:
    """What the dissector shows differently from the Python decoder for one frame."""
    out = []
    if values(node, "top.id") != [expected["id"]]:
        out.append(f"id {values(node, 'top.id')}")
    if values(node, "top.dialect") != [expected["dialect"]]:
        out.append(f"dialect {values(node, 'top.dialect')} != {expected['dialect']}")
    if values(node, "top.dialect.tried") != expected["tried"]:
        out.append(f"tried first {values(node, 'top.dialect.tried')} != {expected['tried']}")
    want_form = [expected["form"]] if expected["form"] else []
    if values(node, "top.form") != want_form:
        out.append(f"form {values(node, 'top.form')} != {want_form}")
    if expected["name"] is not None and (expected["fields"] is None) != bool(values(node, "top.fields_error")):
        out.append(f"fields error {values(node, 'top.fields_error')} vs {expected['error']!r}")
    nulls = values(node, "top.field_null")
    for name, want in (expected["fields"] or {}).items():
        got = values(node, f"top.field.{name}")
        if want is None:
            if name not in nulls:
                out.append(f"{name}: null expected, got {got}")
        elif isinstance(want, (int, float)) and not isinstance(want, bool):
            ok = len(got) == 1 and (
                (math.isnan(want) and got[0].lower() == "nan")
                or (math.isinf(want) and float(got[0]) == want)
                or abs(float(got[0]) - want) <= 1e-9 * max(1.0, abs(want))
            )
            if not ok:
                out.append(f"{name}: {want!r} != {got}")
        elif got != [want]:
            out.append(f"{name}: {want!r} != {got}")
    return out
