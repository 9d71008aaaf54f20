"""Offline protocol subcommands: `decode`, `encode`, `catalog`. No device needed."""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Iterable
from typing import Any

from ..errors import FieldValueError, UnknownCommandError
from ..protocol import DIALECT_NAMES, Dialect, Dissection, Message, decode_any, dissect, get_dialect, get_model
from ..protocol.catalog import REQUEST
from ..protocol.frame import Frame, bytes_from_text
from .args import add_dialect_argument, add_json_argument


def register(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
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
    from .wire_cmds import add_pcap_arguments  # decode --pcap lives with the other capture tools

    add_pcap_arguments(p)
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


def _dialect_from_args(args: argparse.Namespace) -> Dialect | None:
    if getattr(args, "dialect", "auto") not in (None, "auto"):
        return get_dialect(args.dialect)
    if getattr(args, "model", None):
        return get_model(args.model)[0]
    return None


def decode_with(frame: Frame, dialect: Dialect | None) -> tuple[Dialect, Message]:
    """Decode with `dialect` (or the most likely one), falling back to the other dialect when the
    first cannot name the fields; the dialect returned is the one that decoded it."""
    msg = decode_any(frame, prefer=dialect)
    return get_dialect(msg.dialect or (dialect.name if dialect else DIALECT_NAMES[0])), msg


# -- decode ---------------------------------------------------------------------------------------


def _show_data(data: bytes | None) -> str | None:
    if data is None:
        return None
    return data.decode("latin-1").encode("ascii", "backslashreplace").decode("ascii")


RECORD_KEYS = (
    "frame", "ok", "error", "header", "src", "dst", "length", "rw", "id", "data", "data_hex", "checksum",
    "expected_checksum", "anomaly", "dialect", "name", "fields", "units", "fields_error",
)  # fmt: skip


def _failed(text: str, error: str) -> dict[str, Any]:
    """The record of an input line that is not even a candidate frame (same keys as any other)."""
    rec: dict[str, Any] = dict.fromkeys(RECORD_KEYS)
    rec.update(frame=text, ok=False, error=error)
    return rec


def decode_line(line: str, *, as_hex: bool, dialect: Dialect | None) -> dict[str, Any]:
    """Everything `decode --json` prints for one input line (always the keys of RECORD_KEYS)."""
    text = line.strip()
    try:
        # as `encode` prints a frame: \xNN for a byte outside printable ASCII, \\ for a backslash
        raw = bytes.fromhex(text) if as_hex else bytes_from_text(text)
    except UnicodeEncodeError:  # a ValueError too: caught first
        return _failed(text, "frames are ASCII; give binary bytes as \\xNN escapes or the frame with --hex")
    except ValueError as exc:
        return _failed(text, f"not valid hex: {exc}")
    return dissection_record(dissect(raw), dialect)


def dissection_record(d: Dissection, dialect: Dialect | None, message: Message | None = None) -> dict[str, Any]:
    """`decode --json`'s record of a dissected frame. `message`: the frame already decoded by the
    caller (the proxy decodes each frame once and passes it), else it is decoded here."""
    out: dict[str, Any] = {
        "frame": _show_data(d.raw),
        "ok": d.ok,
        "error": d.error,
        "header": d.header,
        "src": d.src,
        "dst": d.dst,
        "length": d.length,
        "rw": d.rw,
        "id": d.ident,
        "data": _show_data(d.data),
        "data_hex": d.data.hex() if d.data is not None else None,
        "checksum": d.checksum,
        "expected_checksum": d.expected_checksum,
        "anomaly": d.anomaly,
        "dialect": None,
        "name": None,
        "fields": None,
        "units": None,
        "fields_error": None,
    }
    frame = d.frame
    if frame is None and d.header and d.ident and d.data is not None and d.rw is not None and d.src and d.dst:
        # Still name the fields of a frame that is only wrong in its checksum or length: useful when
        # debugging by hand (ok stays false).
        frame = Frame(d.header, d.src, d.dst, d.rw, d.ident, d.data)
    if frame is not None:
        msg = message if message is not None else decode_with(frame, dialect)[1]
        out["dialect"] = msg.dialect if msg.fields is not None else None
        out["name"] = msg.spec.name if msg.spec else None
        out["fields"] = msg.to_dict()["fields"]
        out["units"] = {f.name: f.unit for f in msg.form.fields if f.unit} if msg.form else {}
        out["fields_error"] = msg.error
    return out


def _human(rec: dict[str, Any]) -> str:
    head = rec["frame"]
    lines = [f"{head}  BAD: {rec['error']}"] if not rec["ok"] else [f"{head}  ok"]
    if rec.get("anomaly"):
        lines.append(f"    note: {rec['anomaly']}")
    if rec["id"]:
        lines.append(
            f"    {rec['id']} {rec['name'] or '(unknown)'}  {rec['src']}->{rec['dst']} "
            f"{rec['rw'] or '-'}  length {rec['length']}  data {rec['data']!r}"
        )
        lines.append(f"    decoded by the {rec['dialect']} dialect" if rec["dialect"] else "    not decoded")
    if rec["fields"]:
        width = max(len(k) for k in rec["fields"])
        units = rec.get("units") or {}
        for k, v in rec["fields"].items():
            unit = f" {units[k]}" if k in units and v is not None else ""
            lines.append(f"    {k:<{width}} = {v}{unit}")
    elif rec.get("fields_error"):
        lines.append(f"    fields: {rec['fields_error']}")
    return "\n".join(lines)


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
    bad = 0
    for line in _inputs(args.frames):
        try:
            rec = decode_line(line, as_hex=args.hex, dialect=dialect)
        except Exception as exc:
            rec = _failed(_show_data(line.strip().encode("latin-1", "replace")) or "", f"internal error: {exc!r}")
        bad += not rec["ok"] or rec["fields_error"] is not None
        print(json.dumps(rec, ensure_ascii=False) if args.json else _human(rec))
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
        print(json.dumps(rows, ensure_ascii=False))
    else:
        for r in rows:
            print(f"{r['dialect']:<9} {r['id']}  {r['rw']:<2} {r['address']}  {r['name']:<26} {r['title']}")
    return 0
