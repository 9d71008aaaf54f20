"""Which Host and Origin the console answers: its own names only (DNS rebinding and cross-site
control are refused even on loopback, where no token is asked for).

A web page on `evil.example` whose name the attacker later points at 127.0.0.1 makes the browser
send `Host: evil.example:PORT` to the console, with the page's own origin; a page elsewhere can open
a WebSocket to `ws://127.0.0.1:PORT/ws` with its own `Origin`. Both reach a loopback console, so
the console checks, on every request, that the Host is one of its names and, where a browser would
send one, that the Origin is exactly one of its own `http(s)://name:port` origins.

A page on another site (or another port of this machine: a different origin, the same "site")
can also simply embed the console: `<img src="http://127.0.0.1:PORT/video/visible.mjpg">` takes
a viewer place, an `<iframe>` runs the whole console page. A browser sends no Origin with such
requests, but it does say where they come from: on every route (pages, static files, JSON,
pictures, the socket) a request whose `Sec-Fetch-Site` is anything but `same-origin` (the
console's own page) or `none` (the operator typed the URL, a bookmark, a link from the terminal)
is refused 403; a browser that sends no `Sec-Fetch-Site` (before 2020-2023) is judged by its
`Origin` and, failing that, its `Referer` (it must be one of the console's own origins). Clients
that send none of these (scripts, `curl`, the tests) pass; the token rule still applies to them.

Allowed names: `localhost`, `127.0.0.1`, `::1`, the address the console was bound to, the address
the connection actually arrived on (an IP literal cannot be rebound, so `--host 0.0.0.0` works with
`http://LAN-ADDRESS:PORT/`), and every `--allow-host NAME`. The port must be the one the
connection arrived on.
"""

from __future__ import annotations

import ipaddress
import logging
from collections.abc import Awaitable, Callable, Iterable
from typing import Any

from aiohttp import web

from ..errors import TopGimbalError
from ..logtext import untrusted

log = logging.getLogger(__name__)

LOOPBACK_NAMES = ("localhost", "127.0.0.1", "::1")
WILDCARD_ADDRESSES = ("", "0.0.0.0", "::")
SAFE_METHODS = frozenset({"GET", "HEAD", "OPTIONS"})
# Sec-Fetch-Site values of requests the console answers: its own page, or the operator's own
# navigation (typed URL, bookmark). "same-site" is another port or subdomain: another origin.
OWN_FETCH_SITES = frozenset({"same-origin", "none"})
MAX_LOGGED_REFUSALS = 50  # distinct refusals logged; a flood of bad requests must not flood the log

Handler = Callable[[web.Request], Awaitable[web.StreamResponse]]


class HostNameError(TopGimbalError, ValueError):
    """An `--allow-host` value that is not a host name or address."""


def normalize_host(name: str) -> str:
    """Lower case, without IPv6 brackets or a trailing dot; IP addresses in their canonical form."""
    h = name.strip().lower()
    if h.startswith("[") and h.endswith("]"):
        h = h[1:-1]
    h = h.rstrip(".")
    try:
        return str(ipaddress.ip_address(h))
    except ValueError:
        return h


def check_allow_host(name: str) -> str:
    """An `--allow-host` value, normalized; HostNameError saying what is allowed otherwise."""
    h = normalize_host(name)
    try:
        ipaddress.ip_address(h)
        return h
    except ValueError:
        pass
    labels = h.split(".")
    if (
        not h
        or len(h) > 253
        or not all(
            label and len(label) <= 63 and all(c.isascii() and (c.isalnum() or c == "-") for c in label)
            for label in labels
        )
    ):
        raise HostNameError(
            f"--allow-host {name!r}: expected a host name (letters, digits, '-' and '.') or an IP address, "
            "without scheme, port or wildcard"
        )
    return h


def default_allowed_hosts(bind_host: str, extra: Iterable[str] = ()) -> frozenset[str]:
    """Loopback names, the bound address (unless it is a wildcard) and the extra names."""
    names = set(LOOPBACK_NAMES)
    bound = normalize_host(bind_host)
    if bound not in WILDCARD_ADDRESSES:
        names.add(bound)
    names.update(check_allow_host(n) for n in extra)
    return frozenset(names)


def split_host_port(value: str) -> tuple[str, int | None] | None:
    """`name`, `name:port`, `[v6]` or `[v6]:port` -> (name, port); None when malformed."""
    v = value.strip()
    if not v or any(c in v for c in "/@?#\\ \t"):
        return None
    if v.startswith("["):
        end = v.find("]")
        if end < 0:
            return None
        name, rest = v[: end + 1], v[end + 1 :]
        if rest and not rest.startswith(":"):
            return None
        port_text = rest[1:] if rest else None
    elif v.count(":") == 1:
        name, port_text = v.split(":")
    elif ":" in v:
        return None  # a bare IPv6 address is not a valid Host (it needs brackets)
    else:
        name, port_text = v, None
    if port_text is None:
        return normalize_host(name), None
    if not port_text.isdigit() or len(port_text) > 5 or not 0 < int(port_text) < 65536:
        return None
    return normalize_host(name), int(port_text)


def _local_address(request: web.Request) -> tuple[str | None, int | None]:
    """The address and port this connection arrived on."""
    transport = request.transport
    sock: Any = transport.get_extra_info("sockname") if transport is not None else None
    if isinstance(sock, tuple) and len(sock) >= 2:
        return normalize_host(str(sock[0])), int(sock[1])
    return None, None


