"""`topgimbal media list URL` and `topgimbal media get URL [NAME...] [-o DIR]`: the files of a
camera's card served over HTTP (the simulator's `--media DIR --media-port N` prints URL).

`get` without names fetches every file (into `-o DIR`, created if missing); a file that fails is reported and the others go on (exit
status 1). Bounded: each file at most `--max-mib` MiB (a longer one is dropped, nothing partial is
left), each request `--timeout` seconds."""

from __future__ import annotations

import argparse
import http.client
import json
import os
import sys
import urllib.error
import urllib.request
from pathlib import Path
from urllib.parse import quote, urlsplit

from ..errors import TopGimbalError

CHUNK = 64 * 1024


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


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = subparsers.add_parser("media", help="list and fetch a camera's photos and recordings over HTTP")
    sub = p.add_subparsers(dest="media_command", metavar="ACTION", required=True)
    ls = sub.add_parser("list", help="the files, oldest first")
    ls.add_argument("url", type=_url, metavar="URL", help="http://HOST:PORT/ (sim --media-port prints it)")
    ls.add_argument("--json", action="store_true", help="print the index as JSON")
    get = sub.add_parser("get", help="fetch files (all when no NAME)")
    get.add_argument("url", type=_url, metavar="URL", help="http://HOST:PORT/ (sim --media-port prints it)")
    get.add_argument("names", nargs="*", metavar="NAME", help="file names from `media list`")
    get.add_argument("-o", "--output", default=".", metavar="DIR", help="where to write them (default: here)")
    get.add_argument("--max-mib", type=_positive, default=1024.0, metavar="MIB", help="largest file (default 1024)")
    for q in (ls, get):
        q.add_argument("--timeout", type=_positive, default=10.0, metavar="S", help="per request (default 10 s)")
    p.set_defaults(func=run)


def index(url: str, timeout_s: float) -> list[dict[str, object]]:
    try:
        with urllib.request.urlopen(url, timeout=timeout_s) as r:
            data = json.loads(r.read(4 * 1024 * 1024))
    except (urllib.error.URLError, http.client.HTTPException, OSError, ValueError) as exc:
        raise MediaFetchError(f"{url}: no media index ({exc})") from None
    if not isinstance(data, list) or not all(isinstance(e, dict) and isinstance(e.get("name"), str) for e in data):
        raise MediaFetchError(f"{url}: the answer is not a media index")
    return data


def fetch(url: str, name: str, out_dir: Path, max_bytes: int, timeout_s: float) -> Path:
    if "/" in name or "\\" in name or name in ("", ".", ".."):
        raise MediaFetchError(f"{name!r} is not a file name from `media list`")
    dest = out_dir / name
    tmp = dest.with_name(name + ".part")
    try:
        with urllib.request.urlopen(url + quote(name), timeout=timeout_s) as r, tmp.open("wb") as f:
            size = 0
            while chunk := r.read(CHUNK):
                size += len(chunk)
                if size > max_bytes:
                    raise MediaFetchError(f"{name}: longer than {max_bytes} bytes (--max-mib)")
                f.write(chunk)
        os.replace(tmp, dest)
    except urllib.error.HTTPError as exc:
        raise MediaFetchError(f"{name}: {exc.code} {exc.reason}") from None
    except (urllib.error.URLError, http.client.HTTPException, OSError) as exc:
        raise MediaFetchError(f"{name}: {exc}") from None
    finally:
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
            print(fetch(args.url, name, out_dir, int(args.max_mib * 1024 * 1024), args.timeout))
        except MediaFetchError as exc:
            failed += 1
            print(f"topgimbal media: {exc}", file=sys.stderr)
    return 1 if failed else 0
