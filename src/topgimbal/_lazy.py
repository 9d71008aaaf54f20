"""Lazy package attributes (PEP 562): a package names what it exports without importing the
modules behind it, so `topgimbal --help` does not load the client, simulator or servers. One
implementation for every package that does this (topgimbal.client, .sim, .sim.servers)."""

from __future__ import annotations

import importlib
import importlib.util
from collections.abc import Callable, Mapping
from typing import Any


def lazy_getattr(package: str, names: Mapping[str, str], namespace: dict[str, Any]) -> Callable[[str], object]:
    """A module `__getattr__` for `package`: `names` maps an exported name to the submodule holding
    it; the value is cached in `namespace` (the package's globals) on first use. Any other public
    name that is a submodule is imported, as the eager imports it replaces made it an attribute.
    A module named in full (`topgimbal.links.mav`) is taken as it is: a name re-exported from a
    lower layer."""

    def getattr_(name: str) -> object:
        if name in names:
            where = names[name]
            module = (
                importlib.import_module(where)
                if where.startswith("topgimbal.")
                else importlib.import_module(f".{where}", package)
            )
            value = getattr(module, name)
            namespace[name] = value
            return value
        if not name.startswith("_") and importlib.util.find_spec(f"{package}.{name}") is not None:
            return importlib.import_module(f".{name}", package)
        raise AttributeError(f"module {package!r} has no attribute {name!r}")

    return getattr_
