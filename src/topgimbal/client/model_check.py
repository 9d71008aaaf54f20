"""Asking the device what it is: the check on connect, `detect_model()`, and foreign frames.

On connect the client asks the identity queries of its own model (version first: quick and usually
enough; then the model name, which a C12 may answer minutes late or never; then the hardware
version), one at a time with a short timeout, in the background: nothing waits for it, and other
requests go out meanwhile. When the answers fit another model, or the device refuses its own
model's queries, it also asks the other dialects' queries to say which `--model` fits. The result is
`cam.model_check` (an `identity.Verdict`), a log warning and the `on_model_check` callbacks; a model
name that arrives later (a late MOD answer) or a frame only another dialect decodes updates it.
"""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Callable, Iterable

from ..errors import DeviceError, LinkLostError, RequestTimeoutError, TopGimbalError
from ..protocol import DIALECT_NAMES, DeviceModel, Dialect, Frame, Message, decode_any, get_dialect
from . import identity, roles
from .identity import Report, Verdict
from .ports import ModelCheckPort

log = logging.getLogger("topgimbal.client")

CHECK_TIMEOUT_S = 0.5  # per identity query: the check must never hold anything up for long
FOREIGN_LIMIT = 8  # frames only another dialect decodes that are looked at (the rest are counted)

Listener = Callable[[Verdict], object]


class ModelChecker:
    def __init__(self, core: ModelCheckPort) -> None:
        self.core = core
        self.reports: list[Report] = []
        self.verdict = Verdict(identity.PENDING, core.model.name)
        self.done = asyncio.Event()
        self.listeners: list[Listener] = []
        self.foreign_frames = 0
        self._warned = False
        self.unheard = False  # the check ended with nothing heard from the device: asked again when it is
        self.detecting = 0  # `detect()` runs: what the device says is its answer, not evidence against the model

    # -- results -----------------------------------------------------------------------------

    def _set(self, verdict: Verdict) -> None:
        changed = verdict.status != self.verdict.status or verdict.fits != self.verdict.fits
        self.verdict = verdict
        if verdict.status == identity.MISMATCH and not self._warned:
            self._warned = True
            log.warning("%s: %s", self.core.url, verdict.message, extra={"model_check": verdict})
        if changed:
            for cb in list(self.listeners):
                try:
                    cb(verdict)
                except Exception:
                    log.exception("model check callback %r failed", cb)

    def add(self, report: Report) -> None:
        """Something the device said outside the check (a late model name, a foreign frame).
        While the check runs it only collects; after, it may change the verdict."""
        if self.detecting:
            return  # asked by `detect()` in every dialect: the model given is a placeholder
        self.reports.append(report)
        if not self.done.is_set():
            return
        if self.verdict.status in (identity.UNKNOWN, identity.OFF) or report.role == "model_name":
            verdict = identity.judge(self.core.model, self.reports)
            if verdict.status != identity.UNKNOWN:
                self._set(verdict)

    def on_model_name(self, text: object) -> None:
        if isinstance(text, str) and not any(r.role == "model_name" and r.text == text for r in self.reports):
            ident = roles.role_ident(self.core.dialect, self.core.model, "model_name") or "?"
            self.add(Report("model_name", ident, self.core.dialect.name, text.strip()))

    def on_foreign(self, frame: Frame) -> Message | None:
        """A frame the client's dialect cannot decode: when another dialect can, that is evidence
        of a wrong `--model`. Returns the other dialect's message (None: nobody decodes it)."""
        self.foreign_frames += 1
        if self.foreign_frames > FOREIGN_LIMIT:
            return None
        other = decode_any(frame, prefer=self.core.dialect)
        if other.fields is None or other.dialect == self.core.dialect.name or other.spec is None:
            return None
        role = other.spec.role
        text = roles.answer_text(other.spec, other.fields) if role in roles.IDENTITY_ROLES else None
        self.add(Report(role or "frame", frame.ident, other.dialect or "", text, foreign=True))
        return other

    def finish(self, verdict: Verdict) -> None:
        self._set(verdict)
        self.done.set()

    def recheck(self) -> bool:
        """The device's first frame after a check that heard nothing from it (it was off, or not
        there yet): the verdict goes back to pending, and the caller runs the check again (True).
        Without this a camera that came up later as another model kept "unknown" and was served."""
        if not self.unheard:
            return False
        self.unheard = False
        self.done.clear()
        self._set(Verdict(identity.PENDING, self.core.model.name, message="asked again: nothing was heard before"))
        return True

    # -- the check ---------------------------------------------------------------------------

    async def run(self) -> Verdict:
        """Ask the device (see the module docstring); never raises."""
        core = self.core
        try:
            own = await ask(core, core.dialect, core.model, stop_when=self._conclusive)
            self.reports += own
            verdict = identity.judge(core.model, self.reports)
            if verdict.status == identity.UNKNOWN and identity.suspicious(core.model, own) and core.stats.frames_in:
                for name in DIALECT_NAMES:
                    other = get_dialect(name)
                    if other.name != core.dialect.name:
                        self.reports += await ask(core, other, None, roles_=("model_name", "version"))
                verdict = identity.judge(core.model, self.reports)
        except asyncio.CancelledError:
            raise
        except TopGimbalError as exc:
            verdict = Verdict(identity.UNKNOWN, core.model.name, message=f"the model check stopped: {exc}")
        self.unheard = verdict.status == identity.UNKNOWN and not core.stats.frames_in
        self.finish(verdict)
        return verdict

    def _conclusive(self, reports: list[Report]) -> bool:
        return identity.judge(self.core.model, [*self.reports, *reports]).status != identity.UNKNOWN


