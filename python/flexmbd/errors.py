"""Exceptions of flexmbd.

Every error flexmbd raises is a :class:`FlexmbdError`. Bad input is a :class:`ModelError`
(also a :class:`ValueError`), a failed simulation a :class:`SimulationError` (also a
:class:`RuntimeError`). Errors carry the offending ``item`` (for example ``"joint 'pivot'"``)
and, for run-time failures, the ``time`` at which they happened. A failed simulation attaches
everything computed up to the failure as ``error.result`` (a :class:`flexmbd.Result`).
"""

from __future__ import annotations

from typing import Any


class FlexmbdError(Exception):
    """Base class of every flexmbd error."""

    item: str | None
    time: float | None
    result: Any

    def __init__(self, message: str, item: str | None = None, time: float | None = None):
        super().__init__(message)
        self.item = item
        self.time = time
        self.result = None


class ModelError(FlexmbdError, ValueError):
    """The model or its input data is wrong."""


class InvalidParameterError(ModelError):
    """A parameter is out of range: NaN, a non-positive mass, an inertia that is not
    positive definite, a matrix that is not a rotation, ..."""


class UnknownItemError(ModelError):
    """A body, marker, joint, force or sensor id or name that does not exist."""


class InvalidModelError(ModelError):
    """A structural error: a joint between a body and itself, a duplicated name, ..."""


class ModelFileError(InvalidModelError):
    """A model file (YAML) that cannot be read: a syntax error, an unknown key, a value of the
    wrong type or out of range, a missing file, a name that refers to nothing. The message
    names the file, the line and the key path (``model.yaml: line 12: joints[1].marker1:
    ...``); ``file``, ``line`` (1-based, or None) and ``key`` (the key path, or None) carry
    them as data."""

    file: str | None
    line: int | None
    key: str | None

    def __init__(
        self,
        message: str,
        *,
        file: str | None = None,
        line: int | None = None,
        key: str | None = None,
    ):
        super().__init__(message, item=key)
        self.file = file
        self.line = line
        self.key = key


class SimulationError(FlexmbdError, RuntimeError):
    """A simulation failed; ``error.result`` holds the results up to the failure."""


class InitialConditionsError(SimulationError):
    """The initial positions cannot be made to satisfy the constraints."""


class NewtonDivergedError(SimulationError):
    """Newton's method did not converge, even at the smallest step size."""


class StepSizeTooSmallError(SimulationError):
    """The step-size control went below the minimum step size."""


class SingularMatrixError(SimulationError):
    """A linear system is singular: redundant or conflicting constraints, or a singular
    configuration."""


class NonFiniteError(SimulationError):
    """A NaN or infinity appeared in the state or in a computed quantity."""


class CallbackError(SimulationError):
    """A user function raised or returned a value of the wrong shape; the original
    exception is chained as ``__cause__``."""


class SimulationInterrupted(SimulationError):
    """The run was interrupted (Ctrl-C); ``error.result`` holds what was computed."""


__all__ = [
    "CallbackError",
    "FlexmbdError",
    "InitialConditionsError",
    "InvalidModelError",
    "InvalidParameterError",
    "ModelError",
    "ModelFileError",
    "NewtonDivergedError",
    "NonFiniteError",
    "SimulationError",
    "SimulationInterrupted",
    "SingularMatrixError",
    "StepSizeTooSmallError",
    "UnknownItemError",
]
