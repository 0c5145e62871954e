"""Design studies: many runs of one model with parameters varied, on Dask.

    study = fm.Study(
        fm.examples.flexible_slider_crank,                 # a build function, or a model file
        {"rod_diameter": [4e-3, 6e-3, 8e-3], "crank_speed": [100.0, 150.0]},
        outputs={"deflection": "max-abs(deflection:rod:5[y])"},
        folder="crank-study",
    )
    data = study.run(workers=2)                            # an xarray.Dataset, one row a case

The cases (:mod:`flexmbd.study.sampling`: a grid, a list, random or Latin-hypercube samples)
are checked before anything runs (parameter names, key paths and values, outputs). Each case
runs as a task on a ``dask.distributed`` cluster: by default a ``LocalCluster`` of worker
processes on this machine (``workers=N``), or the scheduler of an existing cluster
(``scheduler="tcp://host:8786"``), the same code path in both. A case writes its own results
file (HDF5) and a summary into the study folder; a case that fails is recorded with its error
class and message, keeps its partial results and does not stop the others. The study gathers
the summaries into one dataset (a ``case`` dimension with the parameters as coordinates, a
``time`` dimension for ``series`` outputs), saved as ``study.nc``. Running the study again
skips the cases done (keyed by a hash of the model, the parameters and the run settings).
Dask, distributed and xarray are the optional extra ``flexmbd[dask]``.
"""

from __future__ import annotations

import json
import multiprocessing
import os
import sys
import warnings
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from .._checks import number
from .._core import ExplicitSolver, GeneralizedAlpha
from ..errors import ArgumentTypeError, InvalidParameterError, StudyError
from ..progress import ProgressBar
from .cases import (
    RUN_SETTINGS,
    CaseTask,
    ModelSource,
    _setting_text,
    case_key,
    check_case,
    check_cases,
    check_outputs,
    record_lost_case,
    refresh_outputs,
    run_case,
)
from .sampling import SAMPLINGS, make_cases

if TYPE_CHECKING:
    import numpy as np

__all__ = ["SAMPLINGS", "Study", "load_study"]

#: The file of a study's description in its folder.
DESCRIPTION = "study.json"
#: The file of the gathered dataset.
DATASET = "study.nc"


