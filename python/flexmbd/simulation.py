"""Running a simulation: :func:`simulate`."""

from __future__ import annotations

import logging
import math
import os
import signal
import threading
import time
import warnings
from collections.abc import Callable, Iterator
from contextlib import AbstractContextManager, contextmanager, nullcontext
from typing import Any

import numpy as np

from . import _boundary, _core
from ._checks import number
from .errors import (
    CallbackError,
    InitialCorrectionWarning,
    InvalidParameterError,
    NonFiniteError,
    ResultsFileError,
    SimulationInterrupted,
    SingularMatrixError,
    StepSizeWarning,
)
from .progress import SimulationProgress, simulation_progress, status
from .result import Result
from .state import State
from .system import identity_of, unheld_frame_error

#: How a run may start: the model's given state, static (or steady) equilibrium, or the
#: steady rotation of a rotor (see :func:`simulate`).
STARTS = ("given", "equilibrium", "steady-rotation")

logger = logging.getLogger("flexmbd.simulation")

#: The level at which each kind of event of ``result.events`` is logged; other kinds: INFO.
#: WARNING: what may spoil the results or asks for a look at the model (a changed initial
#: state, drift, near-singular constraints); INFO: what the run handles as planned.
EVENT_LEVELS = {
    "initial correction": logging.WARNING,
    "step size": logging.WARNING,
    "constraint drift": logging.WARNING,
    "singular configuration": logging.WARNING,
    "loop rank": logging.WARNING,
    "redundant constraints": logging.INFO,
    "redundancy re-selected": logging.INFO,
    "repartition": logging.INFO,
    "joint coordinates rebased": logging.INFO,
    "actuator saturation": logging.INFO,
}

#: A share of rejected steps above which the run's summary is logged as a WARNING.
REJECTED_WARNING = 0.1


def _start(
    model: _core.Model, initial_state: State | str | None, start_time: float | None
) -> tuple[float, State | None]:
    """The start time and the state to start from (None: the model's own)."""
    if start_time is not None:
        start_time = number(start_time, "start_time")
    if initial_state is None or (isinstance(initial_state, str) and initial_state == "given"):
        return (0.0 if start_time is None else start_time), None
    if isinstance(initial_state, str):
        from .analysis import equilibrium, steady_rotation

        if initial_state not in STARTS:
            raise InvalidParameterError(
                f"initial_state must be a State or one of {STARTS}, got {initial_state!r}",
                item="initial_state",
            )
        time = 0.0 if start_time is None else start_time
        solve = equilibrium if initial_state == "equilibrium" else steady_rotation
        return time, solve(model, time)
    if not isinstance(initial_state, State):
        raise InvalidParameterError(
            f"initial_state must be a State or one of {STARTS}, got {type(initial_state).__name__}",
            item="initial_state",
        )
    if start_time is not None and start_time != initial_state.time:
        raise InvalidParameterError(
            f"start_time {start_time} differs from the initial state's time "
            f"{initial_state.time}; give one of them",
            item="start_time",
        )
    return initial_state.time, initial_state


def _same_system(state: State, model: _core.Model) -> bool:
    """Whether `state` is one of the System `model` was compiled from (or of unknown origin:
    a results file's, a model without a System)."""
    here = identity_of(model)
    return state.system_identity is None or here is None or state.system_identity == here


def _check_paths(results_file: Any, protect: Any) -> None:
    """`results_file` is None or a path; `protect` a sequence of paths."""
    if results_file is not None and not isinstance(results_file, str | os.PathLike):
        raise InvalidParameterError(
            f"results_file must be a path (a str or os.PathLike), got "
            f"{type(results_file).__name__}",
            item="results_file",
        )
    paths = protect if isinstance(protect, tuple | list) else None
    if paths is None or not all(isinstance(p, str | os.PathLike) for p in paths):
        raise InvalidParameterError(
            f"protect must be a tuple of paths, got {protect!r}"[:200], item="protect"
        )


#: The events of a run that Python also warns of, and the class of the warning.
WARNED_EVENTS = {"initial correction": InitialCorrectionWarning, "step size": StepSizeWarning}


