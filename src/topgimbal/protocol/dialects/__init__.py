"""The two dialects as explicit objects. `get_dialect(name, **options)` builds one; with no
options the built object is memoised (dialects are immutable, so sharing one is safe)."""

from __future__ import annotations

from functools import cache
from typing import Any

from ...errors import UnknownCommandError
from ..catalog import DeviceModel, Dialect
from .skydroid import skydroid
from .topotek import topotek

BUILDERS = {"skydroid": skydroid, "topotek": topotek}
DIALECT_NAMES = tuple(BUILDERS)


@cache
def _default(name: str) -> Dialect:
    return BUILDERS[name]()


def get_dialect(name: str | Dialect, **options: Any) -> Dialect:
    if isinstance(name, Dialect):
        return name
    key = name.lower()
    if key not in BUILDERS:
        raise UnknownCommandError(f"{name!r} is not a dialect; known: {', '.join(BUILDERS)}")
    return BUILDERS[key](**options) if options else _default(key)


def all_models() -> dict[str, DeviceModel]:
    out: dict[str, DeviceModel] = {}
    for name in BUILDERS:
        out.update(_default(name).models)
    return out


def get_model(name: str) -> tuple[Dialect, DeviceModel]:
    """The dialect and profile of a device model, by name (case-insensitive)."""
    for dname in BUILDERS:
        d = _default(dname)
        for m in d.models.values():
            if m.name.lower() == name.lower():
                return d, m
    raise UnknownCommandError(f"{name!r} is not a device model; known: {', '.join(all_models())}")
