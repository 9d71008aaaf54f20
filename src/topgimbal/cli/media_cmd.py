"""`topgimbal media list URL` and `topgimbal media get URL [NAME...] [-o DIR]`: the files of a
camera's card served over HTTP (the simulator's `--media DIR --media-port N` prints URL).

`get` without names fetches every file (into `-o DIR`, created if missing); a file that fails is
reported and the others go on (exit status 1). What a server says is untrusted:

- only the camera's media names are written (`IMG_0001.jpg`, `snap_0_1.jpeg`, ...: video/lens.py's
  MEDIA_NAME); any other listed name (`.bashrc`, a NUL byte, a path) is reported and skipped;
- an existing file is never replaced unless `--overwrite`;
- a file is written under a temporary `.NAME.XXXX.part` name (created exclusively; a media name
  never starts with a dot, so it cannot collide with one) and renamed only once its length is the
  Content-Length the server announced: a cut-short body is never a file;
- each request (index or file) is bounded as a whole by `--timeout` seconds, not each read, and
  each file by `--max-mib` MiB; the index by INDEX_BYTES and JSON that parses (deep nesting too)."""

from __future__ import annotations

import argparse
import contextlib
import http.client
import json
import os
import sys
import tempfile
from pathlib import Path
from typing import Any
from urllib.parse import quote, urlsplit

from ..clock import monotonic
from ..errors import TopGimbalError
from ..video.lens import MEDIA_NAME

CHUNK = 64 * 1024
INDEX_BYTES = 4 * 1024 * 1024


class MediaFetchError(TopGimbalError):
    pass


def _url(text: str) -> str:
    parts = urlsplit(text)
    try:
        port = parts.port  # a port that is not a number raises here
    except ValueError:
        port = -1
    if parts.scheme != "http" or not parts.hostname or port == -1:
        raise argparse.ArgumentTypeError(f"{text!r} is not an http://HOST:PORT/ URL (the simulator prints it)")
    return text if text.endswith("/") else text + "/"


