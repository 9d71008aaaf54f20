"""Offline protocol subcommands: `decode`, `encode`, `catalog`. No device needed."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Iterable
from typing import Any

from ..errors import FieldValueError, UnknownCommandError
from ..protocol import DIALECT_NAMES, Dialect, get_dialect, get_model
from ..protocol.catalog import REQUEST
from ..protocol.decoded import RECORD_KEYS, decode_line, decode_with, dissection_record
from ..protocol.decoded import failed_record as _failed
from ..protocol.decoded import human_text as _human
from ..protocol.decoded import show_data as _show_data
from .args import add_dialect_argument, add_json_argument, add_pcap_arguments, dialect_from_args

# json is imported by the functions that print it: most runs print text (a fast start, cli/main.py).

__all__ = ["RECORD_KEYS", "decode_line", "decode_with", "dissection_record", "register"]


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("decode", help="decode frames given as arguments or one per line on stdin")
    p.add_argument(
        "frames",
        nargs="*",
        metavar="FRAME",
        help="frame text, e.g. '#TPUG2wPTZ006A' (binary bytes as encode prints them: \\xNN, \\\\ for a backslash)",
    )
    p.add_argument("--hex", action="store_true", help="frames are given as hex (binary data: GPS, UAV, LOC)")
    add_dialect_argument(p)
    add_json_argument(p)
    add_pcap_arguments(p)  # decode --pcap runs in wire_cmds, with the other capture tools
    p.set_defaults(func=cmd_decode)

    p = sub.add_parser("encode", help="print the frame for a command: encode GAY yaw_deg=-50 --dialect skydroid")
    p.add_argument("ident", metavar="ID", help="3-character identifier (or the command's name)")
    p.add_argument("values", nargs="*", metavar="NAME=VALUE", help="field values in user units")
    add_dialect_argument(p, auto=True)
    p.add_argument("--read", action="store_true", help="the query (r) form instead of the write (w) form")
    p.add_argument("--src", help="source address (default: the dialect's host address)")
    p.add_argument("--dst", help="destination address (default: the command's)")
    p.add_argument("--header", choices=["#TP", "#tp", "#tP", "#Tp"], help="force a header")
    p.add_argument("--form", metavar="TITLE", help="pick a form by its title (`catalog ID` lists them)")
    add_json_argument(p)
    p.set_defaults(func=cmd_encode)

    p = sub.add_parser("catalog", help="list the commands of a dialect, or show one command's fields")
    p.add_argument("ident", nargs="?", metavar="ID")
    add_dialect_argument(p, auto=True)
    add_json_argument(p)
    p.set_defaults(func=cmd_catalog)


# -- dialect choice -------------------------------------------------------------------------------


_dialect_from_args = dialect_from_args  # its old name (cli/wire_cmds.py, tests)


# -- decode ---------------------------------------------------------------------------------------


def _inputs(frames: list[str]) -> Iterable[str]:
    if frames:
        yield from frames
        return
    for line in sys.stdin:
        if line.strip():
            yield line


def cmd_decode(args: argparse.Namespace) -> int:
    """Every input line gets one record, whatever it holds; the exit status is 1 when any line is
    not a good frame or its fields could not be named (the records say which and why)."""
    if getattr(args, "pcap", None):
        from .wire_cmds import decode_pcap

        return decode_pcap(args)
    dialect = _dialect_from_args(args)
    if args.json:
        from .. import jsonl  # json Lines without a line breaker inside a string (jsonl.py)
    bad = 0
    for line in _inputs(args.frames):
        try:
            rec = decode_line(line, as_hex=args.hex, dialect=dialect)
        except Exception as exc:
            rec = _failed(_show_data(line.strip().encode("latin-1", "replace")) or "", f"internal error: {exc!r}")
        bad += not rec["ok"] or rec["fields_error"] is not None
        print(jsonl.line(rec) if args.json else _human(rec))
    return 1 if bad else 0


# -- encode ---------------------------------------------------------------------------------------


def _parse_values(
    dialect: Dialect, ident: str, read: bool, pairs: list[str], form_title: str | None = None
) -> dict[str, Any]:
    spec = dialect.command(ident)
    keys = []
    for p in pairs:
        if "=" not in p:
            raise FieldValueError(p, p, "NAME=VALUE")
        keys.append(p.split("=", 1)[0])
    rw = "r" if read else "w"
    form = spec.form(form_title, rw, REQUEST) if form_title else spec.request_form(rw, keys)
    codecs = {f.name: f.codec for f in form.fields}
    values: dict[str, Any] = {}
    for p in pairs:
        k, v = p.split("=", 1)
        if k not in codecs:
            raise FieldValueError(k, v, f"a field of {spec.ident}: {', '.join(codecs) or 'no fields'}")
        try:
            values[k] = codecs[k].parse_text(v)
        except ValueError:
            raise FieldValueError(k, v, codecs[k].allowed()) from None
    return values


def cmd_encode(args: argparse.Namespace) -> int:
    dialect = _dialect_from_args(args)
    if dialect is None:
        raise UnknownCommandError("encode needs --dialect skydroid|topotek (or --model)")
    values = _parse_values(dialect, args.ident, args.read, args.values, args.form)
    if args.model:
        _, model = get_model(args.model)
        dialect.check_values(model, dialect.command(args.ident).ident, values)
    frame = dialect.encode(
        args.ident, read=args.read, src=args.src, dst=args.dst, header=args.header, form=args.form, **values
    )
    if args.json:
        import json

        print(json.dumps({"frame": frame.text(), "hex": frame.to_bytes().hex(), "dialect": dialect.name}))
    else:
        print(frame.text())
    return 0


# -- catalog --------------------------------------------------------------------------------------


def model_limits(dialect: Dialect, ident: str) -> dict[str, dict[str, tuple[float, float]]]:
    """{model: {field: (lo, hi)}} where a model's profile narrows `ident`'s field ranges (the C12's
    pitch to -45..45): what that model accepts, next to the catalog's field range."""
    spec = dialect.command(ident)
    angles = {
        f.name: (f.axis, f.codec) for form in spec.forms for f in form.fields if f.sign_kind == "angle" and f.axis
    }
    out: dict[str, dict[str, tuple[float, float]]] = {}
    for name, model in dialect.models.items():
        if not dialect.supports(model, ident):
            continue
        narrowed: dict[str, tuple[float, float]] = {}
        for field_name, (axis, codec) in angles.items():  # the model's gimbal range for the axis
            lo, hi = getattr(model, f"{axis}_range_deg")
            cmin, cmax = getattr(codec, "min", None), getattr(codec, "max", None)
            if (cmin is not None and lo > cmin) or (cmax is not None and hi < cmax):
                narrowed[field_name] = (lo, hi)
        for (lim_ident, field_name), (lo, hi) in model.limits.items():
            if lim_ident == ident:
                old = narrowed.get(field_name, (lo, hi))
                narrowed[field_name] = (max(lo, old[0]), min(hi, old[1]))
        if narrowed:
            out[name] = narrowed
    return out