class Study:
    """A set of cases of one model (see the module).

    `model`: a build function (called with the parameters as keyword arguments, plus the
    fixed `arguments`; returning a System, a Model, an Example or a ModelFile) or the path of a
    model file (parameters are key paths into it, such as
    ``bodies.rod.section.radius``). `parameters` and `sampling`, `samples`, `seed`: see
    :func:`flexmbd.study.sampling.make_cases`. `outputs`: name -> output specification
    (:mod:`flexmbd.quantities`, e.g. ``"max-abs(deflection:rod:5[y])"``), or a list of
    specifications named by themselves. `end_time`, `step_size`, `output_interval`, `solver`
    replace the model's (an Example's or a model file's) settings.
    """

    def __init__(
        self,
        model: Callable[..., Any] | str | os.PathLike[str],
        parameters: Mapping[str, Any] | Sequence[Mapping[str, Any]],
        *,
        folder: str | os.PathLike[str],
        outputs: Mapping[str, str] | Sequence[str] = (),
        sampling: str = "grid",
        samples: int | None = None,
        seed: int = 0,
        arguments: Mapping[str, Any] | None = None,
        end_time: float | None = None,
        step_size: float | None = None,
        output_interval: float | None = None,
        solver: Any = None,
    ):
        from ..quantities import parse_output

        if callable(model):
            self.source = ModelSource(build=model, arguments=dict(arguments or {}))
        elif not isinstance(model, str | os.PathLike):  # (a bare TypeError of pathlib)
            raise ArgumentTypeError(
                f"model: a build function or a model file's path, got {type(model).__name__}",
                item="model",
            )
        else:
            if arguments:
                raise InvalidParameterError("arguments are for build functions, not model files")
            path = Path(model)
            if not path.is_file():
                raise InvalidParameterError(f"model file {str(model)!r} does not exist")
            self.source = ModelSource(path=str(path.resolve()))
        if not isinstance(folder, str | os.PathLike):
            raise ArgumentTypeError(f"folder: a path, got {type(folder).__name__}", item="folder")
        self.folder = Path(folder)
        if isinstance(outputs, str):  # (one output; it was taken a character at a time)
            outputs = [outputs]
        self.outputs = (
            dict(outputs) if isinstance(outputs, Mapping) else {spec: spec for spec in outputs}
        )
        for spec in self.outputs.values():
            parse_output(spec)
        given = {
            "end_time": end_time,
            "step_size": step_size,
            "output_interval": output_interval,
            "solver": solver,
        }
        self.settings = {k: v for k, v in given.items() if v is not None}
        # Checked here: a bad value failed every case, recorded as done (nothing left to run).
        for name in ("end_time", "step_size", "output_interval"):
            if name in self.settings:
                value = number(self.settings[name], name)
                if not value > 0:
                    raise InvalidParameterError(f"{name} must be > 0, got {value}", item=name)
                self.settings[name] = value
        if "solver" in self.settings and not isinstance(
            self.settings["solver"], GeneralizedAlpha | ExplicitSolver
        ):
            raise ArgumentTypeError(
                "solver: a flexmbd.GeneralizedAlpha or ExplicitSolver, got "
                f"{type(self.settings['solver']).__name__}",
                item="solver",
            )
        self.cases = make_cases(parameters, sampling, samples, seed)
        self.parameter_names = list(self.cases[0]) if self.cases else []
        # A swept model-file key that a run setting of the study replaces made every case
        # alike (a sweep of simulation.step_size with step_size=1e-4: two identical runs).
        overridden = {
            "end_time": ("simulation.end_time",),
            "step_size": ("simulation.step_size",),
            "output_interval": ("simulation.output_interval",),
            "solver": ("solver",),
        }
        for setting, keys in overridden.items():
            if setting not in self.settings:
                continue
            for name in self.parameter_names:
                if any(name == key or name.startswith(key + ".") for key in keys):
                    raise InvalidParameterError(
                        f"the study's {setting} replaces the swept {name!r} in every case: "
                        f"sweep one or the other",
                        item=name,
                    )
        self.source.check_names(self.parameter_names)
        _check_output_names(self.outputs, self.parameter_names)
        identity = self.source.identity()
        self.keys = [case_key(identity, case, self.settings) for case in self.cases]
        seen: dict[str, int] = {}
        for k, key in enumerate(self.keys):
            if key in seen:
                # Dask ran one task per key: the second lost its bookkeeping (a KeyError).
                raise InvalidParameterError(
                    f"cases {seen[key]} and {k} are the same case {dict(self.cases[k])}: "
                    "give each parameter combination once",
                    item=f"case {k}",
                )
            seen[key] = k

    def __repr__(self) -> str:
        names, folder = self.parameter_names, str(self.folder)
        return f"Study({len(self.cases)} cases of {names}, folder {folder!r})"

    def check(self) -> None:
        """Checks every case's values against the model (key paths and values of a model file;
        a build function builds each case): the first one refused raises, naming the case and
        the parameter or key path. The outputs are checked on the first case
        (:func:`~flexmbd.study.cases.check_outputs`)."""
        for k, case in enumerate(self.cases):
            check_case(self.source, k, case)
        if self.cases and self.outputs:
            check_outputs(self.source, 0, self.cases[0], self.outputs)

    def pending(self) -> list[int]:
        """Indices of the cases not done yet (no summary in the folder)."""
        return [k for k, key in enumerate(self.keys) if not self._summary(key).exists()]

    def _task(self, k: int) -> CaseTask:
        return CaseTask(
            index=k,
            key=self.keys[k],
            parameters=self.cases[k],
            source=self.source,
            settings=self.settings,
            outputs=self.outputs,
            folder=str((self.folder / "cases").resolve()),
        )

    def refresh(self) -> None:
        """Computes the outputs of the cases done again where the study's outputs have changed
        since they ran (a new or corrected ``outputs``), from their results files; the
        simulations do not run again. A case whose results file is gone becomes pending. The
        outputs are checked first, on the first case to refresh (`check_outputs`): a mistyped
        one raises before any summary changes."""
        checked = not self.outputs
        for k, key in enumerate(self.keys):
            path = self._summary(key)
            if not path.exists():
                continue
            try:
                summary = json.loads(path.read_text())
            except (OSError, ValueError):
                path.unlink(missing_ok=True)  # unreadable: the case runs again
                continue
            if summary.get("outputs_of") != self.outputs:
                if not checked:
                    # (a mistyped output marked every case done failed)
                    check_outputs(self.source, k, self.cases[k], self.outputs)
                    checked = True
                refresh_outputs(self._task(k), summary)

    def _summary(self, key: str) -> Path:
        return self.folder / "cases" / f"case-{key}.json"

    def run(
        self,
        workers: int | None = None,
        scheduler: str | None = None,
        progress: bool = True,
    ) -> Any:
        """Runs the cases not done yet and returns the gathered dataset (also saved as
        ``study.nc`` in the folder). `workers`: worker processes of the local cluster (default:
        the number of CPUs); `scheduler`: the address of an existing Dask scheduler instead.
        The cases to run are checked first, on the cluster's workers (each builds its models);
        nothing runs if one is refused, and the error names the case and the key path."""
        if workers is not None and (
            isinstance(workers, bool) or not isinstance(workers, int) or workers < 1
        ):
            # A LocalCluster of -2 workers waited for them forever.
            raise InvalidParameterError(
                f"workers must be a whole number of at least 1, got {workers!r}", item="workers"
            )
        self._check_folder()
        self.refresh()
        todo = self.pending()
        if todo:
            client, cluster = _connect(scheduler, workers)
            try:
                cases = [(k, self.cases[k]) for k in todo]
                refusal = _check_on_dask(client, self.source, cases, self.outputs)
                if refusal is not None:
                    raise refusal
                (self.folder / "cases").mkdir(parents=True, exist_ok=True)
                self._write_description()
                # (a run stopped before it gathers leaves no dataset of the cases before)
                (self.folder / DATASET).unlink(missing_ok=True)
                tasks = [self._task(k) for k in todo]
                for task in tasks:  # markers of an earlier run that was stopped
                    task.started_path.unlink(missing_ok=True)
                _import_in_background(GATHER_MODULES)
                _run_on_dask(client, tasks, progress, len(self.cases))
            finally:
                _disconnect(client, cluster)
        else:
            self.folder.mkdir(parents=True, exist_ok=True)
            self._write_description()
        return self.gather()

    def _model_name(self) -> str:
        """The model of the study as its description names it: the model file, or the build
        function's module and name."""
        return self.source.path or (
            f"{getattr(self.source.build, '__module__', '')}."
            f"{getattr(self.source.build, '__qualname__', '')}"
        )

    def _check_folder(self) -> None:
        """Refuses a folder that holds another study (of another model or other parameters):
        its description was replaced, and its cases could no longer be loaded. The same study
        with more cases or other outputs goes on in its folder."""
        path = self.folder / DESCRIPTION
        if self.folder.exists() and not self.folder.is_dir():
            raise InvalidParameterError(f"folder: {str(self.folder)!r} is a file", item="folder")
        if not path.is_file():
            return
        try:
            earlier = json.loads(path.read_text())
        except (OSError, ValueError):
            return  # (a damaged description is written again)
        model = self._model_name()
        if earlier.get("model") != model or earlier.get("parameters") != self.parameter_names:
            raise InvalidParameterError(
                f"the folder {str(self.folder)!r} holds another study (model "
                f"{earlier.get('model')!r}, parameters {earlier.get('parameters')}); this one "
                f"(model {model!r}, parameters {self.parameter_names}) needs a folder of its own",
                item="folder",
            )

    def _write_description(self) -> None:
        description = {
            "model": self._model_name(),
            "parameters": self.parameter_names,
            "cases": [
                {"index": k, "key": key, "parameters": case}
                for k, (key, case) in enumerate(zip(self.keys, self.cases, strict=True))
            ],
            "outputs": self.outputs,
            "settings": {k: _setting_text(v) for k, v in self.settings.items()},
        }
        (self.folder / DESCRIPTION).write_text(json.dumps(description, indent=1))

    def gather(self) -> Any:
        """The dataset of the cases done so far (cases not run: status "pending")."""
        summaries = []
        for key in self.keys:
            path = self._summary(key)
            summaries.append(json.loads(path.read_text()) if path.exists() else None)
        data = _dataset(self.cases, self.parameter_names, self.outputs, summaries)
        with warnings.catch_warnings():
            # netCDF keeps names with spaces as variables; load_study makes them coordinates.
            warnings.simplefilter("ignore")
            data.to_netcdf(self.folder / DATASET, engine="scipy")
        return data


