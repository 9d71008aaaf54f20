"""Request frames from command names and values in API units: model support, value ranges and
wire signs checked before anything is built (every failure a FieldValueError or a CatalogError)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from ..errors import FieldValueError, TopGimbalError, UnknownCommandError, UnsupportedError
from ..protocol import CommandSpec, DeviceModel, Dialect, Frame
from ..protocol.frame import DEVICE_ADDRESSES
from . import checks
from .signs import map_values


class FrameBuilder:
    def __init__(self, dialect: Dialect, model: DeviceModel, signs: Mapping[str, int], host_address: str) -> None:
        self.dialect = dialect
        self.model = model
        self.signs = signs
        self.host_address = host_address
        self._plain_frames: dict[tuple[str, bool, str | None], Frame] = {}

    def spec(self, ident: str) -> CommandSpec:
        if not isinstance(ident, str):
            raise FieldValueError("ident", ident, "a command identifier such as 'GAC' or a catalog name")
        try:
            spec = self.dialect.command(ident)
        except UnknownCommandError as exc:
            raise checks.CommandNameError(str(exc)) from None
        if not self.dialect.supports(self.model, spec.ident):
            raise UnsupportedError(f"the {self.model.name} does not support {spec.ident} ({spec.title})")
        return spec

    def build(self, ident: str, values: Mapping[str, object], *, read: bool = False, dst: str | None = None) -> Frame:
        """The frame `request()` would send (values in API units and signs), validated."""
        if not isinstance(read, bool):
            raise FieldValueError("read", read, "True or False")
        if not values:
            cached = self._plain_frames.get((ident, read, dst))
            if cached is not None:
                return cached
        spec = self.spec(ident)
        if dst is not None and (not isinstance(dst, str) or dst not in DEVICE_ADDRESSES):
            raise FieldValueError("dst", dst, f"a device address, one of {', '.join(DEVICE_ADDRESSES)}")
        try:
            self.dialect.check_values(self.model, spec.ident, values)
            wire: dict[str, Any] = map_values(spec, values, self.signs)  # each codec checks its value
            frame = self.dialect.encode(spec.ident, read=read, src=self.host_address, dst=dst, **wire)
        except TopGimbalError:
            raise
        except (ValueError, TypeError, KeyError, ArithmeticError) as exc:
            # a codec that met a value of a kind it does not take: say which, never half-send
            bad = next(iter(values), "values")
            raise FieldValueError(bad, values.get(bad), f"values {spec.ident} accepts ({exc})") from None
        limit = self.model.max_frame_bytes
        if limit is not None and len(frame.to_bytes()) > limit:
            # the firmware drops longer frames (C11: 28 bytes): say so rather than send in vain
            bad = next(iter(values), "values")
            raise FieldValueError(
                bad,
                values.get(bad),
                f"values whose {spec.ident} frame fits the {self.model.name}'s {limit} bytes "
                f"({frame.text()} has {len(frame.to_bytes())})",
            )
        if not values and len(self._plain_frames) < 256 and isinstance(ident, str):
            self._plain_frames[(ident, read, dst)] = frame  # queries: frames are immutable
        return frame
