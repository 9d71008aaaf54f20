"""The two dialects as explicit objects, their model profiles, and decoding across dialects.

`get_dialect(name, **options)` builds one; built objects are memoised by their options (dialects are
immutable, so sharing one is safe). `get_model(name)` returns a model's profile with the dialect
built for it (its `dialect_options` and `destinations` applied): the C11's dialect counts GSY in
0.5 deg/s steps and sends DZM to M, every other SkyDroid model's follows the document."""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from functools import partial
from typing import Any

from ... import _speedups
from ...errors import UnknownCommandError
from ..dialect import Dialect
from ..frame import Frame
from ..message import LazyText, Message
from ..models import DeviceModel
from . import skydroid_models, topotek_models
from .skydroid import skydroid
from .topotek import topotek

_new_tuple = tuple.__new__
_HOSTS = frozenset("UP")

BUILDERS: dict[str, Callable[..., Dialect]] = {"skydroid": skydroid, "topotek": topotek}
DIALECT_NAMES = tuple(BUILDERS)
PROFILES: dict[str, tuple[DeviceModel, ...]] = {"skydroid": skydroid_models.MODELS, "topotek": topotek_models.MODELS}
_built: dict[tuple[str, tuple[tuple[str, Any], ...]], Dialect] = {}


def _key(options: Mapping[str, Any]) -> tuple[tuple[str, Any], ...] | None:
    """A hashable form of build options, or None when they cannot be one (then: no memo)."""
    items = []
    for k, v in sorted(options.items()):
        if isinstance(v, Mapping):
            v = tuple(sorted(v.items()))
        try:
            hash(v)
        except TypeError:
            return None
        items.append((k, v))
    return tuple(items)


def get_dialect(name: str | Dialect, **options: Any) -> Dialect:
    """A dialect by name (`skydroid`, `topotek`), built with `options` (see each builder)."""
    if isinstance(name, Dialect):
        return name
    key = name.lower()
    if key not in BUILDERS:
        raise UnknownCommandError(f"{name!r} is not a dialect; known: {', '.join(BUILDERS)}")
    okey = _key(options)
    if okey is None:
        return BUILDERS[key](**options)
    memo = (key, okey)
    if memo not in _built:
        _built[memo] = BUILDERS[key](**options)
    return _built[memo]


def dialect_for(model: DeviceModel) -> Dialect:
    """The dialect `model` speaks, built with the model's options and destinations."""
    options = dict(model.dialect_options)
    if model.destinations:
        options["destinations"] = dict(model.destinations)
    return get_dialect(model.dialect, **options)


def _profile(name: str) -> DeviceModel:
    for profiles in PROFILES.values():
        for m in profiles:
            if m.name.lower() == name.lower():
                return m
    known = ", ".join(m.name for profiles in PROFILES.values() for m in profiles)
    raise UnknownCommandError(f"{name!r} is not a device model; known: {known}")


def get_model(model: str | DeviceModel) -> tuple[Dialect, DeviceModel]:
    """The dialect and profile of a device model, by name (case-insensitive) or by profile (a
    user's variant from `dataclasses.replace` keeps its own fields)."""
    if isinstance(model, DeviceModel):
        return dialect_for(model), model
    d = dialect_for(_profile(model))
    return d, d.model(model)


def model_names() -> list[str]:
    """Every model's name, from the profiles alone (no dialect is built: cheap, for CLI choices)."""
    return [m.name for profiles in PROFILES.values() for m in profiles]


def all_models() -> dict[str, DeviceModel]:
    """Every model's profile as its own dialect holds it, by name."""
    return {m.name: get_model(m.name)[1] for profiles in PROFILES.values() for m in profiles}


# -- decoding across dialects ---------------------------------------------------------------------


def guess_dialects(frame: Frame, dialects: Iterable[Dialect] | None = None) -> list[Dialect]:
    """Dialects in the order most likely to decode `frame`, from data only: a dialect whose catalog
    has the identifier, whose host addresses include the frame's host side and whose headers include
    its header ranks first; ties keep the default order."""
    candidates = list(dialects) if dialects is not None else [get_dialect(n) for n in DIALECT_NAMES]
    ident, header = frame.ident, frame.header
    host = {frame.src, frame.dst} & _HOSTS  # computed once per frame: this runs for every frame no dialect took
    return sorted(candidates, key=lambda d: -_score(d, ident, header, host))


def _score(d: Dialect, ident: str, header: str, host: set[str]) -> int:
    """guess_dialects' rank of `d` for a frame: 4 for the identifier, 2 for the header, 1 for the
    host side (at most 7, or 6 when the frame has no host address)."""
    return (
        (ident in d.commands) * 4
        + (header in d.headers) * 2
        + (bool(host) and all(a in d.host_addresses for a in host))
    )