async def ask(
    core: ModelCheckPort,
    dialect: Dialect,
    model: DeviceModel | None,
    *,
    roles_: Iterable[str] = roles.IDENTITY_ROLES,
    stop_when: Callable[[list[Report]], bool] | None = None,
    timeout_s: float = CHECK_TIMEOUT_S,
) -> list[Report]:
    """Ask `dialect`'s identity queries (those `model` has, when given), version first, one at a
    time; returns what came back. Stops early once `stop_when(reports)` holds."""
    wanted = set(roles_)
    queries = [(r, s) for r, s in roles.identity_queries(dialect, model) if r in wanted]
    queries.sort(key=lambda q: q[0] != "version")
    src = core.host_address if core.host_address in dialect.host_addresses else dialect.host_addresses[0]
    out: list[Report] = []
    models = list(dialect.models.values()) if model is None else [model]
    for role, spec in queries:
        slow = any(spec.ident in m.slow_answers for m in models)
        lenient = any(spec.ident in roles.recovered_ok(dialect, m) for m in models)
        probe = dialect.encode(spec.ident, read=True, src=src)
        try:
            reply = await core.transact(
                probe, timeout_s=min(timeout_s, core.timeout_s), retries=0, slow=slow, lenient=lenient
            )
        except DeviceError:
            out.append(Report(role, spec.ident, dialect.name, refused=True))
            continue
        except RequestTimeoutError:
            out.append(Report(role, spec.ident, dialect.name))
            continue
        except LinkLostError:
            break
        if reply is None:
            continue
        decoded = decode_any(reply.frame, prefer=dialect)
        text = roles.answer_text(decoded.spec, decoded.fields) if decoded.spec and decoded.fields else None
        out.append(Report(role, spec.ident, decoded.dialect or dialect.name, text))
        if stop_when is not None and stop_when(out):
            break
    return out


async def detect(
    core: ModelCheckPort, timeout_s: float, default: str, checker: ModelChecker | None = None
) -> str | None:
    """The model the device's identity answers fit best (see `identity.best_guess`). While it asks,
    `checker` (the client's) takes no evidence from the answers: a model name or a frame of another
    dialect is what detection is for, not a wrong model to warn about (`--model auto` is quiet)."""
    reports: list[Report] = []
    if checker is not None:
        checker.detecting += 1
    try:
        for name in DIALECT_NAMES:
            d = get_dialect(name)
            got = await ask(core, d, None, roles_=("version", "model_name"), timeout_s=timeout_s)
            reports += got
            if any(identity.matching_models(r.text) for r in got if r.text):
                break
    finally:
        if checker is not None:
            checker.detecting -= 1
    return identity.best_guess(reports, default)