def cmd_catalog(args: argparse.Namespace) -> int:
    dialects = [_dialect_from_args(args)] if _dialect_from_args(args) else [get_dialect(n) for n in DIALECT_NAMES]
    if args.ident:
        out: list[dict[str, Any]] = []
        for d in dialects:
            assert d is not None
            if args.ident.upper() not in d.commands:
                continue
            spec = d.command(args.ident)
            entry: dict[str, Any] = {"dialect": d.name, **spec.describe()}
            entry["models"] = entry["models"] or sorted(d.models)
            entry["model_limits"] = model_limits(d, spec.ident)
            out.append(entry)
        if not out:
            raise UnknownCommandError(f"{args.ident!r} is in no catalog")
        if args.json:
            import json

            print(json.dumps(out, ensure_ascii=False, indent=2))
        else:
            for e in out:
                print(f"{e['dialect']} {e['id']} ({e['name']}): {e['title']}  -> {e['address']}  [{e['section']}]")
                print(f"    role: {e['role'] or '-'}  group: {e['group'] or '-'}  models: {', '.join(e['models'])}")
                for model, limits in e["model_limits"].items():
                    narrowed = ", ".join(f"{name} {lo:g}..{hi:g}" for name, (lo, hi) in limits.items())
                    print(f"    on the {model} (its profile): {narrowed}")
                for f in e["forms"]:
                    arrow = "host->device" if f["direction"] == REQUEST else "device->host"
                    body = (
                        f"data {f['const']!r}"
                        if f["const"]
                        else ", ".join(f"{x['name']} ({x['allowed']})" for x in f["fields"]) or "no data"
                    )
                    where = f" [{f['section']}]" if f["section"] else ""
                    print(f"    {f['rw']} {arrow} {f['title']}{where}: {body}")
        return 0
    rows = []
    for d in dialects:
        assert d is not None
        for spec in d.commands.values():
            rw = ("r" if spec.readable else "") + ("w" if spec.writable else "")
            rows.append(
                {
                    "dialect": d.name,
                    "id": spec.ident,
                    "name": spec.name,
                    "rw": rw or "-",
                    "address": spec.address,
                    "title": spec.title,
                }
            )
    if args.json:
        from .. import jsonl

        print(jsonl.line(rows))
    else:
        for r in rows:
            print(f"{r['dialect']:<9} {r['id']}  {r['rw']:<2} {r['address']}  {r['name']:<26} {r['title']}")
    return 0