class HostGuard:
    """The allow-list and its checks; `middleware()` applies them to every request."""

    def __init__(self, allowed: Iterable[str]) -> None:
        self.allowed = frozenset(normalize_host(n) for n in allowed)
        self._logged: set[tuple[str, str]] = set()

    def names(self) -> str:
        return ", ".join(sorted(self.allowed))

    def _name_ok(self, name: str, request: web.Request) -> bool:
        local, _ = _local_address(request)
        return name in self.allowed or (local is not None and name == local)

    def _port_ok(self, port: int | None, request: web.Request, default: int) -> bool:
        _, local_port = _local_address(request)
        if local_port is None:
            return True
        return (port if port is not None else default) == local_port

    def host_problem(self, request: web.Request) -> str | None:
        """Why the request's Host is refused (None when it is one of ours)."""
        raw = request.headers.get("Host")
        if raw is None:
            return "the request has no Host header"
        parsed = split_host_port(raw)
        if parsed is None:
            return f"Host {raw!r} is not a host name with an optional port"
        name, port = parsed
        if not self._name_ok(name, request):
            return (
                f"Host {raw!r} is not one of this console's names ({self.names()}); a page that reaches it "
                f"under another name may be a DNS-rebinding attack. To allow the name, start the console "
                f"with --allow-host {name}"
            )
        if not self._port_ok(port, request, 80):
            return f"Host {raw!r} names another port than the one this console listens on"
        return None

    def origin_problem(self, request: web.Request) -> str | None:
        """Why the request's Origin is refused (None when absent or exactly one of ours)."""
        origin = request.headers.get("Origin")
        if origin is None:
            return None  # not sent by a browser (scripts, tests): the token rule still applies
        scheme, sep, rest = origin.partition("://")
        allowed = f"http(s)://NAME:PORT with NAME one of {self.names()} and this console's port"
        if not sep or scheme not in ("http", "https"):
            return f"Origin {origin!r} is not an http(s) origin of this console (expected {allowed})"
        parsed = split_host_port(rest)
        if parsed is None:
            return f"Origin {origin!r} is not scheme://host[:port] (expected {allowed})"
        name, port = parsed
        if not self._name_ok(name, request) or not self._port_ok(port, request, 443 if scheme == "https" else 80):
            return f"Origin {origin!r} is another site (expected {allowed}): cross-site requests are refused"
        return None

    def _own_origin_problem(self, header: str, value: str, request: web.Request) -> str | None:
        """Why `value` (an Origin, or a Referer URL) is not one of this console's origins."""
        scheme, sep, rest = value.partition("://")
        allowed = f"http(s)://NAME:PORT with NAME one of {self.names()} and this console's port"
        if not sep or scheme.lower() not in ("http", "https"):
            return f"{header} {value[:100]!r} is not an http(s) origin of this console (expected {allowed})"
        authority = rest.split("/", 1)[0].split("?", 1)[0].split("#", 1)[0]
        parsed = split_host_port(authority)
        if parsed is None:
            return f"{header} {value[:100]!r} does not name a host and port (expected {allowed})"
        name, port = parsed
        default = 443 if scheme.lower() == "https" else 80
        if not self._name_ok(name, request) or not self._port_ok(port, request, default):
            return f"{header} {value[:100]!r} is another site (expected {allowed}): cross-site requests are refused"
        return None

    def embedding_problem(self, request: web.Request) -> str | None:
        """Why a request looks made by another site's page (None when it is the console's own
        page, the operator's own navigation, or not a browser)."""
        site = request.headers.get("Sec-Fetch-Site")
        if site is not None:
            if site.strip().lower() in OWN_FETCH_SITES:
                return None
            dest = request.headers.get("Sec-Fetch-Dest", "?")
            return (
                f"Sec-Fetch-Site {site[:40]!r} (a {dest[:20]} request made by another site's page, or by a page on "
                "another port of this machine): the console answers only its own page and the URL opened directly"
            )
        origin = request.headers.get("Origin")
        if origin is not None:
            return self._own_origin_problem("Origin", origin, request)
        referer = request.headers.get("Referer")
        if referer:
            return self._own_origin_problem("Referer", referer, request)
        return None

    def _log_refusal(self, request: web.Request, status: int, message: str) -> None:
        key = (request.path, message)
        if key in self._logged or len(self._logged) > MAX_LOGGED_REFUSALS:
            return
        self._logged.add(key)
        peer = request.remote or "?"
        log.warning(
            "refused %s %s from %s (%d): %s",
            untrusted(request.method), untrusted(request.path), peer, status, untrusted(message, 600),
        )  # fmt: skip
        if len(self._logged) > MAX_LOGGED_REFUSALS:
            log.warning("further refused requests are not logged")

    def middleware(self) -> Callable[[web.Request, Handler], Awaitable[web.StreamResponse]]:
        @web.middleware
        async def check(request: web.Request, handler: Handler) -> web.StreamResponse:
            problem = self.host_problem(request)
            if problem is not None:
                self._log_refusal(request, 421, problem)
                return web.json_response({"error": "misdirected", "message": problem}, status=421)
            problem = None
            if request.method not in SAFE_METHODS or request.path == "/ws":
                problem = self.origin_problem(request)
            # Every route, media included: no other site's page may embed or read the console.
            problem = problem or self.embedding_problem(request)
            if problem is not None:
                self._log_refusal(request, 403, problem)
                return web.json_response({"error": "forbidden", "message": problem}, status=403)
            return await handler(request)

        return check


__all__ = [
    "LOOPBACK_NAMES",
    "HostGuard",
    "HostNameError",
    "check_allow_host",
    "default_allowed_hosts",
    "normalize_host",
    "split_host_port",
]
