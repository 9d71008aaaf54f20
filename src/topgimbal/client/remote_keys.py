"""The Zenoh key layout of a camera fleet and what travels on it (pure: no Zenoh, no I/O).

Both ends use this module: the server (`fleet/`, `topgimbal zenoh`) and the remote client
(`client/remote.py`, `connect("zenoh/NAME?connect=...")`). The layout is documented and stable
(docs/fleet.md):

    topgimbal/<name>/attitude        JSON {"yaw_deg", "pitch_deg", "roll_deg", "t"} per stream sample
    topgimbal/<name>/state           JSON camera state, on change
    topgimbal/<name>/link            JSON {"up", "reason", "t"} on every link change
    topgimbal/<name>/info            queryable: {"name", "model", "dialect", "methods", ...}
    topgimbal/<name>/call/<method>   queryable: JSON keyword arguments -> {"ok": ...} reply
    topgimbal/<name>                 liveliness token while the server serves the camera

A call's reply is `{"ok": true, "result": ...}` or `{"ok": false, "error": TEXT, "kind": KIND}`,
KIND being the `kind` of the SDK's exception (errors.py) or one of the call-level kinds below."""

from __future__ import annotations

import inspect
import json
import re
import types
import typing
from collections.abc import Mapping
from dataclasses import dataclass
from urllib.parse import parse_qs, urlsplit

from .. import errors
from ..errors import FieldValueError, TopGimbalError
from ..geo import Fix
from ..protocol import Message, get_model, parse_frame
from .api_camera import CameraMethods
from .api_core import CoreMethods
from .api_motion import MotionMethods
from .jsonable import jsonable
from .methods import api_method
from .state import GimbalAttitude, SdCard

ROOT = "topgimbal"
NAME_RE = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]{0,62}")
MAX_CALL_BYTES = 16 * 1024  # a call's JSON keyword arguments
MAX_REPLY_TEXT = 2000  # an error's text in a reply

# Call-level error kinds (the SDK's own kinds come from errors.py).
KIND_UNKNOWN_METHOD = "unknown_method"
KIND_BAD_REQUEST = "bad_request"
KIND_BUSY = "busy"
KIND_INTERNAL = "internal"


class RemoteCallError(TopGimbalError):
    """A call the server refused before the camera saw it (unknown method, bad arguments, too
    many calls at once) or one that failed inside the server; `kind` says which."""

    kind = KIND_BAD_REQUEST

    def __init__(self, message: str, kind: str = KIND_BAD_REQUEST) -> None:
        super().__init__(message)
        self.kind = kind


def _collect() -> dict[str, api_method[..., object]]:
    out: dict[str, api_method[..., object]] = {}
    for cls in (CoreMethods, MotionMethods, CameraMethods):
        for name, value in cls.__dict__.items():
            if isinstance(value, api_method) and not name.startswith("_"):
                out[name] = value
    return out


# The allow-list: exactly the SDK's typed public methods (api_*.py), nothing else of the client.
METHODS: dict[str, api_method[..., object]] = _collect()


def check_name(name: str) -> str:
    if not isinstance(name, str) or not NAME_RE.fullmatch(name):
        raise FieldValueError("name", name, "1..63 letters, digits, '_', '-' or '.', starting with a letter or digit")
    return name


def key(name: str, leaf: str) -> str:
    return f"{ROOT}/{name}/{leaf}"


def call_key(name: str, method: str) -> str:
    return f"{ROOT}/{name}/call/{method}"


def liveliness_key(name: str) -> str:
    return f"{ROOT}/{name}"


def split_call_key(k: str) -> tuple[str, str] | None:
    """(camera name, method) of a concrete call key, None for anything else (wildcards included)."""
    parts = k.split("/")
    if len(parts) != 4 or parts[0] != ROOT or parts[2] != "call" or "*" in k or "$" in k:
        return None
    return parts[1], parts[3]


# -- arguments ------------------------------------------------------------------------------------


def bind_arguments(method: str, payload: bytes | None) -> tuple[api_method[..., object], dict[str, object]]:
    """The method and its keyword arguments from a call's payload, checked against the SDK's
    signature and annotations (the checks the local client makes); RemoteCallError otherwise."""
    spec = METHODS.get(method)
    if spec is None:
        raise RemoteCallError(f"no method {method!r}; allowed: {', '.join(sorted(METHODS))}", KIND_UNKNOWN_METHOD)
    raw = payload or b""
    if len(raw) > MAX_CALL_BYTES:
        raise RemoteCallError(f"arguments of {len(raw)} bytes: at most {MAX_CALL_BYTES}")
    try:
        kwargs = json.loads(raw.decode("utf-8")) if raw.strip() else {}
    except (UnicodeDecodeError, ValueError, RecursionError) as exc:
        raise RemoteCallError(f"arguments are not JSON: {exc}") from None
    if not isinstance(kwargs, dict):
        raise RemoteCallError("arguments must be a JSON object of keyword arguments")
    sig = inspect.signature(spec.fn)
    params = list(sig.parameters.values())[1:]  # the core
    try:
        inspect.Signature(params).bind(**kwargs)
    except TypeError as exc:
        allowed = ", ".join(p.name for p in params if p.kind is not p.VAR_KEYWORD) or "none"
        raise RemoteCallError(f"{method}: {exc} (arguments: {allowed})") from None
    _tuples_from_json(spec, kwargs)
    spec.check((), kwargs)  # FieldValueError, as the local client raises
    return spec, kwargs