def _report(result: Result) -> None:
    """Warns (``warnings``) of the initial corrections of a run and of a step size that the
    output interval cuts short."""
    for event in result.events:
        category = WARNED_EVENTS.get(event["kind"])
        if category is not None:
            message = f"t = {event['time']:g}: {event['message']}"
            warnings.warn(message, category, stacklevel=3)


def _handled(log: logging.Logger, level: int) -> bool:
    """True if a record of `level` from `log` reaches a handler that is not a NullHandler."""
    if not log.isEnabledFor(level):
        return False
    current: logging.Logger | None = log
    found = False
    while current is not None:
        for handler in current.handlers:
            found = True
            if not isinstance(handler, logging.NullHandler) and level >= handler.level:
                return True
        if not current.propagate:
            break
        current = current.parent
    # Python's last resort (stderr, WARNING) when no handler at all is configured.
    last = logging.lastResort
    return not found and last is not None and level >= last.level


class _EventLog:
    """Logs the events of a run once each, as they come (from the records delivered during
    the run) and at its end; erases a terminal progress line first."""

    def __init__(self, display: SimulationProgress | None):
        self.display = display
        self.logged: set[tuple[float, str, str]] = set()

    def log(self, events: list[dict[str, Any]]) -> None:
        fresh = [e for e in events if (e["time"], e["kind"], e["message"]) not in self.logged]
        if not fresh:
            return
        lowest = min(EVENT_LEVELS.get(e["kind"], logging.INFO) for e in fresh)
        if self.display is not None and _handled(logger, lowest):
            self.display.clear()
        for event in fresh:
            self.logged.add((event["time"], event["kind"], event["message"]))
            level = EVENT_LEVELS.get(event["kind"], logging.INFO)
            logger.log(
                level,
                "t = %.6g s: %s: %s",
                event["time"],
                event["kind"],
                event["message"],
                extra={"event": event},
            )

    def chunk(self, raw: dict[str, Any]) -> None:
        """The records delivered during the run: their events, and the step number."""
        if self.display is not None:
            self.display.steps = int(raw["statistics"]["steps"])
        self.log(raw["events"])


def _summary(result: Result, start_time: float, wall: float) -> None:
    """Logs what the run did: INFO, or WARNING if many steps were rejected."""
    stats = result.statistics
    steps, rejected = int(stats.get("steps", 0)), int(stats.get("rejected_steps", 0))
    end = result.time[-1] if len(result.time) else _file_end(result, start_time)
    work = f"{steps} steps"
    if rejected:
        smallest = stats.get("min_step_size", math.nan)
        work += f" ({rejected} rejected, smallest step {smallest:.3g} s)"
    if stats.get("newton_iterations"):
        work += f", {stats['newton_iterations'] / max(steps, 1):.2f} Newton iterations per step"
    if stats.get("function_evaluations"):
        work += f", {stats['function_evaluations']} function evaluations"
    outcome = "done" if result.error is None else f"stopped ({type(result.error).__name__})"
    level = logging.INFO
    if rejected > REJECTED_WARNING * max(steps, 1):
        level = logging.WARNING
        work += ": many rejected steps (the step size is too large or the model stiff)"
    logger.log(
        level, "run %s: t = %.6g .. %.6g s, %s; %.3g s", outcome, start_time, end, work, wall
    )


def _file_end(result: Result, start_time: float) -> float:
    """The time of the last record in the result's file (a run that kept its records only
    there holds none in memory after a failure), else `start_time`."""
    from .results_file import read_results_metadata

    if getattr(result, "file", None) is None:
        return start_time
    try:
        end = read_results_metadata(result.file)["last_time"]
    except (ResultsFileError, OSError):
        return start_time
    return start_time if end is None else float(end)


