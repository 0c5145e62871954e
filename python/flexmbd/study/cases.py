"""One case of a study: the model it builds (from a build function or a model file with values
replaced by key path), its key (a hash of the model and the parameters), and its run on a
worker, which writes the results file and a summary next to it."""

from __future__ import annotations

import functools
import hashlib
import inspect
import json
import math
import os
import sys
import time
import traceback
import warnings
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..errors import FlexmbdError, InvalidParameterError, ModelFileError, SimulationError

#: Seconds of wall time between writes of a case's results file: a case that fails still
#: writes all it computed, and a case killed with its worker runs again on the next run.
CASE_WRITE_INTERVAL = 2.0

#: Settings of a run a study may give (they replace the model's).
RUN_SETTINGS = ("end_time", "step_size", "output_interval", "solver")


@dataclass(frozen=True)
class ModelSource:
    """Where the cases' models come from: `build` (a function of the parameters returning a
    System, a Model, an Example or a ModelFile; `arguments` are passed to every call) or
    `path` (a model file whose values the parameters replace by key path)."""

    build: Callable[..., Any] | None = None
    path: str | None = None
    arguments: Mapping[str, Any] = field(default_factory=dict)

    def identity(self) -> str:
        """What the cases' keys hash for the model: the model file's bytes and those of the
        files it names (meshes, body files, Nastran decks and results: a mesh written again
        by the preprocessor is another model), or the build function (:func:`_callable_text`:
        its source, defaults, closure, a partial's arguments, a callable object's state) and
        its fixed arguments."""
        if self.path is not None:
            from ..model_file import referenced_files

            digest = hashlib.sha256(Path(self.path).read_bytes())
            for used in referenced_files(self.path):
                digest.update(str(used.name).encode())
                digest.update(used.read_bytes() if used.is_file() else b"(missing)")
            return f"file {Path(self.path).name} {digest.hexdigest()}"
        assert self.build is not None
        return f"function {_callable_text(self.build)} {_canonical(self.arguments)}"

    def check_names(self, names: list[str]) -> None:
        """Refuses parameter names a build function does not take (model files check their
        key paths with the values)."""
        if self.build is None:
            return
        try:
            signature = inspect.signature(self.build)
        except (TypeError, ValueError):
            return
        accepted = signature.parameters
        if any(p.kind is inspect.Parameter.VAR_KEYWORD for p in accepted.values()):
            return
        for name in names:
            if name not in accepted:
                raise InvalidParameterError(
                    f"parameter {name!r}: {getattr(self.build, '__name__', 'the build function')}"
                    f" takes {list(accepted)}",
                    item=name,
                )

    def check(self, parameters: Mapping[str, Any]) -> None:
        """Refuses values the model does not take, naming the key path: a model file is read
        and checked with them; a build function builds the model."""
        if self.path is not None:
            from ..model_file import check_model

            check_model(self.path, parameters)
        else:
            self.load(parameters)

    def load(self, parameters: Mapping[str, Any]) -> tuple[Any, dict[str, Any]]:
        """The model of a case, and the run settings it comes with (a model file's or an
        Example's)."""
        if self.path is not None:
            from ..model_file import load_model

            model_file = load_model(self.path, parameters)
            return model_file.system, _settings_of(model_file)
        assert self.build is not None
        built = self.build(**self.arguments, **parameters)
        system = getattr(built, "system", built)
        if not hasattr(system, "compile") and not hasattr(system, "describe"):
            name = getattr(self.build, "__name__", "the build function")
            raise InvalidParameterError(
                f"{name} returned {type(built).__name__} {built!r:.40}, not a System, Model, "
                "Example or ModelFile (a `return` missing?)",
                item=name,
            )
        return system, _settings_of(built)


def check_case(source: ModelSource, index: int, parameters: Mapping[str, Any]) -> None:
    """Refuses case `index` if its model does not take `parameters`: the error names the case
    and the key path (a model file's :class:`ModelFileError`) or the build function's error."""
    try:
        source.check(parameters)
    except ModelFileError as error:
        where = {"file": error.file, "line": error.line, "key": error.key}
        raise ModelFileError(f"case {index} {dict(parameters)}: {error}", **where) from error
    except Exception as error:
        raise InvalidParameterError(
            f"case {index} {dict(parameters)}: {type(error).__name__}: {error}"
        ) from error


