"""Generate docs/protocol.md from the catalog (`--check` fails when the file is stale).

The catalog is the single source: this page is never edited by hand."""

from __future__ import annotations

import argparse
import difflib
import sys
from pathlib import Path

from ..protocol import DIALECT_NAMES, get_dialect
from ..protocol.catalog import REQUEST, CommandSpec, Dialect, Form
from ..protocol.frame import ADDRESS_NAMES

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


def render() -> str:
    out = [
        "# TOP protocol reference",
        "",
        "Generated from the catalog by `python -m topgimbal.tools.gendocs docs/protocol.md`; CI checks it is",
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
    for name in DIALECT_NAMES:
        d = get_dialect(name)
        out += [f"## {d.title} — dialect `{d.name}`", ""]
        out.append("| model | endpoints | yaw / pitch / roll range (deg) | wire signs | features |")
        out.append("|---|---|---|---|---|")
        for m in d.models.values():
            feats = [f for f, on in (("thermal", m.thermal), ("laser range", m.lrf_range_m is not None)) if on]
            if m.optical_zoom_max > 1:
                feats.append(f"{m.optical_zoom_max:g}x optical zoom")
            signs = ", ".join(f"{k} {'+' if v > 0 else '-'}" for k, v in m.wire_signs.items())
            out.append(
                f"| {m.name} | {', '.join(str(e) for e in m.endpoints)} | "
                f"{m.yaw_range_deg[0]:g}..{m.yaw_range_deg[1]:g} / {m.pitch_range_deg[0]:g}..{m.pitch_range_deg[1]:g} / "
                f"{m.roll_range_deg[0]:g}..{m.roll_range_deg[1]:g} | {signs} | {', '.join(feats) or '-'} |"
            )
        out.append("")
        by_class: dict[str, list[CommandSpec]] = {}
        for spec in d.commands.values():
            by_class.setdefault(spec.address, []).append(spec)
        for cls in CLASS_ORDER:
            specs = by_class.get(cls)
            if not specs:
                continue
            out += [f"### `{d.name}` {cls} class — {ADDRESS_NAMES[cls]}", ""]
            out.append("| id | name | write (host → device) | query / answer | other device → host | models | source |")
            out.append("|---|---|---|---|---|---|---|")
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
                    f"| `{spec.ident}` | {spec.name}<br>{title} | {write} | {qa} | {other} | {_models(d, spec)} | "
                    f"{_cell(spec.section)} |"
                )
            out.append("")
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
