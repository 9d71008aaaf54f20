"""Date and time as fixed decimal text (SkyDroid TIM, TOPOTEK TIM and UTC)."""

from __future__ import annotations

from dataclasses import dataclass, field
from datetime import datetime
from typing import ClassVar

from ...errors import FieldValueError
from .base import Codec


@dataclass(frozen=True)
class Timestamp(Codec):
    """A date and time as fixed decimal text. `layout` is a strftime pattern; `%f2` means
    hundredths of a second (SkyDroid TIM `hhmmss.ssDDMMYY`). User value: `datetime` (naive; an
    aware one is sent as its own wall-clock time).

    The years a layout can hold: 2000..2099 with `%y` (a camera clock lives there), 1000..9999 with
    `%Y`; anything else is refused rather than sent in a shape the device cannot parse."""

    layout: str = "%Y%m%d%H%M%S"
    kind: ClassVar[str] = "datetime"
    width: int | None = field(init=False, default=None)
    _years: tuple[int, int] = field(init=False, repr=False, compare=False, default=(1000, 9999))
    _hundredths_at: int = field(init=False, repr=False, compare=False, default=-1)

    def __post_init__(self) -> None:
        sample = datetime(2000, 1, 1).strftime(self.layout.replace("%f2", "00"))
        object.__setattr__(self, "width", len(sample))
        object.__setattr__(self, "_years", (2000, 2099) if "%y" in self.layout else (1000, 9999))
        if "%f2" in self.layout:
            at = self.layout.index("%f2")
            object.__setattr__(self, "_hundredths_at", len(datetime(2000, 1, 1).strftime(self.layout[:at])))

    def allowed(self) -> str:
        lo, hi = self._years
        return f"a date and time in {lo}..{hi} (ISO 8601 text or datetime), sent as {self.layout.replace('%f2', 'ss')}"

    def encode(self, value: object, name: str = "value") -> bytes:
        if isinstance(value, str) and len(value) <= 40:
            try:
                value = datetime.fromisoformat(value)
            except ValueError:
                raise FieldValueError(name, value, self.allowed()) from None
        if not isinstance(value, datetime) or not self._years[0] <= value.year <= self._years[1]:
            raise FieldValueError(name, value, self.allowed())
        out = value.strftime(self.layout.replace("%f2", f"{value.microsecond // 10000:02d}"))
        if len(out) != self.width or not out.replace(".", "").isdigit():
            raise FieldValueError(name, value, self.allowed())
        return out.encode("ascii")

    def decode(self, raw: bytes) -> datetime:
        text = raw.decode("ascii")
        if len(text) != self.width:
            raise ValueError(f"{raw!r} is not {self.width} characters")
        if not text.replace(".", "").isdigit():
            raise ValueError(f"{raw!r} is not {self.layout.replace('%f2', 'ss')}")
        at = self._hundredths_at
        if at >= 0:
            hundredths = int(text[at : at + 2])
            dt = datetime.strptime(text[:at] + text[at + 2 :], self.layout.replace("%f2", ""))
            dt = dt.replace(microsecond=hundredths * 10000)
        else:
            dt = datetime.strptime(text, self.layout)
        if "%y" in self.layout and dt.year < 2000:
            dt = dt.replace(year=dt.year + 100)  # two-digit years: a camera clock lives in 2000..2099
        return dt

    def parse_text(self, text: str) -> datetime:
        return datetime.now() if text == "now" else datetime.fromisoformat(text)

    def neutral(self) -> datetime:
        return datetime(2000, 1, 1)


__all__ = ["Timestamp"]
