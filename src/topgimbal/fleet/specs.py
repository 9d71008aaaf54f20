"""Which cameras a fleet server serves: `NAME=URL,MODEL` on the command line or in a file (pure).

A file holds one `NAME=URL,MODEL` per line (blank lines and `#` comments ignored) or a JSON list of
`{"name", "url", "model"}` objects. Names become Zenoh key segments (client/remote_keys.py)."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

from ..client.remote_keys import check_name, is_zenoh_url
from ..errors import FieldValueError
from ..inputfile import InputFileError, loads, read_text
from ..protocol import get_model

MAX_CAMERAS = 1024  # per server process (each is a client, a route on the shared socket and a stream)
MAX_FILE_BYTES = 1 << 20
FORM = "NAME=URL,MODEL (e.g. cam1=udp://127.0.0.1:5000,C12)"


@dataclass(frozen=True)
class CameraSpec:
    name: str
    url: str
    model: str


def _checked(name: str, url: str, model: str, where: str) -> CameraSpec:
    try:
        check_name(name)
    except FieldValueError as exc:
        raise FieldValueError("camera", where, f"{FORM}; the name: {exc.allowed}") from None
    if "://" not in url or is_zenoh_url(url):
        raise FieldValueError("camera", where, f"{FORM}: the URL is udp://, tcp:// or serial://")
    try:
        get_model(model)
    except Exception:
        raise FieldValueError("camera", where, f"{FORM}: {model!r} is not a known model") from None
    return CameraSpec(name, url, model)


def parse_camera(text: str) -> CameraSpec:
    name, eq, rest = text.partition("=")
    url, comma, model = rest.rpartition(",")
    if not eq or not comma:
        raise FieldValueError("camera", text, FORM)
    return _checked(name.strip(), url.strip(), model.strip(), text)


def read_camera_file(path: str) -> list[CameraSpec]:
    try:  # a regular file (not a FIFO or /dev/zero), at most MAX_FILE_BYTES, JSON nesting bounded
        text = read_text(path, MAX_FILE_BYTES, "camera file")
        items = loads(text, f"camera file {path}") if text.lstrip().startswith("[") else None
    except InputFileError as exc:
        raise FieldValueError(
            "camera file", path, f"a readable UTF-8 file of NAME=URL,MODEL lines or a JSON list ({exc})"
        ) from None
    if items is not None:
        if not isinstance(items, list):
            raise FieldValueError("camera file", path, "a JSON list of {name, url, model}")
        out = []
        for i, item in enumerate(items):
            if not isinstance(item, dict) or not all(isinstance(item.get(k), str) for k in ("name", "url", "model")):
                raise FieldValueError("camera file", f"{path} item {i}", 'an object {"name", "url", "model"}')
            out.append(_checked(item["name"], item["url"], item["model"], f"{path} item {i}"))
        return out
    lines = (line.strip() for line in text.splitlines())
    return [parse_camera(line) for line in lines if line and not line.startswith("#")]


def collect(specs: Iterable[CameraSpec]) -> list[CameraSpec]:
    """Checked as a set: at least one, at most MAX_CAMERAS, names unique."""
    out = list(specs)
    if not out:
        raise FieldValueError("camera", None, f"at least one --camera {FORM} or --cameras FILE")
    if len(out) > MAX_CAMERAS:
        raise FieldValueError("camera", len(out), f"at most {MAX_CAMERAS} cameras per process")
    seen: set[str] = set()
    for s in out:
        if s.name in seen:
            raise FieldValueError("camera", s.name, "each camera name once")
        seen.add(s.name)
    return out
