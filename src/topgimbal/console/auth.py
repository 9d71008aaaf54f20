"""The console's access rule.

Bound to a loopback address the console is open to the local user (as any local service is).
Bound to any other address, anyone on that network could steer the gimbal, so a token is then
required: given with `--token`, or generated and printed in the URL. When a token is set, every
HTTP request and the WebSocket must carry it: `?token=...`, the `X-Topgimbal-Token` header,
`Authorization: Bearer ...`, or the cookie the page receives when it is opened with the token.
"""

from __future__ import annotations

import hmac
import ipaddress
import secrets
from collections.abc import Awaitable, Callable

from aiohttp import web

TOKEN_HEADER = "X-Topgimbal-Token"
TOKEN_COOKIE = "topgimbal_token"
TOKEN_QUERY = "token"

Handler = Callable[[web.Request], Awaitable[web.StreamResponse]]


def is_loopback(host: str) -> bool:
    """True for 127.0.0.0/8, ::1 and `localhost`; False for anything else (0.0.0.0, names, LAN IPs)."""
    h = host.strip().strip("[]")
    if h.lower() == "localhost":
        return True
    try:
        return ipaddress.ip_address(h).is_loopback
    except ValueError:
        return False


def needs_token(host: str) -> bool:
    """A non-loopback bind address requires a token."""
    return not is_loopback(host)


def generate_token() -> str:
    return secrets.token_urlsafe(18)


def resolve_token(host: str, token: str | None) -> tuple[str | None, bool]:
    """The token to enforce for `host`, and whether it was generated here.

    An explicit token is always enforced (also on loopback); a non-loopback host without one
    gets a fresh random token."""
    if token:
        return token, False
    if needs_token(host):
        return generate_token(), True
    return None, False


def request_token(request: web.Request) -> str | None:
    """The token a request carries, from the query, a header or the cookie."""
    found = request.query.get(TOKEN_QUERY) or request.headers.get(TOKEN_HEADER)
    if not found:
        auth = request.headers.get("Authorization", "")
        if auth.lower().startswith("bearer "):
            found = auth[7:].strip()
    return found or request.cookies.get(TOKEN_COOKIE)


def token_matches(expected: str, given: str | None) -> bool:
    return given is not None and hmac.compare_digest(expected.encode(), given.encode())


def token_middleware(token: str | None) -> Callable[[web.Request, Handler], Awaitable[web.StreamResponse]]:
    """Reject (401) every request without the token; set the cookie when the page is opened with it."""

    @web.middleware
    async def middleware(request: web.Request, handler: Handler) -> web.StreamResponse:
        if token is None:
            return await handler(request)
        if not token_matches(token, request_token(request)):
            return web.json_response(
                {
                    "error": "unauthorized",
                    "message": "this console requires its token: open the URL it printed (…/?token=…)",
                },
                status=401,
            )
        response = await handler(request)
        if request.query.get(TOKEN_QUERY) and not response.prepared:
            response.set_cookie(TOKEN_COOKIE, token, httponly=True, samesite="Strict", path="/")
        return response

    return middleware
