"""MAVLink messages as the JSON BlueOS's mavlink-server puts on Zenoh, both ways (pure).

mavlink-server (bluerobotics/mavlink-server, `src/lib/drivers/zenoh/json.rs`, rust-mavlink 0.16
with its `serde` feature) writes a message as

    {"header": {"system_id": 1, "component_id": 154, "sequence": 7, "message_id": 285},
     "message": {"type": "GIMBAL_DEVICE_ATTITUDE_STATUS", "time_boot_ms": 1234, ...}}

rust-mavlink's serde form, which this module reproduces from pymavlink's message metadata:
- fields in wire order (pymavlink's `ordered_fieldnames`, extensions last), named as in the XML
  except `type`, which rust-mavlink calls `mavtype`;
- an enum field as `{"type": "ENTRY_NAME"}`; a bit mask (an enum marked bitmask) as bitflags 2's
  text `"A | B"` (`""` when none is set), bits no entry names being dropped as rust-mavlink's
  parser drops them;
- `char[N]` as a string up to the first NUL; other arrays (enum arrays too) as lists of numbers.

Decisions where rust-mavlink has no answer: an enum value that is no entry of its enum (rust-mavlink
refuses the whole message) is written as the plain number, and read back from one; a string that is
not UTF-8 is decoded with replacement characters. Reading is as lenient as serde is, plus: a missing
field is zero, and an enum may be given as a number. Anything else wrong raises `ShapeError`."""

from __future__ import annotations

import json
import math
from typing import Any

from ..errors import TopGimbalError
from .mav import mavlink

MAX_IN_BYTES = 16 * 1024  # a message's JSON from the network; the largest real one is ~2 KiB
_INT_RANGES = {
    "int8_t": (-(2**7), 2**7 - 1), "uint8_t": (0, 2**8 - 1), "uint8_t_mavlink_version": (0, 255),
    "int16_t": (-(2**15), 2**15 - 1), "uint16_t": (0, 2**16 - 1),
    "int32_t": (-(2**31), 2**31 - 1), "uint32_t": (0, 2**32 - 1),
    "int64_t": (-(2**63), 2**63 - 1), "uint64_t": (0, 2**64 - 1),
}  # fmt: skip
# Bit masks whose XML declares the high bits first: bitflags writes names in declaration order,
# pymavlink keeps entries sorted by value (every other mask in common.xml is declared low bit first).
_DESCENDING_MASKS = frozenset({"MAV_MODE_FLAG"})


class ShapeError(TopGimbalError, ValueError):
    """JSON that is not a MAVLink message in mavlink-server's shape."""


def json_name(field: str) -> str:
    return "mavtype" if field == "type" else field


def _enum(name: str | None) -> Any:
    if name is None:
        return None
    return mavlink().enums.get(name)


def _entries(enum: Any, name: str) -> list[tuple[int, str]]:
    out = [(v, e.name) for v, e in enum.items() if not e.name.endswith("_ENUM_END")]
    return sorted(out, reverse=name in _DESCENDING_MASKS)


def flags_text(value: int, enum: Any, enum_name: str) -> str:
    """bitflags 2's Display of the bits rust-mavlink keeps (those some entry names)."""
    entries = _entries(enum, enum_name)
    known = 0
    for v, _ in entries:
        known |= v
    source = remaining = value & known
    names = []
    for v, n in entries:
        if v and source & v == v and remaining & v:
            names.append(n)
            remaining &= ~v
    return " | ".join(names)


def _parse_flags(text: str, enum: Any, enum_name: str) -> int:
    by_name = {n: v for v, n in _entries(enum, enum_name)}
    value = 0
    for part in text.split("|"):
        p = part.strip()
        if not p:
            if text.strip():
                raise ShapeError(f"{enum_name}: empty flag in {text!r}")
            continue
        if p.lower().startswith("0x"):
            try:
                value |= int(p[2:], 16)
            except ValueError:
                raise ShapeError(f"{enum_name}: {p!r} is not a hex number") from None
        elif p in by_name:
            value |= by_name[p]
        else:
            raise ShapeError(f"{enum_name}: no flag {p!r}")
    return value