#: How often the scheduler of a study's own LocalCluster runs a task again after its worker
#: died (Dask's default 3): a case that kills its worker (out of memory, a crash in native
#: code) would kill it again, so it is recorded as failed at once (`_run_on_dask`).
ALLOWED_FAILURES = 0

#: Times a batch whose worker died before it started goes to the workers again.
LOST_BATCH_ATTEMPTS = 4

#: Dask settings of the LocalCluster a study starts: no statistical profiler, no GIL monitor,
#: no retries of a task whose worker died.
QUIET_WORKERS = {
    "distributed.worker.profile.enabled": False,
    "distributed.admin.system-monitor.gil.enabled": False,
    "distributed.scheduler.allowed-failures": ALLOWED_FAILURES,
}


#: The modules `Study.gather` imports (xarray, pandas, scipy's netCDF writer: 0.4-0.7 s),
#: imported while the cases run instead of after the last one (serial time of every study).
GATHER_MODULES = ("xarray", "scipy.io")


def _import_in_background(modules: Sequence[str]) -> None:
    """Imports `modules` in a daemon thread (the import lock makes a later import of one
    wait for it to finish); an import that fails here fails again, with its message, where
    the module is used."""
    import importlib
    import threading

    def load() -> None:
        for name in modules:
            try:
                importlib.import_module(name)
            except Exception:  # noqa: BLE001,S110 - reported by the import where it is used
                pass

    threading.Thread(target=load, name="flexmbd-study-imports", daemon=True).start()


