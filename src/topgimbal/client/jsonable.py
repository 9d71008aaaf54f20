"""The one JSON encoding of SDK results: what CLI `--json`, the web console and the Zenoh server
print or send. One rule per kind of value, so the three agree and every output is valid JSON:

- NaN and ±inf become `null` (JSON has no literal for them; `json.dumps` would print `NaN`, which
  browsers' and most languages' parsers reject). A value the device did not give is `null` too.
- a `Message` becomes `Message.to_dict()` (`id`, `name`, `rw`, `src`, `dst`, `fields`, `error`,
  `dialect`); a `Frame` its text (`#TP...`).
- datetimes, dates and times become ISO 8601 text (as `Message.to_dict` writes a date field).
- an enum becomes its value (as `json` writes an `IntEnum`), bytes their Latin-1 text (the wire's
  bytes one to one), dataclasses and named tuples objects of their fields, sets lists.
- anything with `as_dict()` or `to_dict()` becomes what that returns, encoded by these rules.
- anything else becomes `str(value)`: output never fails on an unexpected type.

The Zenoh server sends a `Message` in its own shape (`remote_keys.encode_result`), which its
`RemoteClient` decodes back into a `Message`; the values inside still follow these rules.
"""

from __future__ import annotations

import dataclasses
import datetime
import enum
import json
import math
from collections.abc import Mapping
from typing import Any, TypeAlias, Union

from ..protocol import Frame, Message

JsonValue: TypeAlias = Union[bool, int, float, str, list["JsonValue"], dict[str, "JsonValue"], None]  # noqa: UP007


def jsonable(value: object) -> JsonValue:
    """`value` as data `json.dumps(..., allow_nan=False)` writes: see the module's rules."""
    if value is None or isinstance(value, (bool, str)):
        return value
    if isinstance(value, enum.Enum):  # before int: an IntEnum is an int
        return jsonable(value.value)
    if isinstance(value, int):
        return int(value)
    if isinstance(value, float):
        return float(value) if math.isfinite(value) else None
    if isinstance(value, Message):  # before the tuples: a Message and a Frame are named tuples
        return jsonable(value.to_dict())
    if isinstance(value, Frame):
        return value.text()
    to_dict = getattr(value, "as_dict", None) or getattr(value, "to_dict", None)
    if callable(to_dict) and not isinstance(value, type):
        return jsonable(to_dict())
    if isinstance(value, Mapping):
        return {str(k): jsonable(v) for k, v in value.items()}
    as_tuple_dict = getattr(value, "_asdict", None)  # a named tuple
    if isinstance(value, tuple) and callable(as_tuple_dict):
        return jsonable(as_tuple_dict())
    if isinstance(value, (list, tuple)):
        return [jsonable(v) for v in value]
    if isinstance(value, (set, frozenset)):
        return sorted((jsonable(v) for v in value), key=repr)
    if isinstance(value, (bytes, bytearray, memoryview)):
        return bytes(value).decode("latin-1")
    if isinstance(value, (datetime.datetime, datetime.date, datetime.time)):
        return value.isoformat()
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: jsonable(getattr(value, f.name)) for f in dataclasses.fields(value)}
    return str(value)


def dumps(value: object, **kwargs: Any) -> str:
    """`value` as JSON text by `jsonable`'s rules; never a `NaN` literal (`allow_nan=False`)."""
    return json.dumps(jsonable(value), allow_nan=False, **kwargs)


__all__ = ["JsonValue", "dumps", "jsonable"]