def check_cases(
    source: ModelSource,
    cases: list[tuple[int, Mapping[str, Any]]],
    outputs: Mapping[str, str] | None = None,
) -> FlexmbdError | None:
    """Checks a batch of cases (on a worker: the check builds each model) and returns the
    refusal of the first one refused, or None. `outputs` (the study's, or None) are checked
    on the batch's first case (`check_outputs`)."""
    for index, parameters in cases:
        try:
            check_case(source, index, parameters)
        except FlexmbdError as refusal:
            return refusal
    if outputs and cases:
        try:
            check_outputs(source, *cases[0], outputs)
        except FlexmbdError as refusal:
            return refusal
    return None


def check_outputs(
    source: ModelSource, index: int, parameters: Mapping[str, Any], outputs: Mapping[str, str]
) -> None:
    """Refuses outputs that name what the model of case `index` lacks (a body, joint,
    sensor, node or component): each is evaluated on the model's first record, from a run of
    no length, before the cases run (a mistyped name failed every case after its whole run).
    A model that cannot start (its initial state refused) is not refused here: its run
    records that failure."""
    from ..quantities import output_value
    from ..simulation import simulate

    try:
        model, defaults = source.load(parameters)
        start = float(defaults.get("start_time") or 0.0)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            first = simulate(model, start, 1.0, start_time=start)
    except Exception:  # noqa: BLE001 - the case's run reports it
        return
    for name, spec in outputs.items():
        try:
            output_value(first, spec)
        except FlexmbdError as error:
            label = repr(spec) if name == spec else f"{name!r} ({spec})"
            raise InvalidParameterError(
                f"output {label}, on case {index} {dict(parameters)}: {error}",
                item=name,
            ) from error


def _settings_of(built: Any) -> dict[str, Any]:
    """The run settings an Example or a ModelFile carries."""
    settings = {}
    for name in RUN_SETTINGS:
        value = getattr(built, name, None)
        if value is not None:
            settings[name] = value
    if getattr(built, "start_time", None) is not None:
        settings["start_time"] = built.start_time
    start = getattr(built, "start", None)
    if start is not None:
        settings["initial_state"] = start
    return settings


def _canonical(value: Any, depth: int = 0) -> str:
    """A stable text of parameter values and settings for hashing (arrays by their bytes,
    not their repr, which shows 8 digits and elides long ones; functions by
    :func:`_callable_text`, `depth` deep in a function's text)."""
    return json.dumps(value, sort_keys=True, default=lambda v: _value_text(v, depth))


def _value_text(value: Any, depth: int = 0) -> str:
    """The text `_canonical` hashes for a value JSON does not hold."""
    import numpy as np

    if isinstance(value, np.ndarray):
        data = np.ascontiguousarray(value)
        digest = hashlib.sha256(data.tobytes()).hexdigest() if data.dtype != object else repr(data)
        return f"array {data.dtype} {data.shape} {digest}"
    if isinstance(value, np.generic):
        return repr(value.item())
    if callable(value) and not isinstance(value, type):
        return _callable_text(value, depth)
    text = repr(value)
    # (a default repr holds the object's address, another in every process: its type)
    return f"<{type(value).__qualname__}>" if " at 0x" in text else text