def _tuples_from_json(spec: api_method[..., object], kwargs: dict[str, object]) -> None:
    """JSON has no tuple: a list given where the SDK takes a tuple (locate's `position`) is one."""
    hints = typing.get_type_hints(spec.fn)
    for name, value in kwargs.items():
        if not isinstance(value, list):
            continue
        tp = hints.get(name)
        parts = typing.get_args(tp) if typing.get_origin(tp) in (typing.Union, types.UnionType) else (tp,)
        if any(typing.get_origin(t) is tuple or t is tuple for t in parts):
            kwargs[name] = tuple(value)


# -- results --------------------------------------------------------------------------------------


def encode_result(value: object) -> object:
    """A method's result as JSON-ready data: the SDK's one encoding (`jsonable`; NaN is null), but
    a `Message` in the shape `decode_result` turns back into one (frame text, fields, dialect)."""
    if isinstance(value, Message):
        return {"frame": value.frame.text(), "fields": jsonable(value.fields), "dialect": value.dialect}
    return jsonable(value)


def decode_result(method: str, value: object, model: str) -> object:
    """A reply's result as the local client returns it (GimbalAttitude, SdCard, Message, plain data)."""
    ret = typing.get_type_hints(METHODS[method].fn).get("return")
    kinds = set(typing.get_args(ret)) | {ret}
    if value is None:
        return None
    if GimbalAttitude in kinds and isinstance(value, dict):
        return GimbalAttitude(**{k: v for k, v in value.items() if k in GimbalAttitude.__dataclass_fields__})
    if SdCard in kinds and isinstance(value, dict):
        return SdCard(**{k: v for k, v in value.items() if k in SdCard.__dataclass_fields__})
    if Message in kinds and isinstance(value, dict):
        return _message(value, model)
    if Fix in kinds and isinstance(value, dict):  # locate(): the geo.Fix the local call returns
        return Fix(**{k: v for k, v in value.items() if k in Fix.__dataclass_fields__})
    return value


def _message(value: Mapping[str, object], model: str) -> Message:
    frame = parse_frame(str(value["frame"]))
    dialect = get_model(model)[0]
    local = dialect.decode(frame)  # spec and form; the fields are the server's (API convention)
    fields = value.get("fields")
    return Message(frame, local.spec, local.form, dict(fields) if isinstance(fields, dict) else None,
                   local.error, str(value.get("dialect") or local.dialect))  # fmt: skip


# -- errors ---------------------------------------------------------------------------------------


def error_reply(exc: BaseException) -> dict[str, object]:
    kind = getattr(exc, "kind", None)
    if not isinstance(exc, TopGimbalError) or not isinstance(kind, str):
        kind = KIND_INTERNAL
    text = str(exc) or type(exc).__name__
    out: dict[str, object] = {"ok": False, "error": text[:MAX_REPLY_TEXT], "kind": kind}
    if isinstance(exc, FieldValueError):
        out.update(field=exc.field, value=jsonable(exc.value), allowed=exc.allowed[:MAX_REPLY_TEXT])
    return out


def _error_classes() -> dict[str, type[TopGimbalError]]:
    out: dict[str, type[TopGimbalError]] = {}
    for obj in vars(errors).values():
        if isinstance(obj, type) and issubclass(obj, TopGimbalError) and "kind" in obj.__dict__:
            out.setdefault(obj.kind, obj)
    return out


_BY_KIND = _error_classes()


def error_from_reply(reply: Mapping[str, object]) -> TopGimbalError:
    """The exception the local client would have raised, from a `{"ok": false}` reply."""
    kind, text = str(reply.get("kind", "")), str(reply.get("error", "the call failed"))
    cls = _BY_KIND.get(kind)
    if cls is None or kind == "catalog":
        return RemoteCallError(text, kind or KIND_INTERNAL) if cls is None else cls(text)
    if cls is errors.FieldValueError:
        return FieldValueError(str(reply.get("field", "")), reply.get("value"), str(reply.get("allowed", text)))
    if cls is errors.ChecksumError:
        return errors.ChecksumError(text, expected="", found="")
    return cls(text)


# -- the remote URL -------------------------------------------------------------------------------


@dataclass(frozen=True)
class ZenohTarget:
    name: str
    connect: tuple[str, ...] = ()
    listen: tuple[str, ...] = ()
    mode: str = "client"
    config_file: str | None = None


def is_zenoh_url(url: object) -> bool:
    return isinstance(url, str) and (url.startswith("zenoh/") or url.startswith("zenoh://"))


def parse_zenoh_url(url: str) -> ZenohTarget:
    """`zenoh/NAME?connect=tcp/127.0.0.1:7447` or `zenoh://NAME?connect=...` (`connect` and
    `listen` repeatable, `mode=client|peer`, `config=FILE`)."""
    rest = url[len("zenoh://") :] if url.startswith("zenoh://") else url[len("zenoh/") :]
    parts = urlsplit("x://" + rest)
    name = parts.netloc + parts.path
    check_name(name)
    q = parse_qs(parts.query, keep_blank_values=True)
    unknown = set(q) - {"connect", "listen", "mode", "config"}
    if unknown:
        raise FieldValueError("url", url, f"options connect, listen, mode, config (not {', '.join(sorted(unknown))})")
    mode = q.get("mode", ["client"])[-1]
    if mode not in ("client", "peer"):
        raise FieldValueError("mode", mode, "client or peer")
    if mode == "client" and not q.get("connect"):
        raise FieldValueError("url", url, "a Zenoh endpoint to reach the server: zenoh/NAME?connect=tcp/HOST:PORT")
    return ZenohTarget(name, tuple(q.get("connect", [])), tuple(q.get("listen", [])), mode, q.get("config", [None])[-1])
