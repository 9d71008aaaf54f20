"""The camera definitions over HTTP: a small read-only server for `cam_definition_uri`.

It serves only the files it was given (GET or HEAD of `/<name>`; anything else 404 / 405 / 400),
answers one request per connection, and is bounded: at most MAX_CONNECTIONS at once and
MAX_PER_CLIENT from one client address (more are closed at once, with a rate-limited log line: one
client renewing slow connections takes its own places, not everyone's), a request head of at most MAX_HEAD_BYTES read
within HEAD_TIMEOUT_S. It binds loopback by default (`--definition-http HOST:PORT`)."""

from __future__ import annotations

import asyncio
import contextlib
import logging

from ..clock import monotonic
from ..logthrottle import ThrottledLog
from ..timeouts import within

log = logging.getLogger("topgimbal.mavlink")

MAX_CONNECTIONS = 16
MAX_PER_CLIENT = 4  # connections at once from one client address
MAX_HEAD_BYTES = 8192
HEAD_TIMEOUT_S = 5.0
LOG_EVERY_S = 10.0


class DefinitionServer:
    def __init__(self, files: dict[str, str], host: str = "127.0.0.1", port: int = 0) -> None:
        self.files = {name: text.encode("utf-8") for name, text in files.items()}
        self.host = host
        self.port = port
        self.server: asyncio.Server | None = None
        self.active = 0
        self.refused = 0
        self.served = 0
        self._refusal_log = ThrottledLog(log, LOG_EVERY_S)
        self._per_client: dict[str, int] = {}
        # What the pacer (pacing.py) reads: when the last connection closed, when each file was last
        # sent (on the loop's clock)
        self.last_closed_at = float("-inf")
        self.served_at: dict[str, float] = {}

    async def start(self) -> None:
        self.server = await asyncio.start_server(self._client, self.host, self.port, limit=MAX_HEAD_BYTES)
        self.port = self.server.sockets[0].getsockname()[1]

    def uri(self, name: str, advertise_host: str | None = None) -> str:
        host = advertise_host or self.host
        if host in ("0.0.0.0", "", "::"):
            host = "127.0.0.1"
        if ":" in host:
            host = f"[{host}]"
        return f"http://{host}:{self.port}/{name}"

    async def close(self) -> None:
        if self.server is not None:
            self.server.close()
            with contextlib.suppress(Exception):
                await self.server.wait_closed()

    async def _client(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        peer = writer.get_extra_info("peername")
        client = str(peer[0]) if isinstance(peer, tuple) and peer else "?"
        held = self._per_client.get(client, 0)
        if self.active >= MAX_CONNECTIONS or held >= MAX_PER_CLIENT:
            self.refused += 1
            if self._refusal_log.allow("full") is not None:
                log.warning("camera definition server: %d connections open (%d from %s; limits %d, %d per client), "
                            "refused %d", self.active, held, client, MAX_CONNECTIONS, MAX_PER_CLIENT, self.refused)  # fmt: skip
            writer.close()
            return
        self.active += 1
        self._per_client[client] = held + 1
        try:
            head = await within(reader.readuntil(b"\r\n\r\n"), HEAD_TIMEOUT_S)
            status, body, ctype = self._answer(head)
            head_only = head.startswith(b"HEAD ")
        except (asyncio.TimeoutError, asyncio.IncompleteReadError, asyncio.LimitOverrunError, ValueError,
                ConnectionError):  # fmt: skip
            status, body, ctype, head_only = "400 Bad Request", b"bad request\n", "text/plain", False
        try:
            writer.write(
                f"HTTP/1.1 {status}\r\nContent-Type: {ctype}\r\nContent-Length: {len(body)}\r\n"
                "Connection: close\r\n\r\n".encode()
                + (b"" if head_only else body)
            )
            await within(writer.drain(), HEAD_TIMEOUT_S)
        except (OSError, asyncio.TimeoutError):
            pass
        finally:
            self.active -= 1
            self.last_closed_at = monotonic()
            left = self._per_client.get(client, 1) - 1
            if left > 0:
                self._per_client[client] = left
            else:
                self._per_client.pop(client, None)
            writer.close()

    def _answer(self, head: bytes) -> tuple[str, bytes, str]:
        line = head.split(b"\r\n", 1)[0].decode("latin-1")
        parts = line.split(" ")
        if len(parts) != 3 or not parts[2].startswith("HTTP/"):
            return "400 Bad Request", b"bad request\n", "text/plain"
        method, path = parts[0], parts[1].split("?", 1)[0]
        if method not in ("GET", "HEAD"):
            return "405 Method Not Allowed", b"only GET\n", "text/plain"
        body = self.files.get(path.lstrip("/"))
        if body is None:
            return "404 Not Found", b"no such definition\n", "text/plain"
        self.served += 1
        self.served_at[path.lstrip("/")] = monotonic()
        return "200 OK", body, "application/xml"
