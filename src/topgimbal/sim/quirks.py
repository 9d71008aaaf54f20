"""Known real-device quirks, switchable per simulator. Each is off unless its model's default or the
caller turns it on; `resolve()` rejects names it does not know, listing the ones it does."""

from __future__ import annotations

from collections.abc import Mapping

QUIRKS: dict[str, str] = {
    "lowercase_header": "frames that would start #TP (replies, streams, errors) start #tp instead, as seen from TOPOTEK firmware",
    "crlf": "every frame the simulator sends ends with CR LF (some firmware does)",
    "no_motion_echo": "motion commands (PTZ, GS*, RPS, YPR, GA*, GI*) are obeyed but not echoed",
    "ver_wrong_length": "the VER reply's length character says 3 although it carries 6 characters "
    "(a real C12: #tpDU3rVER0105025A; the checksum covers all 6)",
}

# What each model does by default. The C12's VER reply is documented from a real unit; every other
# quirk is off so that a client written against the documents works unchanged.
MODEL_DEFAULTS: dict[str, frozenset[str]] = {
    "C12": frozenset({"ver_wrong_length"}),
}


def resolve(model: str, overrides: Mapping[str, bool] | None = None) -> dict[str, bool]:
    """The quirk switches for `model`: its defaults, then `overrides`."""
    on = MODEL_DEFAULTS.get(model, frozenset())
    out = {name: name in on for name in QUIRKS}
    for name, value in (overrides or {}).items():
        if name not in QUIRKS:
            raise ValueError(f"unknown quirk {name!r}; known: {', '.join(QUIRKS)}")
        out[name] = bool(value)
    return out


def parse(text: str) -> dict[str, bool]:
    """CLI form: `lowercase_header,crlf,-ver_wrong_length` (a leading - or no- turns one off)."""
    out: dict[str, bool] = {}
    for item in filter(None, (p.strip() for p in text.split(","))):
        name, value = item, True
        if item.startswith("-"):
            name, value = item[1:], False
        elif item.startswith("no-"):
            name, value = item[3:], False
        elif "=" in item:
            name, _, raw = item.partition("=")
            if raw.lower() not in ("1", "0", "on", "off", "true", "false", "yes", "no"):
                raise ValueError(f"quirk {item!r}: expected NAME, -NAME or NAME=on/off")
            value = raw.lower() in ("1", "on", "true", "yes")
        if name not in QUIRKS:
            raise ValueError(f"unknown quirk {name!r}; known: {', '.join(QUIRKS)}")
        out[name] = value
    return out
