"""`topgimbal sim --media DIR --media-port N`: the card's files over HTTP on loopback, as a camera's
web server or a download app would give them.

GET /             JSON: [{"name", "size", "mtime"}] of the media files, oldest first
GET /<name>       one file (only names the media store writes: no paths, no other files)
HEAD /<name>      its size

Bounded: at most `MAX_CONNECTIONS` connections (each a thread) and `MAX_PER_CLIENT` per client
address (one whose answer's last bytes are on their way and that closes no longer counts), checked
when a connection is accepted (beyond them it gets a 503 line and is closed, no thread made); at most `MAX_CLIENTS` requests at once (more get 503); every socket wait (the request
head, each write to a client that does not read) at most `SOCKET_TIMEOUT_S`, a whole response at
most `MAX_RESPONSE_S`. Each refusal is counted and logged at most every LOG_EVERY_S. A request line
or header block that does not parse gets 400 from http.server itself."""

from __future__ import annotations

import contextlib
import json
import logging
import socket
import threading
from http import HTTPStatus
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from typing import Any
from urllib.parse import unquote, urlsplit

from ..clock import monotonic
from ..logthrottle import ThrottledLog
from .lens import MEDIA_NAME

log = logging.getLogger("topgimbal.sim")

MAX_CLIENTS = 8  # requests in progress
MAX_CONNECTIONS = 32  # open connections (threads)
MAX_PER_CLIENT = 2  # open connections per client address
SOCKET_TIMEOUT_S = 10.0  # each wait on a client's socket
MAX_RESPONSE_S = 600.0  # a whole response (a client reading a byte a second is cut off)
CHUNK = 64 * 1024
LOG_EVERY_S = 10.0
REFUSAL = b"HTTP/1.0 503 Service Unavailable\r\nContent-Length: 0\r\nConnection: close\r\n\r\n"
TYPES = {".jpg": "image/jpeg", ".jpeg": "image/jpeg", ".mp4": "video/mp4"}


def media_index(directory: Path) -> list[dict[str, object]]:
    out = []
    for p in directory.iterdir():
        if p.is_file() and MEDIA_NAME.match(p.name):
            st = p.stat()
            out.append({"name": p.name, "size": st.st_size, "mtime": round(st.st_mtime, 3)})
    out.sort(key=lambda e: (e["mtime"], e["name"]))
    return out


