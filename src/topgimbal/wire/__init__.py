"""See the wire: captures (pcap/pcapng in and out), the generated Wireshark dissector, and the
proxy that sits between a ground station and a camera.

Imports point down: this package uses `protocol/`, `transport/` (the proxy's links) and
`client/traffic.py` (the JSONL traffic log format); `cli/` and later `console/` use it."""

from __future__ import annotations

from .capture import PacketNote, WireFrame, frames_in_capture
from .dissector import DissectorError, generate_dissector
from .pcapfile import CaptureError, CaptureProblem, CaptureRecord, PcapngWriter, PcapWriter, open_writer, read_capture
from .synth import CaptureWriter

__all__ = [
    "CaptureError",
    "CaptureProblem",
    "CaptureRecord",
    "CaptureWriter",
    "DissectorError",
    "PacketNote",
    "PcapWriter",
    "PcapngWriter",
    "WireFrame",
    "frames_in_capture",
    "generate_dissector",
    "open_writer",
    "read_capture",
]
