"""The decoded-frame record: everything `topgimbal decode --json` says about one frame, and its text
form. Shared by `decode`, `decode --pcap` and `proxy` (cli/protocol_cmds.py, cli/wire_cmds.py), so
the three print the same record and neither CLI module imports the other."""

from __future__ import annotations

from typing import Any

from .dialect import Dialect
from .dialects import DIALECT_NAMES, decode_any, get_dialect
from .frame import Dissection, Frame, bytes_from_text, dissect
from .message import Message


def decode_with(frame: Frame, dialect: Dialect | None) -> tuple[Dialect, Message]:
    """Decode with `dialect` (or the most likely one), falling back to the other dialect when the
    first cannot name the fields; the dialect returned is the one that decoded it."""
    msg = decode_any(frame, prefer=dialect)
    return get_dialect(msg.dialect or (dialect.name if dialect else DIALECT_NAMES[0])), msg


def show_data(data: bytes | None) -> str | None:
    if data is None:
        return None
    return data.decode("latin-1").encode("ascii", "backslashreplace").decode("ascii")


RECORD_KEYS = (
    "frame", "ok", "error", "header", "src", "dst", "length", "rw", "id", "data", "data_hex", "checksum",
    "expected_checksum", "anomaly", "dialect", "name", "fields", "units", "fields_error",
)  # fmt: skip


def failed_record(text: str, error: str) -> dict[str, Any]:
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
        return failed_record(text, "frames are ASCII; give binary bytes as \\xNN escapes or the frame with --hex")
    except ValueError as exc:
        return failed_record(text, f"not valid hex: {exc}")
    return dissection_record(dissect(raw), dialect)


def dissection_record(d: Dissection, dialect: Dialect | None, message: Message | None = None) -> dict[str, Any]:
    """`decode --json`'s record of a dissected frame. `message`: the frame already decoded by the
    caller (the proxy decodes each frame once and passes it), else it is decoded here."""
    out: dict[str, Any] = {
        "frame": show_data(d.raw),
        "ok": d.ok,
        "error": d.error,
        "header": d.header,
        "src": d.src,
        "dst": d.dst,
        "length": d.length,
        "rw": d.rw,
        "id": d.ident,
        "data": show_data(d.data),
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


def human_text(rec: dict[str, Any]) -> str:
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
