"""`topgimbal sim --media DIR --media-port N`: the card's files over HTTP on loopback, as a camera's
web server or a download app would give them.

GET /             JSON: [{"name", "size", "mtime"}] of the media files, oldest first
GET /<name>       one file (only names the media store writes: no paths, no other files)
HEAD /<name>      its size

Bounded: at most `MAX_CLIENTS` requests at once (more get 503 and a rate-limited log line); a
request line or header block that does not parse gets 400 from http.server itself."""

from __future__ import annotations

import json
import logging
import shutil
import threading
from http import HTTPStatus
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from urllib.parse import unquote, urlsplit

from ..logthrottle import ThrottledLog
from .lens import MEDIA_NAME

log = logging.getLogger("topgimbal.sim")

MAX_CLIENTS = 8
LOG_EVERY_S = 10.0
TYPES = {".jpg": "image/jpeg", ".jpeg": "image/jpeg", ".mp4": "video/mp4"}


def media_index(directory: Path) -> list[dict[str, object]]:
    out = []
    for p in directory.iterdir():
        if p.is_file() and MEDIA_NAME.match(p.name):
            st = p.stat()
            out.append({"name": p.name, "size": st.st_size, "mtime": round(st.st_mtime, 3)})
    out.sort(key=lambda e: (e["mtime"], e["name"]))  # type: ignore[return-value]
    return out


class MediaServer:
    def __init__(self, directory: str | Path, host: str = "127.0.0.1", port: int = 0) -> None:
        self.dir = Path(directory)
        self._slots = threading.BoundedSemaphore(MAX_CLIENTS)
        self._refusal_log = ThrottledLog(log, LOG_EVERY_S)
        self.refused = 0
        server = self

        class Handler(BaseHTTPRequestHandler):
            server_version = "topgimbal-media"

            def log_message(self, format: str, *args: object) -> None:
                log.debug("media http: " + format, *args)

            def do_GET(self) -> None:
                server.handle(self, body=True)

            def do_HEAD(self) -> None:
                server.handle(self, body=False)

        self.httpd = ThreadingHTTPServer((host, port), Handler)
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

    def handle(self, req: BaseHTTPRequestHandler, *, body: bool) -> None:
        if not self._slots.acquire(blocking=False):
            self.refused += 1
            if self._refusal_log.allow("full") is not None:
                log.warning("media http: more than %d requests at once: refused (%d so far)", MAX_CLIENTS, self.refused)
            req.send_error(HTTPStatus.SERVICE_UNAVAILABLE, f"at most {MAX_CLIENTS} requests at once")
            return
        try:
            self._serve(req, body)
        except (BrokenPipeError, ConnectionResetError):
            pass  # the client went away
        finally:
            self._slots.release()

    def _serve(self, req: BaseHTTPRequestHandler, body: bool) -> None:
        name = unquote(urlsplit(req.path).path).lstrip("/")
        if name in ("", "index.json"):
            data = json.dumps(media_index(self.dir)).encode()
            self._head(req, HTTPStatus.OK, "application/json", len(data))
            if body:
                req.wfile.write(data)
            return
        path = self.dir / name
        if not MEDIA_NAME.match(name) or not path.is_file():
            req.send_error(HTTPStatus.NOT_FOUND, "no such media file (GET / lists them)")
            return
        try:
            f = path.open("rb")
        except OSError:  # dropped by the size cap meanwhile
            req.send_error(HTTPStatus.NOT_FOUND, "no such media file (GET / lists them)")
            return
        with f:
            size = path.stat().st_size
            self._head(req, HTTPStatus.OK, TYPES.get(path.suffix, "application/octet-stream"), size)
            if body:
                shutil.copyfileobj(f, req.wfile)

    @staticmethod
    def _head(req: BaseHTTPRequestHandler, status: HTTPStatus, ctype: str, length: int) -> None:
        req.send_response(status)
        req.send_header("Content-Type", ctype)
        req.send_header("Content-Length", str(length))
        req.end_headers()
