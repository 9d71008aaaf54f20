"""Moved (issue 44: one owner each): the model profile's streams and the card's file names to
`topgimbal.protocol.streams`, tracking requests to `topgimbal.protocol.picture_tracking`, the lens
model (fields of view, pixels <-> bearings) to `topgimbal.geo.optics`. The names stay importable
from here for code that imported them here."""

from __future__ import annotations

from ..geo.earth import wrap180
from ..geo.optics import PixelView, Vec, View, basis, direction, focal_px, hfov_at, vfov_for
from ..protocol.picture_tracking import LOC_HALF_SPAN, POINT_BOX, tracking_requests
from ..protocol.streams import (
    ASSUMED_HFOV_DEG,
    DEFAULT_SIZE_PX,
    LENSES,
    MEDIA_NAME,
    RTSP_DEFAULT_PORT,
    StreamSpec,
    VideoError,
    host_of,
    photo_names,
    plan_ports,
    recording_name,
    spec_of,
    stream_for,
    stream_urls,
    streams_for,
    video_url,
)

__all__ = [
    "ASSUMED_HFOV_DEG",
    "DEFAULT_SIZE_PX",
    "LENSES",
    "LOC_HALF_SPAN",
    "MEDIA_NAME",
    "POINT_BOX",
    "RTSP_DEFAULT_PORT",
    "PixelView",
    "StreamSpec",
    "Vec",
    "VideoError",
    "View",
    "basis",
    "direction",
    "focal_px",
    "hfov_at",
    "host_of",
    "photo_names",
    "plan_ports",
    "recording_name",
    "spec_of",
    "stream_for",
    "stream_urls",
    "streams_for",
    "tracking_requests",
    "vfov_for",
    "video_url",
    "wrap180",
]
