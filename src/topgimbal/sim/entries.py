"""One precomputed entry per identifier of a model: its handler and every per-model fact the
device checks on each request (support, limits, wire signs, quirks), so a request costs one
dictionary lookup before its handler runs instead of a walk over the profile and catalog."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from ..protocol import CommandSpec, DeviceModel, Dialect
from .context import Handler

# Catalog groups whose commands wait for video output (the needs_video_output quirk); the
# video_output role itself is what starts it.
CAMERA_GROUPS = frozenset({"camera", "lens", "thermal"})


@dataclass(frozen=True, slots=True)
class Entry:
    spec: CommandSpec
    handler: Handler
    supported: bool  # the model has it (else: the error frame)
    signed: bool  # has fields the model's wire signs apply to
    limits: tuple[tuple[str, float, float], ...]  # the model's narrower ranges
    ignored: bool = False  # ignored_commands: dropped without effect or echo
    silent_motion: bool = False  # no_motion_echo: obeyed, not echoed (the profile's no_echo set;
    # a profile without one: every motion command)
    needs_video: bool = False  # needs_video_output: a write acts only once video output runs
    slow: bool = False  # late_answers: the answer goes out late or never
    echo_form: bool = False  # the profile's echo_rules: a write is answered with that form
    header: str | None = None  # gimbal_header_required: the header frames must carry
    destination: str | None = None  # strict_destinations: the address frames must go to


def build_entries(
    dialect: Dialect, model: DeviceModel, table: Mapping[str, Handler], quirks: Mapping[str, bool]
) -> dict[str, Entry]:
    out: dict[str, Entry] = {}
    gimbal_header = model.gimbal_header if quirks.get("gimbal_header_required") else None
    for ident, spec in dialect.commands.items():
        handler = table.get(ident)
        if handler is None:
            continue
        out[ident] = Entry(
            spec=spec,
            handler=handler,
            supported=spec.role != "error" and dialect.supports(model, ident),
            signed=bool(spec.wire_sign_fields),
            limits=tuple((f, lo, hi) for (i, f), (lo, hi) in model.limits.items() if i == ident),
            ignored=bool(quirks.get("ignored_commands")) and ident in model.ignored,
            silent_motion=bool(quirks.get("no_motion_echo"))
            and (ident in model.no_echo or (not model.no_echo and spec.motion)),
            needs_video=bool(quirks.get("needs_video_output"))
            and spec.group in CAMERA_GROUPS
            and spec.role != "video_output",
            slow=bool(quirks.get("late_answers")) and ident in model.slow_answers,
            echo_form=ident in model.echo_rules,
            header=gimbal_header if spec.address == "G" else None,
            destination=model.destinations.get(ident) if quirks.get("strict_destinations") else None,
        )
    return out


__all__ = ["CAMERA_GROUPS", "Entry", "build_entries"]