def _warn_of_explicit_stability(
    model: Any, solver: Any, step_size: float, span: float
) -> str | None:
    """Warns (StepSizeWarning, and the log) before a run of Runge-Kutta 4 or Dormand-Prince
    whose step the stiffest elastic mode holds below the nominal step
    (:mod:`flexmbd.stability`): Dormand-Prince then takes millions of steps, Runge-Kutta 4 at
    its fixed step diverges. Returns, for Runge-Kutta 4, what a failure of the run is then
    (for :func:`_explained`), else None."""
    from .stability import STABILITY_POLYNOMIALS, explicit_step_limit

    method = getattr(solver, "method", None)
    if not isinstance(solver, _boundary.ExplicitSolver) or method not in STABILITY_POLYNOMIALS:
        return None
    limit = explicit_step_limit(model, method)
    if limit is None or limit.step >= step_size:
        return None
    mode = (
        f"eigenvalue {limit.eigenvalue.real:.3g} 1/s, overdamped by its damping"
        if limit.eigenvalue.imag == 0.0
        else f"{limit.frequency / (2 * math.pi):.3g} Hz"
    )
    if method == "rk4":
        outcome = f"at its fixed step of {step_size:g} s Runge-Kutta 4 is unstable and diverges"
    else:
        outcome = f"{span / limit.step:,.0f} steps to the end"
    message = (
        f"{method}: the stiffest elastic mode of body '{limit.body}' ({mode}) holds explicit "
        f"steps to about {limit.step:.2g} s by stability: {outcome}. Generalized-alpha (the "
        "default) and 'tr-bdf2' are not held to it."
    )
    logger.warning(message)
    warnings.warn(message, StepSizeWarning, stacklevel=3)
    if method != "rk4":
        return None
    return (
        f"the run diverged: its step of {step_size:g} s is above Runge-Kutta 4's stability "
        f"limit of about {limit.step:.2g} s for the stiffest elastic mode of body "
        f"'{limit.body}' ({mode}); take a step below it, or generalized-alpha (the default)"
    )


#: Largest rotation of an angle driver in one step (rad) without a warning: beyond pi a step
#: cannot tell the turn from its complement (the body turned 4 - 2 pi = -2.28 rad a step
#: under a driver of 4 rad a step, its kinetic energy 29 times too large), and well before
#: that the step resolves the motion poorly.
DRIVER_TURN_PER_STEP = math.pi / 2

#: Times at which the drivers' rates are sampled for that warning.
DRIVER_SAMPLES = 2001


def _warn_of_fast_drivers(
    system: Any, model: Any, step_size: float, start: float, end: float
) -> None:
    """Warns (StepSizeWarning, and the log) before a run whose angle driver turns more than
    :data:`DRIVER_TURN_PER_STEP` in one step anywhere in the run (its rate sampled at
    :data:`DRIVER_SAMPLES` times): such a step cannot follow the driver. Needs the System
    (a compiled Model does not keep the drivers' functions); a function that cannot be
    sampled is skipped."""
    if system is None or not hasattr(system, "driver_function") or not end > start:
        return
    times = np.linspace(start, end, DRIVER_SAMPLES)
    for joint in model.describe()["joints"]:
        if joint["type"] != "angle driver":
            continue
        try:
            function = system.driver_function(joint["name"])
            rates = np.array([abs(float(function.derivatives(t)[1])) for t in times])
        except Exception:  # noqa: BLE001 - a function the check cannot sample: no warning
            continue
        fastest = int(np.argmax(rates))
        turn = rates[fastest] * step_size
        if not turn > DRIVER_TURN_PER_STEP:
            continue
        message = (
            f"the angle driver {joint['name']!r} turns {turn:.3g} rad in one step of "
            f"{step_size:g} s (its rate {rates[fastest]:.4g} rad/s at t = {times[fastest]:.4g} "
            f"s): steps of more than pi/2 do not follow it, and beyond pi the body turns the "
            f"other way; take step_size below {DRIVER_TURN_PER_STEP / 4 / rates[fastest]:.2g} s"
        )
        logger.warning(message)
        warnings.warn(message, StepSizeWarning, stacklevel=3)


@contextmanager
def _ctrl_c_stops_the_run() -> Iterator[None]:
    """Ctrl-C raises KeyboardInterrupt during the run, so that the run stops cleanly with its
    records (`SimulationInterrupted`), also where the process's SIGINT was left at the
    operating system's default action, which ends the process at once: Gmsh's
    `gmsh.initialize()` does that (its `interruptible=True`), so a script or notebook that
    meshed with Gmsh lost its run to a Ctrl-C. Only in the main thread, where Python takes
    signals; the process's handler is put back after the run."""
    if (
        threading.current_thread() is not threading.main_thread()
        or signal.getsignal(signal.SIGINT) != signal.SIG_DFL
    ):
        yield
        return
    signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, signal.SIG_DFL)