def _callable_text(function: Any, depth: int = 0) -> str:
    """A text that changes when what `function` computes may change: its name and source
    (or its compiled code where there is no source), its defaults, the values its closure
    holds and the module-level values it reads (a build function made in a loop over a
    length; the functions it calls, likewise), a partial's function and arguments, a bound
    method's object and a callable object's class source and state."""
    if depth > 4:  # (a closure holding itself)
        return f"{getattr(function, '__qualname__', type(function).__qualname__)}"

    def text(value: Any) -> str:
        return _canonical(value, depth + 1)

    if isinstance(function, functools.partial):
        inner = _callable_text(function.func, depth + 1)
        return f"partial({inner}, {text(list(function.args))}, {text(function.keywords)})"
    if inspect.ismethod(function):
        owner = getattr(function.__self__, "__dict__", repr(function.__self__))
        return f"method({_callable_text(function.__func__, depth + 1)}, {text(owner)})"
    if inspect.isfunction(function):
        name = f"{function.__module__}.{function.__qualname__}"
        try:
            source = inspect.getsource(function).encode()
        except (OSError, TypeError):
            code = function.__code__
            source = code.co_code + repr(code.co_consts).encode() + repr(code.co_names).encode()
        cells = []
        for cell in function.__closure__ or ():
            try:
                cells.append(cell.cell_contents)
            except ValueError:  # (an empty cell)
                cells.append(None)
        # The module-level values it reads (a length set by a loop in a script, a helper
        # function it calls); modules and classes by name.
        names = set(function.__code__.co_names)
        for constant in function.__code__.co_consts:
            if inspect.iscode(constant):
                names.update(constant.co_names)
        reads = {}
        for read in sorted(names):
            if read in function.__globals__:
                value = function.__globals__[read]
                if inspect.ismodule(value) or isinstance(value, type):
                    reads[read] = getattr(value, "__name__", read)
                else:
                    reads[read] = value
        digest = hashlib.sha256(source).hexdigest()
        defaults = text([function.__defaults__, function.__kwdefaults__, cells, reads])
        return f"{name} {digest} {defaults}"
    kind = type(function)
    try:
        source = inspect.getsource(kind).encode()
    except (OSError, TypeError):
        source = b""
    state = getattr(function, "__dict__", None)
    name = f"{kind.__module__}.{kind.__qualname__}"
    return f"object {name} {hashlib.sha256(source).hexdigest()} {text(state) if state else ''}"


def _as_floats(value: Any) -> Any:
    """`value` with its integers (not bools) as floats, in lists and dicts too: the same
    number written 1 or 1.0 is the same case."""
    if isinstance(value, bool):
        return value
    if isinstance(value, int):
        return float(value)
    if isinstance(value, list | tuple):
        return [_as_floats(v) for v in value]
    if isinstance(value, Mapping):
        return {k: _as_floats(v) for k, v in value.items()}
    return value


def _setting_text(value: Any) -> str:
    """A run setting as the text its key hashes: a solver with every setting."""
    from .._boundary import solver_settings
    from .._core import ExplicitSolver, GeneralizedAlpha

    if isinstance(value, GeneralizedAlpha | ExplicitSolver):
        return solver_settings(value)
    return repr(_as_floats(value))


def case_key(identity: str, parameters: Mapping[str, Any], settings: Mapping[str, Any]) -> str:
    """The key of a case: a hash of the model, its parameter values and the run settings
    (numbers compared as floats: 1 and 1.0 give one key; a solver by every setting,
    :func:`flexmbd._boundary.solver_settings`)."""
    shown = {k: _setting_text(v) for k, v in settings.items()}
    text = _canonical([identity, _as_floats(dict(parameters)), shown])
    return hashlib.sha256(text.encode()).hexdigest()[:16]


@dataclass(frozen=True)
class CaseTask:
    """What a worker needs to run a case."""

    index: int
    key: str
    parameters: dict[str, Any]
    source: ModelSource
    settings: dict[str, Any]
    outputs: dict[str, str]
    folder: str

    @property
    def results_path(self) -> Path:
        return Path(self.folder) / f"case-{self.key}.h5"

    @property
    def summary_path(self) -> Path:
        return Path(self.folder) / f"case-{self.key}.json"

    @property
    def started_path(self) -> Path:
        """Written as the case starts on a worker, removed with its summary: a case with it and
        no summary was running when its worker died."""
        return Path(self.folder) / f"case-{self.key}.started"


