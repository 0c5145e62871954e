"""The Python boundary of the Rust core: an argument of the wrong type or out of range for its
Rust type is an :class:`~flexmbd.errors.ArgumentTypeError` naming the call and the parameter.

PyO3 converts the arguments of a call before the Rust code runs; a failed conversion raises a
``TypeError`` ("must be real number, not str") or an ``OverflowError`` (a negative number for
an unsigned one) whose message does not name the parameter: PyO3 adds the name as a note
("while processing 'mass'"). :func:`converted` reads that note. The core's methods are wrapped
in place (:func:`wrap_methods`); its value classes (materials, time functions, solver
settings) cannot have their constructor replaced, so flexmbd exports subclasses of them
(:func:`boundary_class`) that convert the errors of construction and of setting a field.
"""

from __future__ import annotations

import functools
import inspect
import re
from collections.abc import Callable
from typing import Any, TypeVar

from . import _core
from .errors import ArgumentTypeError, FlexmbdError, InvalidParameterError

_NOTE = re.compile(r"^while processing '(\w+)'$")

T = TypeVar("T", bound=type)


def converted(error: BaseException, owner: str) -> InvalidParameterError | None:
    """The ArgumentTypeError for PyO3's conversion error `error` of a call to `owner` (an
    InvalidParameterError for a value PyO3 cannot take: a tuple of the wrong length), or None
    when `error` is not one (an error of the Rust code itself is left as it is)."""
    if not isinstance(error, (TypeError, OverflowError, ValueError)) or isinstance(
        error, FlexmbdError
    ):
        return None
    names = [m.group(1) for note in getattr(error, "__notes__", ()) if (m := _NOTE.match(note))]
    if not names:
        return None
    detail = str(error)
    message = f"{owner}: argument {names[0]!r}: {detail}"
    if isinstance(error, ValueError):
        return InvalidParameterError(message, item=names[0])
    if isinstance(error, OverflowError):
        message = f"{owner}: argument {names[0]!r}: out of range ({detail})"
    return ArgumentTypeError(message, item=names[0])


def _wrapped(function: Callable[..., Any], owner: str) -> Callable[..., Any]:
    @functools.wraps(function)
    def call(*args: Any, **kwargs: Any) -> Any:
        try:
            return function(*args, **kwargs)
        except (TypeError, OverflowError, ValueError) as error:
            typed = converted(error, owner)
            if typed is None:
                raise
            raise typed from error

    return call


def wrap_methods(cls: type) -> None:
    """Wraps the public methods and static methods of the Rust class `cls` in place."""
    for name, member in list(vars(cls).items()):
        if name.startswith("_"):
            continue
        owner = f"{cls.__name__}.{name}"
        if isinstance(member, staticmethod):
            setattr(cls, name, staticmethod(_wrapped(member.__func__, owner)))
        elif type(member).__name__ == "method_descriptor":
            setattr(cls, name, _wrapped(member, owner))


def _signature(base: type) -> inspect.Signature | None:
    """The Rust constructor's parameters (not ``*args, **kwargs``), for help() and inspect.
    Settings whose default is None in the binding take the core's default there (the
    binding fills them in), so they are shown with the value a default instance holds."""
    try:
        signature = inspect.signature(base)
    except (TypeError, ValueError):
        return None
    try:
        defaults = base()
    except (TypeError, ValueError):  # no constructor without arguments: defaults as they are
        return signature
    parameters = [
        p.replace(default=getattr(defaults, p.name))
        if p.default is None and getattr(defaults, p.name, None) is not None
        else p
        for p in signature.parameters.values()
    ]
    return signature.replace(parameters=parameters)


def boundary_class(base: T, module: str) -> T:
    """A subclass of the Rust value class `base` (same name, fields and methods) whose
    construction and field assignment raise ArgumentTypeError for arguments of the wrong
    type."""
    name = base.__name__

    namespace = {
        "__new__": _wrapped(base.__new__, name),
        "__setattr__": _wrapped(base.__setattr__, name),
        "__doc__": base.__doc__,
        "__module__": module,
        "__qualname__": name,
        "__slots__": (),
    }
    signature = _signature(base)
    if signature is not None:
        namespace["__signature__"] = signature
    return type(name, (base,), namespace)  # type: ignore[return-value]


for _cls in (_core.System, _core.Model, _core.Section, _core.SymmetricFactor):
    wrap_methods(_cls)
for _cls in (
    _core.Constant,
    _core.Polynomial,
    _core.Harmonic,
    _core.Spline,
    _core.Step,
    _core.Trapezoidal,
    _core.UserFunction,
):
    wrap_methods(_cls)

Constant = boundary_class(_core.Constant, "flexmbd")
Polynomial = boundary_class(_core.Polynomial, "flexmbd")
Harmonic = boundary_class(_core.Harmonic, "flexmbd")
Spline = boundary_class(_core.Spline, "flexmbd")
Step = boundary_class(_core.Step, "flexmbd")
Trapezoidal = boundary_class(_core.Trapezoidal, "flexmbd")
UserFunction = boundary_class(_core.UserFunction, "flexmbd")
GeneralizedAlpha = boundary_class(_core.GeneralizedAlpha, "flexmbd")
ExplicitSolver = boundary_class(_core.ExplicitSolver, "flexmbd")


def solver_settings(solver: Any) -> str:
    """Every setting of a solver (a GeneralizedAlpha or ExplicitSolver), as text: its class
    and each attribute by name, sorted. Its repr shows those that usually matter only (not
    the tolerances of an error-controlled run, the linear solver, the step bounds), so a
    study keyed by it took a run with other tolerances for one already made."""
    names = sorted(
        name
        for name in dir(solver)
        if not name.startswith("_") and not callable(getattr(solver, name, None))
    )
    shown = ", ".join(f"{name}={getattr(solver, name)!r}" for name in names)
    return f"{type(solver).__name__}({shown})"


Material = boundary_class(_core.Material, "flexmbd.fe")
