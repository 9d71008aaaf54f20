"""Issue 33, items 7-10 (and 35.4): `media get` against a hostile server keeps nothing bad, and the
media server bounds its clients. The hostile server is http.server on loopback, answering what
each test sets."""

from __future__ import annotations

import json
import socket
import threading
import time
from collections.abc import Callable, Iterator
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from typing import Any

import pytest

from topgimbal.cli.main import main
from topgimbal.video import media_http
from topgimbal.video.media_http import MediaServer

pytestmark = pytest.mark.loopback

Answer = Callable[[BaseHTTPRequestHandler], None]


@pytest.fixture
def hostile() -> Iterator[tuple[str, dict[str, Answer]]]:
    routes: dict[str, Answer] = {}

    class Handler(BaseHTTPRequestHandler):
        def log_message(self, format: str, *args: object) -> None:
            pass

        def do_GET(self) -> None:
            answer = routes.get(self.path)
            if answer is None:
                self.send_error(404)
                return
            try:
                answer(self)
            except OSError:
                pass

    httpd = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
    httpd.daemon_threads = True
    t = threading.Thread(target=httpd.serve_forever, daemon=True)
    t.start()
    yield f"http://127.0.0.1:{httpd.server_address[1]}/", routes
    httpd.shutdown()
    httpd.server_close()


def body(data: bytes, length: int | None = None, per_byte_s: float = 0.0) -> Answer:
    def answer(h: BaseHTTPRequestHandler) -> None:
        h.send_response(200)
        h.send_header("Content-Length", str(len(data) if length is None else length))
        h.end_headers()
        if per_byte_s:
            for i in range(len(data)):
                h.wfile.write(data[i : i + 1])
                h.wfile.flush()
                time.sleep(per_byte_s)
        else:
            h.wfile.write(data)

    return answer


def index(*names: str) -> Answer:
    return body(json.dumps([{"name": n, "size": 1} for n in names]).encode())


def test_a_cut_short_body_is_never_a_file(hostile: Any, tmp_path: Path, capsys: Any) -> None:
    url, routes = hostile
    routes["/"] = index("IMG_0001.jpg")
    routes["/IMG_0001.jpg"] = body(b"x" * 5000, length=100000)
    assert main(["media", "get", url, "-o", str(tmp_path)]) == 1
    assert "cut short: 5000 of 100000 bytes" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []  # neither the file nor a .part


def test_only_media_names_are_written_and_nothing_is_replaced(hostile: Any, tmp_path: Path, capsys: Any) -> None:
    url, routes = hostile
    routes["/"] = index(".bashrc", "notes.txt", "IMG_0001.jpg", "snap_0_1.jpeg\x00x", "IMG_0002.jpg", "IMG_0003.jpg\n")
    for n in ("IMG_0001.jpg", "IMG_0002.jpg", ".bashrc", "notes.txt"):
        routes["/" + n] = body(b"new " + n.encode())
    (tmp_path / "IMG_0002.jpg").write_bytes(b"mine")
    (tmp_path / "IMG_0001.jpg.part").write_bytes(b"a file of mine that looks like a partial")
    assert main(["media", "get", url, "-o", str(tmp_path)]) == 1
    err = capsys.readouterr().err
    assert "'.bashrc' is not a camera media name" in err and "'notes.txt'" in err
    assert "snap_0_1.jpeg\\x00x" in err and "\x00" not in err  # reported, and the run went on
    assert "IMG_0002.jpg exists: not replaced" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["IMG_0001.jpg", "IMG_0001.jpg.part", "IMG_0002.jpg"]
    assert (tmp_path / "IMG_0001.jpg").read_bytes() == b"new IMG_0001.jpg"
    assert (tmp_path / "IMG_0002.jpg").read_bytes() == b"mine"
    assert (tmp_path / "IMG_0001.jpg.part").read_bytes().startswith(b"a file of mine")
    # options after the names, and --overwrite
    assert main(["media", "get", url, "-o", str(tmp_path), "IMG_0002.jpg", "--overwrite"]) == 0
    assert (tmp_path / "IMG_0002.jpg").read_bytes() == b"new IMG_0002.jpg"


