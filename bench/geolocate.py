"""Where the camera looks, measured (issue 36): median horizontal error of the geolocation at
300 m slant range on a synthetic landscape with hills, a ridge and small undulations, whose DEM is
a GeoTIFF with 10 m cells sampled from the analytic truth.

Each case puts a true target on the analytic ground, a camera 300 m back along a random ray
(bearing 0-360, pitch -15 to -70 degrees; cases where the truth's ground hides the target first
are dropped), then perturbs what the camera knows by an error profile (1-sigma: angles of the
gimbal and vehicle, horizontal position, altitude; a laser's range error). Methods:

- exact: topgimbal.geo.locate on the DEM (cell-by-cell exact ray-DEM intersection);
- ardupilot: AP_Mount_Backend's POI search as written in ArduPilot (march along the ray in
  max(grid spacing, 10 m) steps, stop at the first point below the terrain, interpolate linearly
  between the last two steps) over the same DEM, bilinear as AP_Terrain is;
- laser: locate with the simulated laser (the true range along the true ray, rounded to 0.1 m as
  the simulator answers, plus the profile's range error), fused with the DEM along the ray.

    .venv/bin/python bench/geolocate.py [--cases 400] [--seed 36]
"""

from __future__ import annotations

import argparse
import math
import random
import statistics
import tempfile
import time  # bench/ may time with perf_counter
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import pymap3d

from topgimbal.geo import Attitude, Fix, Geodetic, GridTerrain, LocalFrame, Pointing, Uncertainty, View, locate, ray
from topgimbal.geo.dem import load_dem
from topgimbal.geo.frames import M_PER_DEG
from topgimbal.geo.synthetic import height_at, write_dem

LAT0, LON0 = 47.0, 8.0
SLANT_M = 300.0


@dataclass(frozen=True)
class Profile:
    name: str
    angle_deg: float
    position_m: float
    altitude_m: float
    laser_m: float


PROFILES = (
    Profile("exact inputs", 0.0, 0.0, 0.0, 0.0),
    Profile("RTK + good IMU", 0.05, 0.05, 0.1, 0.3),
    Profile("GNSS + IMU", 0.1, 1.0, 1.0, 0.5),
)


def ground_at(lat: float, lon: float) -> float:
    """The analytic truth at a place: the synthetic landscape is laid on latitude and longitude by
    its own map (synthetic.py: metres per degree about its origin), heights above the ellipsoid."""
    return height_at((lat - LAT0) * M_PER_DEG, (lon - LON0) * M_PER_DEG * math.cos(math.radians(LAT0)))


def true_range(cam: Geodetic, d: tuple[float, float, float], max_m: float = 1500.0) -> float | None:
    """The analytic ground's first crossing along the ray (north, east, up in the camera's tangent
    frame): the ray's points placed on the WGS84 ellipsoid by pymap3d (not topgimbal's earth model),
    a 0.25 m march, then bisection."""

    def above(t: float) -> float:
        lat, lon, h = pymap3d.enu2geodetic(d[1] * t, d[0] * t, d[2] * t, cam.lat_deg, cam.lon_deg, cam.alt_m)
        return float(h) - ground_at(float(lat), float(lon))

    prev, t = 0.0, 0.25
    while t < max_m:
        if above(t) <= 0:
            lo, hi = prev, t
            for _ in range(50):
                mid = 0.5 * (lo + hi)
                lo, hi = (mid, hi) if above(mid) > 0 else (lo, mid)
            return hi
        prev, t = t, t + 0.25
    return None


def ardupilot_poi(terrain: GridTerrain, view: View, max_m: float = 10_000.0) -> Geodetic | None:
    """AP_Mount_Backend's POI search: step max(grid spacing, 10 m) along the ray (bearing and pitch
    from the mount's attitude), stop below the terrain, interpolate between the last two steps."""
    d = ray(view)
    frame = LocalFrame(view.position)
    step = 10.0
    total = 0.0

    def height_above(t: float) -> float | None:
        p = frame.to_geodetic(d[0] * t, d[1] * t, d[2] * t)
        h = terrain.height_m(p.lat_deg, p.lon_deg)
        return None if h is None else p.alt_m - h

    cur = height_above(0.0)
    prev = cur
    while cur is not None and total < max_m and cur > 0:
        total += step
        prev = cur
        cur = height_above(total)
    if cur is None or prev is None or total >= max_m:
        return None
    t = total - step + step * prev / (prev - cur)
    return frame.to_geodetic(d[0] * t, d[1] * t, d[2] * t)