def _out_value(cls: Any, field: str, ftype: str, length: int, value: Any) -> Any:
    if ftype == "char":
        if isinstance(value, (bytes, bytearray)):
            value = bytes(value).split(b"\0", 1)[0].decode("utf-8", "replace")
        return str(value).split("\0", 1)[0]
    if length:
        return list(value)
    enum_name = cls.fieldenums_by_name.get(field)
    enum = _enum(enum_name)
    if enum is None or not isinstance(value, int):
        return value
    if getattr(enum, "bitmask", False):
        return flags_text(value, enum, str(enum_name))
    entry = enum.get(value)
    if entry is None or entry.name.endswith("_ENUM_END"):
        return value  # no entry: rust-mavlink would refuse the message; the number says the most
    return {"type": entry.name}


def message_obj(msg: Any) -> dict[str, Any]:
    """The `message` part: {"type": NAME, field: value, ...} in wire order."""
    cls = type(msg)
    out: dict[str, Any] = {"type": msg.get_type()}
    for f, ftype, length in _fields(cls):
        out[json_name(f)] = _out_value(cls, f, ftype, length, getattr(msg, f))
    return out


def _fields(cls: Any) -> list[tuple[str, str, int]]:
    """(name, type, array length) in wire order. pymavlink lists `fieldtypes` in XML order and
    `array_lengths` in wire order."""
    types = dict(zip(cls.fieldnames, cls.fieldtypes, strict=True))
    return [(f, types[f], n) for f, n in zip(cls.ordered_fieldnames, cls.array_lengths, strict=True)]


def to_obj(msg: Any) -> dict[str, Any]:
    header = {"system_id": msg.get_srcSystem(), "component_id": msg.get_srcComponent(),
              "sequence": msg.get_seq(), "message_id": msg.get_msgId()}  # fmt: skip
    return {"header": header, "message": message_obj(msg)}


def dumps(obj: Any) -> str:
    """JSON text; NaN and infinities as json5 writes them (mavlink-server writes json5)."""
    return json.dumps(obj, separators=(",", ":"))


def field_payloads(message: dict[str, Any]) -> list[tuple[str, str]]:
    """(key, JSON) per entry of a `message` object, as mavlink-server publishes each under
    `.../{MSG}/{field}` (its serde_json step turns non-finite floats into null)."""
    return [(k, dumps(_finite(v))) for k, v in message.items()]


def _finite(v: Any) -> Any:
    if isinstance(v, float) and not math.isfinite(v):
        return None
    if isinstance(v, list):
        return [_finite(x) for x in v]
    return v


# -- JSON -> pymavlink --------------------------------------------------------------------------------


_BY_NAME: dict[str, Any] = {}  # message name -> pymavlink class, filled on first use


def _by_name() -> dict[str, Any]:
    if not _BY_NAME:
        _BY_NAME.update({cls.msgname: cls for cls in mavlink().mavlink_map.values()})
    return _BY_NAME


def _number(where: str, ftype: str, v: Any) -> int | float:
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise ShapeError(f"{where}: expected a number, not {type(v).__name__}")
    if ftype in ("float", "double"):
        return float(v)
    if not isinstance(v, int):
        raise ShapeError(f"{where}: expected an integer ({ftype}), not {v!r}")
    lo, hi = _INT_RANGES[ftype]
    if not lo <= v <= hi:
        raise ShapeError(f"{where}: {v} is out of {ftype}'s range {lo}..{hi}")
    return v


