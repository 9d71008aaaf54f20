"""What each identifier does, grouped by subsystem. Importing this package fills
`dispatch.HANDLERS`; identifiers without a handler of their own are stored settings (`setting`)."""

from __future__ import annotations

from . import camera, gimbal, ranging, system, thermal  # noqa: F401  (register handlers)
from .common import setting
from .reports import pending_reports, stream_frame

__all__ = ["pending_reports", "setting", "stream_frame"]
