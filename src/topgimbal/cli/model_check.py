"""What a device command checks of the model first (the module docstring of device_cmds.py says
why): `--model auto` asks the device what it is (`detect`); with a model given, the client's
background model check is waited for briefly and a device that says it is another model is refused
before anything is sent (`refuse_wrong_model`); after the command, an answer read through the wrong
model is not shown (`verdict_of`, `with_hint`). While a command runs, the client's own log records of
the check are left out: the command says the same in its one line. Used by the device commands and
by the bridges' start (model_guard.py)."""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import copy
import logging
from collections.abc import Iterator
from typing import TYPE_CHECKING

from ..client.identity import Verdict
from ..clock import monotonic
from ..errors import ModelMismatchError, TopGimbalError

if TYPE_CHECKING:
    from ..client import AsyncClient

MODEL_CHECK_WAIT_S = 2.0  # at most this long before / after a command for the device to say what it is
NOTHING_HEARD_S = 0.6  # no frame at all by then: stop waiting for the model check (the port is empty)
AUTO_MODEL = "auto"  # --model auto: ask the device what it is


async def refuse_wrong_model(cam: AsyncClient) -> None:
    """Wait for the model check before the command (module docstring); raise ModelMismatchError when
    the device says it is another model. Nothing heard within NOTHING_HEARD_S: go on, the command's
    own error says there is nothing at the address."""
    start = monotonic()
    while not cam.identity.done.is_set() and monotonic() - start < MODEL_CHECK_WAIT_S:
        if monotonic() - start >= NOTHING_HEARD_S and not cam.stats.frames_in:
            return
        await asyncio.sleep(0.02)
    verdict = cam.model_check
    if verdict.status == "mismatch":
        found = f" (found: {verdict.fits[0]})" if verdict.fits else ""
        raise ModelMismatchError(f"{verdict.message}; nothing was sent{found}; --model auto uses what the device says",
                                 fits=verdict.fits)  # fmt: skip


async def verdict_of(cam: AsyncClient) -> Verdict | None:
    """The model check's verdict when the device says it is another model than --model (the check
    runs in the background from connect; a command that finished first waits for it briefly)."""
    if not cam.stats.frames_in:
        return None  # nothing has come at all: the command's own error says so
    verdict = await cam.wait_model_check(MODEL_CHECK_WAIT_S)
    return verdict if verdict.status == "mismatch" else None


def with_hint(exc: TopGimbalError, hint: str, model: str) -> TopGimbalError:
    from ..client.requesting import model_hint

    new = copy.copy(exc)  # keeps `request` (the frame the error is about)
    new.args = (f"{str(exc).replace(model_hint(model), '')}; {hint}",)
    return new


@contextlib.contextmanager
def model_check_records_left_out() -> Iterator[None]:
    """While the command runs, the client's log records of the model check (and of a link lost
    before anything was heard) are left out: the command says the same in its own one line. Scoped,
    not installed for good: `main()` called in a process that goes on (a test, a program embedding
    the CLI) must keep the client's log as it was (a left-over filter hid a later client's lines)."""
    client_log, quiet = logging.getLogger("topgimbal.client"), _NoModelCheckRecords()
    client_log.addFilter(quiet)
    try:
        yield
    finally:
        client_log.removeFilter(quiet)


class _NoModelCheckRecords(logging.Filter):
    """The CLI says what the model check found in its own one line: the log record would repeat it;
    so does a link lost before anything was heard (the command's error says nothing answered)."""

    def filter(self, record: logging.LogRecord) -> bool:
        if getattr(record, "link_lost", False) and not getattr(record, "heard", True):
            return False
        return not hasattr(record, "model_check")


async def detect(args: argparse.Namespace) -> str:
    """No --model: ask the device what it is (version and model name, in every dialect)."""
    from ..client import connect

    async with connect(
        args.url, model="C12", timeout_s=min(args.timeout, 0.5), retries=1, check_model=False, host_feeds=False
    ) as cam:
        found = await cam.detect_model()
        heard = cam.stats.frames_in > 0
    if found is None:
        why = "it answered neither query" if heard else f"nothing at all came from {args.url}"
        raise TopGimbalError(f"no --model given and the device did not identify itself ({why}); pass --model")
    return found
