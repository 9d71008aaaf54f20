"""Opening a Zenoh session for a camera fleet (server or remote client), with scouting off.

Zenoh's defaults scout by UDP multicast (224.0.0.224) and gossip: a fleet is wired by explicit
endpoints instead (`--listen` / `--connect`), so nothing is sent to addresses nobody named. A
Zenoh configuration file (TLS, user/password, access control) is read first and then given the
endpoints, mode and scouting settings; a file that turns scouting back on is overridden.

Nothing listens unless asked: Zenoh's peer default (`tcp/[::]:0`, every interface, a random port)
is replaced by no listener when neither `listen` nor the file names one, and `final_endpoints`
reads what the final configuration will really listen on and connect to (what the exposure check
of fleet/access.py judges)."""

from __future__ import annotations

import json
import re
from collections.abc import Sequence
from typing import Any

from ..errors import FieldValueError, TransportError

MODES = ("peer", "client")
# eclipse-zenoh's errors end with the Rust source line that raised them ("... at /root/.cargo/git/
# checkouts/zenoh-.../orchestrator.rs:447."): of no use to a user, so it is cut.
_RUST_AT = re.compile(r"\s+at\s+\S+\.rs:\d+\.?")


def zenoh_error_text(exc: BaseException) -> str:
    """One line: the Rust source path cut, a parser's multi-line pointer drawing joined."""
    return " ".join(_RUST_AT.sub("", str(exc)).split()) or type(exc).__name__


def _zenoh() -> Any:
    try:
        import zenoh
    except ImportError:  # pragma: no cover - the extra is part of the dev install
        raise TransportError("Zenoh needs the eclipse-zenoh package: pip install 'topgimbal[zenoh]'") from None
    return zenoh


def check_endpoint(endpoint: str) -> str:
    proto, sep, rest = endpoint.partition("/")
    if not sep or proto not in ("tcp", "udp", "tls", "quic", "ws", "unixsock-stream") or not rest:
        raise FieldValueError("endpoint", endpoint, "a Zenoh locator such as tcp/127.0.0.1:7447")
    return endpoint


def make_config(
    *, listen: Sequence[str] = (), connect: Sequence[str] = (), mode: str = "peer", config_file: str | None = None
) -> Any:
    zenoh = _zenoh()
    if mode not in MODES:
        raise FieldValueError("mode", mode, " or ".join(MODES))
    for e in (*listen, *connect):
        check_endpoint(e)
    if mode == "client" and not connect:
        raise FieldValueError("connect", None, "a client needs at least one --connect endpoint")
    try:
        conf = zenoh.Config.from_file(config_file) if config_file else zenoh.Config()
    except Exception as exc:  # zenoh's own error type: say which file, whole (the value shown is cut at 80)
        raise FieldValueError(
            "config", config_file, f"a Zenoh configuration file: {config_file} is not one ({zenoh_error_text(exc)})"
        ) from None
    conf.insert_json5("mode", json.dumps(mode))
    conf.insert_json5("scouting/multicast/enabled", "false")
    conf.insert_json5("scouting/gossip/enabled", "false")
    if listen:
        conf.insert_json5("listen/endpoints", json.dumps(list(listen)))
    elif _endpoints(conf, "listen", mode) == _endpoints(zenoh.Config(), "listen", mode):
        # Zenoh's own default (a peer listens on every interface): none, unless asked for
        conf.insert_json5("listen/endpoints", "[]")
    if connect:
        conf.insert_json5("connect/endpoints", json.dumps(list(connect)))
    return conf


def _endpoints(conf: Any, which: str, mode: str) -> list[str]:
    """`listen` or `connect` endpoints of a configuration for `mode` (Zenoh keeps them as a list,
    or per mode as {"router": [...], "peer": [...], "client": [...]})."""
    try:
        value = json.loads(conf.get_json(f"{which}/endpoints"))
    except Exception:  # a key this eclipse-zenoh version does not know
        return []
    if isinstance(value, dict):
        value = value.get(mode, [])
    return [str(e) for e in value] if isinstance(value, list) else []


def final_endpoints(conf: Any, mode: str) -> tuple[list[str], list[str]]:
    """(listen, connect): the endpoints the configuration will really listen on and connect to,
    command line and configuration file together."""
    return _endpoints(conf, "listen", mode), _endpoints(conf, "connect", mode)


def open_session(
    *, listen: Sequence[str] = (), connect: Sequence[str] = (), mode: str = "peer", config_file: str | None = None
) -> Any:
    """An open `zenoh.Session` (blocking call: a client waits for its router or peer)."""
    zenoh = _zenoh()
    conf = make_config(listen=listen, connect=connect, mode=mode, config_file=config_file)
    try:
        return zenoh.open(conf)
    except Exception as exc:  # e.g. an endpoint already in use, nothing to connect to
        where = ", ".join([*listen, *connect]) or "no endpoint"
        raise TransportError(f"cannot open a Zenoh session ({mode}, {where}): {zenoh_error_text(exc)}") from None
