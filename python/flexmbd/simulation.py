"""Running a simulation: :func:`simulate`."""

from __future__ import annotations

import os
from collections.abc import Callable
from typing import Any

from . import _core
from .result import Result


def simulate(
    model: _core.Model | _core.System,
    end_time: float,
    step_size: float,
    *,
    start_time: float = 0.0,
    output_interval: float | None = None,
    solver: _core.GeneralizedAlpha | _core.ExplicitSolver | None = None,
    progress: Callable[[float, float, int], object] | None = None,
    results_file: str | os.PathLike[str] | None = None,
    metadata: dict[str, Any] | None = None,
) -> Result:
    """Simulates ``model`` (a :class:`Model`, or a :class:`System`, which is compiled first)
    from ``start_time`` to ``end_time`` (s) with nominal step ``step_size`` (s).

    Results are recorded every ``output_interval`` seconds (steps land exactly on these times)
    or, if None, after every step. ``solver`` defaults to ``GeneralizedAlpha()`` (spectral
    radius 0.9); an :class:`ExplicitSolver` selects Runge-Kutta 4 or Dormand-Prince 5(4) with
    one of the seed's three strategies (integrate all accelerations, coordinate partitioning,
    projection) or in joint plus elastic coordinates (open trees, loops cut), see
    ``docs/solvers.md``. ``progress(time, step_size, newton_iterations)`` is
    called about ten times a second.

    ``results_file`` (a path, conventionally ``*.h5``) writes the results to an HDF5 file
    while the run goes on (:mod:`flexmbd.results_file`; ``metadata``, a JSON-compatible dict,
    is stored with them): a run that fails, is interrupted or is killed keeps every record
    up to its last flush, about a tenth of a second before. :func:`flexmbd.read_results`
    reads the file back.

    Redundant constraints are found by rank before the run and, by default, removed (see
    ``Result.redundancy`` and ``Result.events``).

    Initial positions and velocities that violate the constraints are corrected first
    (minimum-norm change); initial accelerations and multipliers come from seed eq. 26.

    Raises a :class:`flexmbd.SimulationError` subclass if the run fails; its ``result``
    attribute holds everything computed up to the failure. Ctrl-C raises
    :class:`flexmbd.SimulationInterrupted`, also with ``result``.
    """
    if isinstance(model, _core.System):
        model = model.compile()
    writer = None
    if results_file is not None:
        from .results_file import ResultsWriter

        writer = ResultsWriter(results_file, model, metadata=metadata)
    try:
        raw, error = _core.simulate(
            model,
            end_time,
            step_size,
            start_time=start_time,
            output_interval=output_interval,
            solver=solver,
            progress=progress,
            records=None if writer is None else writer.append,
        )
        result = Result(
            raw, model.describe(), error=error, flexible=getattr(model, "_flexible", None)
        )
        if writer is not None:
            writer.finish(result)
    finally:
        if writer is not None:
            writer.close()
    if error is not None:
        error.result = result
        raise error
    return result
