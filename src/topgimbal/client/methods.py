"""Typed methods written once, for the asyncio client and the blocking facade alike.

pymodbus writes its API once as `ModbusClientMixin(Generic[T])`, T being a PDU or an awaitable PDU.
Our methods return different types (an Attitude, an SdCard, a bool), and Python has no generic over
"awaitable of", so the same idea takes the form of a descriptor: each method is one coroutine
function taking the client core; `api_method` makes it a coroutine method on `AsyncClient` and a
blocking method on `Gimbal` (run on the facade's loop thread). mypy and IDEs see the real signature
and return type on both (overloaded `__get__`).

Every call's arguments are checked against the method's annotations before anything is sent: a
wrong type raises FieldValueError (a ValueError and a TopGimbalError) naming the argument.
"""

from __future__ import annotations

import functools
import inspect
import types
import typing
from collections.abc import Callable, Coroutine, Mapping
from typing import TYPE_CHECKING, Concatenate, Generic, Literal, ParamSpec, TypeVar, Union, overload

from ..errors import FieldValueError
from .checks import is_number as _is_number

if TYPE_CHECKING:
    from .core import ClientCore

P = ParamSpec("P")
R = TypeVar("R")
Check = tuple[str, int, "Callable[[object], bool]", str]  # argument, position, predicate, what is allowed


class SyncDriver:
    """Base of the blocking facade: runs a coroutine of the core on its loop thread."""

    def _core(self) -> ClientCore:
        raise NotImplementedError

    def _run(self, coro: Coroutine[object, object, R]) -> R:
        raise NotImplementedError


class api_method(Generic[P, R]):  # noqa: N801 - used as a decorator, like property
    def __init__(self, fn: Callable[Concatenate[ClientCore, P], Coroutine[object, object, R]]) -> None:
        self.fn = fn
        self.__doc__ = fn.__doc__
        self.__name__ = fn.__name__
        self.__wrapped__ = fn
        self._checks: list[Check] | None = None

    def __set_name__(self, owner: type, name: str) -> None:
        self.__name__ = name

    @overload
    def __get__(self, obj: None, owner: type) -> api_method[P, R]: ...
    @overload
    def __get__(self, obj: SyncDriver, owner: type) -> Callable[P, R]: ...
    @overload  # the client core, or a CameraAPI (the Protocol made of these methods)
    def __get__(self, obj: object, owner: type) -> Callable[P, Coroutine[object, object, R]]: ...
    def __get__(self, obj: object, owner: type) -> object:
        if obj is None:
            return self
        # The wrappers pass whatever they are given on: `check` has vetted it against `fn`'s hints.
        fn: Callable[..., Coroutine[object, object, object]] = self.fn
        check = self.check
        bound: Callable[..., object]
        if isinstance(obj, SyncDriver):
            core, run = obj._core(), obj._run

            def bound(*args: object, **kwargs: object) -> object:
                check(args, kwargs)
                return run(fn(core, *args, **kwargs))

        else:

            async def bound(*args: object, **kwargs: object) -> object:
                check(args, kwargs)
                return await fn(obj, *args, **kwargs)

        functools.update_wrapper(bound, fn)
        bound.__signature__ = _public_signature(fn)  # type: ignore[attr-defined]
        # Cached on the instance (a non-data descriptor): later look-ups cost nothing.
        obj.__dict__[self.__name__] = bound
        return bound

    # -- argument checks from the annotations --------------------------------------------------

    def check(self, args: tuple[object, ...], kwargs: Mapping[str, object]) -> None:
        checks = self._checks if self._checks is not None else self._compile()
        for name, position, ok, expected in checks:
            if position < len(args):
                value = args[position]
            elif name in kwargs:
                value = kwargs[name]
            else:
                continue
            if not ok(value):
                raise FieldValueError(name, value, expected)

    def _compile(self) -> list[Check]:
        hints = typing.get_type_hints(self.fn)
        out = []
        params = list(inspect.signature(self.fn).parameters.values())[1:]  # the core
        for i, p in enumerate(params):
            if p.kind in (p.VAR_POSITIONAL, p.VAR_KEYWORD) or p.name not in hints:
                continue
            ok, expected = _checker(hints[p.name])
            if ok is not None:
                position = i if p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD) else 1 << 30
                out.append((p.name, position, ok, expected))
        self._checks = out
        return out


@functools.cache
def _public_signature(fn: Callable[..., object]) -> inspect.Signature:
    sig = inspect.signature(fn)
    return sig.replace(parameters=list(sig.parameters.values())[1:])


def _checker(tp: object) -> tuple[Callable[[object], bool] | None, str]:
    """A predicate for values of annotation `tp` and its description; None: not checked."""
    if tp is typing.Any or tp is object:
        return None, ""
    origin = typing.get_origin(tp)
    if origin in (Union, types.UnionType):
        parts = [_checker(a) for a in typing.get_args(tp)]
        if any(ok is None for ok, _ in parts):
            return None, ""
        oks = [ok for ok, _ in parts if ok is not None]
        return (lambda v: any(ok(v) for ok in oks)), " or ".join(d for _, d in parts)
    if origin is Literal:
        choices = typing.get_args(tp)
        return (lambda v: v in choices), "one of " + ", ".join(repr(c) for c in choices)
    if tp is type(None):
        return (lambda v: v is None), "None"
    if tp is float:
        return _is_number, "a finite number"
    if tp is int:
        return (lambda v: isinstance(v, int) and not isinstance(v, bool)), "a whole number"
    if tp is bool:
        return (lambda v: isinstance(v, bool)), "True or False"
    if tp is str:
        return (lambda v: isinstance(v, str)), "text"
    if origin in (Mapping, dict) or tp in (Mapping, dict):
        return (lambda v: isinstance(v, Mapping)), "a mapping"
    if origin is not None and isinstance(origin, type):
        return (lambda v: isinstance(v, origin)), f"a {origin.__name__}"
    if isinstance(tp, type):
        return (lambda v: isinstance(v, tp)), f"a {tp.__name__}"
    return None, ""