def _disconnect(client: Any, cluster: Any) -> None:
    """Closes `client` and stops the local `cluster` (if any) in the background."""
    client.close()
    if cluster is not None:
        _close_in_background(cluster)


def _connect(scheduler: str | None, workers: int | None) -> tuple[Any, Any]:
    """A Dask client of `scheduler`'s cluster, or of a LocalCluster of `workers` processes
    (default: the number of CPUs) started here: (client, the local cluster or None)."""
    import dask
    from dask.distributed import Client, LocalCluster

    if scheduler is not None:
        return Client(scheduler), None
    if getattr(multiprocessing.current_process(), "_inheriting", False):
        # A spawned process imports the main script before it runs (multiprocessing's own
        # test for the same mistake): here it is a worker of this study's cluster.
        raise StudyError(f"a worker process started a study as it imported the script: {UNGUARDED}")
    count = workers or os.cpu_count() or 1
    _wait_for_closing()
    # The cases are CPU-bound and the cluster is this study's own: its processes do not
    # sample the stacks (every 10 ms) or the GIL (every 1 ms) of the running cases.
    try:
        with dask.config.set(QUIET_WORKERS):
            cluster = LocalCluster(
                n_workers=count,
                threads_per_worker=1,
                processes=True,
                dashboard_address=None,
                # Workers import flexmbd as they start, in parallel, not at their first case;
                # its `dask_setup` quiets what they log as the cluster closes.
                preload=["flexmbd.study.cases"],
            )
    except Exception as error:
        script = getattr(sys.modules.get("__main__"), "__file__", None)
        hint = f"; if {script!r} runs the study, {UNGUARDED}" if script else ""
        raise StudyError(
            f"the local cluster's {count} worker process(es) did not start ({error}){hint}"
        ) from error
    try:
        return Client(cluster), cluster
    except BaseException:
        cluster.close()
        raise


#: Batches of a study's cases: each takes the cases left over `GUIDED_FACTOR` times the
#: workers (guided self-scheduling). The first batches are large (Dask's cost per task, about
#: 6 ms of a 2-core machine's time, is paid a few times per worker, not per case), the last
#: are single cases, so the workers finish within about one case of each other.
GUIDED_FACTOR = 2