def run_case(task: CaseTask) -> dict[str, Any]:
    """Builds and simulates a case, writing its results file, then its outputs and status to
    the summary file (written last, by rename: a case is done when it exists). A case that
    fails keeps its partial results and records the error's class and message. A case done
    already (a batch run again after its worker died) is not run again: its summary is
    returned."""
    from ..simulation import simulate

    if task.summary_path.exists():
        try:
            return json.loads(task.summary_path.read_text())
        except (OSError, ValueError):
            pass  # unreadable: run the case again
    task.started_path.write_text(str(os.getpid()))
    started = time.perf_counter()
    error: BaseException | None = None
    result = None
    try:
        model, defaults = task.source.load(task.parameters)
        run = {**defaults, **task.settings}
        missing = [name for name in ("end_time", "step_size") if name not in run]
        if missing:
            raise InvalidParameterError(
                f"the study gives no {' and '.join(missing)} and the model has none"
            )
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            result = simulate(
                model,
                run.pop("end_time"),
                run.pop("step_size"),
                results_file=task.results_path,
                results_write_interval=CASE_WRITE_INTERVAL,
                metadata={"study case": task.index, "parameters": task.parameters},
                **run,
            )
    except SimulationError as failure:
        error, result = failure, getattr(failure, "result", None)
    except Exception as failure:  # noqa: BLE001 - any error of a case is recorded, not raised
        error = failure
    return _write_summary(task, result, error, time.perf_counter() - started, os.getpid())


class WorkerDied(Exception):
    """The error recorded for a case whose worker process died while running it."""


def record_lost_case(task: CaseTask, cause: BaseException) -> dict[str, Any]:
    """Records, from the main process, a case whose worker process died while running it (out
    of memory, a crash in native code, an os._exit in a callback; `cause`, Dask's report) as
    failed with the error class `WorkerDied`, its outputs computed from what its results file
    kept (the records flushed before the death, if any)."""
    from ..results_file import read_results

    result = None
    if task.results_path.exists():
        try:
            result = read_results(task.results_path)
        except Exception:  # noqa: BLE001,S110 - a file cut short by the death: no records
            pass
    error = WorkerDied(
        f"the worker process died while running this case (Dask: {type(cause).__name__}); out "
        "of memory, a crash in native code or an exit in a callback can do that. Its results "
        "file keeps what was written before"
    )
    error.__cause__ = cause  # Dask's own report, in the summary's traceback
    return _write_summary(task, result, error, None, None)


def _write_summary(
    task: CaseTask,
    result: Any,
    error: BaseException | None,
    elapsed: float | None,
    pid: int | None,
) -> dict[str, Any]:
    """A case's outputs (computed from `result`, which may be partial) and status, written to
    its summary file (last, by rename: the case is then done) and returned. `error` is the
    run's; an output that cannot be computed fails the case too, and is computed again when
    the study's outputs change (`refresh_outputs`)."""
    run_error = None if error is None else _error_entry(error)
    summary = {
        "index": task.index,
        "key": task.key,
        "parameters": task.parameters,
        "warnings": [] if result is None else case_warnings(result.events),
        "records": 0 if result is None else len(result.time),
        "elapsed": elapsed,
        "worker_pid": pid,
        "worker_peak_memory": _peak_memory() if pid is not None else None,
        "run_error": run_error,
    }
    _with_outputs(summary, task.outputs, result)
    _save_summary(task, summary)
    task.started_path.unlink(missing_ok=True)
    return summary


def refresh_outputs(task: CaseTask, summary: dict[str, Any]) -> dict[str, Any] | None:
    """The summary of a case done, its outputs computed again for the study's outputs
    (`task.outputs`) from its results file, and saved; None (and the summary removed: the case
    runs again) for a summary of a version that did not keep the run's own error apart, or a
    case whose results file is gone."""
    from ..results_file import read_results

    if "run_error" not in summary or not task.results_path.exists():
        task.summary_path.unlink(missing_ok=True)
        return None
    try:
        result = read_results(task.results_path)
    except Exception:  # noqa: BLE001 - a file cut short (a worker died): no records
        result = None
    summary = dict(summary)
    _with_outputs(summary, task.outputs, result)
    _save_summary(task, summary)
    return summary