def _interruption(error: BaseException | None) -> BaseException | None:
    """Ctrl-C (or a signal raised as KeyboardInterrupt) that arrives while Python code of the
    run runs (the progress display, the results writer, a user's function) is reported as
    the core reports it between steps: SimulationInterrupted, not CallbackError."""
    if isinstance(error, CallbackError) and isinstance(error.__cause__, KeyboardInterrupt):
        interrupted = SimulationInterrupted(f"interrupted at t = {error.time:g}", time=error.time)
        interrupted.__cause__ = error.__cause__
        return interrupted
    return error


def simulate(
    model: _core.Model | _core.System,
    end_time: float,
    step_size: float,
    *,
    start_time: float | None = None,
    initial_state: State | str | None = None,
    initial_conditions: str = "correct",
    output_interval: float | None = None,
    solver: _boundary.GeneralizedAlpha | _boundary.ExplicitSolver | None = None,
    progress: bool | Callable[[float, float, int], object] | None = None,
    results_file: str | os.PathLike[str] | None = None,
    metadata: dict[str, Any] | None = None,
    keep_in_memory: bool = True,
    protect: tuple[str | os.PathLike[str], ...] = (),
    results_write_interval: float = 0.0,
) -> Result:
    """Simulates ``model`` (a :class:`Model`, or a :class:`System`, which is compiled first)
    from ``start_time`` (default 0, or the time of ``initial_state``) to ``end_time`` (s)
    with nominal step ``step_size`` (s).

    ``initial_state``: where the run starts. None or "given": the model's initial positions
    and velocities; a :class:`flexmbd.State` (from :func:`flexmbd.equilibrium`,
    ``Result.state``, or edited with its ``with_*`` methods); "equilibrium": the static (or,
    under moving drivers, steady) equilibrium at the start time, so that a driven flexible arm
    does not drop under gravity first; "steady-rotation": the centrifugally stretched state
    of rotors turned at constant speed by drivers (:func:`flexmbd.steady_rotation`).

    Results are recorded every ``output_interval`` seconds (steps land exactly on these times)
    or, if None, after every step. A nominal step longer than the output interval is cut to
    it: the run has a "step size" event and Python warns
    (:class:`flexmbd.errors.StepSizeWarning`).

    ``solver`` defaults to ``GeneralizedAlpha()`` (spectral radius 0.9); an
    :class:`ExplicitSolver` selects Runge-Kutta 4 or Dormand-Prince 5(4) with one of the seed's
    three strategies (integrate all accelerations, coordinate partitioning, projection) or in
    joint plus elastic coordinates (open trees, loops cut), see ``docs/solvers.md``.

    ``progress``: True shows a progress bar (simulated time of end time, step, step size,
    Newton iterations per step, elapsed and remaining wall time) on stderr: redrawn on a
    terminal, a line every 10 % in a pipe or log file, a widget in a Jupyter notebook with
    ipywidgets (:class:`flexmbd.progress.SimulationProgress`; give one to choose the stream or
    style). A function ``progress(time, step_size, newton_iterations)`` is called about ten
    times a second instead; its exception stops the run (:class:`flexmbd.CallbackError`,
    with the results so far), while a failure of the built-in bar only switches it off.
    The events of the run go to the ``"flexmbd.simulation"`` logger as they come (when it
    has a handler) or at the end, at the levels of :data:`EVENT_LEVELS`, then a summary at
    INFO (see ``docs/progress-and-logging.md``).

    ``results_file`` (a path, conventionally ``*.h5``) writes the results to an HDF5 file
    while the run goes on (:mod:`flexmbd.results_file`; ``metadata``, a JSON-compatible dict,
    is stored with them): a run that fails, is interrupted or is killed keeps every record
    up to its last flush, about a tenth of a second before. :func:`flexmbd.read_results`
    reads the file back. The path may not be a folder or an existing file of another kind,
    nor one of the files in ``protect`` (the model file of the run); another run writing it
    is refused; the file replaces an earlier one only once the run has taken its first step
    (see :class:`flexmbd.results_file.ResultsWriter`). A failed write (a full disk) raises
    :class:`flexmbd.ResultsFileError` with ``result``, the file keeping what was committed.
    ``results_write_interval`` (s of wall time) writes the file less often, the records of
    that time together (a study's short cases, whose failures still write everything they
    computed; a killed run loses up to that much).

    ``keep_in_memory=False`` (with a ``results_file``) keeps the records only in the file:
    the memory of the run stays flat however many records it writes, and the returned
    ``Result`` holds only the records written after the last delivery to the file (at
    least the last one; the result of a failed run, ``error.result``, may hold none, its
    records all in the file); read the whole run with :func:`flexmbd.read_results`.

    Redundant constraints are found by rank before the run and, by default, removed (see
    ``Result.redundancy`` and ``Result.events``); where the rows kept become ill-conditioned
    during the motion they are chosen again (a "redundancy re-selected" event).

    Initial positions and velocities that violate the constraints are corrected first
    (minimum-norm change); initial accelerations and multipliers come from seed eq. 26. A
    correction that moves a coordinate or velocity by more than 1e-6 (relative to max(1,
    |value|)) is not silent: ``result.events`` holds an "initial correction" event for every
    joint it closes and every body it moves, and Python warns
    (:class:`flexmbd.errors.InitialCorrectionWarning`, and the "flexmbd.simulation" logger).
    ``initial_conditions="strict"`` refuses such a correction instead
    (:class:`flexmbd.InitialConditionsError`).

    Raises a :class:`flexmbd.SimulationError` subclass if the run fails; its ``result``
    attribute holds everything computed up to the failure. Ctrl-C raises
    :class:`flexmbd.SimulationInterrupted`, also with ``result``.
    """
    system = model if isinstance(model, _core.System) else None
    if isinstance(model, _core.System):
        model = model.compile()
    end_time = number(end_time, "end_time")
    step_size = number(step_size, "step_size")
    if output_interval is not None:
        output_interval = number(output_interval, "output_interval")
    # Refused before a results file is opened (the core refused them after: a file of no
    # records named .failed.h5).
    for name, value in (("step_size", step_size), ("output_interval", output_interval)):
        if value is not None and not value > 0.0:
            raise InvalidParameterError(f"{name} must be above zero (s), got {value:g}", item=name)
    if not (isinstance(initial_conditions, str) and initial_conditions in ("correct", "strict")):
        raise InvalidParameterError(
            f"initial_conditions must be 'correct' or 'strict', got {initial_conditions!r}",
            item="initial_conditions",
        )
    if not isinstance(keep_in_memory, bool | np.bool_):
        raise InvalidParameterError(
            f"keep_in_memory must be True or False, got {keep_in_memory!r}", item="keep_in_memory"
        )
    _check_paths(results_file, protect)
    progress, display = simulation_progress(progress, end_time)
    # An equilibrium or steady rotation to start from is solved first (seconds on large
    # models): a status line on a terminal meanwhile.
    solving: AbstractContextManager[None] = nullcontext()
    if display is not None and isinstance(initial_state, str) and initial_state in STARTS[1:]:
        label = f"{display.bar.label}: finding the {initial_state} state"
        solving = status(label, stream=display.bar.stream)
    with solving:
        start_time, start = _start(model, initial_state, start_time)
    if end_time < start_time:
        raise InvalidParameterError(
            f"end time {end_time:g} is before start time {start_time:g}", item="end_time"
        )
    start_q = np.asarray(
        model.initial_coordinates if start is None else start.coordinates, dtype=float
    )
    unheld = None
    if start_q.shape == (model.coordinate_count,):  # (other sizes: refused by the run)
        unheld = unheld_frame_error(model, start_q, start_time, "acceleration system")
    if unheld is not None:
        # Refused before the run: the pivots of such a matrix are round-off, which the
        # factorization does not always tell from small true pivots (the run went on and
        # diverged, or gave spurious motions).
        raise unheld
    unstable = _warn_of_explicit_stability(model, solver, step_size, end_time - start_time)
    _warn_of_fast_drivers(system, model, step_size, start_time, end_time)
    start_arrays: dict[str, Any] = {}
    if start is not None:
        start_arrays = {
            "coordinates": np.ascontiguousarray(start.coordinates, dtype=float),
            "velocities": np.ascontiguousarray(start.velocities, dtype=float),
            # A continuation only on the model that recorded it: on another System the
            # state is a given one, whose corrections are initial corrections.
            "recorded": bool(start.recorded) and _same_system(start, model),
        }
        discrete = start.discrete_for(model)
        if discrete is not None:
            # The unwrapped angles a recorded state carries: a spring wound past half a turn
            # went on from its wrapped angle (a wheel continued at 1 s ended at 4.45 rad/s
            # instead of 1.56).
            start_arrays["discrete"] = discrete
    if not keep_in_memory and results_file is None:
        raise InvalidParameterError(
            "keep_in_memory=False keeps the records only in a results file: give results_file",
            item="keep_in_memory",
        )
    writer = None
    if results_file is not None:
        from .results_file import ResultsWriter, check_metadata

        check_metadata(metadata)  # before the file is made: a refused value leaves none
        writer = ResultsWriter(
            results_file,
            model,
            metadata=metadata,
            protect=protect,
            write_interval=results_write_interval,
        )
    events = _EventLog(display)
    records = None if writer is None else writer.append
    if display is not None or _handled(logger, logging.WARNING):
        # The records delivered during the run give the step number and the events as they
        # come (a copy of the new records about ten times a second: a few % on small models,
        # so only when they are shown).
        def records(raw: dict[str, Any]) -> None:
            if writer is not None:
                writer.append(raw)
            events.chunk(raw)

    began = time.perf_counter()
    result = None
    try:
        if display is not None:
            display.begin(start_time)
        with _ctrl_c_stops_the_run():
            raw, error = _core.simulate(
                model,
                end_time,
                step_size,
                start_time=start_time,
                output_interval=output_interval,
                solver=solver,
                progress=progress,
                records=records,
                initial_conditions=initial_conditions,
                keep_in_memory=keep_in_memory,
                **start_arrays,
            )
        error = _interruption(error)
        result = Result(raw, model.describe(), error=error, flexible=model.flexible_bodies)
        result.system_identity = identity_of(model)
        if writer is not None:
            if writer.failure is not None:
                # The run stopped because its file could not be written: that is the error.
                error = writer.failure
            else:
                try:
                    result.file = writer.finish(result, released=int(raw.get("released", 0)))
                except ResultsFileError as failure:
                    error = failure
    finally:
        if writer is not None:
            writer.close()
        if display is not None and result is None:
            display.close()
    events.log(result.events)
    if display is not None:
        display.finish(result)
    _summary(result, start_time, time.perf_counter() - began)
    _report(result)
    if error is not None:
        error = _explained(error, model, start, start_time, unstable)
        error.result = result
        raise error
    return result


def _explained(
    error: Exception,
    model: _core.Model,
    start: State | None,
    time: float,
    unstable: str | None = None,
) -> Exception:
    """A singular matrix at the start explained, when it is: a deformable body whose frame
    nothing fixes (its reference conditions and the joints both leave it free) becomes an
    error naming the body and the way out. A run of Runge-Kutta 4 above its stability limit
    (`unstable`, from :func:`_warn_of_explicit_stability`) that failed on a non-finite value
    or a singular matrix diverged: its message says so (a singular matrix was put down to a
    mass matrix that is not positive definite). Any other error is returned as it is."""
    if unstable is not None and isinstance(error, NonFiniteError | SingularMatrixError):
        error.args = (f"{error.args[0] if error.args else error}; {unstable}", *error.args[1:])
        return error
    if not isinstance(error, SingularMatrixError) or error.time is None or error.time != time:
        return error
    q = np.asarray(model.initial_coordinates if start is None else start.coordinates, dtype=float)
    return unheld_frame_error(model, q, time, error.item or "matrix") or error
