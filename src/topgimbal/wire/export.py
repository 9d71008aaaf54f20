"""A JSONL traffic log (the client's `log_path`, the proxy's `--log`) written as a pcap, so a
session recorded by the SDK opens in Wireshark.

The log holds frames, not packets, so the packets are synthesised: loopback addresses of the log
URL's IP version, the URL's transport and port for the device (a serial URL becomes UDP on the
dialect's documented port), and for the host port 9004 on TOPOTEK (its documented client port,
which makes the dissector pick the dialect) or 40000 otherwise. Each logged frame becomes one
datagram or TCP segment with the log's wall-clock time, "out" from the host and "in" from the
device. A line that is not a logged frame is reported and passed over.
"""

from __future__ import annotations

import ipaddress
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..errors import TopGimbalError
from ..inputfile import InputFileError, require_regular
from ..transport import network_address
from .packets import Endpoint
from .pcapfile import CaptureError
from .ports import CLIENT_PORTS, client_port, documented_ports
from .synth import CaptureWriter

HOST_PORT = 40000  # the host's side of a conversation when no convention gives one


@dataclass
class ExportReport:
    frames: int = 0
    problems: list[str] = field(default_factory=list)
    transport: str = "udp"
    host: Endpoint = ("127.0.0.1", HOST_PORT)
    device: Endpoint = ("127.0.0.1", 5000)


def _endpoints(header: dict[str, Any], problems: list[str] | None = None) -> tuple[str, Endpoint, Endpoint]:
    dialect = str(header.get("dialect") or "")
    url_text = str(header.get("url") or "")
    transport, port, loopback = "udp", 0, "127.0.0.1"
    try:
        address = network_address(url_text)
    except (ValueError, TopGimbalError) as exc:  # a damaged header: the frames are still worth having
        if problems is not None:
            problems.append(f"header: url {url_text!r} is not a transport URL ({exc}): loopback UDP assumed")
        address = None
    if address is not None:
        transport, host, port = address
        try:
            if ipaddress.ip_address(host).version == 6:
                loopback = "::1"
        except ValueError:
            pass  # a host name: IPv4 loopback
    if not port:
        ports = sorted(
            p for (t, p), d in documented_ports().items() if d == dialect and t == "udp" and (t, p) not in CLIENT_PORTS
        )
        port = ports[0] if ports else 5000
    host_port = client_port(transport, dialect, HOST_PORT)
    if host_port == port:  # the device on the host's conventional port: the host takes another
        host_port = HOST_PORT
    return transport, (loopback, host_port), (loopback, port)


def log_to_pcap(log_path: str | Path, out_path: str | Path) -> ExportReport:
    """Write the frames of a traffic log to a pcap/pcapng file; returns what was written and the
    lines that could not be used. Raises CaptureError when the log cannot be read at all."""
    try:
        require_regular(log_path, "log")
        lines = Path(log_path).read_text(encoding="utf-8", errors="replace").splitlines()
    except InputFileError as exc:
        raise CaptureError(str(exc)) from None
    except OSError as exc:
        raise CaptureError(f"{log_path}: {exc.strerror or exc}") from None
    report = ExportReport()
    header: dict[str, Any] = {}
    records: list[tuple[int, dict[str, Any]]] = []
    for n, line in enumerate(lines, 1):
        if not line.strip():
            continue
        try:
            obj = json.loads(line)
        except (ValueError, RecursionError) as exc:  # RecursionError: nested past Python's recursion
            report.problems.append(f"line {n}: not JSON ({exc})")
            continue
        if not isinstance(obj, dict):
            report.problems.append(f"line {n}: not a JSON object")
        elif "topgimbal_log" in obj:
            header = header or obj
        elif obj.get("dir") in ("in", "out") and isinstance(obj.get("raw"), str):
            records.append((n, obj))
        else:
            report.problems.append(f"line {n}: no 'dir' (in/out) and 'raw' frame text")
    if not header and records:
        report.problems.append("no header line (url, dialect): loopback UDP port 5000 assumed")
    report.transport, report.host, report.device = _endpoints(header, report.problems)
    with CaptureWriter(out_path) as out:
        for n, obj in records:
            try:
                raw = obj["raw"].encode("latin-1")
                ts = float(obj.get("t", 0.0))
            except (UnicodeEncodeError, ValueError, TypeError) as exc:
                report.problems.append(f"line {n}: {exc}")
                continue
            src, dst = (report.host, report.device) if obj["dir"] == "out" else (report.device, report.host)
            try:
                if report.transport == "tcp":
                    out.tcp(src, dst, raw, ts, client=report.host)
                else:
                    out.udp(src, dst, raw, ts)
            except CaptureError as exc:  # a time or size no capture can hold: this line only
                report.problems.append(f"line {n}: {exc}")
                continue
            report.frames += 1
    return report