def _with_outputs(summary: dict[str, Any], outputs: Mapping[str, str], result: Any) -> None:
    """Sets a summary's outputs (from `result`, None for none), their time, status and error
    (the run's, else the first output's that failed)."""
    import numpy as np

    from ..quantities import output_value

    values: dict[str, Any] = {}
    series_time = None
    error = summary["run_error"]
    if result is not None:
        for name, spec in outputs.items():
            try:
                value = output_value(result, spec)
            except FlexmbdError as failure:
                values[name] = None
                error = error or _error_entry(failure)
                continue
            if isinstance(value, np.ndarray):
                values[name] = [_json_number(v) for v in value]
                series_time = [float(t) for t in result.time]
            else:
                values[name] = _json_number(value)
    summary.update(
        status="complete" if error is None else "failed",
        error=error,
        outputs=values,
        outputs_of=dict(outputs),
        time=series_time,
    )


def _error_entry(error: BaseException) -> dict[str, Any]:
    failed_at = getattr(error, "time", None)
    return {
        "class": type(error).__name__,
        "message": str(error),
        "traceback": "".join(traceback.format_exception(error))[-4000:],
        # (what and when the error names: a callback's force, the time the run failed)
        "item": getattr(error, "item", None),
        "time": float(failed_at) if isinstance(failed_at, int | float) else None,
    }


def _save_summary(task: CaseTask, summary: dict[str, Any]) -> None:
    """Writes a summary file by rename (a case is done once it exists)."""
    partial = task.summary_path.with_suffix(".json.partial")
    partial.write_text(json.dumps(summary, indent=1))
    os.replace(partial, task.summary_path)


def case_warnings(events: list[dict[str, Any]]) -> list[str]:
    """The events of a case's run at the level of warnings (`simulation.EVENT_LEVELS`: an
    initial correction, a step size longer than the output interval, ...), one line per kind:
    its first message, and how many more there were. Python's warnings are not shown in the
    workers; these go into the case's summary and the study's dataset."""
    import logging

    from ..simulation import EVENT_LEVELS

    first: dict[str, str] = {}
    counts: dict[str, int] = {}
    for event in events:
        kind = event["kind"]
        if EVENT_LEVELS.get(kind, logging.INFO) < logging.WARNING:
            continue
        first.setdefault(kind, f"{kind}: {event['message']}")
        counts[kind] = counts.get(kind, 0) + 1
    return [
        text if counts[kind] == 1 else f"{text} (and {counts[kind] - 1} more)"
        for kind, text in first.items()
    ]


def _peak_memory() -> int | None:
    """The peak resident memory of this process (bytes), where the system tells it."""
    try:
        import resource
    except ImportError:
        return None
    scale = 1 if sys.platform == "darwin" else 1024  # bytes on macOS, kilobytes elsewhere
    return int(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss) * scale


def _json_number(value: Any) -> float | None:
    number = float(value)
    return number if math.isfinite(number) else None


#: The loggers of a Dask worker that report its scheduler going away: the heartbeat's closed
#: connection, and the running task's cancellation as the worker closes.
WORKER_LOGGERS = ("distributed.worker", "distributed.worker.state_machine")


def is_closing_noise(record: Any) -> bool:
    """Whether a worker's log record is caused by its cluster closing: an exception raised by a
    connection that was closed (the scheduler stopped, during a heartbeat), or a task cancelled
    (the worker stopped while a case ran)."""
    if record.exc_info and record.exc_info[1] is not None:
        error: BaseException | None = record.exc_info[1]
        while error is not None:
            if type(error).__name__ in ("CommClosedError", "StreamClosedError"):
                return True
            error = error.__cause__ or error.__context__
    return "CancelledError" in record.getMessage()


def dask_setup(worker: Any) -> None:
    """Dask's preload hook, run in each worker process of a study's own LocalCluster
    (`study._connect`) as it starts. The cluster's scheduler is the study's process, so a
    worker finds it gone only when the study closes the cluster (finished or interrupted, with
    a case running): those messages are left out of the user's terminal (an interrupted sweep
    printed a heartbeat's traceback in one run of 25, a cancelled task's warning in each)."""
    import logging

    for name in WORKER_LOGGERS:
        logging.getLogger(name).addFilter(lambda record: not is_closing_noise(record))
