"""HDF5 results files, written while the simulation runs: an interrupted, killed or failed run
keeps every record up to its last flush (about every 0.1 s of wall time).

Layout (``version`` 1)
----------------------
Root attributes: ``format = "flexmbd-results"``, ``version``, ``writer`` (``"flexmbd X.Y"``),
``layout`` (the model description, :meth:`Model.describe`, as JSON), ``metadata`` (a JSON
object given by the caller: model file, solver, end time, step size, ...) and ``units`` (JSON:
SI, ``{"length": "m", "mass": "kg", "time": "s", "angle": "rad", "force": "N"}``).

Datasets, time first, one row per record, extensible along the first axis (SI units):

* ``time`` (n,) s; ``coordinates``, ``velocities``, ``accelerations`` (n, coordinates);
  ``multipliers`` (n, constraints); ``reactions`` (n, joints, 6): force and torque on the
  joint's first body at its first marker, in that marker's axes; ``sensors`` (n, width);
  ``energy`` (n, 2): kinetic and potential, J; ``constraint_violation`` (n,).
* ``records`` (1,) int64: the number of rows that are complete. Rows are flushed to the file
  before this count is raised, so a reader trusts the count, never the dataset lengths.
* ``statistics``, ``events``, ``redundancy`` and ``status``: JSON texts (UTF-8 bytes in
  extensible uint8 datasets). ``status`` is ``{"state": "running" | "complete" | "failed" |
  "interrupted", "error": class name or null, "message": ...}``; a killed run stays
  ``"running"``.

Group ``flexible``: one group per deformable body, named by its body index, in the layout of a
body file (:mod:`flexmbd.fe.body_file`), so that node positions, stresses and animations can
be computed from the file alone.

The file is written in HDF5's single-writer/multiple-reader mode, whose ordered writes keep it
readable after the writer is killed; :func:`read_results` opens it accordingly. Nothing in the
file is executed or unpickled on reading.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from . import _core, errors
from .errors import FlexmbdError, InvalidModelError
from .fe.body_file import read_body_group, write_body_group
from .result import Result

#: Value of the root attribute ``format`` of a results file.
RESULTS_FILE_FORMAT = "flexmbd-results"
#: Layout version this flexmbd writes.
RESULTS_FILE_VERSION = 1
#: The units of every value in a results file (root attribute ``units``): SI.
RESULTS_UNITS = {"length": "m", "mass": "kg", "time": "s", "angle": "rad", "force": "N"}

#: Record datasets: name -> shape of one record, from the model description.
_RECORD_FIELDS = (
    "time",
    "coordinates",
    "velocities",
    "accelerations",
    "multipliers",
    "reactions",
    "sensors",
    "energy",
    "constraint_violation",
)
_TEXT_FIELDS = ("statistics", "events", "redundancy", "status")


def _record_shapes(layout: dict[str, Any]) -> dict[str, tuple[int, ...]]:
    n, m = layout["coordinate_count"], layout["constraint_count"]
    width = sum(int(sensor.get("size", 0)) for sensor in layout["sensors"])
    return {
        "time": (),
        "coordinates": (n,),
        "velocities": (n,),
        "accelerations": (n,),
        "multipliers": (m,),
        "reactions": (len(layout["joints"]), 6),
        "sensors": (width,),
        "energy": (2,),
        "constraint_violation": (),
    }


def _json(value: Any) -> str:
    """JSON of results metadata; NumPy scalars and arrays become numbers and lists."""

    def convert(item: Any) -> Any:
        if isinstance(item, np.ndarray):
            return item.tolist()
        if isinstance(item, np.generic):
            return item.item()
        raise TypeError(f"cannot store {type(item).__name__} in a results file")

    return json.dumps(value, default=convert)


class ResultsWriter:
    """Writes a results file record by record (see the module docstring for the layout).

    ``append`` takes the raw record chunks that :func:`flexmbd.simulate` delivers during the
    run; ``finish`` writes the remaining records and the final statistics, events and status.
    The file is created next to ``path`` under its own name; an existing file is replaced.
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        model: _core.Model,
        *,
        metadata: dict[str, Any] | None = None,
    ):
        self.path = Path(path)
        self.layout = model.describe()
        self._shapes = _record_shapes(self.layout)
        self.records = 0
        file = h5py.File(self.path, "w", libver="latest", track_order=True)
        self._file = file
        try:
            file.attrs["format"] = RESULTS_FILE_FORMAT
            file.attrs["version"] = np.int64(RESULTS_FILE_VERSION)
            file.attrs["writer"] = f"flexmbd {_core.__version__}"
            file.attrs["layout"] = _json(self.layout)
            file.attrs["metadata"] = _json(metadata or {})
            file.attrs["units"] = _json(RESULTS_UNITS)
            for name, shape in self._shapes.items():
                chunk_rows = max(1, min(1024, (1 << 16) // (8 * max(1, int(np.prod(shape))))))
                file.create_dataset(
                    name,
                    shape=(0, *shape),
                    maxshape=(None, *shape),
                    chunks=(chunk_rows, *shape) if all(shape) else None,
                    dtype="f8",
                )
            file.create_dataset("records", data=np.zeros(1, dtype=np.int64))
            for name in _TEXT_FIELDS:
                file.create_dataset(name, shape=(0,), maxshape=(None,), dtype="u1", chunks=(4096,))
            flexible = file.create_group("flexible")
            for index, body in sorted(getattr(model, "_flexible", {}).items()):
                write_body_group(flexible.create_group(str(index)), body)
            self._write_text("status", {"state": "running", "error": None, "message": ""})
            file.swmr_mode = True
            file.flush()
        except BaseException:
            file.close()
            raise

    def _write_text(self, name: str, value: Any) -> None:
        data = np.frombuffer(_json(value).encode("utf-8"), dtype=np.uint8)
        dataset = self._file[name]
        dataset.resize((len(data),))
        dataset[:] = data

    def append(self, raw: dict[str, Any]) -> None:
        """Appends the records of a raw chunk (the dict of ``_core.simulate``'s ``records``
        callback), with its statistics and events, and makes them durable."""
        count = len(raw["time"])
        if count:
            start, end = self.records, self.records + count
            for name in _RECORD_FIELDS:
                values = np.asarray(raw[name], dtype=np.float64).reshape(count, *self._shapes[name])
                dataset = self._file[name]
                dataset.resize(end, axis=0)
                dataset[start:end] = values
        self._write_text("statistics", dict(raw["statistics"]))
        self._write_text("events", list(raw.get("events", [])))
        self._write_text("redundancy", raw.get("redundancy"))
        # The rows reach the file before the count that makes them visible.
        self._file.flush()
        if count:
            self.records += count
            self._file["records"][0] = self.records
            self._file.flush()

    def finish(self, result: Result) -> None:
        """Writes the records of ``result`` not yet in the file, the final statistics and
        events, and the status (complete, failed or interrupted); closes the file."""
        chunk: dict[str, Any] = {
            name: result._record(name)[self.records :] for name in _RECORD_FIELDS
        }
        chunk["statistics"] = result.statistics
        chunk["events"] = result.events
        chunk["redundancy"] = result.redundancy
        self.append(chunk)
        error = result.error
        if error is None:
            status = {"state": "complete", "error": None, "message": ""}
        else:
            state = "interrupted" if isinstance(error, errors.SimulationInterrupted) else "failed"
            status = {"state": state, "error": type(error).__name__, "message": str(error)}
        self._write_text("status", status)
        self.close()

    def close(self) -> None:
        """Closes the file (what was appended stays; the status stays "running" unless
        :meth:`finish` wrote it)."""
        if self._file.id.valid:
            self._file.flush()
            self._file.close()

    def __enter__(self) -> ResultsWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _open(path: Path) -> h5py.File:
    if not path.exists():
        raise FileNotFoundError(2, "No such results file", str(path))
    if not h5py.is_hdf5(path):
        raise InvalidModelError(
            f"{path} is not a flexmbd results file (not an HDF5 file)", item=f"file '{path}'"
        )
    try:
        # A file whose writer was killed is still marked as open for writing; the
        # single-writer/multiple-reader mode reads it.
        return h5py.File(path, "r", swmr=True)
    except OSError:
        return h5py.File(path, "r")


def _text(file: h5py.File, name: str) -> Any:
    """A JSON text field, or None when it is absent, empty or torn: the writer of a running
    simulation rewrites these fields with every chunk (resize, then write), and a reader in
    between sees a text that does not decode; it reads as not written yet."""
    data = file[name][:] if name in file else np.zeros(0, np.uint8)
    if not len(data):
        return None
    try:
        return json.loads(data.tobytes().decode("utf-8"))
    except ValueError:  # JSONDecodeError and UnicodeDecodeError
        return None


def read_results_metadata(path: str | os.PathLike[str]) -> dict[str, Any]:
    """The header of a results file without its records: ``layout``, ``metadata``,
    ``records``, ``status``, ``statistics``, ``events``, ``redundancy``, ``flexible`` (body
    indices) and ``version``."""
    path = Path(path)
    with _open(path) as file:
        _check_header(file, path)
        return {
            "version": int(file.attrs["version"]),
            "writer": str(file.attrs.get("writer", "")),
            "layout": json.loads(file.attrs["layout"]),
            "metadata": json.loads(file.attrs["metadata"]),
            "units": json.loads(file.attrs.get("units", "{}")),
            "records": int(file["records"][0]),
            "status": _text(file, "status"),
            "statistics": _text(file, "statistics") or {},
            "events": _text(file, "events") or [],
            "redundancy": _text(file, "redundancy"),
            "flexible": sorted(int(key) for key in file["flexible"]),
        }


def _check_header(file: h5py.File, path: Path) -> None:
    found = file.attrs.get("format")
    if isinstance(found, bytes):
        found = found.decode("utf-8", "replace")
    if found != RESULTS_FILE_FORMAT:
        raise InvalidModelError(
            f"{path} is not a flexmbd results file (format {found!r}, expected "
            f"{RESULTS_FILE_FORMAT!r})",
            item=f"file '{path}'",
        )
    version = int(file.attrs.get("version", 0))
    if version > RESULTS_FILE_VERSION:
        raise InvalidModelError(
            f"{path} was written by a newer flexmbd: version {version} > "
            f"{RESULTS_FILE_VERSION}; update flexmbd to read it",
            item=f"file '{path}'",
        )
    for name in (*_RECORD_FIELDS, "records", "status"):
        if name not in file:
            raise InvalidModelError(
                f"{path}: the results file has no dataset '{name}'", item=f"file '{path}'"
            )


def read_results(path: str | os.PathLike[str]) -> Result:
    """Reads a results file into a :class:`flexmbd.Result`: every complete record, the
    statistics and events, and the deformable bodies' data. A run that did not complete
    gives ``success`` False and an ``error`` of the recorded class (a killed run:
    :class:`flexmbd.SimulationInterrupted` saying so)."""
    path = Path(path)
    with _open(path) as file:
        _check_header(file, path)
        count = int(file["records"][0])
        raw: dict[str, Any] = {name: file[name][:count] for name in _RECORD_FIELDS}
        raw["statistics"] = _text(file, "statistics") or {}
        raw["events"] = _text(file, "events") or []
        raw["redundancy"] = _text(file, "redundancy")
        status = _text(file, "status") or {"state": "running"}
        layout = json.loads(file.attrs["layout"])
        flexible = {
            int(key): read_body_group(group, path) for key, group in file["flexible"].items()
        }
    error: FlexmbdError | None = None
    if status["state"] != "complete":
        last = f"{raw['time'][-1]:g} s" if count else "its start"
        if status["state"] == "running":
            error = errors.SimulationInterrupted(
                f"{path}: the run did not finish (killed or still running); records up to "
                f"t = {last} are in the file"
            )
        else:
            kind = getattr(errors, str(status.get("error")), None)
            if not (isinstance(kind, type) and issubclass(kind, FlexmbdError)):
                kind = errors.SimulationError
            error = kind(status.get("message", ""))
    return Result(raw, layout, error=error, flexible=flexible)