def horizontal_m(a: Geodetic, lat: float, lon: float) -> float:
    n, e, _ = LocalFrame(a).to_local(lat, lon, a.alt_m)
    return math.hypot(n, e)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", type=int, default=400)
    ap.add_argument("--seed", type=int, default=36)
    ap.add_argument("--pitch", default="-70,-15", help="pitch range in degrees (e.g. -12,-3 for grazing rays)")
    args = ap.parse_args()
    pitch_lo, pitch_hi = (float(x) for x in args.pitch.split(","))
    tmp = Path(tempfile.mkdtemp(prefix="geolocate-"))
    # 0.5 m: the bilinear 10 m grid's height error against the analytic truth (at most ~0.5 m here)
    dem = write_dem(tmp / "hills.tif", LAT0, LON0, half_size_m=1500.0, cell_m=10.0)
    terrain = load_dem(dem, vertical_error_m=0.5)
    rng = random.Random(args.seed)

    cases = []
    while len(cases) < args.cases:
        lat_t = LAT0 + rng.uniform(-900, 900) / M_PER_DEG
        lon_t = LON0 + rng.uniform(-900, 900) / (M_PER_DEG * math.cos(math.radians(LAT0)))
        target = Geodetic(lat_t, lon_t, ground_at(lat_t, lon_t))
        b, p = math.radians(rng.uniform(0, 360)), math.radians(rng.uniform(pitch_lo, pitch_hi))
        # the camera SLANT_M back from the target (pymap3d), then the ray seen from the camera
        lat_c, lon_c, h_c = pymap3d.enu2geodetic(-SLANT_M * math.cos(p) * math.sin(b), -SLANT_M * math.cos(p) * math.cos(b),
                                                 -SLANT_M * math.sin(p), lat_t, lon_t, target.alt_m)  # fmt: skip
        cam = Geodetic(float(lat_c), float(lon_c), float(h_c))
        e, n, u = (
            float(v) for v in pymap3d.geodetic2enu(lat_t, lon_t, target.alt_m, cam.lat_deg, cam.lon_deg, cam.alt_m)
        )
        r = math.sqrt(n * n + e * e + u * u)
        d = (n / r, e / r, u / r)
        t = true_range(cam, d)
        if t is None or abs(t - SLANT_M) > 0.01:
            continue  # the ground hides the target: not a 300 m case
        bearing, pitch = math.degrees(math.atan2(e, n)), math.degrees(math.asin(u / r))
        cases.append((cam, bearing, pitch, target))

    print(
        f"geolocation at {SLANT_M:.0f} m slant range, pitch {pitch_lo:g}..{pitch_hi:g} deg, {len(cases)} cases,"
        " DEM 10 m cells (synthetic hills); horizontal error to the true point"
    )
    print(
        f"{'inputs (1-sigma)':<48} {'method':<10} {'median m':>9} {'p90 m':>7} {'max m':>7}"
        f" {'est. m':>7} {'misses':>6} {'us/call':>8}"
    )
    for prof in PROFILES:
        prng = random.Random(args.seed + 1)
        errs: dict[str, list[float]] = {"exact": [], "ardupilot": [], "laser": []}
        miss = dict.fromkeys(errs, 0)
        cost = dict.fromkeys(errs, 0.0)
        est: dict[str, list[float]] = {"exact": [], "ardupilot": [], "laser": []}
        for cam, bearing, pitch, target in cases:
            frame = LocalFrame(cam)
            pos = frame.to_geodetic(
                prng.gauss(0, prof.position_m), prng.gauss(0, prof.position_m), prng.gauss(0, prof.altitude_m)
            )
            view = View(
                pos,
                Attitude(roll_deg=prng.gauss(0, prof.angle_deg), pitch_deg=prng.gauss(0, prof.angle_deg), yaw_deg=0.0),
                Pointing(bearing + prng.gauss(0, prof.angle_deg), pitch + prng.gauss(0, prof.angle_deg)),
            )
            laser = round(SLANT_M + prng.gauss(0, prof.laser_m), 1)
            u = Uncertainty(
                angle_deg=max(1e-3, prof.angle_deg * math.sqrt(2)),  # gimbal and vehicle angles together
                position_m=max(1e-3, prof.position_m),
                altitude_m=max(1e-3, prof.altitude_m),
                laser_m=max(0.05, prof.laser_m),  # the simulator rounds to 0.1 m
            )
            runs: dict[str, Callable[[], Geodetic | None]] = {
                "exact": lambda view=view, u=u, est=est: _g(locate(view, terrain=terrain, uncertainty=u), est["exact"]),
                "ardupilot": lambda view=view: ardupilot_poi(terrain, view),
                "laser": lambda view=view, laser=laser, u=u, est=est: _g(
                    locate(view, terrain=terrain, laser_range_m=laser, uncertainty=u), est["laser"]
                ),
            }
            for name, fn in runs.items():
                t0 = time.perf_counter()
                got = fn()
                cost[name] += time.perf_counter() - t0
                if got is None:
                    miss[name] += 1
                else:
                    errs[name].append(horizontal_m(target, got.lat_deg, got.lon_deg))
        label = f"{prof.name}: {prof.angle_deg} deg, {prof.position_m}/{prof.altitude_m} m, laser {prof.laser_m} m"
        for name, e in errs.items():
            e.sort()
            med = statistics.median(e) if e else math.nan
            p90 = e[int(0.9 * (len(e) - 1))] if e else math.nan
            guess = f"{statistics.median(est[name]):7.2f}" if est[name] else f"{'-':>7}"
            print(
                f"{label if name == 'exact' else '':<48} {name:<10} {med:9.2f} {p90:7.2f} {max(e or [math.nan]):7.2f}"
                f" {guess} {miss[name]:6d} {1e6 * cost[name] / len(cases):8.0f}"
            )


def _g(fix: Fix | None, estimates: list[float]) -> Geodetic | None:
    """The fix's point; its own error estimate goes to `estimates` (the "est." column)."""
    if fix is None:
        return None
    estimates.append(fix.error_m)
    return Geodetic(fix.lat_deg, fix.lon_deg, fix.alt_m)


if __name__ == "__main__":
    main()
