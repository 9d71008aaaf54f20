"""See the wire: `dissector`, `proxy`, `pcap from-log`, and `decode --pcap`.

topgimbal dissector -o topgimbal.lua            # the Wireshark dissector, from the catalog
topgimbal decode --pcap session.pcapng --port 5000 --json
topgimbal proxy --listen udp://127.0.0.1:5600 --to udp://127.0.0.1:5000 --pcap s.pcap --log s.jsonl
topgimbal pcap from-log session.jsonl -o session.pcap
"""

from __future__ import annotations

import argparse
import datetime
import gc
import heapq
import json
import signal
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any, TextIO

from .. import jsonl
from ..protocol import Diagnostic, Dialect, Frame, Message, dissect, get_dialect, get_model
from ..protocol.decoded import dissection_record
from ..protocol.decoded import human_text as _human
from ..protocol.frame import DEVICE_ADDRESSES, HOST_ADDRESSES
from .args import FileArgumentError, add_dialect_argument, add_json_argument, input_file, writable_output, write_whole
from .args import add_pcap_arguments as add_pcap_arguments  # its old home (tests, scripts)
from .args import dialect_from_args as _dialect_from_args

if TYPE_CHECKING:
    from ..wire import WireFrame
    from ..wire.proxy import Proxy, ProxyEvent

# The proxy's default client cap, repeated so `topgimbal --help` need not import the proxy (asyncio,
# the transports); tests/wire/test_cli.py checks the two agree.
MAX_CLIENTS = 8


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("dissector", help="write the Wireshark Lua dissector generated from the catalog")
    p.add_argument("-o", "--output", metavar="FILE", help="where to write it (default: stdout)")
    p.add_argument("--check", metavar="FILE", help="exit 1 if FILE is not what would be generated now")
    p.set_defaults(func=cmd_dissector)

    p = sub.add_parser(
        "proxy",
        help="forward between a ground station and a camera, decoding every frame live",
        description="Listen where a ground station or vendor app sends, forward both ways unchanged to the "
        "camera, and print each frame decoded. Either side may be udp://HOST:PORT, tcp://HOST:PORT or "
        "serial:///dev/ttyX?baud=115200 (port 0 picks a free port; the listening URL is printed on stderr).",
    )
    p.add_argument("--listen", required=True, metavar="URL", help="where clients connect, e.g. udp://127.0.0.1:5600")
    p.add_argument("--to", required=True, metavar="URL", help="the camera, e.g. udp://192.0.2.10:5000")
    p.add_argument("--pcap", metavar="FILE", help="also write the traffic as pcap (pcapng if FILE ends in .pcapng)")
    p.add_argument("--log", dest="traffic_log", metavar="FILE", help="also write the JSONL traffic log")
    p.add_argument("--quiet", action="store_true", help="print nothing per frame")
    p.add_argument("--max-clients", type=int, default=MAX_CLIENTS, help=f"clients at once (default {MAX_CLIENTS})")
    add_dialect_argument(p)
    add_json_argument(p)
    p.set_defaults(func=cmd_proxy)

    p = sub.add_parser("pcap", help="capture files: convert a traffic log to pcap")
    pcap_sub = p.add_subparsers(dest="pcap_command", metavar="COMMAND", required=True)
    q = pcap_sub.add_parser("from-log", help="write a JSONL traffic log (client log_path, proxy --log) as pcap")
    q.add_argument("log_file", metavar="LOG")
    q.add_argument("-o", "--output", required=True, metavar="FILE", help="pcap to write (pcapng if it ends in .pcapng)")
    q.set_defaults(func=cmd_from_log)


# -- decode --pcap ---------------------------------------------------------------------------------


def _ep(ep: tuple[str, int]) -> str:
    return f"[{ep[0]}]:{ep[1]}" if ":" in ep[0] else f"{ep[0]}:{ep[1]}"


def _record(
    raw: bytes, item: Frame | Diagnostic, dialect: Dialect | None, message: Message | None = None
) -> dict[str, Any]:
    """`decode --json`'s record of one frame or diagnostic (`message`: the frame already decoded)."""
    rec = dissection_record(dissect(raw), dialect, message if isinstance(item, Frame) else None)
    if isinstance(item, Diagnostic) and item.kind != "bad_checksum":
        rec["ok"] = False
        rec["error"] = f"{item.detail} ({item.kind})"
    return rec


def _direction(rec: dict[str, Any]) -> str | None:
    """ "out" for host -> device frames, "in" for device -> host (the traffic log's words)."""
    if not rec.get("src") or not rec.get("dst"):
        return None
    return "in" if rec["src"] in DEVICE_ADDRESSES and rec["dst"] in HOST_ADDRESSES else "out"