def test_timeout_bounds_the_whole_request(hostile: Any, tmp_path: Path, capsys: Any) -> None:
    url, routes = hostile
    routes["/"] = index("IMG_0001.jpg")
    routes["/IMG_0001.jpg"] = body(b"y" * 300, per_byte_s=0.1)  # 30 s at a byte every 0.1 s
    assert main(["media", "get", url, "-o", str(tmp_path), "--timeout", "1"]) == 1
    assert "no complete answer within --timeout 1 s" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def test_deeply_nested_json_is_a_clear_error(hostile: Any, tmp_path: Path, capsys: Any) -> None:
    url, routes = hostile
    routes["/"] = body(b"[" * 200000)
    assert main(["media", "list", url]) == 1
    err = capsys.readouterr().err
    assert "no media index (JSON nested too deeply)" in err and "Traceback" not in err


# -- the media server -----------------------------------------------------------------------------


@pytest.fixture
def served(tmp_path: Path) -> Iterator[MediaServer]:
    card = tmp_path / "card"
    card.mkdir()
    (card / "VID_0001.mp4").write_bytes(b"\0" * (48 * 1024 * 1024))  # more than socket buffers hold
    (card / "IMG_0001.jpg").write_bytes(b"jpeg")
    server = MediaServer(card).start()
    yield server
    server.stop()


def _get(port: int, path: str, source: str = "127.0.0.1") -> bytes:
    with socket.create_connection(("127.0.0.1", port), timeout=30, source_address=(source, 0)) as s:
        s.sendall(f"GET {path} HTTP/1.0\r\n\r\n".encode())
        out = b""
        while chunk := s.recv(65536):
            out += chunk
        return out


def test_clients_that_never_read_do_not_deny_the_others(served: MediaServer) -> None:
    port = int(served.httpd.server_address[1])
    hogs = []
    for _ in range(8):  # all from one address, as one attacker
        s = socket.socket()
        s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
        s.bind(("127.0.0.1", 0))
        s.connect(("127.0.0.1", port))
        s.sendall(b"GET /VID_0001.mp4 HTTP/1.0\r\n\r\n")
        hogs.append(s)
    try:
        for n in range(2, 22):  # 20 other clients, each its own loopback address
            reply = _get(port, "/IMG_0001.jpg", f"127.0.0.{n}")
            assert reply.startswith(b"HTTP/1.0 200") and reply.endswith(b"jpeg"), reply[:80]
        assert served.refused_connections >= 6  # the attacker's beyond MAX_PER_CLIENT
    finally:
        for s in hogs:
            s.close()


def test_slow_request_heads_make_no_threads_beyond_the_cap(served: MediaServer, monkeypatch: Any) -> None:
    port = int(served.httpd.server_address[1])
    before = threading.active_count()
    idle = []
    try:
        for n in range(2, 202):  # 200 connections that never send their request head
            idle.append(socket.create_connection(("127.0.0.1", port), source_address=(f"127.0.1.{n % 250}", 0)))
        assert threading.active_count() - before <= media_http.MAX_CONNECTIONS
        assert served.refused_connections > 0
    finally:
        for s in idle:
            s.close()


def test_a_silent_connection_is_closed_after_the_socket_timeout(tmp_path: Path, monkeypatch: Any) -> None:
    monkeypatch.setattr(media_http, "SOCKET_TIMEOUT_S", 0.5)
    card = tmp_path / "card"
    card.mkdir()
    server = MediaServer(card).start()
    try:
        with socket.create_connection(("127.0.0.1", int(server.httpd.server_address[1])), timeout=30) as s:
            s.sendall(b"GET / HTTP/1.0\r\n")  # the head never ends
            assert s.recv(100) == b""  # closed by the server, not by our 30 s
    finally:
        server.stop()


def test_a_client_fetching_one_file_after_another_is_not_refused(
    served: MediaServer, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A connection that has its whole answer no longer counts against its client's limit, even
    while its thread is still closing (slowed here, as on a loaded machine: the client, which read
    its Content-Length, opens the next connection first). Before, the third request got 503."""
    import urllib.error
    import urllib.request

    release = MediaServer._release

    def slow_release(self: MediaServer, conn: socket.socket) -> None:
        time.sleep(0.3)
        release(self, conn)

    monkeypatch.setattr(MediaServer, "_release", slow_release)
    for _ in range(6):
        with urllib.request.urlopen(served.url + "IMG_0001.jpg", timeout=30) as r:
            assert r.read() == b"jpeg"
        with pytest.raises(urllib.error.HTTPError) as err:
            urllib.request.urlopen(served.url + "secret.txt", timeout=30)
        assert err.value.code == 404
    assert served.refused_connections == 0
