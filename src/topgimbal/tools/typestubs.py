"""Typed signatures of `request()` for every catalog command, generated from the catalog
(`python -m topgimbal.tools.regen`), as pymavlink generates a class per message.

`client/catalog_types.pyi` holds Protocols whose `__call__` is overloaded once per identifier
(its identifier and catalog names as `Literal`s, its request fields as keyword arguments typed from their
codec's kind), then one overload marked `@deprecated` that matches a known identifier with any
other keyword (a field that command does not have: mypy reports it, with `deprecated` among its
enabled error codes), then the plain `(ident: str, **values)` for identifiers only known at run
time. `AsyncClient.request` and `Gimbal.request` are typed with them (TYPE_CHECKING only: nothing
changes at run time). A field two dialects give one identifier is accepted for either: which
model has it is checked at run time, as before."""

from __future__ import annotations

import json

from ..protocol import DIALECT_NAMES, REQUEST, CommandSpec, get_dialect

KIND_TYPES = {
    "number": "float",
    "coordinate": "float",
    "enum": "str | int",
    "enum_or_number": "str | float",
    "text": "str",
    "ipv4": "str",
    "raw": "str",
    "literal": "str",
    "datetime": "datetime",
}
OPTIONS = "read: bool = ..., timeout_s: float | None = ..., retries: int | None = ..., wait_reply: bool | None = ..., dst: str | None = ..."
HEADER = '''"""Generated from the catalog by `python -m topgimbal.tools.regen` (tools/typestubs.py); do not
edit. Typed `request()` signatures: `cam.request("GAY", yaw_dgr=5)` is a mypy error."""

from collections.abc import Coroutine
from datetime import datetime
from typing import Literal, Protocol, overload

from typing_extensions import deprecated

from ..protocol import Message

# fmt: off
'''


def _commands() -> dict[str, tuple[set[str], dict[str, set[str]]]]:
    """identifier -> (its names, field -> value types), over both dialects."""
    out: dict[str, tuple[set[str], dict[str, set[str]]]] = {}
    for name in DIALECT_NAMES:
        spec: CommandSpec
        for spec in get_dialect(name).commands.values():
            names, fields = out.setdefault(spec.ident, (set(), {}))
            names.update({spec.ident, spec.name})
            for form in (f for f in spec.forms if f.direction == REQUEST):  # what a host sends
                for field in form.fields:
                    fields.setdefault(field.name, set()).add(KIND_TYPES.get(field.codec.kind, "object"))
    return out


def _literal(names: set[str] | list[str]) -> str:
    return "Literal[" + ", ".join(json.dumps(n) for n in sorted(names)) + "]"


def _type(types: set[str]) -> str:
    parts = sorted({p.strip() for t in types for p in t.split("|")})
    return "object" if "object" in parts else " | ".join([*parts, "None"])


def _protocol(cls: str, returns: str, commands: dict[str, tuple[set[str], dict[str, set[str]]]]) -> str:
    lines = [f"class {cls}(Protocol):"]
    every: set[str] = set()
    for ident in sorted(commands):
        names, fields = commands[ident]
        every |= names
        values = "".join(f", {f}: {_type(t)} = ..." for f, t in sorted(fields.items()))
        lines += [
            "    @overload",
            f"    def __call__(self, ident: {_literal(names)}, *, {OPTIONS}{values}) -> {returns}: ...",
        ]
    lines += [
        "    @overload",
        '    @deprecated("a field this command does not have, or a value of the wrong type (`topgimbal catalog ID`)")',
        f"    def __call__(self, ident: {_literal(every)}, *, {OPTIONS}, **values: object) -> {returns}: ...",
        "    @overload",
        f"    def __call__(self, ident: str, *, {OPTIONS}, **values: object) -> {returns}: ...",
    ]
    return "\n".join(lines) + "\n"


def render() -> str:
    commands = _commands()
    return (
        HEADER
        + _protocol("AsyncRequest", "Coroutine[object, object, Message]", commands)
        + "\n\n"
        + _protocol("SyncRequest", "Message", commands)
    )