# `decode --pcap` prints as it reads, in time order through a window of this many records: a
# capture's packets are in time order but for a few (several interfaces, TCP reassembly), and a
# record more than this many records out of place is printed where it falls. Memory stays bounded
# whatever the capture's size.
REORDER_WINDOW = 4096


def decode_pcap(args: argparse.Namespace) -> int:
    """`decode --pcap FILE`: every frame in the capture, in time order (within REORDER_WINDOW)."""
    from ..wire import CaptureProblem, PacketNote, frames_in_capture

    forced = _dialect_from_args(args)
    window: list[tuple[float, int, dict[str, Any]]] = []
    problems = bad = printed = 0
    start: float | None = None

    def emit() -> None:
        nonlocal bad, printed, start
        ts, _, rec = heapq.heappop(window)
        start = ts if start is None else start
        bad += not rec["ok"]
        printed += 1
        if args.json:
            print(jsonl.line(rec))
        else:
            print(
                f"#{rec['packet']} +{ts - start:.6f}s {rec['transport']} {rec['src_addr']} -> {rec['dst_addr']}"
                f" {rec['dir'] or ''}".rstrip()
            )
            print(_human(rec))

    input_file(args.pcap, "capture")
    for seq, got in enumerate(frames_in_capture(args.pcap, ports=args.port or (), addresses=args.address or ())):
        if isinstance(got, (PacketNote, CaptureProblem)):
            where = f"packet {got.number}" if isinstance(got, PacketNote) else args.pcap
            print(f"topgimbal: {where}: {got.detail if isinstance(got, PacketNote) else got}", file=sys.stderr)
            problems += 1
            continue
        if isinstance(got.item, Diagnostic) and got.item.kind == "length_mismatch":
            continue  # the recovered frame follows, with the same note as its anomaly
        heapq.heappush(window, (got.ts, seq, _pcap_record(got, forced)))
        if len(window) > REORDER_WINDOW:
            emit()
    while window:
        emit()
    if not printed:
        print(f"topgimbal: {args.pcap}: no TOP frames found", file=sys.stderr)
    return 1 if bad or problems else 0


def _pcap_record(got: WireFrame, forced: Dialect | None) -> dict[str, Any]:
    raw = got.item.to_bytes() if isinstance(got.item, Frame) else got.item.raw
    dialect = forced or (get_dialect(got.dialect) if got.dialect else None)
    rec = _record(raw, got.item, dialect)
    rec.update(
        time=round(got.ts, 6),
        packet=got.number,
        transport=got.transport,
        src_addr=_ep(got.src),
        dst_addr=_ep(got.dst),
        dir=_direction(rec),
    )
    return rec


# -- dissector ------------------------------------------------------------------------------------


def cmd_dissector(args: argparse.Namespace) -> int:
    from ..wire import generate_dissector

    text = generate_dissector()
    if args.check:
        try:
            current = Path(input_file(args.check, "dissector")).read_bytes()
        except FileArgumentError as exc:
            print(f"topgimbal: {exc}", file=sys.stderr)
            return 1
        except OSError as exc:
            print(f"topgimbal: {args.check}: {exc.strerror or exc}", file=sys.stderr)
            return 1
        if current != text.encode("utf-8"):  # bytes: a file that is not even UTF-8 is just stale
            print(f"topgimbal: {args.check} is stale: run `topgimbal dissector -o {args.check}`", file=sys.stderr)
            return 1
        return 0
    if args.output and args.output != "-":
        write_whole(args.output, text)
        print(f"wrote {args.output} ({len(text)} bytes)", file=sys.stderr)
    else:
        sys.stdout.write(text)
    return 0


# -- pcap from-log --------------------------------------------------------------------------------


def cmd_from_log(args: argparse.Namespace) -> int:
    from ..wire.export import log_to_pcap

    report = log_to_pcap(input_file(args.log_file, "traffic log"), writable_output(args.output))
    for problem in report.problems:
        print(f"topgimbal: {args.log_file}: {problem}", file=sys.stderr)
    print(
        f"wrote {args.output}: {report.frames} frames as {report.transport.upper()} "
        f"{_ep(report.host)} <-> {_ep(report.device)}",
        file=sys.stderr,
    )
    return 1 if report.problems else 0


# -- proxy ----------------------------------------------------------------------------------------


