"""Checks of arguments at the Python boundary: a value of the wrong type or out of range is an
:class:`~flexmbd.errors.InvalidParameterError` naming the parameter, not a ``TypeError`` or
``OverflowError`` from deep inside NumPy or the core."""

from __future__ import annotations

import math
import numbers
import operator
from typing import Any

from .errors import InvalidParameterError


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
