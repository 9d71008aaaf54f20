"""Who may act on a served camera: the exposure gate and the remotely callable methods (pure).

Zenoh itself authenticates and authorises (its `transport.auth.usrpwd` or TLS/mTLS, and its
`access_control` rules by key and subject, in a `--config` file): topgimbal builds no access layer
of its own. What it adds is a safe default around that:

- a session reachable beyond loopback (any `--listen` or `--connect` endpoint not on 127.0.0.0/8,
  ::1 or localhost) starts only with a configuration that turns Zenoh's access control on and
  authenticates peers (user/password or mTLS), or with an explicit `--insecure`, which the log
  repeats every `INSECURE_LOG_EVERY_S`;
- methods that change the camera's network, its persistent settings or send raw frames are not
  callable remotely unless named by `--allow-remote NAME`;
- the attitude stream is the server's (every subscriber, the console and `--mavlink-keys` read
  it): starting, re-rating or stopping it is never remote."""

from __future__ import annotations

import ipaddress
from collections.abc import Iterable, Sequence
from typing import Any

from ..client.remote_keys import METHODS

# Remotely callable only when named by --allow-remote: they change the camera's address
# (unreachable until someone is on site), send any catalog command (persistent settings
# included) or send a frame as given.
RESTRICTED = frozenset({"set_network", "send_raw", "request"})  # request: unless read=True
# The server owns the attitude stream: never callable remotely, whatever --allow-remote says.
SERVER_OWNED = frozenset({"attitude_stream", "stop_attitude_stream"})
INSECURE_LOG_EVERY_S = 60.0

KIND_FORBIDDEN = "forbidden"


class AccessConfigError(ValueError):
    """The server would be reachable beyond loopback without access control (or a bad name)."""


def endpoint_host(endpoint: str) -> str:
    """The host of `proto/host:port[#...]` (brackets of an IPv6 address removed)."""
    rest = endpoint.partition("/")[2].split("#", 1)[0].split("?", 1)[0]
    if rest.startswith("["):
        return rest[1:].partition("]")[0]
    return rest.rpartition(":")[0] if ":" in rest else rest


def is_loopback(endpoint: str) -> bool:
    if endpoint.startswith("unixsock-stream/"):
        return True  # a local socket file: only this host reaches it
    host = endpoint_host(endpoint)
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False  # a name resolves to whatever the network says: not loopback


def exposed(endpoints: Iterable[str]) -> list[str]:
    return [e for e in endpoints if not is_loopback(e)]


def _json(conf: Any, path: str) -> str:
    try:
        return str(conf.get_json(path))
    except Exception:  # a key this eclipse-zenoh version does not know
        return "null"


def protection(conf: Any) -> str | None:
    """What protects a Zenoh configuration ("ACL + user/password", "ACL + mTLS") or None when
    it lacks access control or peer authentication."""
    if _json(conf, "access_control/enabled") != "true":
        return None
    if _json(conf, "transport/auth/usrpwd/dictionary_file") not in ("null", '""'):
        return "access control + user/password"
    if _json(conf, "transport/link/tls/enable_mtls") == "true":
        return "access control + mTLS"
    return None


def check_exposure(endpoints: Sequence[str], conf: Any, insecure: bool, mode: str = "peer") -> str:
    """The log line saying how the session is protected; AccessConfigError when it is reachable
    beyond loopback without access control and `insecure` is not given. Judged on the endpoints of
    the final configuration (a `--config` file's `listen.endpoints` included) besides `endpoints`."""
    from ..client.zenoh_session import final_endpoints

    listen, connect = final_endpoints(conf, mode)
    wide = list(dict.fromkeys(exposed([*endpoints, *listen, *connect])))
    if not wide:
        return "loopback endpoints only"
    how = protection(conf)
    if how is not None:
        return f"{', '.join(wide)} protected by Zenoh {how} (--config)"
    if insecure:
        return (f"INSECURE: {', '.join(wide)} reachable beyond loopback without access control: anyone who "
                "reaches it controls every camera (--insecure)")  # fmt: skip
    raise AccessConfigError(
        f"{', '.join(wide)} is reachable beyond loopback: give a Zenoh --config FILE with access_control enabled "
        "and user/password (transport.auth.usrpwd) or mTLS (docs/fleet.md, 'Access control'), or --insecure"
    )


def check_allowed(names: Iterable[str]) -> frozenset[str]:
    """The --allow-remote names, each one of RESTRICTED; AccessConfigError otherwise."""
    out = set()
    for n in names:
        if n in SERVER_OWNED:
            raise AccessConfigError(f"--allow-remote {n}: the attitude stream is the server's, never remote")
        if n not in RESTRICTED:
            raise AccessConfigError(f"--allow-remote {n}: expected one of {', '.join(sorted(RESTRICTED))}")
        out.add(n)
    return frozenset(out)


def callable_methods(allowed: frozenset[str]) -> list[str]:
    """What `info` lists: `request` always (its reads are callable)."""
    return sorted(
        m for m in METHODS if m not in SERVER_OWNED and (m not in RESTRICTED or m in allowed or m == "request")
    )


def refusal(method: str, allowed: frozenset[str], kwargs: dict[str, object] | None = None) -> str | None:
    """Why `method` is not remotely callable, or None when it is. With its arguments (`kwargs`),
    a `request` that only reads (`read=True`) is callable: it changes nothing."""
    if method in SERVER_OWNED:
        return f"{method}: the attitude stream is the server's (every subscriber reads it); not callable remotely"
    if method == "request" and kwargs is None:
        return None  # decided once its arguments are known
    if method == "request" and kwargs is not None and kwargs.get("read") is True:
        return None
    if method in RESTRICTED and method not in allowed:
        return f"{method}: not callable remotely unless the server is started with --allow-remote {method}"
    if method == "locate" and kwargs is not None and kwargs.get("terrain") is not None:
        # a path names a file of the server's machine: a peer would learn which files exist there
        return "locate: terrain is not taken from a remote caller (a path on the server's machine); call it without"
    return None
