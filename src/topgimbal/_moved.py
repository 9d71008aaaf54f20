"""Modules that moved keep their old import paths (issue 44): `import topgimbal.mavlink.cot` gives
the very module `topgimbal.outputs.cot`, loaded once, so code written against an old path keeps
working and sees the same classes (isinstance holds, module state is shared).

One table instead of a stub file per old path: a finder on sys.meta_path answers only the names in
MOVED (anything else goes on to Python's own finders), imports the new module and hands it over as
the old one. Installed by `import topgimbal`, which every old path imports first."""

from __future__ import annotations

import sys
from typing import TYPE_CHECKING, cast

if TYPE_CHECKING:
    from collections.abc import Sequence
    from importlib.abc import Loader
    from importlib.machinery import ModuleSpec
    from types import ModuleType

# old path -> where it lives now
MOVED: dict[str, str] = {
    # outputs that are not MAVLink left the bridge
    "topgimbal.mavlink.cot": "topgimbal.outputs.cot",
    "topgimbal.mavlink.cot_stream": "topgimbal.outputs.cot_stream",
    "topgimbal.mavlink.klv": "topgimbal.outputs.klv",
    "topgimbal.mavlink.klv_record": "topgimbal.outputs.klv_record",
    "topgimbal.mavlink.rtp_out": "topgimbal.outputs.rtp_out",
    # the links below the bridge
    "topgimbal.mavlink.endpoints": "topgimbal.links.endpoints",
    "topgimbal.mavlink.memory_link": "topgimbal.links.memory_link",
    "topgimbal.mavlink.zenoh_link": "topgimbal.links.zenoh_link",
    "topgimbal.mavlink.json_shape": "topgimbal.links.json_shape",
    "topgimbal.mavlink.signing": "topgimbal.links.signing",
    # geometry has one owner
    "topgimbal.mavlink.geo": "topgimbal.geo.aim",
    # camera definitions need neither pymavlink nor the bridge
    "topgimbal.mavlink.camdef": "topgimbal.camdef.definition",
    "topgimbal.mavlink.camdef_http": "topgimbal.camdef.http",
    "topgimbal.mavlink.camdef_files": "topgimbal.camdef.files",
    # what the bridge hears from and asks of the autopilots
    "topgimbal.mavlink.vehicle": "topgimbal.autopilot.vehicle",
    "topgimbal.mavlink.feed_sources": "topgimbal.autopilot.feed_sources",
    "topgimbal.mavlink.stream_rates": "topgimbal.autopilot.stream_rates",
    "topgimbal.mavlink.reboots": "topgimbal.autopilot.reboots",
    "topgimbal.mavlink.autopilot_streams": "topgimbal.autopilot.streams",
    "topgimbal.mavlink.periodic": "topgimbal.periodic",
}


class _Alias:
    """The finder and loader of the old paths (duck-typed, as sys.meta_path allows: importlib.abc
    would cost `topgimbal --help` some twenty imports)."""

    def find_spec(
        self, fullname: str, path: Sequence[str] | None, target: ModuleType | None = None
    ) -> ModuleSpec | None:
        if fullname not in MOVED:
            return None
        from importlib.machinery import ModuleSpec

        return ModuleSpec(fullname, cast("Loader", self))

    def create_module(self, spec: ModuleSpec) -> ModuleType:
        import importlib

        module = importlib.import_module(MOVED[spec.name])
        spec.loader_state = module.__spec__  # the import system sets __spec__ next; exec puts it back
        return module

    def exec_module(self, module: ModuleType) -> None:
        if module.__spec__ is not None and module.__spec__.loader_state is not None:
            module.__spec__ = module.__spec__.loader_state


def install() -> None:
    if not any(isinstance(f, _Alias) for f in sys.meta_path):
        sys.meta_path.append(_Alias())