def _live_line(event: ProxyEvent, as_json: bool) -> str:
    item = event.item
    raw = item.to_bytes() if isinstance(item, Frame) else item.raw
    if as_json:
        rec = _record(raw, item, event.dialect, event.message)
        rec.update(time=round(event.t, 6), dir=event.direction, client=event.client)
        return jsonl.line(rec)
    stamp = datetime.datetime.fromtimestamp(event.t).strftime("%H:%M:%S.%f")
    arrow = "->" if event.direction == "out" else "<-"
    if isinstance(item, Diagnostic):
        shown = raw.decode("latin-1").encode("ascii", "backslashreplace").decode("ascii")
        return f"{stamp} {arrow} {event.client}  ! {item.kind}: {item.detail}  {shown!r}"
    msg = event.message
    text = f"{stamp} {arrow} {event.client}  {item.text()}  {item.ident}"
    if msg is not None and msg.spec is not None:
        text += f" {msg.spec.name}"
        if msg.fields is not None:
            text += "".join(f" {k}={_value(v)}" for k, v in msg.fields.items())
        else:
            text += f"  ({msg.error})"
    elif msg is not None:
        text += f"  ({msg.error})"
    return text


def _value(v: object) -> str:
    return v.isoformat() if isinstance(v, datetime.datetime) else str(v)


class _Printer:
    """The live lines, written to `stream` in one call per FLUSH_S (and at exit) rather than one
    system call per frame; a stream that goes away (`| head`) ends the printing, not the proxy."""

    MAX_LINES = 512

    def __init__(self, stream: TextIO | None, as_json: bool) -> None:
        self.stream = stream
        self.as_json = as_json
        self.lines: list[str] = []

    def __call__(self, event: ProxyEvent) -> None:
        if self.stream is None:
            return
        self.lines.append(_live_line(event, self.as_json))
        if len(self.lines) >= self.MAX_LINES:
            self.flush()

    def flush(self) -> None:
        if not self.lines or self.stream is None:
            return
        text = "\n".join(self.lines) + "\n"
        self.lines.clear()
        try:
            self.stream.write(text)
            self.stream.flush()
        except (OSError, ValueError):
            self.stream = None


WATCHER_CODE = "from topgimbal.cli.wire_cmds import watch_main; watch_main()"


def cmd_proxy(args: argparse.Namespace) -> int:
    import asyncio

    from ..wire.offload import WatcherProcess
    from ..wire.proxy import Proxy

    dialect = args.dialect if args.dialect not in (None, "auto") else None
    for path in (args.pcap, args.traffic_log):
        if path:  # the watcher process writes them: say now, not later, when one cannot be written
            try:
                Path(path).open("ab").close()
            except OSError as exc:
                print(f"topgimbal: cannot write {path}: {exc.strerror or exc}", file=sys.stderr)
                return 2
    offload = None
    if not args.quiet or args.pcap or args.traffic_log:
        mode = "quiet" if args.quiet else "json" if args.json else "human"
        offload = WatcherProcess([sys.executable, "-c", WATCHER_CODE, mode])
    proxy = Proxy(
        args.listen,
        args.to,
        dialect=dialect,
        model=args.model,
        pcap=args.pcap,
        log_path=args.traffic_log,
        max_clients=args.max_clients,
        offload=offload,
    )
    return asyncio.run(_serve(proxy))


async def _serve(proxy: Proxy) -> int:
    from .runtime import stop_on_signals

    await proxy.start()
    # Everything alive now (the catalog, modules) lives for the whole run: keep the collector from
    # walking it again and again (a full collection would stall forwarding for milliseconds).
    gc.freeze()
    stop = stop_on_signals()
    name = proxy.dialect.name if proxy.dialect else "auto"
    print(f"topgimbal proxy: {proxy.url} -> {proxy.to} (dialect {name})", file=sys.stderr, flush=True)
    try:
        await stop.wait()
    finally:
        await proxy.stop()
        print(f"topgimbal proxy: {json.dumps(proxy.stats.as_dict())}", file=sys.stderr, flush=True)
    return 0


def watch_main() -> None:
    """`topgimbal proxy`'s watcher process (the proxy starts it: argv is the print mode and the
    descriptor for its counters): decode, capture, log and print what the proxy forwarded."""
    from ..wire.offload import read_config, serve
    from ..wire.watcher import Watcher

    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C reaches the whole group; the proxy says when to end
    mode = sys.argv[1]
    config = read_config(0)
    if config["model"]:
        dialect: Dialect | None = get_model(config["model"])[0]
    else:
        dialect = get_dialect(config["dialect"]) if config["dialect"] else None
    watcher = Watcher(
        dialect=dialect,
        device=tuple(config["device"]),
        transport=config["transport"],
        pcap=config["pcap"],
        log_path=config["log_path"],
        log_header=config["log_header"],
    )
    watcher.open()
    printer = _Printer(sys.stdout, mode == "json") if mode != "quiet" else None
    if printer is not None:
        watcher.subscribe(printer)
    gc.freeze()
    serve(watcher, printer.flush if printer is not None else lambda: None)
