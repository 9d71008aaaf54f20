"""From parsed flags to a config dataclass, generated from the config's fields (as `regen`
generates the command index): a field whose metadata names a flag (`bridge_config.cli`) is filled
from that flag's value, so a new option is one field and one `add_argument`, never a hand-copied
line. Errors the library raises name the field (`max_peers=300: expected 1..256`); `with_flags`
tells them with the flag the user typed (`--max-peers=300: ...`)."""

from __future__ import annotations

import argparse
import dataclasses
import re
from typing import Any


def flag_dest(flag: str) -> str:
    return flag.lstrip("-").replace("-", "_")


def config_kwargs(cls: type, args: argparse.Namespace) -> dict[str, Any]:
    """{field: value} for each field of dataclass `cls` with a flag the namespace has."""
    out: dict[str, Any] = {}
    for f in dataclasses.fields(cls):
        meta = f.metadata
        if "flag" not in meta:
            continue
        if meta.get("from_args") is not None:
            out[f.name] = meta["from_args"](args)
            continue
        dest = flag_dest(meta["flag"])
        if not hasattr(args, dest):
            continue  # a parser without that flag: the field keeps its default
        value = getattr(args, dest)
        out[f.name] = meta["convert"](value) if meta.get("convert") is not None else value
    return out


def flags_of(cls: type) -> dict[str, str]:
    """{field name: flag} for the fields of `cls` that have one."""
    out = {f.name: f.metadata["flag"] for f in dataclasses.fields(cls) if f.metadata.get("flag")}
    for f in dataclasses.fields(cls):  # a field holding several options by name (BridgeConfig.features)
        if f.metadata.get("named_flags") is not None:
            out.update(f.metadata["named_flags"]())
    return out


def with_flags(message: str, cls: type) -> str:
    """`message` with a leading field name (`record ...`, `max_peers=...`, `video_out: ...`)
    written as its flag, so a CLI user reads the option they gave."""
    m = re.match(r"([a-z_]+)(?=[ =:])", message)
    if m is None:
        return message
    flag = flags_of(cls).get(m.group(1))
    return message if flag is None else flag + message[m.end() :]
