"""Before a bridge serves a camera: one that answers and says it is another model than declared is
refused (ModelMismatchError: exit 2, nothing served, nothing sent), so a wrong model is reported at
start rather than as wrong answers later. One not there yet is served; the bridge's camera link
refuses it later if it turns out to be another model (mavlink/camera_link.py).

Used by `topgimbal mavlink` (one camera, `--camera` several) and `topgimbal zenoh --mavlink-keys`."""

from __future__ import annotations

import argparse
import asyncio
import contextlib
from collections.abc import Iterator, Sequence
from typing import Protocol

from .model_check import detect, model_check_records_left_out
from .model_check import refuse_wrong_model as refuse

AUTO_HINT = "; --model auto uses what the device says"  # model_check.refuse_wrong_model's last words


class DeclaredCamera(Protocol):
    """A camera as given on the command line: NAME=URL,MODEL (MODEL may be "auto" where allowed)."""

    @property
    def name(self) -> str: ...
    @property
    def url(self) -> str: ...
    @property
    def model(self) -> str: ...


@contextlib.contextmanager
def _one_line() -> Iterator[None]:
    """The refusal is the error's one line: the client's log record of the same verdict (and of a
    camera not there yet, which is served) is left out while the check runs, as device commands do."""
    with model_check_records_left_out():
        yield


async def refuse_wrong_model(url: str, model: str, timeout_s: float) -> None:
    """Raise ModelMismatchError when the camera at `url` answers as another model than `model`."""
    from ..client import connect
    from ..errors import TransportError

    with _one_line():
        try:
            async with connect(url, model=model, timeout_s=timeout_s, retries=0, host_feeds=False) as cam:
                await refuse(cam)
        except (TransportError, OSError):
            return  # not there (yet): the bridge keeps trying


async def check_cameras(cameras: Sequence[DeclaredCamera], timeout_s: float, *, auto: bool) -> list[str]:
    """Every camera at once; returns each camera's model. With `auto`, MODEL auto becomes what the
    camera says it is (the camera must answer); without, the form has no auto and the error does
    not offer it. The first refusal in the order given is raised, naming the camera in the
    NAME=URL,MODEL form."""
    from ..errors import ModelMismatchError, TopGimbalError

    async def one(cam: DeclaredCamera) -> str:
        if auto and cam.model == "auto":
            try:
                return await detect(argparse.Namespace(url=cam.url, timeout=timeout_s))
            except TopGimbalError as exc:
                raise TopGimbalError(f"camera {cam.name} ({cam.url}): {exc}") from None
        try:
            await refuse_wrong_model(cam.url, cam.model, timeout_s)
        except ModelMismatchError as exc:
            said = str(exc) if auto else str(exc).replace(AUTO_HINT, "")
            said = said.replace("--model ", f"{cam.name}=URL,")  # this form's way to name the model
            raise ModelMismatchError(f"camera {cam.name} ({cam.url}): {said}", fits=exc.fits) from None
        return cam.model

    results = await asyncio.gather(*(one(c) for c in cameras), return_exceptions=True)
    models = []
    for r in results:  # the first refusal in the order given (the others were checked too)
        if isinstance(r, BaseException):
            raise r
        models.append(r)
    return models
