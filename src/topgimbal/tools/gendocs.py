"""Generate docs/protocol.md from the catalog (`--check` fails when the file is stale).

The catalog is the single source: this page is never edited by hand."""

from __future__ import annotations

import argparse
import difflib
import sys
from collections.abc import Sequence
from pathlib import Path

from ..protocol import DIALECT_NAMES, get_dialect
from ..protocol.catalog import GROUPS, REQUEST, ROLES, CommandSpec, DeviceModel, Dialect, Form
from ..protocol.frame import ADDRESS_NAMES
from ..protocol.signs import SIGN_KEYS, resolve_signs

CLASS_ORDER = ("G", "M", "D", "E", "U")


def _cell(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", " ")


def _form_text(form: Form) -> str:
    if form.const is not None:
        return f"`{form.const.decode()}`"
    if not form.fields:
        return "(no data)"
    parts = []
    for f in form.fields:
        width = f.codec.width
        w = f"{width}" if width is not None else f"{f.codec.min_width}..{f.codec.max_width}"
        parts.append(f"`{f.name}` [{w}] {f.codec.allowed()}")
    return "<br>".join(_cell(p) for p in parts)


def _forms(spec: CommandSpec, rw: str, direction: str) -> str:
    forms = spec.forms_for(rw, direction)
    if not forms:
        return ""
    return "<br>— or —<br>".join(
        (f"*{_cell(f.title)}:* " if len(forms) > 1 and f.title else "") + _form_text(f) for f in forms
    )


def _models(d: Dialect, spec: CommandSpec) -> str:
    return "all" if spec.models is None else ", ".join(m for m in d.models if m in spec.models)


def _signs(m: DeviceModel) -> str:
    signs = resolve_signs(m)
    inverted = [k for k in SIGN_KEYS if "." not in k and signs[k] == -1]
    inverted += [k for k in SIGN_KEYS if "." in k and signs[k] == -1 and signs[k.split(".")[1]] != -1]
    return ", ".join(f"{k} -" for k in inverted) or "as documented"


def _ids(ids: frozenset[str] | set[str]) -> str:
    return ", ".join(f"`{i}`" for i in sorted(ids)) or "-"


def _model_tables(d: Dialect) -> list[str]:
    out = ["| model | endpoints | host | yaw / pitch / roll range (deg) | max rate | wire signs | features |"]
    out.append("|---|---|---|---|---|---|---|")
    for m in d.models.values():
        feats = [f for f, on in (("thermal", m.thermal), ("laser range", m.lrf_range_m is not None)) if on]
        if m.optical_zoom_max > 1:
            feats.append(f"{m.optical_zoom_max:g}x optical zoom")
        eps = ", ".join(str(e) for e in m.endpoints)
        if m.alternate_endpoints:
            eps += " (also seen: " + ", ".join(str(e) for e in m.alternate_endpoints) + ")"
        out.append(
            f"| {m.name} | {_cell(eps)} | `{m.host_address}` | "
            f"{m.yaw_range_deg[0]:g}..{m.yaw_range_deg[1]:g} / {m.pitch_range_deg[0]:g}..{m.pitch_range_deg[1]:g} / "
            f"{m.roll_range_deg[0]:g}..{m.roll_range_deg[1]:g} | {m.max_rate_deg_s:g} deg/s | {_signs(m)} | "
            f"{', '.join(feats) or '-'} |"
        )
    out += ["", "Behaviour from each profile (public sources in [errata.md](errata.md)):", ""]
    out.append("| model | pacing | ignored | not echoed | slow answers | streams at | host keeps sending | "
               "routing | simulator quirks on by default |")  # fmt: skip
    out.append("|---|---|---|---|---|---|---|---|---|")
    for m in d.models.values():
        pacing = [f"{m.min_command_gap_s * 1000:g} ms between commands"] if m.min_command_gap_s else []
        if m.stop_repeats > 1:
            pacing.append(f"stop sent {m.stop_repeats}x")
        if m.max_frame_bytes:
            pacing.append(f"frames up to {m.max_frame_bytes} bytes")
        routing = [f"`{i}` to `{a}`" for i, a in sorted(m.destinations.items())]
        if m.gimbal_header:
            routing.append(f"G class `{m.gimbal_header}` only")
        rates = ", ".join(f"`{i}` {hz:g} Hz" for i, hz in m.stream_rates_hz.items()) or "as asked"
        setup = [f"`{i}` once" for i, _v in m.host_setup]
        feeds = setup + [f"`{i}` {hz:g} Hz" for i, hz in m.host_feeds.items()]
        quirks = ", ".join(q for q, on in m.quirks.items() if on) or "-"
        known_off = [q for q, on in m.quirks.items() if not on]
        if known_off:
            quirks += " (known, off: " + ", ".join(known_off) + ")"
        out.append(
            f"| {m.name} | {'; '.join(pacing) or '-'} | {_ids(m.ignored)} | {_ids(m.no_echo)} | "
            f"{_ids(m.slow_answers)} | {rates} | {', '.join(feeds) or '-'} | {'; '.join(routing) or '-'} | {quirks} |"
        )
    out += [
        "",
        "| model | video stream | lens | URL | field of view at 1x | zoom | source |",
        "|---|---|---|---|---|---|---|",
    ]
    for m in d.models.values():
        for v in m.video:
            fov = f"{v.hfov_deg:g} deg" if v.hfov_deg else "-"
            zoom = f"{v.zoom_range_x[0]:g}..{v.zoom_range_x[1]:g}x"
            out.append(f"| {m.name} | {v.name} | {v.lens} | `{v.url}` | {fov} | {zoom} | {_cell(v.source)} |")
    return out


def _roles_table(dialects: Sequence[Dialect]) -> list[str]:
    out = ["## Roles", "", "What a command is for, so programs find it without naming a dialect: "
           "`dialect.by_role(role, model)` returns the command (None when the model has none).", ""]  # fmt: skip
    out.append("| role | meaning | " + " | ".join(f"`{d.name}`" for d in dialects) + " |")
    out.append("|---|---|" + "---|" * len(dialects))
    for role, text in ROLES.items():
        cells = [", ".join(f"`{c.ident}`" for c in d.commands_with_role(role)) or "-" for d in dialects]
        out.append(f"| `{role}` | {_cell(text)} | " + " | ".join(cells) + " |")
    out += ["", "Console groups: " + "; ".join(f"`{g}` {t}" for g, t in GROUPS.items()) + ".", ""]
    return out


def render(dialects: Sequence[Dialect] | None = None) -> str:
    """The reference page for `dialects` (default: every built-in dialect)."""
    out = [
        "# TOP protocol reference",
        "",
        "Generated from the catalog by `python -m topgimbal.tools.regen` (`make docs`); CI checks it is",
        "current (`make docs-check`). Do not edit by hand. Values are in user units, as on the wire (no sign",
        "changes: the client maps its convention to each model's wire signs). Widths are in data characters.",
        "Decisions on what the documents leave ambiguous are in [errata.md](errata.md).",
        "",
        "Frame: `#TP`/`#tp` + src + dst + length (1 hex char) + `r`/`w` + identifier (3) + data + checksum",
        "(2 upper-case hex chars, sum of all bytes before it mod 256). TOPOTEK adds `#tP` (length as one raw",
        "byte) and `#Tp` (16-bit raw length in the length and control positions).",
        "",
        "Addresses: " + ", ".join(f"`{k}` {v}" for k, v in ADDRESS_NAMES.items()) + ".",
        "",
    ]
    dialects = list(dialects) if dialects is not None else [get_dialect(name) for name in DIALECT_NAMES]
    for d in dialects:
        out += [f"## {d.title} — dialect `{d.name}`", ""]
        out += _model_tables(d)
        out.append("")
        by_class: dict[str, list[CommandSpec]] = {}
        for spec in d.commands.values():
            by_class.setdefault(spec.address, []).append(spec)
        for cls in CLASS_ORDER:
            specs = by_class.get(cls)
            if not specs:
                continue
            out += [f"### `{d.name}` {cls} class — {ADDRESS_NAMES[cls]}", ""]
            out.append(
                "| id | name | role / group | write (host → device) | query / answer | other device → host | models "
                "| source |"
            )
            out.append("|---|---|---|---|---|---|---|---|")
            for spec in sorted(specs, key=lambda s: s.ident):
                write = _forms(spec, "w", REQUEST)
                query = _forms(spec, "r", REQUEST)
                answer = _forms(spec, "r", "response")
                qa = f"{query} → {answer}" if query else (answer and f"(unsolicited) {answer}")
                echo = [
                    f
                    for f in spec.forms_for("w", "response")
                    if write == "" or f.fields != spec.forms_for("w", REQUEST)[0].fields
                ]
                other = "<br>".join((f"*{_cell(f.title)}:* " if f.title else "") + _form_text(f) for f in echo)
                title = _cell(spec.title) + ("" if spec.documented else " *(beyond the documents)*")
                out.append(
                    f"| `{spec.ident}` | {spec.name}<br>{title} | `{spec.role}` / {spec.group} | {write} | {qa} | "
                    f"{other} | {_models(d, spec)} | {_cell(spec.section)} |"
                )
            out.append("")
    out += _roles_table(dialects)
    return "\n".join(out).rstrip() + "\n"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("path", type=Path)
    ap.add_argument("--check", action="store_true", help="exit 1 if the file differs from the catalog")
    args = ap.parse_args(argv)
    text = render()
    if args.check:
        current = args.path.read_text(encoding="utf-8") if args.path.exists() else ""
        if current != text:
            diff = difflib.unified_diff(current.splitlines(), text.splitlines(), str(args.path), "catalog", lineterm="")
            print("\n".join(list(diff)[:40]))
            print(f"{args.path} is out of date: run `make docs`", file=sys.stderr)
            return 1
        print(f"{args.path} is up to date")
        return 0
    args.path.write_text(text, encoding="utf-8")
    print(f"wrote {args.path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