def decode_any(frame: Frame, prefer: str | Dialect | None = None) -> Message:
    """Decode `frame` with `prefer` (a dialect or its name) and, when that cannot name its fields,
    with the other dialects before giving up. `Message.dialect` says which one decoded it; when none
    did, the preferred (or most likely) dialect's message is returned with every reason in `error`.

    The first ONE_OFF_FRAMES frames of a preference are decoded in pure Python, building a
    dialect only when it is needed (with `prefer`, the others only for a frame it cannot decode);
    later ones by `any_decoder(prefer)`, whose C tables cost more to build than a few frames cost
    to decode (a one-frame `topgimbal decode`). The results are the same either way."""
    key = prefer.lower() if isinstance(prefer, str) else prefer
    dec = _ANY_DECODERS.get(key)
    if dec is None:
        used = _one_off.get(key, 0)
        if used >= ONE_OFF_FRAMES:
            return any_decoder(prefer)(frame)
        if len(_one_off) >= _ANY_DECODERS_MAX:
            _one_off.clear()
        _one_off[key] = used + 1
        return _decode_one_off(frame, get_dialect(prefer) if prefer is not None else None)
    return dec(frame)


def _decode_one_off(frame: Frame, first: Dialect | None) -> Message:
    """decode_any in pure Python, building a default dialect only when the answer depends on it.
    `first` decodes first. Then guess_dialects' order: the first default dialect (in default order)
    that scores the most any dialect can for this frame surely ranks first, so the ones after it are
    built only when it cannot decode the frame (a SkyDroid frame needs the SkyDroid dialect alone).
    Anything else goes the whole way, `_decode_any_py`, which gives the same message it always did."""
    if first is not None:
        msg = first._decode_py(frame)
        if msg.fields is not None:
            return msg
    ident, header = frame.ident, frame.header
    host = {frame.src, frame.dst} & _HOSTS
    best = 6 + bool(host)
    for name in DIALECT_NAMES:
        if first is not None and first.name == name:
            continue
        d = get_dialect(name)
        if _score(d, ident, header, host) == best:
            msg = d._decode_py(frame)
            if msg.fields is not None:
                return msg
            break
    return _decode_any_py(frame, first, (get_dialect(n) for n in DIALECT_NAMES), Dialect._decode_py)


ONE_OFF_FRAMES = 64
_one_off: dict[Any, int] = {}  # frames decoded so far without a built decoder, per preference
_ANY_DECODERS: dict[Any, Callable[[Frame], Message]] = {}
_ANY_DECODERS_MAX = 64  # distinct preferences kept (a user's own dialects would otherwise pile up)
_ORDERS_MAX = 1024  # rankings kept per decoder (header, addresses, identifier): bounded for hostile input


def any_decoder(prefer: str | Dialect | None = None) -> Callable[[Frame], Message]:
    """`decode_any` with `prefer` fixed, as one callable (frame -> Message): the C fast path's when
    it is in use, so `FrameParser.feed_messages(data, any_decoder("topotek"))` decodes inside the
    scan; the same results either way."""
    key = prefer.lower() if isinstance(prefer, str) else prefer
    dec = _ANY_DECODERS.get(key)
    if dec is None:
        first = get_dialect(prefer) if prefer is not None else None
        defaults = [get_dialect(n) for n in DIALECT_NAMES]
        orders: dict[tuple[str, ...], list[Dialect]] = {}

        def pure(frame: Frame) -> Message:
            return _decode_any_py(frame, first, defaults, orders=orders)

        fast = _speedups.make_any_decoder(
            first.decoder() if first is not None else None, [d.decoder() for d in defaults], pure
        )
        dec = fast or pure
        if len(_ANY_DECODERS) >= _ANY_DECODERS_MAX:
            _ANY_DECODERS.clear()
        _ANY_DECODERS[key] = dec
    return dec


def _decode_any_py(
    frame: Frame,
    first: Dialect | None,
    defaults: Iterable[Dialect],
    decode: Callable[[Dialect, Frame], Message] = Dialect.decode,
    *,
    orders: dict[tuple[str, ...], list[Dialect]] | None = None,
) -> Message:
    """decode_any in Python (`decode`: how one dialect decodes; the tests pass the pure one).
    `defaults` is read only when `first` cannot decode the frame (a generator builds them then).
    `orders` keeps the ranking per (header, addresses, identifier): the frames no dialect decodes
    natively come here, and ranking them anew each time was most of their cost."""
    if first is not None:
        msg = decode(first, frame)
        if msg.fields is not None:  # the common case: no ranking needed
            return msg
        messages = [msg]
    else:
        messages = []
    key = (frame[0], frame[1], frame[2], frame[4])
    order = orders.get(key) if orders is not None else None
    if order is None:
        order = [d for d in guess_dialects(frame, defaults) if first is None or d.name != first.name]
        if orders is not None:
            if len(orders) >= _ORDERS_MAX:
                orders.clear()
            orders[key] = order
    for d in order:
        msg = decode(d, frame)
        if msg.fields is not None:
            return msg
        messages.append(msg)
    head = messages[0]
    if len(messages) == 1:
        return head
    # Worded only when read (LazyText): every reason, the preferred dialect's first.
    error = LazyText(partial(_all_reasons, messages))
    return _new_tuple(Message, (head[0], head[1], head[2], head[3], error, head[5]))


def _all_reasons(messages: list[Message]) -> str:
    others = "; ".join(f"{m.dialect}: {m.error}" for m in messages[1:])
    return f"{messages[0].error} (also tried {others})"


__all__ = [
    "BUILDERS",
    "DIALECT_NAMES",
    "PROFILES",
    "all_models",
    "any_decoder",
    "decode_any",
    "dialect_for",
    "get_dialect",
    "get_model",
    "guess_dialects",
]