def _in_value(cls: Any, field: str, ftype: str, length: int, v: Any) -> Any:
    where = f"{cls.msgname}.{json_name(field)}"
    if ftype == "char":
        if not isinstance(v, str):
            raise ShapeError(f"{where}: expected a string")
        try:
            return v.encode("utf-8")[: max(length, 1)]  # serde's nulstr keeps the first N bytes
        except UnicodeEncodeError:  # a lone surrogate ("\udcff"), which JSON can carry and UTF-8 cannot
            raise ShapeError(f"{where}: not UTF-8 text (a lone surrogate)") from None
    if length:
        if not isinstance(v, list) or len(v) != length:
            raise ShapeError(f"{where}: expected a list of {length} numbers")
        return [_number(where, ftype, x) for x in v]
    enum_name = cls.fieldenums_by_name.get(field)
    enum = _enum(enum_name)
    if enum is not None and getattr(enum, "bitmask", False) and isinstance(v, str):
        return _number(where, ftype, _parse_flags(v, enum, str(enum_name)))
    if enum is not None and isinstance(v, dict):
        name = v.get("type")
        values = {e.name: k for k, e in enum.items()}
        if len(v) != 1 or not isinstance(name, str) or name not in values:
            raise ShapeError(f'{where}: expected {{"type": an entry of {enum_name}}}, not {v!r}'[:300])
        return _number(where, ftype, values[name])
    return _number(where, ftype, v)


def _zero(ftype: str, length: int) -> Any:
    if ftype == "char":
        return b""
    z: int | float = 0.0 if ftype in ("float", "double") else 0
    return [z] * length if length else z


def from_obj(obj: Any) -> tuple[dict[str, int], Any]:
    """(header, pymavlink message) from a decoded JSON object; ShapeError says what is wrong."""
    if not isinstance(obj, dict) or not isinstance(obj.get("header"), dict) or not isinstance(obj.get("message"), dict):
        raise ShapeError('expected {"header": {...}, "message": {"type": NAME, ...}}')
    h = obj["header"]
    header = {}
    for k in ("system_id", "component_id", "sequence"):
        v = h.get(k, 0 if k == "sequence" else None)
        if isinstance(v, bool) or not isinstance(v, int) or not 0 <= v <= 255:
            raise ShapeError(f"header.{k}: expected 0..255")
        header[k] = v
    m = obj["message"]
    name = m.get("type")
    cls = _by_name().get(name) if isinstance(name, str) else None
    if cls is None:
        raise ShapeError(f"message.type {str(name)[:64]!r}: not a message of the common dialect")
    mid = h.get("message_id")
    if mid is not None and mid != cls.id:
        raise ShapeError(f"header.message_id {str(mid)[:16]} is not {name}'s ({cls.id})")
    kwargs = {}
    for f, ftype, length in _fields(cls):
        key = json_name(f)
        kwargs[f] = _in_value(cls, f, ftype, length, m[key]) if key in m else _zero(ftype, length)
    try:
        return header, cls(**kwargs)
    except Exception as exc:  # pymavlink's own checks
        raise ShapeError(f"{name}: {exc}"[:300]) from None


def loads(data: bytes | str) -> tuple[dict[str, int], Any]:
    """(header, message) from JSON text of at most MAX_IN_BYTES; ShapeError otherwise."""
    if len(data) > MAX_IN_BYTES:
        raise ShapeError(f"{len(data)} bytes: more than {MAX_IN_BYTES}")
    try:
        obj = json.loads(data)
    except (ValueError, RecursionError) as exc:  # UnicodeDecodeError is a ValueError
        raise ShapeError(f"not JSON: {exc}"[:200]) from None
    return from_obj(obj)


def encode(header: dict[str, int], msg: Any) -> bytes:
    """The MAVLink 2 frame of `msg` sent as header's system, component and sequence."""
    mav = mavlink().MAVLink(None, srcSystem=header["system_id"], srcComponent=header["component_id"])
    mav.seq = header.get("sequence", 0)
    try:
        return bytes(msg.pack(mav))
    except Exception as exc:  # struct.error on a value pymavlink cannot pack
        raise ShapeError(f"{msg.get_type()}: cannot encode: {exc}"[:300]) from None
