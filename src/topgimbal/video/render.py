"""Draw what the simulated camera sees: numpy for the sky/ground shading, Pillow (C) for lines,
discs and text. Everything the scene contains is a point or a straight line on the sphere or the
ground plane, so it is projected (a few hundred points per frame with numpy) and drawn as vectors:
crisp at any zoom, and cheap (see bench/video.py).

The shading is per pixel but needs no trigonometry per frame: for a pinhole camera the sine of a
pixel's elevation is (f_z + a r_z + b u_z) / |(1, a, b)|, where (a, b) are the pixel's tangent-plane
coordinates (fixed for a given field of view: precomputed), and f, r, u the camera's forward,
right and up vectors. It is computed at a quarter of the resolution and scaled up.

A renderer draws in RGB (`mode="RGB"`, for people and tests) or straight in Y'CbCr
(`mode="YCbCr"`: BT.601, limited range, what an H.264 stream carries): the shading tables, the
palettes and every colour are converted once, so the encoder only averages the chroma over 2x2
pixels instead of converting every pixel from RGB (bench/video.py measures both paths).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from dataclasses import dataclass
from datetime import datetime
from typing import Union, overload

import numpy as np
from PIL import Image, ImageDraw, ImageFont

from ..geo.earth import wrap360
from . import world
from .lens import basis, focal_px, hfov_at
from .projection import Camera, clip_far, world_dir
from .snapshot import SceneState

SHADE_DOWNSCALE = 4
LUT_SIZE = 1024
# Timestamp barcode: bits of the wall-clock time in ms, one cell each, at the bottom left.
STAMP_BITS = 48
STAMP_CELLS_PER_WIDTH = 80  # a cell is width / 80 pixels square


def stamp_layout(width: int, height: int) -> tuple[float, float, float]:
    """(x of the first bit cell, y of the cells' top, cell size) in pixels. Cells: a white and a
    black guard, then STAMP_BITS bits, most significant first (white = 1)."""
    cell = width / STAMP_CELLS_PER_WIDTH
    return cell, height - 2.0 * cell, cell


def decode_stamp(rgb: np.ndarray) -> int | None:
    """The burned-in wall-clock time (ms) of a decoded picture, or None when the guards are not
    there (a picture from elsewhere, or too damaged)."""
    h, w = rgb.shape[:2]
    x0, y0, cell = stamp_layout(w, h)
    gray = rgb.mean(axis=2) if rgb.ndim == 3 else rgb

    def level(i: int) -> float:
        cx, cy = x0 + (i + 0.5) * cell, y0 + 0.5 * cell
        q = max(1, int(cell / 4))
        return float(gray[int(cy) - q : int(cy) + q, int(cx) - q : int(cx) + q].mean())

    if not (level(0) > 160 and level(1) < 96):
        return None
    value = 0
    for i in range(STAMP_BITS):
        value = (value << 1) | (1 if level(2 + i) > 128 else 0)
    return value


def _lut_visible() -> np.ndarray:
    s = np.linspace(-1.0, 1.0, LUT_SIZE)
    lut = np.zeros((LUT_SIZE, 3), np.float32)
    up = s >= 0
    k = np.sqrt(np.clip(s[up], 0, 1))[:, None]
    lut[up] = (1 - k) * np.array([205, 225, 245]) + k * np.array([40, 95, 185])
    kd = np.clip(-s[~up] * 3.0, 0, 1)[:, None] ** 0.5
    lut[~up] = (1 - kd) * np.array([165, 170, 150]) + kd * np.array([85, 115, 60])
    return lut.astype(np.uint8)


def _lut_thermal() -> np.ndarray:
    """Palette index by sine of elevation: sim/scene.py's sky (cold, warming to the horizon) and
    ground (ambient)."""
    s = np.linspace(-1.0, 1.0, LUT_SIZE)
    el = np.degrees(np.arcsin(s))
    t = np.where(
        el < 0, world.GROUND_C, world.SKY_C + (world.GROUND_C - world.SKY_C) * np.exp(-np.maximum(el, 0) / 3.0)
    )
    lo, hi = world.THERMAL_SPAN_C
    return np.clip(np.round((t - lo) / (hi - lo) * 255), 0, 255).astype(np.uint8)


Colour = Union[int, tuple[int, ...]]  # noqa: UP007  (a PIL fill: a level, or RGB / Y'CbCr)


@overload
def ycc(rgb: tuple[int, int, int]) -> tuple[int, ...]: ...
@overload
def ycc(rgb: np.ndarray) -> np.ndarray: ...
def ycc(rgb: tuple[int, int, int] | np.ndarray) -> tuple[int, ...] | np.ndarray:
    """RGB (0..255, ..., 3) -> BT.601 limited-range Y'CbCr (Y 16..235, Cb/Cr 16..240): what
    FFmpeg's RGB -> yuv420p conversion gives, so pictures look the same either way. Takes one
    colour (a tuple) or an array of them."""
    a = np.asarray(rgb, np.float64)
    m = np.array([[65.481, 128.553, 24.966], [-37.797, -74.203, 112.0], [112.0, -93.786, -18.214]]) / 255.0
    out = np.clip(np.rint(a @ m.T + np.array([16.0, 128.0, 128.0])), 0, 255).astype(np.uint8)
    if out.ndim == 1:
        return tuple(int(v) for v in out)
    return out


def _ycc_colour(rgb: tuple[int, int, int]) -> tuple[int, ...]:
    return ycc(rgb)


_LUT_VISIBLE = _lut_visible()
_LUT_VISIBLE_YCC = ycc(_LUT_VISIBLE)
_LUT_THERMAL = _lut_thermal()
MODES = ("RGB", "YCbCr")


@dataclass
class _Grid:
    """Tangent-plane coordinates of the shading grid for one field of view."""

    hfov_deg: float
    a: np.ndarray  # (w,) per column
    b: np.ndarray  # (h,) per row
    inv_norm: np.ndarray  # (h, w)


class Renderer:
    """Renders one lens's picture. Not thread-safe: one renderer per render thread."""

    def __init__(self, lens: str, width: int, height: int, hfov_1x_deg: float, *, mode: str = "RGB") -> None:
        if width < 64 or height < 48:
            raise ValueError(f"picture too small: {width}x{height} (at least 64x48)")
        if mode not in MODES:
            raise ValueError(f"mode must be one of {', '.join(MODES)} (got {mode!r})")
        self.mode = mode
        self._c: Callable[[tuple[int, int, int]], tuple[int, ...]] = (
            functools.lru_cache(maxsize=64)(_ycc_colour) if mode == "YCbCr" else (lambda rgb: rgb)
        )
        self.lens = lens
        self.width = width
        self.height = height
        self.hfov_1x_deg = hfov_1x_deg
        self._grid: _Grid | None = None
        size = max(10, height // 36)
        # Text heights in pixels: what the fonts were asked for (a FreeType font's `size`).
        self._font_px, self._font_big_px = size, int(size * 1.4)
        self._font: ImageFont.FreeTypeFont | ImageFont.ImageFont = ImageFont.load_default(size=self._font_px)
        self._font_big: ImageFont.FreeTypeFont | ImageFont.ImageFont = ImageFont.load_default(size=self._font_big_px)
        self._palette_name = ""
        self._palette: list[int] = []
        self._palette_ycc: list[int] = []
        # Ground grid: every road as a segment between two points on the ground plane (north, east).
        n = int(world.GRID_HALF_EXTENT_M // world.GRID_SPACING_M)
        ext = world.GRID_HALF_EXTENT_M
        segs = []
        for i in range(-n, n + 1):
            c = i * world.GRID_SPACING_M
            segs.append(((c, -ext), (c, ext)))
            segs.append(((-ext, c), (ext, c)))
        pts = np.array(segs, np.float64)  # (S, 2, 2)
        self._roads = np.concatenate([pts, np.full((*pts.shape[:2], 1), -world.CAMERA_HEIGHT_M)], axis=2)
        self._marks = np.array([world_dir(m.az_deg, m.el_deg) for m in world.LANDMARKS])
        ticks = np.arange(-180, 180, 10.0)
        self._ticks = ticks
        self._tick_dirs = np.array([world_dir(a, 0.0) for a in ticks])

    # -- geometry ----------------------------------------------------------------------------------

    def hfov(self, state: SceneState) -> float:
        z = state.thermal_zoom_x if self.lens == "thermal" else state.zoom_x
        return hfov_at(self.hfov_1x_deg, z)

    def _shading_grid(self, hfov_deg: float) -> _Grid:
        g = self._grid
        if g is not None and abs(g.hfov_deg - hfov_deg) < 1e-9:
            return g
        w, h = self.width // SHADE_DOWNSCALE, self.height // SHADE_DOWNSCALE
        f = focal_px(self.width, hfov_deg)
        xs = (np.arange(w) + 0.5) * SHADE_DOWNSCALE - self.width / 2.0
        ys = self.height / 2.0 - (np.arange(h) + 0.5) * SHADE_DOWNSCALE
        a = (xs / f).astype(np.float32)
        b = (ys / f).astype(np.float32)
        inv = (1.0 / np.sqrt(1.0 + a[None, :] ** 2 + b[:, None] ** 2)).astype(np.float32)
        self._grid = _Grid(hfov_deg, a, b, inv)
        return self._grid

    # -- drawing ----------------------------------------------------------------------------------

    def render(self, state: SceneState) -> Image.Image:
        """The picture: a Pillow image of width x height in the renderer's mode."""
        hfov = self.hfov(state)
        fwd, right, up = (np.array(v) for v in basis(state.yaw_deg, state.pitch_deg, state.roll_deg))
        f = focal_px(self.width, hfov)
        thermal = self.lens == "thermal"
        img = self._shade(fwd, right, up, hfov, thermal)
        draw = ImageDraw.Draw(img)
        cam = Camera(fwd, right, up, f, self.width, self.height)
        self._draw_horizon(draw, cam, state, thermal)
        if thermal:
            self._draw_world_thermal(draw, cam)
            self._draw_targets(draw, cam, state, thermal=True)
            img = self._colourise(img, state.palette)
            draw = ImageDraw.Draw(img)
        else:
            self._draw_world_visible(draw, cam)
            self._draw_targets(draw, cam, state, thermal=False)
        if state.osd:
            self._draw_osd(draw, state, hfov)
        self._draw_stamp(draw, state)
        return img

    def _shade(self, fwd: np.ndarray, right: np.ndarray, up: np.ndarray, hfov: float, thermal: bool) -> Image.Image:
        g = self._shading_grid(hfov)
        sin_el = (fwd[2] + g.a[None, :] * right[2] + g.b[:, None] * up[2]) * g.inv_norm
        idx = ((sin_el + 1.0) * ((LUT_SIZE - 1) / 2.0)).astype(np.int32)
        np.clip(idx, 0, LUT_SIZE - 1, out=idx)
        if thermal:
            small = Image.fromarray(_LUT_THERMAL[idx], "L")
        elif self.mode == "YCbCr":
            small = Image.fromarray(_LUT_VISIBLE_YCC[idx], "YCbCr")
        else:
            small = Image.fromarray(_LUT_VISIBLE[idx], "RGB")
        # Nearest is 10x cheaper than bilinear here; the steps it leaves are only visible at the
        # horizon, which _draw_horizon covers with a line.
        return small.resize((self.width, self.height), Image.Resampling.NEAREST)

    def _colourise(self, img: Image.Image, palette_name: str) -> Image.Image:
        if palette_name != self._palette_name:
            self._palette_name = palette_name
            self._palette = world.palette(palette_name)
            self._palette_ycc = [int(v) for v in ycc(np.array(self._palette, np.uint8).reshape(-1, 3)).ravel()]
        p = Image.frombuffer("P", img.size, img.tobytes(), "raw", "P", 0, 1)
        if self.mode == "YCbCr":
            # Pillow's palette lookup, with Y'CbCr triples in the palette: the bytes are relabelled
            # (no colour conversion by Pillow, whose own YCbCr is full range).
            p.putpalette(self._palette_ycc)
            return Image.frombuffer("YCbCr", img.size, p.convert("RGB").tobytes(), "raw", "YCbCr", 0, 1)
        p.putpalette(self._palette)
        return p.convert("RGB")

    def _draw_horizon(self, draw: ImageDraw.ImageDraw, cam: Camera, state: SceneState, thermal: bool) -> None:
        """The horizon (a great circle: a straight line in a pinhole picture) over the seam the
        coarse shading leaves."""
        pts = [p for p in cam.points(np.array([world_dir(state.yaw_deg + d, 0.0) for d in (-45.0, 45.0)])) if p]
        if len(pts) == 2:
            (x0, y0), (x1, y1) = clip_far(pts[0], pts[1], 4.0 * self.width, self.width, self.height)
            colour: Colour = int(_LUT_THERMAL[LUT_SIZE // 2]) if thermal else self._c((185, 190, 185))
            draw.line((x0, y0, x1, y1), fill=colour, width=SHADE_DOWNSCALE + 2)

    def _draw_world_visible(self, draw: ImageDraw.ImageDraw, cam: Camera) -> None:
        w = max(1, self.width // 640)
        c = self._c
        road = c((70, 70, 70))
        for (x0, y0), (x1, y1) in cam.segments(self._roads):
            draw.line((x0, y0, x1, y1), fill=road, width=w)
        self._draw_ticks(draw, cam, c((30, 30, 30)))
        self._draw_marks(draw, cam, (c((250, 250, 250)), c((200, 30, 30))), c((255, 255, 0)))
        hot = cam.point(world_dir(*world.HOT_SPOT))
        if hot is not None:
            r = cam.radius_px(1.2)
            x, y = hot
            draw.rectangle(
                (x - r * 1.6, y - r * 0.8, x + r * 1.6, y + r * 0.8), fill=c((180, 40, 30)), outline=c((0, 0, 0))
            )

    def _draw_world_thermal(self, draw: ImageDraw.ImageDraw, cam: Camera) -> None:
        w = max(1, self.width // 320)
        road = world.temperature_level(world.ROAD_C)
        for (x0, y0), (x1, y1) in cam.segments(self._roads):
            draw.line((x0, y0, x1, y1), fill=road, width=w)
        warm = world.temperature_level(world.LANDMARK_C)
        self._draw_marks(draw, cam, (warm, world.temperature_level(world.GROUND_C)), warm)
        hot = cam.point(world_dir(*world.HOT_SPOT))
        if hot is not None:
            # sim/scene.py's Gaussian blob, drawn as rings of falling temperature.
            x, y = hot
            peak = world.HOT_SPOT_C - world.GROUND_C
            for k in range(1, 13):
                dt = peak * k / 12.0
                radius_deg = world.HOT_SPOT_WIDTH_DEG * math.sqrt(2.0 * math.log(peak / dt)) if k < 12 else 0.3
                r = cam.radius_px(max(0.3, radius_deg))
                draw.ellipse((x - r, y - r, x + r, y + r), fill=world.temperature_level(world.GROUND_C + dt))

    def _draw_targets(self, draw: ImageDraw.ImageDraw, cam: Camera, state: SceneState, *, thermal: bool) -> None:
        """The simulated world's targets (sim/targets.py): discs of their angular size, dark by
        their contrast in the visible picture, at their temperature (hot) in the thermal one."""
        for az, el, size_deg, contrast, temp_c in state.targets:
            p = cam.point(world_dir(az, el))
            if p is None:
                continue
            x, y = p
            r = max(1.5, cam.radius_px(size_deg / 2.0))
            if not (-r < x < self.width + r and -r < y < self.height + r):
                continue
            if thermal:
                fill: Colour = world.temperature_level(temp_c)
            else:
                level = round(230 * (1.0 - contrast))
                fill = self._c((level, level, level))
            draw.ellipse((x - r, y - r, x + r, y + r), fill=fill)

    def _draw_ticks(self, draw: ImageDraw.ImageDraw, cam: Camera, colour: Colour) -> None:
        pts = cam.points(self._tick_dirs)
        h = max(4, self.height // 60)
        for az, p in zip(self._ticks, pts, strict=False):
            if p is None:
                continue
            x, y = p
            long = int(az) % 30 == 0
            draw.line((x, y - (2 * h if long else h), x, y), fill=colour, width=1)
            if long:
                label = {0: "N", 90: "E", -180: "S", -90: "W"}.get(int(az), f"{int(wrap360(int(az))):03d}")
                draw.text((x + 3, y - 2 * h - self._font_px), label, fill=colour, font=self._font)

    def _draw_marks(
        self, draw: ImageDraw.ImageDraw, cam: Camera, rings: tuple[Colour, Colour], text_fill: Colour
    ) -> None:
        r = cam.radius_px(world.LANDMARK_RADIUS_DEG)
        for m, p in zip(world.LANDMARKS, cam.points(self._marks), strict=False):
            if p is None:
                continue
            x, y = p
            if not (-4 * r < x < self.width + 4 * r and -4 * r < y < self.height + 4 * r):
                continue
            for k, rr in enumerate((r, r * 0.66, r * 0.33)):
                draw.ellipse((x - rr, y - rr, x + rr, y + rr), fill=rings[k % 2])
            draw.text((x + r + 3, y - r - self._font_big_px), str(m.number), fill=text_fill, font=self._font_big)

    def _draw_osd(self, draw: ImageDraw.ImageDraw, state: SceneState, hfov: float) -> None:
        fg, sh = self._c((255, 255, 255)), self._c((0, 0, 0))
        fs = self._font_px
        zoom = state.thermal_zoom_x if self.lens == "thermal" else state.zoom_x
        lines = [
            f"{state.model} {self.lens.upper()}",
            f"YAW {state.yaw_deg:+7.2f}  PIT {state.pitch_deg:+7.2f}  ROL {state.roll_deg:+6.2f}",
            f"ZOOM {zoom:.1f}x  HFOV {hfov:.1f}",
        ]
        if self.lens == "thermal":
            lines.append(f"PAL {state.palette}")
        if state.tracking not in ("stopped", "stop"):
            lines.append(f"TRK {state.tracking}")
        for i, line in enumerate(lines):
            pos = (fs // 2, fs // 2 + i * int(fs * 1.3))
            draw.text((pos[0] + 1, pos[1] + 1), line, fill=sh, font=self._font)
            draw.text(pos, line, fill=fg, font=self._font)
        if state.track_box is not None and self.lens != "thermal":
            # The camera tracker's box (sim/tracker.py), as a camera's OSD draws it.
            bx, by, bw, bh = state.track_box
            x0, y0 = (bx - bw / 2) * self.width, (by - bh / 2) * self.height
            x1, y1 = (bx + bw / 2) * self.width, (by + bh / 2) * self.height
            draw.rectangle((x0, y0, x1, y1), outline=self._c((0, 255, 0)), width=2)
        cx, cy, c = self.width / 2, self.height / 2, max(8, self.height // 30)
        for dx, dy in ((1, 0), (-1, 0), (0, 1), (0, -1)):
            draw.line((cx + dx * c * 0.3, cy + dy * c * 0.3, cx + dx * c, cy + dy * c), fill=fg, width=2)
        if state.recording:
            # Blinks at 1 Hz, as a camera's REC light does; the elapsed time stays.
            x = self.width - fs * 7
            if int(state.record_s * 2) % 2 == 0:
                draw.ellipse((x, fs // 2, x + fs, fs // 2 + fs), fill=self._c((230, 0, 0)))
            m, s = divmod(int(state.record_s), 60)
            draw.text((x + int(fs * 1.4), fs // 2 - 2), f"REC {m:02d}:{s:02d}", fill=fg, font=self._font)

    def _draw_stamp(self, draw: ImageDraw.ImageDraw, state: SceneState) -> None:
        x0, y0, cell = stamp_layout(self.width, self.height)
        ms = int(state.wall_s * 1000) & ((1 << STAMP_BITS) - 1)
        bits = [1, 0] + [(ms >> (STAMP_BITS - 1 - i)) & 1 for i in range(STAMP_BITS)]
        white, black = self._c((255, 255, 255)), self._c((0, 0, 0))
        draw.rectangle(
            (x0 - cell * 0.5, y0 - cell * 0.5, x0 + (len(bits) + 0.5) * cell, y0 + cell * 1.5),
            fill=self._c((128, 128, 128)),
        )
        for i, bit in enumerate(bits):
            draw.rectangle((x0 + i * cell, y0, x0 + (i + 1) * cell - 1, y0 + cell - 1), fill=white if bit else black)
        t = datetime.fromtimestamp(state.wall_s).strftime("%H:%M:%S.%f")[:-3]
        text = f"{t}  #{state.frame}"
        draw.text((x0 + 1, y0 - self._font_px - cell * 0.5), text, fill=black, font=self._font)
        draw.text((x0, y0 - self._font_px - cell * 0.5 - 1), text, fill=white, font=self._font)
