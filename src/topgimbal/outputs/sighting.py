"""The sighting port: what every output (CoT, KLV's recorder, a fleet's feed) is told about where
the camera looks, built by whoever knows it (today the MAVLink bridge's camera view, mavlink/camera_view.py).
Outputs depend on this and on geo only, never on MAVLink (tests/test_architecture.py)."""

from __future__ import annotations

from dataclasses import dataclass

from ..geo import Fix as GeoFix

__all__ = ["Sighting"]


@dataclass(frozen=True)
class Sighting:
    """What one CoT update says: the vehicle, where the camera looks, the picture's corners."""

    vehicle_lat_deg: float
    vehicle_lon_deg: float
    vehicle_alt_m: float  # MSL (CoT's hae is height above the ellipsoid: see docs/errata.md)
    azimuth_deg: float  # the optical axis, earth frame
    elevation_deg: float
    roll_deg: float
    hfov_deg: float
    vfov_deg: float
    target: GeoFix | None
    corners: list[GeoFix | None]
    video_url: str | None = None
