"""The synthetic world the simulated camera looks at: a sphere of directions around the camera
with a horizon, a ground grid, numbered landmarks at known bearings and the warm object of
sim/scene.py (so the thermal picture and the TMP reports agree). Pure data and small functions.

Angles are earth-frame: bearing (azimuth, right-positive from north) and elevation (up-positive).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

from ..geo.earth import wrap180
from ..sim import scene as sim_scene

# The camera stands this high above flat ground; the grid is a square of roads around it.
CAMERA_HEIGHT_M = 30.0
GRID_SPACING_M = 25.0
GRID_HALF_EXTENT_M = 500.0
# A landmark is a bullseye this wide (angular radius) with its number beside it.
LANDMARK_RADIUS_DEG = 0.8


@dataclass(frozen=True)
class Landmark:
    number: int
    az_deg: float
    el_deg: float


def _landmarks() -> tuple[Landmark, ...]:
    marks = [Landmark(i + 1, wrap(i * 30.0), 0.0) for i in range(12)]  # 1..12 round the horizon
    # A few on the ground (and one in the sky) to point at with pitch as well.
    extra = [(15.0, -20.0), (-45.0, -35.0), (100.0, -60.0), (-120.0, -12.0), (60.0, 15.0), (-20.0, -8.0)]
    marks += [Landmark(13 + i, az, el) for i, (az, el) in enumerate(extra)]
    return tuple(marks)


wrap = wrap180  # the one angle wrap (topgimbal.geo.earth), by its old name here


LANDMARKS = _landmarks()

HOT_SPOT = (sim_scene.HOT_SPOT_YAW_DEG, sim_scene.HOT_SPOT_PITCH_DEG)
HOT_SPOT_C = sim_scene.HOT_SPOT_C
HOT_SPOT_WIDTH_DEG = sim_scene.HOT_SPOT_WIDTH_DEG
SKY_C = sim_scene.SKY_C
GROUND_C = sim_scene.GROUND_C
ROAD_C = 31.0
LANDMARK_C = 48.0
# The thermal picture maps this temperature span onto its 256 palette entries.
THERMAL_SPAN_C = (-15.0, 65.0)


def landmark(number: int) -> Landmark:
    for m in LANDMARKS:
        if m.number == number:
            return m
    raise KeyError(number)


# -- palettes ------------------------------------------------------------------------------------

# Colour stops (position 0..1 -> RGB) per palette name of either dialect; unknown names are white hot.
_STOPS: dict[str, list[tuple[float, tuple[int, int, int]]]] = {
    "white_hot": [(0, (0, 0, 0)), (1, (255, 255, 255))],
    "black_hot": [(0, (255, 255, 255)), (1, (0, 0, 0))],
    "ironbow": [
        (0, (0, 0, 20)),
        (0.3, (90, 0, 140)),
        (0.55, (220, 40, 40)),
        (0.8, (250, 170, 0)),
        (1, (255, 255, 220)),
    ],
    "hot_iron": [(0, (0, 0, 0)), (0.4, (160, 0, 0)), (0.75, (255, 160, 0)), (1, (255, 255, 255))],
    "lava": [(0, (0, 0, 60)), (0.4, (120, 0, 120)), (0.7, (255, 60, 0)), (1, (255, 255, 120))],
    "rainbow": [(0, (0, 0, 160)), (0.25, (0, 160, 255)), (0.5, (0, 220, 0)), (0.75, (255, 220, 0)), (1, (255, 0, 0))],
    "rainbow1": [(0, (0, 0, 160)), (0.25, (0, 160, 255)), (0.5, (0, 220, 0)), (0.75, (255, 220, 0)), (1, (255, 0, 0))],
    "rainbow2": [(0, (60, 0, 90)), (0.3, (0, 0, 255)), (0.55, (0, 255, 120)), (0.8, (255, 255, 0)), (1, (255, 40, 0))],
    "sepia": [(0, (20, 10, 0)), (1, (255, 220, 160))],
    "night": [(0, (0, 20, 0)), (1, (160, 255, 160))],
    "aurora": [(0, (0, 0, 40)), (0.5, (0, 180, 160)), (1, (230, 255, 120))],
    "red_hot": [(0, (0, 0, 0)), (0.7, (200, 200, 200)), (0.85, (255, 120, 0)), (1, (255, 0, 0))],
    "red_tint": [(0, (0, 0, 0)), (0.7, (200, 200, 200)), (0.85, (255, 120, 0)), (1, (255, 0, 0))],
    "jungle": [(0, (0, 30, 0)), (0.5, (60, 140, 20)), (1, (255, 255, 80))],
    "medical": [(0, (0, 0, 0)), (0.3, (0, 0, 255)), (0.5, (0, 255, 0)), (0.7, (255, 255, 0)), (1, (255, 0, 0))],
    "arctic": [(0, (0, 0, 80)), (0.5, (80, 160, 255)), (0.8, (255, 200, 0)), (1, (255, 255, 255))],
    "glory_hot": [(0, (0, 0, 0)), (0.6, (180, 120, 40)), (1, (255, 230, 120))],
}


def palette(name: str) -> list[int]:
    """A 256-entry RGB palette (flat list of 768 ints, Pillow's putpalette form)."""
    stops = _STOPS.get(name, _STOPS["white_hot"])
    out: list[int] = []
    for i in range(256):
        t = i / 255.0
        for (p0, c0), (p1, c1) in itertools.pairwise(stops):
            if p0 <= t <= p1:
                k = 0.0 if p1 == p0 else (t - p0) / (p1 - p0)
                out += [round(a + (b - a) * k) for a, b in zip(c0, c1, strict=False)]
                break
    return out


def palette_names() -> list[str]:
    return sorted(_STOPS)


def temperature_level(t_c: float) -> int:
    """Palette index (0..255) of a temperature."""
    lo, hi = THERMAL_SPAN_C
    return max(0, min(255, round((t_c - lo) / (hi - lo) * 255)))
