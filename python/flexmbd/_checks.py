"""Checks of arguments at the Python boundary: a value of the wrong type or out of range is an
:class:`~flexmbd.errors.InvalidParameterError` naming the parameter, not a ``TypeError`` or
``OverflowError`` from deep inside NumPy or the core."""

from __future__ import annotations

import math
import numbers
import operator
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .errors import ArgumentTypeError, InvalidParameterError


def _shown(value: Any) -> str:
    text = repr(value)
    text = text if len(text) <= 60 else text[:57] + "..."
    return f"{text} ({type(value).__name__})"


def number(value: Any, name: str, *, finite: bool = True) -> float:
    """`value` as a float: a real number (not a bool), finite unless `finite` is False."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise InvalidParameterError(f"{name} must be a number, got {_shown(value)}", item=name)
    result = float(value)
    if finite and not math.isfinite(result):
        raise InvalidParameterError(f"{name} must be finite, got {result}", item=name)
    return result


def integer(value: Any, name: str) -> int:
    """`value` as an int: an integer (Python or NumPy, not a bool or a float)."""
    if isinstance(value, bool):
        raise InvalidParameterError(f"{name} must be an integer, got {_shown(value)}", item=name)
    try:
        return operator.index(value)
    except TypeError:
        raise InvalidParameterError(
            f"{name} must be an integer, got {_shown(value)}", item=name
        ) from None


def numbers_array(value: Any, name: str, item: str | None = None) -> NDArray[np.float64]:
    """`value` as an array of floats (its shape kept), else an `ArgumentTypeError` naming the
    parameter: strings, bools, complex numbers, ids and other objects are not numbers.
    `item` (a body, ...) starts the message when given."""
    try:
        array = np.asarray(value)
        if array.dtype.kind == "O":
            array = array.astype(float)
    except (TypeError, ValueError, OverflowError):
        array = None
    if array is None or array.dtype.kind not in "fiu":
        where = f"{item}: " if item else ""
        raise ArgumentTypeError(f"{where}{name} must be numbers, got {_shown(value)}", item=name)
    return array.astype(float)


def flag(value: Any, name: str, item: str | None = None) -> bool:
    """The bool parameter `name`: True or False (also NumPy's), else an `ArgumentTypeError`
    naming it (a number, a string or a list is not taken for a truth value)."""
    if isinstance(value, bool | np.bool_):
        return bool(value)
    where = f"{item}: " if item else ""
    raise ArgumentTypeError(f"{where}{name} must be True or False, got {_shown(value)}", item=name)
