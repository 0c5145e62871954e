"""Exceptions of flexmbd.

Every error flexmbd raises is a :class:`FlexmbdError`. Bad input is a :class:`ModelError`
(also a :class:`ValueError`), a failed simulation a :class:`SimulationError` (also a
:class:`RuntimeError`). Errors carry the offending ``item`` (for example ``"joint 'pivot'"``)
and, for run-time failures, the ``time`` at which they happened. A failed simulation attaches
everything computed up to the failure as ``error.result`` (a :class:`flexmbd.Result`).
"""

from __future__ import annotations

from dataclasses import FrozenInstanceError
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


class ArgumentTypeError(InvalidParameterError, TypeError):
    """An argument of the wrong type (a string where a number is expected, a float where a
    marker id is): an :class:`InvalidParameterError` whose ``item`` is the parameter's name,
    and also a :class:`TypeError`."""


class FrozenBodyError(InvalidParameterError, FrozenInstanceError):
    """An attempt to change the data of a deformable body after it was built (a field, an
    array element or a dictionary entry of a :class:`flexmbd.fe.FlexibleBodyData`). Body data
    is immutable: variants are new bodies made by its ``with_*`` methods. Also a
    :class:`dataclasses.FrozenInstanceError` (an ``AttributeError``)."""


class UnknownItemError(ModelError):
    """A body, marker, joint, force or sensor id or name that does not exist."""


class InvalidModelError(ModelError):
    """A structural error: a joint between a body and itself, a duplicated name, ..."""


class FreeMotionError(InvalidModelError):
    """The model moves freely in some direction (a free-flying body, a mechanism with no
    spring or driver on a joint): it has no static equilibrium. ``directions`` is how many
    independent motions lack stiffness and constraint. The free-free modes of such a structure
    come from :func:`flexmbd.linearize_at_rest`."""

    directions: int

    def __init__(self, message: str, *, item: str | None, directions: int):
        super().__init__(message, item=item)
        self.directions = directions


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


class ResultsFileError(FlexmbdError, OSError):
    """A results file cannot be written or read: its folder is missing or read-only, the path
    is a folder or a file that is not a flexmbd results file (a model file, say), another
    process is writing it, the disk is full, or the file is damaged. ``item`` names the file.
    When a run's file fails, the records committed before the fault stay in the file and the
    run's ``result`` holds what was computed. Also an ``OSError``."""


class NotAResultsFileError(ResultsFileError, InvalidModelError):
    """A path read as a results file is not one a flexmbd can read: not a regular file, not
    HDF5, another format (a body file, another program's HDF5), a newer version or a file
    without its datasets. A :class:`ResultsFileError` (an ``OSError``), as its docstring
    says, and an :class:`InvalidModelError` (a ``ValueError``), as it was before."""


class MissingFileError(FlexmbdError, FileNotFoundError):
    """A file to read does not exist: a mesh, body, results, model, Nastran, OP2, OP4 or SID
    file. ``item`` and ``filename`` are its path. Also a ``FileNotFoundError``."""

    def __init__(self, what: str, path: Any):
        FileNotFoundError.__init__(self, 2, f"No such {what}", str(path))
        self.item = str(path)
        self.time = None
        self.result = None


class SimulationError(FlexmbdError, RuntimeError):
    """A simulation failed; ``error.result`` holds the results up to the failure."""


class InitialConditionsError(SimulationError):
    """The initial positions cannot be made to satisfy the constraints."""


class NewtonDivergedError(SimulationError):
    """Newton's method did not converge, even at the smallest step size."""


class EquilibriumError(NewtonDivergedError):
    """No equilibrium (static or steady) was found: Newton's method did not converge.
    ``residual`` is the largest residual of the equations of motion left, ``bodies`` the
    names of the bodies that carry the largest residuals (largest first)."""

    residual: float
    bodies: list[str]

    def __init__(self, message: str, *, residual: float, bodies: list[str], time: float):
        super().__init__(message, item=", ".join(bodies) or None, time=time)
        self.residual = residual
        self.bodies = bodies


class StepSizeTooSmallError(SimulationError):
    """The step-size control went below the minimum step size."""


class SingularMatrixError(SimulationError):
    """A linear system is singular: redundant or conflicting constraints, or a singular
    configuration."""