class MediaServer:
    def __init__(self, directory: str | Path, host: str = "127.0.0.1", port: int = 0) -> None:
        self.dir = Path(directory)
        self._slots = threading.BoundedSemaphore(MAX_CLIENTS)
        self._refusal_log = ThrottledLog(log, LOG_EVERY_S)
        self.refused = 0
        self.refused_connections = 0
        self._conn_lock = threading.Lock()
        self._open: dict[socket.socket, str] = {}  # connection -> client address
        self._per_client: dict[str, int] = {}
        # Connections whose response's last bytes are on their way and that close (HTTP/1.0,
        # `Connection: close`): not counted against their client's MAX_PER_CLIENT any more. Marked
        # before that last write, not after: the client, which then has its whole answer, may open
        # its next connection before this thread runs again (counted, a client fetching files one
        # after another got 503 on a loaded machine, twice: once when the mark came only as the
        # thread closed the connection, once when it came right after the last write).
        self._answered: set[socket.socket] = set()
        server = self

        class Handler(BaseHTTPRequestHandler):
            server_version = "topgimbal-media"
            timeout = SOCKET_TIMEOUT_S  # StreamRequestHandler sets it on the socket

            def log_message(self, format: str, *args: object) -> None:
                log.debug("media http: " + format, *args)

            def do_GET(self) -> None:
                server.handle(self, body=True)

            def do_HEAD(self) -> None:
                server.handle(self, body=False)

        class Bounded(ThreadingHTTPServer):
            request_queue_size = 64  # accepted fast (a refusal makes no thread): a short queue only drops SYNs

            def process_request(self, request: Any, client_address: Any) -> None:
                if not server._admit(request, str(client_address[0])):
                    with contextlib.suppress(OSError):
                        request.setblocking(False)
                        request.send(REFUSAL)
                    self.shutdown_request(request)
                    return
                super().process_request(request, client_address)

            def shutdown_request(self, request: Any) -> None:
                server._release(request)
                super().shutdown_request(request)

        self.httpd = Bounded((host, port), Handler)
        self.httpd.daemon_threads = True
        self._thread = threading.Thread(target=self.httpd.serve_forever, name="media-http", daemon=True)

    @property
    def url(self) -> str:
        host, port = self.httpd.server_address[:2]
        host = str(host)
        return f"http://{'[' + host + ']' if ':' in host else host}:{port}/"

    def start(self) -> MediaServer:
        self._thread.start()
        return self

    def stop(self) -> None:
        self.httpd.shutdown()
        self.httpd.server_close()
        self._thread.join(5.0)

    def _admit(self, conn: socket.socket, client: str) -> bool:
        with self._conn_lock:
            held = self._per_client.get(client, 0) - sum(1 for c in self._answered if self._open.get(c) == client)
            if len(self._open) < MAX_CONNECTIONS and held < MAX_PER_CLIENT:
                self._open[conn] = client
                self._per_client[client] = held + 1
                return True
            self.refused_connections += 1
            n, total = self.refused_connections, len(self._open)
        if self._refusal_log.allow("connections") is not None:
            log.warning("media http: %s has %d connections (limit %d per client, %d of %d in all): refused "
                        "(%d so far)", client, held, MAX_PER_CLIENT, total, MAX_CONNECTIONS, n)  # fmt: skip
        return False

    def _release(self, conn: socket.socket) -> None:
        with self._conn_lock:
            self._answered.discard(conn)
            client = self._open.pop(conn, None)
            if client is not None:
                left = self._per_client.get(client, 1) - 1
                if left > 0:
                    self._per_client[client] = left
                else:
                    self._per_client.pop(client, None)

    def handle(self, req: BaseHTTPRequestHandler, *, body: bool) -> None:
        if not self._slots.acquire(blocking=False):
            self.refused += 1
            if self._refusal_log.allow("full") is not None:
                log.warning("media http: more than %d requests at once: refused (%d so far)", MAX_CLIENTS, self.refused)
            req.send_error(HTTPStatus.SERVICE_UNAVAILABLE, f"at most {MAX_CLIENTS} requests at once")
            return
        try:
            self._serve(req, body)
        except OSError as exc:  # the client went away, or did not read within SOCKET_TIMEOUT_S
            req.close_connection = True
            log.debug("media http: %s: %s", req.client_address[0], exc)
        finally:
            self._slots.release()
            self._last_write(req)  # an answer that ended otherwise (an error)

    def _last_write(self, req: BaseHTTPRequestHandler) -> None:
        """The answer's last bytes go next and the connection then ends: its client may open another."""
        if req.close_connection:
            with self._conn_lock:
                if req.connection in self._open:
                    self._answered.add(req.connection)

    def _serve(self, req: BaseHTTPRequestHandler, body: bool) -> None:
        name = unquote(urlsplit(req.path).path).lstrip("/")
        if name in ("", "index.json"):
            data = json.dumps(media_index(self.dir)).encode()
            if not body:
                self._last_write(req)
            self._head(req, HTTPStatus.OK, "application/json", len(data))
            if body:
                self._last_write(req)
                req.wfile.write(data)
            return
        path = self.dir / name
        if not MEDIA_NAME.match(name) or not path.is_file():
            self._last_write(req)
            req.send_error(HTTPStatus.NOT_FOUND, "no such media file (GET / lists them)")
            return
        try:
            f = path.open("rb")
        except OSError:  # dropped by the size cap meanwhile
            self._last_write(req)
            req.send_error(HTTPStatus.NOT_FOUND, "no such media file (GET / lists them)")
            return
        with f:
            size = path.stat().st_size
            if not body or size == 0:
                self._last_write(req)
            self._head(req, HTTPStatus.OK, TYPES.get(path.suffix, "application/octet-stream"), size)
            if body:
                deadline = monotonic() + MAX_RESPONSE_S
                data = f.read(CHUNK)
                while data:
                    after = f.read(CHUNK)
                    if monotonic() > deadline:
                        raise TimeoutError(f"response longer than {MAX_RESPONSE_S:g} s")
                    if not after:
                        self._last_write(req)
                    req.wfile.write(data)
                    data = after

    @staticmethod
    def _head(req: BaseHTTPRequestHandler, status: HTTPStatus, ctype: str, length: int) -> None:
        req.send_response(status)
        req.send_header("Content-Type", ctype)
        req.send_header("Content-Length", str(length))
        req.end_headers()