def batch_sizes(cases: int, workers: int) -> list[int]:
    """The sizes of the batches `cases` go to `workers` in (decreasing; at least 1 case)."""
    sizes = []
    left = cases
    while left > 0:
        size = max(1, -(-left // (GUIDED_FACTOR * max(1, workers))))
        sizes.append(size)
        left -= size
    return sizes


def _batches(items: list[Any], workers: int) -> list[list[Any]]:
    """`items` in the batches of `batch_sizes` (no worker known yet: as for one)."""
    batches, start = [], 0
    for size in batch_sizes(len(items), workers):
        batches.append(items[start : start + size])
        start += size
    return batches


def _worker_count(client: Any) -> int:
    """The number of workers the scheduler knows (all of them: newer Dask lists only some
    unless asked)."""
    try:
        info = client.scheduler_info(n_workers=-1)
    except TypeError:  # Dask before the n_workers argument lists them all
        info = client.scheduler_info()
    return len(info.get("workers", {}))


def _check_on_dask(
    client: Any,
    source: ModelSource,
    cases: list[tuple[int, Mapping[str, Any]]],
    outputs: Mapping[str, str],
) -> Exception | None:
    """Checks `cases` (index, parameters) on the cluster's workers (`check_cases`: each
    builds its models, in parallel, warming up the workers for the run; the first batch checks
    the `outputs` on its first case) and returns the refusal of the first case refused, or
    None."""
    batches = _batches(cases, _worker_count(client))
    futures = [
        client.submit(
            check_cases,
            source,
            batch,
            outputs if k == 0 else None,
            key=f"flexmbd-check-{k}",
            pure=False,
        )
        for k, batch in enumerate(batches)
    ]
    refusals, lost = [], []
    for batch, future in zip(batches, futures, strict=True):
        try:
            refusals.append(future.result())
        except Exception as death:  # noqa: BLE001 - Dask's KilledWorker, or a lost worker
            lost.append(([k for k, _ in batch], death))
    if lost:
        indices = sorted(k for batch, _ in lost for k in batch)
        raise StudyError(
            f"a worker process died while building the models of the cases {indices} to check "
            f"them (out of memory, a crash in native code, an exit in the build function: "
            f"{type(lost[0][1]).__name__}); build one of them alone to see why"
        ) from lost[0][1]
    return next((refusal for refusal in refusals if refusal is not None), None)


def run_cases(tasks: list[CaseTask]) -> list[dict[str, Any]]:
    """Runs a batch of cases one after the other (`run_case`: each writes its own files and
    records its own failure) and returns their summaries."""
    return [run_case(task) for task in tasks]


def _run_on_dask(client: Any, tasks: list[CaseTask], progress: bool, total: int) -> None:
    """Runs `tasks` on `client`'s cluster and reports cases done, failed and the time left.

    A batch whose worker process died (Dask gives up on it: at once on a study's own
    cluster, `ALLOWED_FAILURES`; after its retries on another) lost the case that was running,
    the one started (`CaseTask.started_path`) without a summary: it is recorded as failed here
    (`record_lost_case`), and the cases after it go to the workers again as a batch of their
    own. A batch that had not started (Dask also gives up on the tasks queued on the worker
    that died) goes again whole, up to `LOST_BATCH_ATTEMPTS` times."""
    from dask.distributed import as_completed

    bar = ProgressBar("cases") if progress else None
    finished = failed = 0

    def count(summaries: list[dict[str, Any]]) -> None:
        nonlocal finished, failed
        finished += len(summaries)
        failed += sum(summary["status"] != "complete" for summary in summaries)
        if bar is not None:
            # The fraction of the cases run now (the time left is theirs); all counted.
            done = total - len(tasks) + finished
            bar.update(finished / len(tasks), f"{done}/{total} cases, {failed} failed")

    def submit(batch: list[CaseTask], attempt: int = 0) -> Any:
        key = f"flexmbd-cases-{batch[0].key}" + (f"-{attempt}" if attempt else "")
        future = client.submit(run_cases, batch, key=key, pure=False)
        batches[future.key] = (batch, attempt)
        return future

    batches: dict[str, tuple[list[CaseTask], int]] = {}
    try:
        running = as_completed([submit(b) for b in _batches(tasks, _worker_count(client))])
        for future in running:
            batch, attempt = batches.pop(future.key)
            try:
                summaries = future.result()
            except Exception as death:  # noqa: BLE001 - Dask's KilledWorker, or a lost worker
                left = [task for task in batch if not task.summary_path.exists()]
                summaries = [json.loads(t.summary_path.read_text()) for t in batch if t not in left]
                lost = [task for task in left if task.started_path.exists()][:1]
                if left and not lost and attempt + 1 >= LOST_BATCH_ATTEMPTS:
                    lost = left[:1]
                summaries += [record_lost_case(task, death) for task in lost]
                rest = [task for task in left if task not in lost]
                if rest:
                    running.add(submit(rest, attempt + 1))
            # Released at once: a finished batch held by the client would be run again if its
            # worker died later.
            future.release()
            count(summaries)
    finally:
        if bar is not None:
            bar.close(failed=bar.fraction < 1.0)


#: How a script that runs a study keeps the cluster's spawned workers, which import it as they
#: start, from running the study again.
UNGUARDED = (
    'guard the study with `if __name__ == "__main__":` (the worker processes are spawned and '
    "import the script: see docs/studies.md)"
)


#: Threads stopping the local clusters of earlier studies (`_close_in_background`).
_CLOSING: list[Any] = []


def _close_in_background(cluster: Any) -> None:
    """Stops a local cluster in a thread: its worker processes shut down (0.1-0.4 s) while
    the study gathers its dataset. The thread is not a daemon, so the interpreter waits for
    it before it exits; the next local cluster waits for it too (`_wait_for_closing`)."""
    import threading

    thread = threading.Thread(target=cluster.close, name="flexmbd-cluster-close")
    thread.start()
    _CLOSING.append(thread)


def _wait_for_closing() -> None:
    """Waits until the local clusters of earlier studies have stopped. A cluster keeps Dask's
    log handlers at warnings until it has closed and then restores their level: closing while
    the next one starts, it restored them over the new cluster's (whose start then found
    them quiet already), and every scheduler and nanny message of the next study was printed;
    its scheduler's HTTP server also still held the port the next one asks for."""
    while _CLOSING:
        _CLOSING.pop().join()


def _dataset(
    cases: list[dict[str, Any]],
    names: list[str],
    outputs: Mapping[str, str],
    summaries: list[dict[str, Any] | None],
) -> Any:
    """One xarray Dataset of the cases: parameters as coordinates of ``case``, scalar outputs
    per case, ``series`` outputs over ``time`` (NaN past a failed case's last record)."""
    import numpy as np
    import xarray as xr

    from ..quantities import output_unit

    n = len(cases)
    # The times of every case's records, merged (cases that record at other times, another
    # output interval or an adaptive solver's steps, were put on the longest case's times).
    own = [
        np.asarray(s["time"], dtype=float) if s and s.get("time") else np.zeros(0)
        for s in summaries
    ]
    merged = np.unique(np.concatenate([np.zeros(0), *own]))
    if len(merged) > 1:
        keep = np.concatenate([[True], np.diff(merged) > 1e-12 * (1.0 + np.abs(merged[1:]))])
        merged = merged[keep]
    times = merged
    coords: dict[str, Any] = {"case": np.arange(n)}
    for name in names:
        coords[name] = ("case", _column([case[name] for case in cases]))
    variables: dict[str, Any] = {}
    for name in outputs:
        values = [None if s is None else s["outputs"].get(name) for s in summaries]
        if any(isinstance(v, list) for v in values):
            table = np.full((n, len(times)), np.nan)
            for k, v in enumerate(values):
                if isinstance(v, list):
                    row = np.array([np.nan if x is None else x for x in v], dtype=float)
                    at = own[k][: len(row)]
                    right = np.clip(np.searchsorted(times, at), 0, max(len(times) - 1, 0))
                    left = np.clip(right - 1, 0, None)
                    closer = np.abs(times[left] - at) < np.abs(times[right] - at)
                    columns = np.where(closer, left, right)
                    near = np.abs(times[columns] - at) <= 1e-12 * (1.0 + np.abs(at))
                    table[k, columns[near]] = row[: len(at)][near]
            variables[name] = (("case", "time"), table)
        else:
            variables[name] = ("case", np.array([np.nan if v is None else v for v in values]))
    if any(isinstance(v, tuple) and "time" in v[0] for v in variables.values()):
        coords["time"] = np.asarray(times, dtype=float)
    status = ["pending" if s is None else s["status"] for s in summaries]
    variables["status"] = ("case", np.array(status, dtype=str))
    errors = [None if s is None else s["error"] for s in summaries]
    variables["error"] = (
        "case",
        np.array(["" if e is None else f"{e['class']}: {e['message']}" for e in errors], dtype=str),
    )
    variables["warnings"] = (
        "case",
        np.array(
            ["" if s is None else "\n".join(s.get("warnings", [])) for s in summaries], dtype=str
        ),
    )
    variables["elapsed"] = (
        "case",
        np.array([np.nan if s is None else s["elapsed"] for s in summaries], dtype=float),
    )
    data = xr.Dataset(variables, coords=coords)
    data.attrs["outputs"] = json.dumps(dict(outputs))
    for name, spec in outputs.items():
        data[name].attrs["units"] = output_unit(spec)
    return data


#: Names of the study dataset's own variables and dimensions, which outputs cannot take.
RESERVED_NAMES = ("case", "time", "status", "error", "warnings", "elapsed")


def _check_output_names(outputs: Mapping[str, str], parameters: list[str]) -> None:
    """Refuses output names the dataset uses already (its own variables, a parameter's
    coordinate) or that are empty: the output was overwritten, or the dataset could not be
    made after every case had run."""
    for name in outputs:
        if not isinstance(name, str) or not name.strip():
            raise InvalidParameterError(
                f"outputs: an output needs a name, got {name!r}", item="outputs"
            )
        if name in RESERVED_NAMES or name in parameters:
            what = "a parameter" if name in parameters else "a variable of the study's dataset"
            raise InvalidParameterError(
                f"output {name!r}: the name is {what} ({', '.join(RESERVED_NAMES)} and the "
                "parameters are taken); give the output another name",
                item=name,
            )


def _column(values: list[Any]) -> np.ndarray:
    """Parameter values as an array: numbers as floats, anything else (text, lists) as
    text."""
    import numpy as np

    if all(isinstance(v, (int, float)) for v in values):
        return np.array(values, dtype=float)
    return np.array([str(v) for v in values], dtype=str)


def load_study(folder: str | os.PathLike[str]) -> Any:
    """The dataset of a study folder (``study.nc``) and its description (``study.json``):
    (xarray.Dataset, dict)."""
    import xarray as xr

    folder = Path(folder)
    if not (folder / DESCRIPTION).is_file():
        raise InvalidParameterError(f"{str(folder)!r} is not a study folder (no {DESCRIPTION})")
    description = json.loads((folder / DESCRIPTION).read_text())
    if not (folder / DATASET).is_file() or _stale(folder):
        # A study stopped before it gathered (Ctrl-C), or still running: the cases done,
        # from their summaries.
        return _gathered_from_summaries(folder, description), description
    with xr.open_dataset(folder / DATASET, engine="scipy") as data:
        data = data.load()
    parameters = [n for n in description["parameters"] if n in data.data_vars]
    return data.set_coords(parameters), description


def _stale(folder: Path) -> bool:
    """Whether ``study.nc`` is older than the description or a case's summary (written by a
    run since: one stopped before it gathered, or still going)."""
    made = (folder / DATASET).stat().st_mtime
    newer = [folder / DESCRIPTION, *(folder / "cases").glob("case-*.json")]
    return any(path.stat().st_mtime > made for path in newer if path.is_file())


def _gathered_from_summaries(folder: Path, description: dict[str, Any]) -> Any:
    """The dataset of a study folder without ``study.nc``, from the summaries of the cases
    done (the others "pending"), also saved as ``study.nc``."""
    from ..errors import MissingFileError

    cases = description.get("cases")
    if not isinstance(cases, list):
        raise MissingFileError("study dataset", folder / DATASET)
    summaries = []
    for case in cases:
        path = folder / "cases" / f"case-{case['key']}.json"
        try:
            summaries.append(json.loads(path.read_text()) if path.is_file() else None)
        except (OSError, ValueError):
            summaries.append(None)
    data = _dataset(
        [case["parameters"] for case in cases],
        list(description["parameters"]),
        dict(description["outputs"]),
        summaries,
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        data.to_netcdf(folder / DATASET, engine="scipy")
    return data


__all__ += ["DATASET", "DESCRIPTION", "RESERVED_NAMES", "RUN_SETTINGS"]
