"""Coordinates with a hemisphere letter, in the two spellings the documents use.

One codec, `Geo(axis, style)`:

    style "dm"   NMEA degrees and minutes   N3030.1234   E11400.5678   (host -> device position)
    style "deg"  decimal degrees            N22.123456   E113.123456   (TOPOTEK §8.7 target solution)

The user value is signed decimal degrees (south and west negative). Encoding rounds once, in whole
units of the last digit (1e-4 minute or 1e-6 degree), so a value just below a whole minute never
becomes "60.0000" and re-encoding a decoded value gives the same text."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar

from ...errors import FieldValueError
from .base import Codec, to_number

_STYLES = {
    # style: (digits after the point, units per degree, pattern for lat, pattern for lon)
    "dm": (4, 60 * 10**4, "N/S ddmm.mmmm", "E/W dddmm.mmmm"),
    "deg": (6, 10**6, "N/S dd.dddddd", "E/W ddd.dddddd"),
}


@dataclass(frozen=True)
class Geo(Codec):
    """A latitude (`axis="lat"`) or longitude (`axis="lon"`) with a hemisphere letter, in degrees
    and minutes (`style="dm"`) or decimal degrees (`style="deg"`)."""

    axis: str = "lat"
    style: str = "dm"
    unit: str = "deg"
    kind: ClassVar[str] = "coordinate"
    width: int | None = field(init=False, default=None)
    limit: int = field(init=False, default=90)
    _hemi: tuple[str, str] = field(init=False, repr=False, compare=False, default=("N", "S"))
    _deg_digits: int = field(init=False, repr=False, compare=False, default=2)
    _frac_digits: int = field(init=False, repr=False, compare=False, default=4)
    _per_deg: int = field(init=False, repr=False, compare=False, default=1)
    _pattern: str = field(init=False, repr=False, compare=False, default="")

    def __post_init__(self) -> None:
        if self.axis not in ("lat", "lon") or self.style not in _STYLES:
            raise ValueError(f"Geo(axis={self.axis!r}, style={self.style!r}): axis lat|lon, style dm|deg")
        frac, per_deg, lat_pat, lon_pat = _STYLES[self.style]
        lat = self.axis == "lat"
        set_ = object.__setattr__
        set_(self, "width", 10 if lat else 11)
        set_(self, "limit", 90 if lat else 180)
        set_(self, "_hemi", ("N", "S") if lat else ("E", "W"))
        set_(self, "_deg_digits", 2 if lat else 3)
        set_(self, "_frac_digits", frac)
        set_(self, "_per_deg", per_deg)
        set_(self, "_pattern", lat_pat if lat else lon_pat)

    @property
    def min(self) -> float:
        return -float(self.limit)

    @property
    def max(self) -> float:
        return float(self.limit)

    @property
    def step(self) -> float:
        """The resolution in degrees (1e-4 minute or 1e-6 degree)."""
        return 1 / self._per_deg

    def allowed(self) -> str:
        return f"-{self.limit}..{self.limit} deg (sent as {self._pattern})"

    def encode(self, value: object, name: str = "value") -> bytes:
        v = to_number(value, name, self)
        if not -self.limit <= v <= self.limit:
            raise FieldValueError(name, value, self.allowed())
        units = round(abs(v) * self._per_deg)
        hemi = self._hemi[0] if v >= 0 or units == 0 else self._hemi[1]
        deg, rest = divmod(units, self._per_deg)
        frac_scale = 10**self._frac_digits
        if self.style == "dm":
            minutes, frac = divmod(rest, frac_scale)
            body = f"{deg:0{self._deg_digits}d}{minutes:02d}.{frac:0{self._frac_digits}d}"
        else:
            body = f"{deg:0{self._deg_digits}d}.{rest:0{self._frac_digits}d}"
        return (hemi + body).encode("ascii")

    def decode(self, raw: bytes) -> float:
        text = raw.decode("ascii").replace(" ", "")
        hemi, body = text[:1].upper(), text[1:]
        point = self._deg_digits + (2 if self.style == "dm" else 0)
        if (
            hemi not in self._hemi
            or body.find(".") != point
            or not body.replace(".", "", 1).isdigit()
            or len(body) - point - 1 < 1
        ):
            raise ValueError(f"{raw!r} is not {self._pattern}")
        if self.style == "dm":
            deg, minutes = int(body[: point - 2]), float(body[point - 2 :])
            if minutes >= 60:
                raise ValueError(f"{raw!r}: minutes {minutes} >= 60")
            v = deg + minutes / 60
        else:
            v = float(body)
        if v > self.limit:
            raise ValueError(f"{raw!r} is beyond {self.limit} degrees")
        return round(v if hemi == self._hemi[0] else -v, 7) + 0.0

    def neutral(self) -> float:
        return 0.0


def GeoDM(axis: str = "lat") -> Geo:  # noqa: N802  (the former class name, kept for imports)
    """Degrees and minutes: `Geo(axis, "dm")`."""
    return Geo(axis, "dm")


def GeoDeg(axis: str = "lat") -> Geo:  # noqa: N802
    """Decimal degrees: `Geo(axis, "deg")`."""
    return Geo(axis, "deg")


__all__ = ["Geo", "GeoDM", "GeoDeg"]
