"""One or more valid frames for every form of every command in the catalog, with sample values
taken from each codec's own metadata (the protocol tests' `samples()`), and what the Python
decoder makes of them: the reference the Wireshark dissector is compared with."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from topgimbal.errors import TopGimbalError
from topgimbal.protocol import DIALECT_NAMES, REQUEST, Form, Frame, get_dialect, make_frame
from topgimbal.protocol.examples import example_values as samples
from topgimbal.wire.ports import documented_ports

HOST = ("127.0.0.1", 40000)


@dataclass(frozen=True)
class FormFrame:
    dialect: str
    ident: str
    form_index: int  # position in spec.forms
    frame: Frame
    src: tuple[str, int]
    dst: tuple[str, int]
    expected: dict[str, Any]  # Message.to_dict() plus "form"


def device_port(dialect: str) -> int:
    return min(p for (t, p), d in documented_ports().items() if d == dialect and t == "udp" and p != 9004)


def form_label(form: Form) -> str:
    return f"{form.rw} {form.direction} {form.title}" + (f" {form.role}" if form.role else "")


def _value_sets(form: Form) -> list[dict[str, Any]]:
    if form.const is not None or not form.fields:
        return [{}]
    pools = [samples(f.codec) for f in form.fields]
    n = max(len(p) for p in pools)
    return [{f.name: pool[i % len(pool)] for f, pool in zip(form.fields, pools, strict=True)} for i in range(n)]


def form_frames() -> list[FormFrame]:
    out: list[FormFrame] = []
    for name in DIALECT_NAMES:
        d = get_dialect(name)
        device = ("127.0.0.1", device_port(name))
        for ident in sorted(d.commands):
            spec = d.commands[ident]
            for k, form in enumerate(spec.forms):
                for values in _value_sets(form):
                    try:
                        data = form.encode(values, ident)
                    except TopGimbalError:
                        continue
                    host = d.host_addresses[0]
                    src, dst = (host, spec.address) if form.direction == REQUEST else (spec.address, host)
                    header = d.header_for(spec, len(data), dst)
                    frame = make_frame(ident, data, src=src, dst=dst, rw=form.rw, header=header)
                    msg = d.decode(frame)
                    expected = msg.to_dict()
                    expected["form"] = form_label(msg.form) if msg.form else None
                    a, b = (HOST, device) if form.direction == REQUEST else (device, HOST)
                    out.append(FormFrame(name, ident, k, frame, a, b, expected))
    return out
