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


def value_text(value: Any) -> str:
    """A value for a message: its repr, at most 60 characters."""
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def id_text(value: Any) -> str:
    """An id (of a node or an element) for a message: as given, or, beyond the 64-bit integers
    that no mesh numbers its nodes with, in exponent form (a 31-digit echo reads as noise)."""
    try:
        whole = int(value)
    except (TypeError, ValueError, OverflowError):
        return value_text(value)
    return str(whole) if abs(whole) < 2**63 else f"{float(whole):.3e}"


def _shown(value: Any) -> str:
    return f"{value_text(value)} ({type(value).__name__})"


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


def direction(value: Any, name: str) -> NDArray[np.float64]:
    """`value` as a unit vector (3,): three finite numbers, not all zero, else an
    `InvalidParameterError` (`ArgumentTypeError` for what is not numbers) naming `name`."""
    array = numbers_array(value, name)
    if array.shape != (3,) or not np.all(np.isfinite(array)):
        raise InvalidParameterError(
            f"{name} must be one vector of three finite numbers, got {_shown(value)}", item=name
        )
    length = float(np.linalg.norm(array))
    if not length > 0:
        raise InvalidParameterError(f"{name} must not be the zero vector", item=name)
    return array / length


def flag(value: Any, name: str, item: str | None = None) -> bool:
    """The bool parameter `name`: True or False (also NumPy's), else an `ArgumentTypeError`
    naming it (a number, a string or a list is not taken for a truth value)."""
    if isinstance(value, bool | np.bool_):
        return bool(value)
    where = f"{item}: " if item else ""
    raise ArgumentTypeError(f"{where}{name} must be True or False, got {_shown(value)}", item=name)


_INT64 = np.iinfo(np.int64)


def integers_array(value: Any, name: str, item: str | None = None) -> NDArray[np.int64]:
    """`value` as an array of int64 (its shape kept): node indices, ids, ... Integers only
    (Python or NumPy): strings, bytes, bools, floats (also 1.0 and NaN), None and other
    objects are an `ArgumentTypeError` naming the parameter, integers beyond int64 an
    `InvalidParameterError`. An empty list is an empty array. `item` (a body, ...) starts the
    message when given."""
    where = f"{item}: " if item else ""

    def wrong() -> ArgumentTypeError:
        return ArgumentTypeError(f"{where}{name} must be integers, got {_shown(value)}", item=name)

    if isinstance(value, str | bytes | bytearray | memoryview):
        raise wrong()
    try:
        array = np.asarray(value)
    except (TypeError, ValueError, OverflowError):
        raise wrong() from None
    if array.size == 0 and array.dtype.kind in "fiuO":
        return np.zeros(array.shape, dtype=np.int64)
    if array.dtype.kind == "O":
        flat = array.ravel()
        if any(isinstance(v, bool | np.bool_) for v in flat):
            raise wrong()
        try:
            entries = [operator.index(v) for v in flat]
        except TypeError:
            raise wrong() from None
        outside = [v for v in entries if not _INT64.min <= v <= _INT64.max]
        if outside:
            raise InvalidParameterError(
                f"{where}{name} must be integers within int64, got an integer of "
                f"{outside[0].bit_length()} bits{' (negative)' if outside[0] < 0 else ''}",
                item=name,
            )
        return np.array(entries, dtype=np.int64).reshape(array.shape)
    if array.dtype.kind not in "iu":
        raise wrong()
    if array.dtype.kind == "u" and array.dtype.itemsize >= 8 and array.max() > _INT64.max:
        raise InvalidParameterError(
            f"{where}{name} must be integers within int64, got {int(array.max())} (uint64)",
            item=name,
        )
    return array.astype(np.int64)


def choice(
    value: Any,
    name: str,
    options: tuple[str, ...],
    item: str | None = None,
    *,
    what: str | None = None,
) -> str:
    """The str parameter `name`, one of `options`: a value that is not a string (an array, a
    number, None) is an `ArgumentTypeError`, another string an `InvalidParameterError`, both
    naming the parameter (as `what`, when given, in the message) and the options. `item` (a
    body, ...) starts the message when given."""
    where = f"{item}: " if item else ""
    called = what or name
    listed = ", ".join(repr(o) for o in options[:-1]) + f" or {options[-1]!r}"
    if not isinstance(value, str):
        raise ArgumentTypeError(f"{where}{called} must be {listed}, got {_shown(value)}", item=name)
    if value not in options:
        text = repr(value)
        text = text if len(text) <= 60 else text[:57] + "..."
        raise InvalidParameterError(f"{where}{called} must be {listed}, got {text}", item=name)
    return str(value)


def time_argument(text: str) -> float:
    """A time (s) on the command line (an argparse type): a finite number. argparse reports
    anything else as a usage error before the run starts."""
    import argparse

    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number of seconds") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"{text!r}: a time must be finite")
    return value


def duration_argument(text: str) -> float:
    """A step size or interval (s) on the command line (an argparse type): a finite number
    above zero."""
    import argparse

    value = time_argument(text)
    if value <= 0.0:
        raise argparse.ArgumentTypeError(f"{text!r}: must be above zero (s)")
    return value
