"""Checks of argument values shared by the client's constructors and methods: each raises
FieldValueError (a ValueError and a TopGimbalError) naming the argument and what is allowed."""

from __future__ import annotations

import math
from typing import TypeGuard

from ..errors import FieldValueError, UnknownCommandError


class CommandNameError(UnknownCommandError, ValueError):
    """An identifier or catalog name the model's dialect does not have: an UnknownCommandError
    that is also a ValueError, like every other bad argument."""


def is_number(v: object) -> TypeGuard[float]:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def positive_seconds(name: str, value: object, *, allow_none: bool = True, allow_zero: bool = False) -> None:
    """Timeouts and intervals: a finite number of seconds above zero (or None for the default)."""
    if value is None and allow_none:
        return
    if not is_number(value) or value < 0 or (value == 0 and not allow_zero):
        raise FieldValueError(name, value, "a number of seconds above 0" + (" or None" if allow_none else ""))


def count(name: str, value: object, *, allow_none: bool = True, maximum: int = 100) -> None:
    if value is None and allow_none:
        return
    if not isinstance(value, int) or isinstance(value, bool) or not 0 <= value <= maximum:
        raise FieldValueError(name, value, f"a whole number 0..{maximum}" + (" or None" if allow_none else ""))
