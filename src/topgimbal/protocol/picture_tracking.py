"""Tracking what is at a point or in a box of the picture: picture fractions -> the model's tracking
request, found by role (SkyDroid GOT, TOPOTEK LOC). Pure; `topgimbal.video.lens` re-exports it."""

from __future__ import annotations

from typing import Any

from .commands import CommandSpec
from .dialect import Dialect
from .models import DeviceModel
from .streams import VideoError

# TOPOTEK's LOC box, as ArduPilot's TOPOTEK driver (written with the vendor, fixed on hardware)
# sends it: centre and size in a frame whose centre is 0 and whose edges are -1000 and +1000 on
# each axis (its 1920x1080 picture: x = (px - 960) / 0.96), and LOC alone starts tracking. A point
# is tracked as a box of TRACK_RANGE 60 px of that picture; the two bytes after the box are 0, 1.
# (The catalog names the fields x_px... and "reserved" and gives no range: for protocol/ to settle.)
LOC_HALF_SPAN = 1000
POINT_BOX = (60 / 1920, 60 / 1080)  # fractions of the picture


def _field_max(spec: CommandSpec, name: str) -> float | None:
    for form in spec.describe()["forms"]:
        for f in form["fields"]:
            if f["name"] == name and f.get("max") is not None:
                return float(f["max"])
    return None


def tracking_requests(
    dialect: Dialect, model: DeviceModel, x0: float, y0: float, x1: float | None = None, y1: float | None = None
) -> list[tuple[str, dict[str, Any]]]:
    """The requests that start tracking what is at a point (x0, y0) or in a box (x0, y0)-(x1, y1)
    of the picture (fractions 0..1, top left 0, 0), found by role: the `tracking_target` command
    (SkyDroid GOT) at the point or the box's centre, in the picture its catalog fields span
    (1280x720); else the `tracking_box` command (TOPOTEK LOC) with the box (a point: a small box
    around it). Raises VideoError for a model that does not track."""
    if x1 is None or y1 is None:
        x1, y1 = x0, y0
    xa, xb, ya, yb = min(x0, x1), max(x0, x1), min(y0, y1), max(y0, y1)
    if not all(0.0 <= v <= 1.0 for v in (xa, xb, ya, yb)):
        raise VideoError("picture coordinates must be fractions from 0 to 1")
    cx, cy = (xa + xb) / 2, (ya + yb) / 2
    target, box_spec = dialect.by_role("tracking_target", model), dialect.by_role("tracking_box", model)
    if target is not None:
        w, h = _field_max(target, "x_px") or 1280.0, _field_max(target, "y_px") or 720.0
        return [(target.ident, {"x_px": round(cx * w), "y_px": round(cy * h)})]
    if box_spec is not None:
        bw, bh = (xb - xa, yb - ya) if (xb > xa and yb > ya) else POINT_BOX
        s = LOC_HALF_SPAN
        box = {
            "x_px": round((2 * cx - 1) * s),
            "y_px": round((2 * cy - 1) * s),
            "width_px": max(1, round(bw * 2 * s)),
            "height_px": max(1, round(bh * 2 * s)),
            "reserved": "0001",
        }  # fmt: skip  (ArduPilot's last two bytes: 0, 1)
        return [("LOC", box)]
    raise VideoError(f"the {model.name} does not track targets")