def _positive(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        v = -1.0
    if not 0 < v < 1e6:
        raise argparse.ArgumentTypeError(f"{text!r}: give a positive number")
    return v


class _Intermixed(argparse.ArgumentParser):
    """Options and names in any order (`media get URL -o DIR NAME`): argparse's intermixed parse."""

    _mixing = False

    def parse_known_args(self, args: Any = None, namespace: Any = None) -> Any:
        if self._mixing or self._subparsers is not None:
            return super().parse_known_args(args, namespace)
        self._mixing = True
        try:
            return self.parse_known_intermixed_args(args, namespace)
        finally:
            self._mixing = False


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = subparsers.add_parser("media", help="list and fetch a camera's photos and recordings over HTTP")
    sub = p.add_subparsers(dest="media_command", metavar="ACTION", required=True, parser_class=_Intermixed)
    ls = sub.add_parser("list", help="the files, oldest first")
    ls.add_argument("url", type=_url, metavar="URL", help="http://HOST:PORT/ (sim --media-port prints it)")
    ls.add_argument("--json", action="store_true", help="print the index as JSON")
    get = sub.add_parser("get", help="fetch files (all when no NAME)")
    get.add_argument("url", type=_url, metavar="URL", help="http://HOST:PORT/ (sim --media-port prints it)")
    get.add_argument("names", nargs="*", metavar="NAME", help="file names from `media list`")
    get.add_argument("-o", "--output", default=".", metavar="DIR", help="where to write them (default: here)")
    get.add_argument("--max-mib", type=_positive, default=1024.0, metavar="MIB", help="largest file (default 1024)")
    get.add_argument("--overwrite", action="store_true", help="replace files that exist in DIR (default: refuse)")
    for q in (ls, get):
        q.add_argument("--timeout", type=_positive, default=10.0, metavar="S",
                       help="each request as a whole, index or file (default 10 s)")  # fmt: skip
    p.set_defaults(func=run)


class _Request:
    """One GET whose whole exchange (connect, head, body) ends by a deadline: each socket wait is
    the time left, so a server sending a byte a second cannot hold it past `timeout_s`."""

    def __init__(self, url: str, timeout_s: float) -> None:
        self.url = url
        self.timeout_s = timeout_s
        self.deadline = monotonic() + timeout_s
        parts = urlsplit(url)
        self.conn = http.client.HTTPConnection(parts.hostname or "", parts.port or 80, timeout=timeout_s)
        self.path = (parts.path or "/") + (f"?{parts.query}" if parts.query else "")

    def _left(self) -> float:
        left = self.deadline - monotonic()
        if left <= 0:
            raise MediaFetchError(f"{self.url}: no complete answer within --timeout {self.timeout_s:g} s")
        if self.conn.sock is not None:
            self.conn.sock.settimeout(left)
        return left

    def open(self) -> http.client.HTTPResponse:
        self._left()
        self.conn.request("GET", self.path)
        self._left()
        r = self.conn.getresponse()
        if r.status != 200:
            raise MediaFetchError(f"{r.status} {r.reason}")
        return r

    def chunks(self, r: http.client.HTTPResponse, max_bytes: int) -> Any:
        size = 0
        while True:
            self._left()
            chunk = r.read1(CHUNK)
            if not chunk:
                return
            size += len(chunk)
            if size > max_bytes:
                raise MediaFetchError(f"longer than {max_bytes} bytes")
            yield chunk

    def close(self) -> None:
        self.conn.close()


def index(url: str, timeout_s: float) -> list[dict[str, object]]:
    req = _Request(url, timeout_s)
    try:
        r = req.open()
        data = json.loads(b"".join(req.chunks(r, INDEX_BYTES)))
    except MediaFetchError as exc:
        raise MediaFetchError(f"{url}: no media index ({exc})") from None
    except (http.client.HTTPException, OSError, ValueError, RecursionError) as exc:
        # RecursionError: JSON nested deeper than Python parses
        text = "JSON nested too deeply" if isinstance(exc, RecursionError) else str(exc) or type(exc).__name__
        raise MediaFetchError(f"{url}: no media index ({text})") from None
    finally:
        req.close()
    if not isinstance(data, list) or not all(isinstance(e, dict) and isinstance(e.get("name"), str) for e in data):
        raise MediaFetchError(f"{url}: the answer is not a media index")
    return data


def fetch(url: str, name: str, out_dir: Path, max_bytes: int, timeout_s: float, overwrite: bool = False) -> Path:
    if not MEDIA_NAME.fullmatch(name):
        raise MediaFetchError(f"{name!r} is not a camera media name (IMG_0001.jpg, snap_0_1.jpeg, ...): skipped")
    dest = out_dir / name
    if not overwrite and (dest.exists() or dest.is_symlink()):
        raise MediaFetchError(f"{dest} exists: not replaced (--overwrite replaces it)")
    req = _Request(url + quote(name), timeout_s)
    fd, tmp_name = tempfile.mkstemp(prefix=f".{name}.", suffix=".part", dir=out_dir)  # O_EXCL: no collision
    tmp = Path(tmp_name)
    try:
        with os.fdopen(fd, "wb") as f:
            r = req.open()
            expected = r.getheader("Content-Length")
            size = 0
            for chunk in req.chunks(r, max_bytes):
                f.write(chunk)
                size += len(chunk)
            if expected is not None and (not expected.isdigit() or int(expected) != size):
                raise MediaFetchError(f"cut short: {size} of {expected} bytes")
        if not overwrite and (dest.exists() or dest.is_symlink()):  # appeared meanwhile
            raise MediaFetchError(f"{dest} exists: not replaced (--overwrite replaces it)")
        os.replace(tmp, dest)
    except MediaFetchError as exc:
        raise MediaFetchError(f"{name}: {exc}") from None
    except (http.client.HTTPException, OSError, ValueError) as exc:
        raise MediaFetchError(f"{name}: {exc or type(exc).__name__}") from None
    finally:
        req.close()
        with contextlib.suppress(OSError):
            tmp.unlink(missing_ok=True)
    return dest


def run(args: argparse.Namespace) -> int:
    entries = index(args.url, args.timeout)
    if args.media_command == "list":
        if args.json:
            print(json.dumps(entries, indent=1))
        for e in entries if not args.json else []:
            print(f"{e['name']}\t{e.get('size', '?')}")
        return 0
    out_dir = Path(args.output)
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise MediaFetchError(f"--output {out_dir}: {exc.strerror or exc}") from None
    names = list(args.names) or [str(e["name"]) for e in entries]
    failed = 0
    for name in names:
        try:
            print(fetch(args.url, name, out_dir, int(args.max_mib * 1024 * 1024), args.timeout, args.overwrite))
        except MediaFetchError as exc:
            failed += 1
            print(f"topgimbal media: {exc}".replace("\x00", "\\x00"), file=sys.stderr)
    return 1 if failed else 0