class ConflictingConstraintsError(SimulationError):
    """A constraint equation left out as redundant is violated during the run: it contradicts
    the kept equations (a driver on a welded joint, two drivers of one joint), or it repeated
    them only at a singular configuration (a mechanism started at a dead centre). ``item``
    names the equation; ``result`` holds the run up to there."""


class NonFiniteError(SimulationError):
    """A NaN or infinity appeared in the state or in a computed quantity."""


class CallbackError(SimulationError):
    """A user function raised or returned a value of the wrong shape; the original
    exception is chained as ``__cause__``."""


class SimulationInterrupted(SimulationError):
    """The run was interrupted (Ctrl-C); ``error.result`` holds what was computed."""


class StudyError(FlexmbdError, RuntimeError):
    """A design study could not run its cases: its local cluster's worker processes did not
    start (a script that runs a study without the ``if __name__ == "__main__":`` guard), or
    a study was started by a worker process as it imported that script."""


class InitialCorrectionWarning(UserWarning):
    """The consistent initial conditions of a run moved given coordinates or velocities by
    more than the report tolerance (a joint that does not close, a velocity that does not
    satisfy a driver). The run's ``events`` name each joint and body; pass
    ``initial_conditions="strict"`` to :func:`flexmbd.simulate` to refuse instead."""


class StepSizeWarning(UserWarning):
    """The nominal step size of a run (generalized-alpha, or Runge-Kutta 4) is longer than
    its output interval: the steps end on the output times, so they are the output interval
    and the step size asked for has no effect. The run's ``events`` hold a "step size"
    event; give a longer output interval, or none, to step as asked."""


class InertiaWarning(UserWarning):
    """A rigid body's inertia that no mass distribution has: its largest principal moment
    exceeds the sum of the other two (I_3 = int x^2 + y^2 dm <= I_1 + I_2), by more than
    :data:`flexmbd.system.INERTIA_TRIANGLE_TOLERANCE` of it (flat bodies sit on the bound, and
    values rounded to a few digits cross it by a little). The motion is computed all the
    same; such data is usually mistyped, or about another point than the centre of mass."""


class ResonanceWarning(UserWarning):
    """A frequency response asked for at an undamped eigenfrequency of the model, within
    round-off (``i w I - A`` singular): the response is unbounded there and is returned as
    inf. Add damping, or step around the frequency."""


class ModeCountWarning(UserWarning):
    """A modal body's `mode_count` keeps some modes of a group of equal frequencies and
    drops the others (a round shaft's second bending pair cut after its first mode): which
    of them is kept is arbitrary (a direction the eigensolver chose), and the body is
    stiffer in the directions of the dropped ones than in the others. The message names the
    frequencies; take one mode more, or fewer, to keep the group whole."""


class MeshQualityWarning(UserWarning):
    """Elements the preprocessor accepts but that give poor or misleading results: quadrilateral
    shells warped out of their mean plane by more than
    :data:`flexmbd.fe.preprocess.SHELL_WARP_LIMIT` (the flat element projects them onto that
    plane: refine the mesh or split them into triangles), and neighbouring shells turned to
    opposite sides (their top and bottom stresses are averaged across each other:
    :func:`flexmbd.fe.orient_shells`), and Abaqus elements read as an element of another
    formulation (C3D8R, reduced integration, as the fully integrated hex8). The message names
    an element by its id and how many there are. Also point masses with an inertia about the
    normal of the flat shells that alone hold their node: it turns with the drilling
    rotation, which has only a penalty stiffness (the message names the node and the
    frequency of the mode it makes)."""


__all__ = [
    "CallbackError",
    "EquilibriumError",
    "FlexmbdError",
    "FrozenBodyError",
    "InitialConditionsError",
    "InertiaWarning",
    "InitialCorrectionWarning",
    "InvalidModelError",
    "InvalidParameterError",
    "MeshQualityWarning",
    "ModeCountWarning",
    "ModelError",
    "MissingFileError",
    "ModelFileError",
    "NewtonDivergedError",
    "ResonanceWarning",
    "ResultsFileError",
    "NonFiniteError",
    "NotAResultsFileError",
    "SimulationError",
    "SimulationInterrupted",
    "SingularMatrixError",
    "StepSizeTooSmallError",
    "StepSizeWarning",
    "StudyError",
    "UnknownItemError",
]
