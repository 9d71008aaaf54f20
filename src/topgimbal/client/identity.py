"""Which model a device is, from what it says about itself. Pure: no I/O.

A device answers identity queries (the catalog roles `model_name`, `version`, `hardware_version`,
`serial_number`: SkyDroid MOD / VER / HWV, TOPOTEK PA2 / VSN / VER). Each model profile lists what
its devices report (`DeviceModel.identity`). A `Report` is one answer; `judge()` compares the
reports with the profiles and says whether they fit the model the client was told, and which
models they fit instead. Real firmware reports versions the profiles do not know, so only an exact
match of a known string counts as evidence; a model name counts most.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field

from ..protocol import DeviceModel, all_models

OK, MISMATCH, UNKNOWN, PENDING, OFF = "ok", "mismatch", "unknown", "pending", "off"


@dataclass(frozen=True)
class Report:
    """One thing the device said about itself: an identity query's answer, a refusal (`text`
    None, `refused` True), or a frame only another dialect decodes (`foreign`)."""

    role: str
    ident: str
    dialect: str
    text: str | None = None
    refused: bool = False
    foreign: bool = False


@dataclass(frozen=True)
class Verdict:
    status: str  # ok | mismatch | unknown | pending | off
    expected: str  # the model the client was told
    fits: tuple[str, ...] = ()  # models the device's answers fit (mismatch: the ones to use)
    reported: Mapping[str, str] = field(default_factory=dict)  # role -> what the device said
    message: str = ""

    def as_dict(self) -> dict[str, object]:
        return {
            "status": self.status,
            "expected": self.expected,
            "fits": list(self.fits),
            "reported": dict(self.reported),
            "message": self.message,
        }


def _norm(text: str) -> str:
    return text.strip().lower()


def matching_models(text: str, profiles: Mapping[str, DeviceModel] | None = None) -> list[str]:
    """Models whose identity strings (any role: a TOPOTEK answers SkyDroid's VER with its serial
    number) or name equal `text`, in catalog order."""
    wanted = _norm(text)
    if not wanted:
        return []
    out = []
    for name, model in (profiles or all_models()).items():
        if wanted == _norm(name) or any(wanted == _norm(v) for v in model.identity.values()):
            out.append(name)
    return out


def models_of_dialect(dialect: str, ident: str, profiles: Mapping[str, DeviceModel] | None = None) -> list[str]:
    """Models of `dialect` that have the command `ident`."""
    return [n for n, m in (profiles or all_models()).items() if m.dialect == dialect and m.supports(ident)]


def judge(model: DeviceModel, reports: Iterable[Report], profiles: Mapping[str, DeviceModel] | None = None) -> Verdict:
    """Whether what the device said fits `model`, and which models it fits."""
    profiles = profiles if profiles is not None else all_models()
    reports = list(reports)
    reported = {r.role: r.text for r in reports if r.text is not None and not r.foreign}
    named = [r for r in reports if r.role == "model_name" and r.text and not r.foreign]
    matched = [(r, matching_models(r.text, profiles)) for r in reports if r.text and not r.foreign]
    expected = model.name

    def verdict(status: str, fits: Iterable[str], message: str) -> Verdict:
        return Verdict(status, expected, tuple(dict.fromkeys(fits)), reported, message)

    # A model name is the strongest evidence.
    for r in named:
        fits = matching_models(r.text or "", profiles)
        if expected in fits:
            return verdict(OK, fits, f"the device reports model {r.text}")
        if fits:
            return verdict(MISMATCH, fits, _mismatch_text(expected, fits, f"{r.ident} answered {r.text}"))
    # Other identity strings: evidence when they match a profile exactly.
    sets = [set(fits) for _, fits in matched if fits]
    if sets:
        common = set.intersection(*sets) or sets[0]
        fits = [n for n in profiles if n in common]
        if expected in common:
            return verdict(OK, fits, f"the identity answers match the {expected} profile")
        what = "; ".join(f"{r.ident} answered {r.text}" for r, f in matched if f)
        return verdict(MISMATCH, fits, _mismatch_text(expected, fits, what))
    # Frames only another dialect decodes: the dialect is wrong, whatever the model.
    foreign = [r for r in reports if r.foreign and r.dialect != model.dialect]
    if foreign:
        r = foreign[0]
        fits = models_of_dialect(r.dialect, r.ident, profiles)
        if r.text:
            fits = matching_models(r.text, profiles) or fits
        return verdict(MISMATCH, fits, _mismatch_text(expected, fits, f"{r.ident} frames from the device decode only "
                                                                       f"as {r.dialect}"))  # fmt: skip
    refused = [r for r in reports if r.refused]
    if refused and len(refused) == len(reports):
        idents = ", ".join(r.ident for r in refused)
        return verdict(UNKNOWN, (), f"the device refused the {expected}'s identity queries ({idents})")
    if named:
        return verdict(UNKNOWN, (), f"the device calls itself {named[0].text}, which no profile knows")
    return verdict(UNKNOWN, (), "the identity answers match no profile (firmware the profiles do not know)")


def suspicious(model: DeviceModel, reports: Iterable[Report]) -> bool:
    """Whether the answers to the model's own queries call for asking in the other dialects: a
    query the model should answer was refused, or nothing answered although the device is there."""
    reports = list(reports)
    return any(r.refused for r in reports) or (bool(reports) and all(r.text is None for r in reports))


def best_guess(
    reports: Iterable[Report], default: str, profiles: Mapping[str, DeviceModel] | None = None
) -> str | None:
    """`detect_model()`'s answer: the model the reports fit best; among several, `default` if it
    is one of them, else the first; a dialect that answered but matched no profile gives its
    `default` (or first) model; None when nothing answered."""
    profiles = profiles if profiles is not None else all_models()
    reports = [r for r in reports if r.text]
    if not reports:
        return None
    for role in ("model_name", "version", "serial_number", "hardware_version"):
        for r in (r for r in reports if r.role == role):
            fits = matching_models(r.text or "", profiles)
            if fits:
                return default if default in fits else fits[0]
    dialect = reports[0].dialect
    in_dialect = [n for n, m in profiles.items() if m.dialect == dialect]
    return default if default in in_dialect else (in_dialect[0] if in_dialect else None)


def _mismatch_text(expected: str, fits: list[str], evidence: str) -> str:
    tail = "with the wrong model, signs and commands may be wrong"
    if not fits:
        return f"the device does not look like a {expected} ({evidence}); check --model; {tail}"
    if len(fits) > 2:  # only the dialect is known
        return (
            f"the device is not a {expected} ({evidence}): it is one of {', '.join(fits)}; pass --model with the "
            f"right one (connect(model=...)); {tail}"
        )
    one = fits[0]
    others = f" (or {fits[1]})" if len(fits) > 1 else ""
    return (
        f"the device looks like a {one}{others}, not a {expected} ({evidence}): pass --model {one} "
        f'(connect(model="{one}")); {tail}'
    )
