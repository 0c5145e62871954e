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
  ``multipliers`` (n, constraints); ``reactions`` (n, joints, 6): force and torque that the
  joint exerts on the body of its second marker, about that marker's origin, in that
  marker's axes (`Result.reaction`); ``sensors`` (n, width);
  ``energy`` (n, 4): kinetic, potential (strain included) and strain energy, J, and the
  power of the forces no potential accounts for, W (`Result.nonconservative_power`; files
  written before it was recorded have (n, 3), before the strain energy (n, 2));
  ``constraint_violation`` (n,); ``discrete`` (n, discrete variables): the unwrapped angles
  of rotational springs and angle actuators and the actuators' saturation states, from which
  a run continued from a record goes on (absent in files written before it was recorded).
* ``records`` (1,) int64: the number of rows that are complete. Rows are flushed to the file
  before this count is raised, so a reader trusts the count, never the dataset lengths.
* ``statistics``, ``events``, ``redundancy`` and ``status``: JSON texts (UTF-8 bytes in
  extensible uint8 datasets). ``status`` is ``{"state": "running" | "complete" | "failed" |
  "interrupted", "error": class name or null, "message": ...}``, and for a failed or
  interrupted run ``"item"`` and ``"time"``, those of its error (read back onto the error);
  a killed run stays ``"running"``.

Group ``flexible``: one group per deformable body, named by its body index, in the layout of a
body file (:mod:`flexmbd.fe.body_file`; arrays of 64 KiB or more gzip-compressed), so that node
positions, stresses and animations can be computed from the file alone. Bodies of the same
content (identical links of a chain) are stored once: the later indices are HDF5 hard links to
the first one's group (files written before had a copy per index; both read alike).

The file is written in HDF5's single-writer/multiple-reader mode, whose ordered writes keep it
readable after the writer is killed; :func:`read_results` opens it accordingly. Nothing in the
file is executed or unpickled on reading.
"""

from __future__ import annotations

import ctypes
import errno
import fcntl
import json
import math
import os
import resource
import time
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from . import _core, errors
from ._hdf5 import global_heap_damage
from .errors import (
    ArgumentTypeError,
    FlexmbdError,
    InvalidParameterError,
    MissingFileError,
    NotAResultsFileError,
    ResultsFileError,
)
from .fe.body_file import copy_body_groups, read_body_group
from .result import Result

#: Value of the root attribute ``format`` of a results file.
RESULTS_FILE_FORMAT = "flexmbd-results"
#: Layout version this flexmbd writes.
RESULTS_FILE_VERSION = 1
#: The units of every value in a results file (root attribute ``units``): SI.
RESULTS_UNITS = {"length": "m", "mass": "kg", "time": "s", "angle": "rad", "force": "N"}

#: Room left free on the disk (and below the file size limit) beyond what the next records
#: need, for HDF5's metadata, bytes.
_SPACE_MARGIN = 1 << 20

#: The bytes of records a writer with a ``write_interval`` holds back at most.
_PENDING_BYTES = 64 << 20

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
    "discrete",
)
_TEXT_FIELDS = ("statistics", "events", "redundancy", "status")
#: Record datasets that files written before them lack (read as zero columns).
_LATER_FIELDS = ("discrete",)


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
        "energy": (4,),
        "constraint_violation": (),
        "discrete": (int(layout.get("discrete_count", 0)),),
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


def check_metadata(metadata: Any) -> None:
    """Refuses run metadata a results file cannot store (`InvalidParameterError` naming the
    entry): None or a dict of JSON values (NumPy numbers and arrays too)."""
    if metadata is None:
        return
    if not isinstance(metadata, dict):
        raise InvalidParameterError(
            f"metadata must be a dict, got {type(metadata).__name__}", item="metadata"
        )
    for key, value in metadata.items():
        try:
            _json({key: value})
        except (TypeError, ValueError) as error:
            raise InvalidParameterError(
                f"metadata[{key!r}]: {error} (JSON values only: numbers, text, lists, dicts)",
                item=f"metadata[{key!r}]",
            ) from None


def _is_results_file(path: Path) -> bool:
    """Whether `path` is a flexmbd results file (an HDF5 file with the format attribute)."""
    try:
        if not path.is_file() or not h5py.is_hdf5(path):
            return False
        with _open(path, check=False) as file:
            found = file.attrs.get("format")
    except (OSError, ResultsFileError):
        return False
    if isinstance(found, bytes):
        found = found.decode("utf-8", "replace")
    return found == RESULTS_FILE_FORMAT


def _writable_target(path: Path, protect: tuple[Path, ...]) -> None:
    """Refuses a results path that is a folder, whose folder is missing, that is one of the
    `protect`ed files (the model file of the run), that holds another kind of file, or that
    the system refuses (a NUL character, a name too long, a folder that cannot be read)."""
    where = f"file '{path}'"
    if "\x00" in str(path):
        raise ResultsFileError(
            f"cannot write {str(path)!r}: a file name cannot hold a NUL character", item=where
        )
    try:
        _check_target(path, protect, where)
    except ResultsFileError:
        raise
    except OSError as error:
        raise ResultsFileError(
            f"cannot write {path}: {error.strerror or error}", item=where
        ) from error


def _check_target(path: Path, protect: tuple[Path, ...], where: str) -> None:
    if path.is_dir():
        raise ResultsFileError(f"{path} is a folder; give a file name such as run.h5", item=where)
    if not path.parent.is_dir():
        raise ResultsFileError(
            f"cannot write {path}: its folder {path.parent} does not exist", item=where
        )
    for other in protect:
        if path.exists() and other.exists() and os.path.samefile(path, other):
            raise ResultsFileError(
                f"{path} is the model file of the run; the results need another file name",
                item=where,
            )
    if path.exists() and not _is_results_file(path):
        raise ResultsFileError(
            f"{path} exists and is not a flexmbd results file: it is not replaced (give another "
            "file name, or remove it first)",
            item=where,
        )


class _Lock:
    """An exclusive lock on a results path for the time of a run: the file
    ``.<name>.lock`` beside it, locked with ``flock`` (released by the system when the
    process ends, also when it is killed) and holding the writer's process id."""

    def __init__(self, path: Path):
        self.path = path.with_name(f".{path.name}.lock")
        try:
            self.fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
        except OSError as error:
            raise ResultsFileError(
                f"cannot write {path}: {error.strerror} ({self.path})", item=f"file '{path}'"
            ) from error
        try:
            fcntl.flock(self.fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as error:
            owner = os.pread(self.fd, 64, 0).decode("ascii", "replace").strip() or "?"
            os.close(self.fd)
            raise ResultsFileError(
                f"{path} is being written by another run (process {owner}); wait for it or give "
                "another file name",
                item=f"file '{path}'",
            ) from error
        os.ftruncate(self.fd, 0)
        os.pwrite(self.fd, f"{os.getpid()}\n".encode("ascii"), 0)

    def release(self) -> None:
        if self.fd < 0:
            return
        try:
            os.unlink(self.path)
        except OSError:
            pass
        os.close(self.fd)
        self.fd = -1


class ResultsWriter:
    """Writes a results file record by record (see the module docstring for the layout).

    ``append`` takes the raw record chunks that :func:`flexmbd.simulate` delivers during the
    run; ``finish`` writes the remaining records and the final statistics, events and status.

    Nothing is lost or replaced by accident:

    - the path may not be a folder, nor in a missing folder, nor one of the `protect`ed
      files (the run's model file), nor an existing file of another kind;
    - a lock beside it refuses a second writer of the same path (``ResultsFileError`` naming
      the process that writes it);
    - over an earlier results file the records go to ``NAME.partial`` first, which replaces
      it only once the run has taken its first step (or has completed); a run that fails
      before leaves the earlier file as it was, and its own records in
      ``STEM.failed.SUFFIX``;
    - a write that fails (a full disk, a quota, an I/O error) raises ``ResultsFileError``;
      the file keeps every record committed before (the record count is raised only after
      the records reached the file).
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        model: _core.Model,
        *,
        metadata: dict[str, Any] | None = None,
        protect: tuple[str | os.PathLike[str], ...] = (),
        write_interval: float = 0.0,
    ):
        self.path = Path(path)
        if not (isinstance(write_interval, int | float) and 0.0 <= write_interval < math.inf):
            raise errors.InvalidParameterError(
                f"write_interval must be a finite number of seconds >= 0, got {write_interval!r}",
                item="write_interval",
            )
        self.write_interval = float(write_interval)
        # Chunks delivered and not yet written (with write_interval > 0), their bytes, and
        # when the file was last written.
        self._pending: list[dict[str, Any]] = []
        self._pending_bytes = 0
        self._written_at = time.monotonic()
        self.layout = model.describe()
        self._shapes = _record_shapes(self.layout)
        self.records = 0
        self.failure: ResultsFileError | None = None
        _writable_target(self.path, tuple(Path(p) for p in protect))
        self._lock = _Lock(self.path)
        self.partial = self.path.with_name(f"{self.path.name}.partial")
        # With no earlier results at the path there is nothing to keep: write it directly.
        self.placed = not self.path.exists()
        try:
            target = self.path if self.placed else self.partial
            file = h5py.File(target, "w", libver="latest", track_order=True)
        except OSError as error:
            self._lock.release()
            raise ResultsFileError(
                f"cannot write {self.path}: {error}", item=f"file '{self.path}'"
            ) from error
        self._file = file
        # The datasets written at every delivery, opened once (a lookup by name per write
        # was a fifth of the writing's time).
        self._datasets: dict[str, Any] = {}
        # The text fields as last written.
        self._texts: dict[str, bytes] = {}
        try:
            file.attrs["format"] = RESULTS_FILE_FORMAT
            file.attrs["version"] = np.int64(RESULTS_FILE_VERSION)
            file.attrs["writer"] = f"flexmbd {_core.__version__}"
            file.attrs["layout"] = _json(self.layout)
            file.attrs["metadata"] = _json(metadata or {})
            file.attrs["units"] = _json(RESULTS_UNITS)
            for name, shape in self._shapes.items():
                chunk_rows = max(1, min(1024, (1 << 16) // (8 * max(1, int(np.prod(shape))))))
                self._datasets[name] = file.create_dataset(
                    name,
                    shape=(0, *shape),
                    maxshape=(None, *shape),
                    chunks=(chunk_rows, *shape) if all(shape) else None,
                    dtype="f8",
                )
            self._datasets["records"] = file.create_dataset(
                "records", data=np.zeros(1, dtype=np.int64)
            )
            for name in _TEXT_FIELDS:
                self._datasets[name] = file.create_dataset(
                    name, shape=(0,), maxshape=(None,), dtype="u1", chunks=(4096,)
                )
            flexible = file.create_group("flexible")
            bodies = sorted(model.flexible_bodies.items())
            copy_body_groups(flexible, {str(index): body for index, body in bodies})
            self._write_text("status", {"state": "running", "error": None, "message": ""})
            file.swmr_mode = True
            file.flush()
        except BaseException as error:
            self._abandon()
            self._lock.release()
            if isinstance(error, OSError):
                raise ResultsFileError(
                    f"cannot write {self.path}: {error}", item=f"file '{self.path}'"
                ) from error
            raise

    def _write_text(self, name: str, value: Any) -> None:
        text = _json(value).encode("utf-8")
        if self._texts.get(name) == text:
            return  # events and redundancy rarely change between deliveries
        data = np.frombuffer(text, dtype=np.uint8)
        dataset = self._datasets[name]
        dataset.resize((len(data),))
        dataset[:] = data
        self._texts[name] = text

    def _abandon(self) -> None:
        """Closes the file after a failure, quietly (what was committed stays)."""
        try:
            if self._file.id.valid:
                self._file.close()
        except Exception:  # noqa: BLE001 - a file that failed may fail again on closing
            pass

    def _place(self) -> None:
        """Moves the partial file into place (the open file follows the rename)."""
        os.replace(self.partial, self.path)
        self.placed = True

    def _fail(self, error: OSError, *, before_writing: bool = False) -> ResultsFileError:
        """Ends the file after a failure (`before_writing`: a write refused before it was
        tried, which leaves the file sound enough to record the failure in its status) and
        returns the ResultsFileError to raise."""
        last = self.records
        where = self.path if self.placed else self.partial
        self.failure = ResultsFileError(
            f"writing the results file {where} failed ({error.strerror or error}); it keeps the "
            f"{last} records written before",
            item=f"file '{where}'",
        )
        if before_writing:
            try:
                status = {
                    "state": "failed",
                    "error": "ResultsFileError",
                    "message": str(self.failure),
                }
                self._write_text("status", status)
                self._file.flush()
            except OSError:
                pass
        self._abandon()
        if not self.placed and last:
            # The records of a run that got no further than its start: kept beside.
            try:
                os.replace(
                    self.partial, self.path.with_name(f"{self.path.stem}.failed{self.path.suffix}")
                )
            except OSError:
                pass
        self._lock.release()
        return self.failure

    def _room(self, count: int) -> tuple[int, str]:
        """How many of `count` records the disk and the process's file size limit leave room
        for (with a margin for HDF5's metadata), and why not more. A full disk must be met
        before it is full: HDF5 cannot be closed cleanly after a failed write (its library
        then crashes at exit)."""
        where = self.path if self.placed else self.partial
        per_record = 16 * sum(max(1, int(np.prod(shape))) for shape in self._shapes.values())
        try:
            size = os.path.getsize(where)
            disk = os.statvfs(where.parent)
            free = disk.f_bavail * disk.f_frsize
            limit = resource.getrlimit(resource.RLIMIT_FSIZE)[0]
        except OSError:
            return count, ""
        allowed, reason = free, "the disk"
        if limit != resource.RLIM_INFINITY and limit - size < free:
            allowed, reason = limit - size, "the file size limit"
        fits = max(0, (allowed - _SPACE_MARGIN) // per_record)
        return min(count, fits), f"{reason} leaves {max(allowed, 0)} bytes"

    def append(self, raw: dict[str, Any]) -> None:
        """Appends the records of a raw chunk (the dict of ``_core.simulate``'s ``records``
        callback), with its statistics and events, and makes them durable: at once, or, with
        a ``write_interval``, together with the chunks that follow within that many seconds
        (at most :data:`_PENDING_BYTES` held back). Where the disk (or the file size limit)
        has no room for all of them, those that fit are written and the file is ended with a
        ResultsFileError."""
        if self.failure is not None:
            raise self.failure
        self._pending.append(raw)
        self._pending_bytes += sum(
            np.asarray(raw[name]).nbytes for name in _RECORD_FIELDS if name in raw
        )
        if (
            time.monotonic() - self._written_at < self.write_interval
            and self._pending_bytes < _PENDING_BYTES
        ):
            return
        self._write_pending()

    def _write_pending(self) -> None:
        """Writes the chunks held back, as one."""
        if not self._pending:
            return
        chunks, self._pending, self._pending_bytes = self._pending, [], 0
        raw = dict(chunks[-1])
        if len(chunks) > 1:
            for name in _RECORD_FIELDS:
                raw[name] = np.concatenate(
                    [
                        np.asarray(c[name], dtype=np.float64).reshape(
                            len(c["time"]), *self._shapes[name]
                        )
                        for c in chunks
                    ]
                )
        self._written_at = time.monotonic()
        count = len(raw["time"])
        fits, reason = self._room(count)
        try:
            if fits < count:
                part = {name: raw[name][:fits] for name in _RECORD_FIELDS}
                self._append({**raw, **part})
            else:
                self._append(raw)
        except OSError as error:
            raise self._fail(error) from error
        if fits < count:
            message = f"{reason}, too little for the next records"
            raise self._fail(OSError(errno.ENOSPC, message), before_writing=True)
        if not self.placed and self.records >= 2:
            try:
                self._place()
            except OSError as error:
                raise self._fail(error) from error

    def _append(self, raw: dict[str, Any]) -> None:
        count = len(raw["time"])
        if count:
            start, end = self.records, self.records + count
            for name in _RECORD_FIELDS:
                values = np.asarray(raw[name], dtype=np.float64).reshape(count, *self._shapes[name])
                dataset = self._datasets[name]
                dataset.resize(end, axis=0)
                dataset[start:end] = values
        self._write_text("statistics", dict(raw["statistics"]))
        self._write_text("events", list(raw.get("events", [])))
        self._write_text("redundancy", raw.get("redundancy"))
        # The rows reach the file before the count that makes them visible.
        self._file.flush()
        if count:
            self.records += count
            self._datasets["records"][0] = self.records
            self._file.flush()

    def finish(self, result: Result, released: int = 0) -> Path:
        """Writes the records of ``result`` not yet in the file (``result`` holds the run's
        records from record `released` on), the final statistics and events, and the status
        (complete, failed or interrupted); closes the file and returns where it is: the
        path, or, for a run that failed before its first step while an earlier results file
        was at the path, ``STEM.failed.SUFFIX`` beside it."""
        if self.failure is not None:
            raise self.failure
        self._write_pending()
        chunk: dict[str, Any] = {
            name: result._record(name)[self.records - released :] for name in _RECORD_FIELDS
        }
        chunk["statistics"] = result.statistics
        chunk["events"] = result.events
        chunk["redundancy"] = result.redundancy
        self._pending.append(chunk)
        self._write_pending()
        run_error = result.error
        if run_error is None:
            status = {"state": "complete", "error": None, "message": ""}
        else:
            kind = (
                "interrupted" if isinstance(run_error, errors.SimulationInterrupted) else "failed"
            )
            status = {
                "state": kind,
                "error": type(run_error).__name__,
                "message": str(run_error),
                # (the item and time the error names: a callback's force, the time it failed)
                "item": getattr(run_error, "item", None),
                "time": getattr(run_error, "time", None),
            }
        try:
            self._write_text("status", status)
            self._file.flush()
        except OSError as error:
            raise self._fail(error) from error
        self._abandon()
        where = self.path
        if not self.placed:
            if run_error is not None and self.path.exists():
                where = self.path.with_name(f"{self.path.stem}.failed{self.path.suffix}")
                os.replace(self.partial, where)
            else:
                self._place()
        self._lock.release()
        return where

    def close(self) -> None:
        """Closes the file (what was appended stays; the status stays "running" unless
        :meth:`finish` wrote it) and releases the lock."""
        if self._file.id.valid:
            try:
                if self.failure is None:
                    self._write_pending()
                self._file.flush()
            except (OSError, ResultsFileError):
                pass
            self._abandon()
        self._lock.release()

    def __enter__(self) -> ResultsWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _hdf5_library() -> Any:
    """The HDF5 library h5py uses (ctypes), for the settings h5py does not expose; None if it
    cannot be found."""
    global _HDF5
    if _HDF5 is False:
        try:
            with open("/proc/self/maps", encoding="utf-8", errors="replace") as maps:
                paths = {line.split()[-1] for line in maps if "libhdf5" in line}
            paths = {p for p in paths if "_hl" not in os.path.basename(p)}
            _HDF5 = ctypes.CDLL(sorted(paths)[0]) if paths else None
        except (OSError, IndexError):
            _HDF5 = None
    return _HDF5


_HDF5: Any = False


def _open(path: Path, *, check: bool = True) -> h5py.File:
    """Opens a results file for reading without HDF5's retries of metadata reads (with them
    a truncated file kept a reader waiting for more than ten minutes): damaged metadata fails
    at once. A file whose writer was killed is still marked as being written; the
    single-writer/multiple-reader mode reads it."""
    if check and not path.exists():
        raise MissingFileError("results file", path)
    if check and not path.is_file():
        # A folder, a FIFO (whose reading would wait for a writer) or a device.
        raise NotAResultsFileError(
            f"{path} is not a flexmbd results file (not a regular file)", item=f"file '{path}'"
        )
    if check and not h5py.is_hdf5(path):
        raise NotAResultsFileError(
            f"{path} is not a flexmbd results file (not an HDF5 file)", item=f"file '{path}'"
        )
    damage = global_heap_damage(path)
    if damage is not None:
        raise ResultsFileError(
            f"{path} cannot be read: the file is truncated or damaged ({damage})",
            item=f"file '{path}'",
        )
    access = h5py.h5p.create(h5py.h5p.FILE_ACCESS)
    access.set_libver_bounds(h5py.h5f.LIBVER_LATEST, h5py.h5f.LIBVER_LATEST)
    library = _hdf5_library()
    if library is not None:
        library.H5Pset_metadata_read_attempts(ctypes.c_int64(access.id), ctypes.c_uint(1))
    name = os.fsencode(path)
    for flags in (h5py.h5f.ACC_RDONLY | h5py.h5f.ACC_SWMR_READ, h5py.h5f.ACC_RDONLY):
        try:
            return h5py.File(h5py.h5f.open(name, flags, fapl=access))
        except (OSError, ValueError) as error:
            failure = error
    raise ResultsFileError(
        f"{path} cannot be opened: the file is damaged ({failure})", item=f"file '{path}'"
    )


#: Largest JSON text field read, bytes (the texts of a run take kilobytes).
_TEXT_LIMIT = 64 << 20


def _text(file: h5py.File, name: str) -> Any:
    """A JSON text field, or None when it is absent, empty, torn or damaged: the writer of a
    running simulation rewrites these fields with every chunk (resize, then write), and a
    reader in between sees a text that does not decode; it reads as not written yet. A
    field that is not a short one-dimensional byte array (a damaged size) is damaged too."""
    try:
        if name not in file:
            return None
        dataset = file[name]
        if not isinstance(dataset, h5py.Dataset) or dataset.ndim != 1:
            return None
        if dataset.size * dataset.dtype.itemsize > _TEXT_LIMIT:
            return None
        data = dataset[:]
        if not len(data):
            return None
        return json.loads(np.asarray(data, dtype=np.uint8).tobytes().decode("utf-8"))
    except (OSError, ValueError, TypeError, KeyError, RecursionError):
        # Damaged, a JSON or Unicode error, or JSON nested too deep to decode.
        return None


def _attribute(file: h5py.File, name: str, path: Path, default: Any = None) -> Any:
    """A JSON root attribute; ResultsFileError naming it when it does not decode."""
    try:
        text = file.attrs.get(name)
        if text is None:
            if default is None:
                raise KeyError(name)
            return default
        if isinstance(text, bytes):
            text = text.decode("utf-8")
        return json.loads(str(text))
    except (OSError, ValueError, TypeError, KeyError) as error:
        raise ResultsFileError(
            f"{path}: the attribute '{name}' of the results file is missing or damaged",
            item=f"file '{path}'",
        ) from error


def _layout(file: h5py.File, path: Path) -> dict[str, Any]:
    layout = _attribute(file, "layout", path)
    try:
        _record_shapes(layout)
    except (KeyError, TypeError, ValueError, AttributeError) as error:
        raise ResultsFileError(
            f"{path}: the model description ('layout') of the results file is damaged",
            item=f"file '{path}'",
        ) from error
    return layout


def _record_count(file: h5py.File, path: Path) -> int:
    try:
        count = int(np.asarray(file["records"][:1])[0])
    except (OSError, ValueError, TypeError, IndexError, KeyError) as error:
        raise ResultsFileError(
            f"{path}: the record count of the results file is damaged", item=f"file '{path}'"
        ) from error
    if count < 0:
        raise ResultsFileError(
            f"{path}: the results file gives a record count of {count}", item=f"file '{path}'"
        )
    return count


def _last_time(file: h5py.File, count: int) -> float | None:
    """The time of record `count` - 1, None without records or where it cannot be read."""
    try:
        return float(file["time"][count - 1]) if count > 0 else None
    except (OSError, ValueError, TypeError, IndexError, KeyError):
        return None


def read_results_metadata(path: str | os.PathLike[str]) -> dict[str, Any]:
    """The header of a results file without its records: ``layout``, ``metadata``,
    ``records``, ``last_time`` (the time of the last record, None without records),
    ``status``, ``statistics``, ``events``, ``redundancy``, ``flexible`` (body indices) and
    ``version``. Raises :class:`flexmbd.ResultsFileError` for a damaged file."""
    path = _path(path)
    return _guarded(path, lambda: _read_results_metadata(path))


def _read_results_metadata(path: Path) -> dict[str, Any]:
    with _open(path) as file:
        _check_header(file, path)
        count = _record_count(file, path)
        return {
            "version": int(file.attrs["version"]),
            "writer": str(file.attrs.get("writer", "")),
            "layout": _layout(file, path),
            "metadata": _attribute(file, "metadata", path, {}),
            "units": _attribute(file, "units", path, {}),
            "records": count,
            "last_time": _last_time(file, count),
            "status": _text(file, "status"),
            "statistics": _text(file, "statistics") or {},
            "events": _text(file, "events") or [],
            "redundancy": _text(file, "redundancy"),
            "flexible": sorted(int(key) for key in file["flexible"]) if "flexible" in file else [],
        }


def _check_header(file: h5py.File, path: Path) -> None:
    try:
        found = file.attrs.get("format")
        version = int(file.attrs.get("version", 0))
    except (OSError, ValueError, TypeError) as error:
        raise ResultsFileError(
            f"{path}: the results file's header is damaged", item=f"file '{path}'"
        ) from error
    if isinstance(found, bytes):
        found = found.decode("utf-8", "replace")
    if found != RESULTS_FILE_FORMAT:
        raise NotAResultsFileError(
            f"{path} is not a flexmbd results file (format {found!r}, expected "
            f"{RESULTS_FILE_FORMAT!r})",
            item=f"file '{path}'",
        )
    if version > RESULTS_FILE_VERSION:
        raise NotAResultsFileError(
            f"{path} was written by a newer flexmbd: version {version} > "
            f"{RESULTS_FILE_VERSION}; update flexmbd to read it",
            item=f"file '{path}'",
        )
    for name in (*_RECORD_FIELDS, "records", "status"):
        if name not in file and name not in _LATER_FIELDS:
            raise NotAResultsFileError(
                f"{path}: the results file has no dataset '{name}'", item=f"file '{path}'"
            )


def _readable_rows(
    file: h5py.File, name: str, count: int, shape: tuple[int, ...], size: int
) -> np.ndarray:
    """The first `count` rows of a record dataset, or as many of them as can be read (a
    damaged chunk ends the readable part; found by halving). No more rows are read than a
    file of `size` bytes can hold (the records are stored uncompressed): a damaged count or
    dataset size does not make the reader allocate what the file cannot hold."""
    empty = np.zeros((0, *shape))
    row_bytes = 8 * int(np.prod(shape))
    try:
        dataset = file[name]
        if not isinstance(dataset, h5py.Dataset) or dataset.shape[1:] != shape:
            return empty
        count = min(count, dataset.shape[0])
        if row_bytes:
            count = min(count, size // row_bytes, _rows_in_file(dataset, count, size))
        return np.asarray(dataset[:count], dtype=np.float64)
    except (OSError, ValueError, TypeError, KeyError, RuntimeError, IndexError):
        if "dataset" not in locals() or not isinstance(dataset, h5py.Dataset):
            return empty
    good, bad = 0, count
    while bad - good > 1:
        middle = (good + bad) // 2
        try:
            dataset[middle - 1 : middle]
            good = middle
        except (OSError, ValueError, TypeError):
            bad = middle
    try:
        return np.asarray(dataset[:good], dtype=np.float64)
    except (OSError, ValueError, TypeError):
        return empty


def _rows_in_file(dataset: h5py.Dataset, count: int, size: int) -> int:
    """How many of the first `count` rows of a record dataset are stored within the file's
    `size` bytes: HDF5 reads the part of a chunk beyond the end of a truncated file, or a
    chunk never written, as zeros without an error (a file cut at 95 % gave a complete run
    whose constraint violations were all 0)."""
    try:
        chunks = dataset.chunks
        row_bytes = dataset.dtype.itemsize * int(np.prod(dataset.shape[1:]))
        if chunks is None:
            offset = dataset.id.get_offset()
            return 0 if offset is None else min(count, max(size - offset, 0) // max(row_bytes, 1))
        whole_rows = tuple(chunks[1:]) == tuple(dataset.shape[1:])
        # The chunks of each block of rows (several when a row is split across chunks).
        per_block = int(
            np.prod([-(-n // c) for n, c in zip(dataset.shape[1:], chunks[1:], strict=True)])
        )
        blocks: dict[int, list[Any]] = {}
        for k in range(dataset.id.get_num_chunks()):
            info = dataset.id.get_chunk_info(k)
            blocks.setdefault(info.chunk_offset[0], []).append(info)
        rows = 0
        while rows < count:
            stored = blocks.get(rows, [])
            if len(stored) < per_block or any(info.byte_offset is None for info in stored):
                break
            if all(size - info.byte_offset >= info.size for info in stored):
                rows += chunks[0]
                continue
            room = size - stored[0].byte_offset
            if whole_rows and dataset.compression is None and room > 0:
                rows += min(chunks[0], room // max(row_bytes, 1))
            break
        return min(rows, count)
    except (OSError, ValueError, TypeError, KeyError, RuntimeError, AttributeError):
        return count  # (the layout cannot be told: the rows are read as they are)


def _ordered(time: np.ndarray) -> tuple[int, str]:
    """How many leading records have finite times that do not decrease, and what is wrong
    with the next one ("" if all are in order): times that are not are damage."""
    wrong = ~np.isfinite(time)
    wrong[1:] |= time[1:] < time[:-1]
    if not wrong.any():
        return len(time), ""
    first = int(np.argmax(wrong))
    if not np.isfinite(time[first]):
        return first, f"record {first} has the time {time[first]}"
    return (
        first,
        f"record {first} has the time {time[first]:g}, before the one of record {first - 1}",
    )


_DAMAGE = (OSError, KeyError, ValueError, RuntimeError, TypeError, AttributeError)


def _path(path: Any) -> Path:
    """A results file's path, or an ArgumentTypeError naming the argument (Path(None) was a
    bare TypeError)."""
    if not isinstance(path, str | os.PathLike):
        raise ArgumentTypeError(
            f"path: a results file's path (str or os.PathLike), got {type(path).__name__}",
            item="path",
        )
    return Path(path)


def _guarded(path: Path, read: Any) -> Any:
    """`read()`, with the errors of a damaged file (h5py raises OSError, KeyError,
    ValueError, RuntimeError for broken metadata) as a ResultsFileError naming the file;
    flexmbd's own errors and a missing file pass through."""
    try:
        return read()
    except FlexmbdError:
        raise
    except FileNotFoundError:
        raise
    except _DAMAGE as error:
        raise ResultsFileError(
            f"{path} cannot be read: the results file is damaged ({error})", item=f"file '{path}'"
        ) from error


def read_results(path: str | os.PathLike[str]) -> Result:
    """Reads a results file into a :class:`flexmbd.Result`: every complete record, the
    statistics and events, and the deformable bodies' data. A run that did not complete
    gives ``success`` False and an ``error`` of the recorded class (a killed run:
    :class:`flexmbd.SimulationInterrupted` saying so). A damaged file (truncated, bit
    flips) gives the records that can be read, with a :class:`flexmbd.ResultsFileError` as
    ``error`` saying how many; a file whose header or model description cannot be read
    raises it. Nothing waits on damaged metadata."""
    path = _path(path)
    return _guarded(path, lambda: _read_results(path))


def _read_results(path: Path) -> Result:
    with _open(path) as file:
        _check_header(file, path)
        layout = _layout(file, path)
        shapes = _record_shapes(layout)
        count = _record_count(file, path)
        size = path.stat().st_size
        energy = file.get("energy")
        if isinstance(energy, h5py.Dataset) and energy.shape[1:] in ((2,), (3,)):
            # Written before the strain energy (2) or the power (3) was recorded.
            shapes["energy"] = energy.shape[1:]
        raw: dict[str, Any] = {
            name: _readable_rows(file, name, count, shapes[name], size)
            for name in _RECORD_FIELDS
            if name in file or name not in _LATER_FIELDS
        }
        readable = min(len(values) for values in raw.values())
        readable, disorder = _ordered(raw["time"][:readable])
        raw = {name: values[:readable] for name, values in raw.items()}
        for name in _LATER_FIELDS:
            raw.setdefault(name, np.zeros((readable, 0)))
        raw["statistics"] = _text(file, "statistics")
        raw["events"] = _text(file, "events") or []
        raw["redundancy"] = _text(file, "redundancy")
        status = _text(file, "status") or {"state": "running"}
        complete = isinstance(status, dict) and status.get("state") == "complete"
        # A complete run wrote its statistics: unreadable, they are damage (else not yet
        # written).
        statistics_lost = raw["statistics"] is None and complete
        raw["statistics"] = raw["statistics"] or {}
        flexible = {}
        # Bodies stored once for several indices (hard links to one group) are read once.
        read: dict[Any, Any] = {}
        for key in file["flexible"] if "flexible" in file else []:
            try:
                group = file["flexible"][key]
                if group.id not in read:
                    read[group.id] = read_body_group(group, path)
                flexible[int(key)] = read[group.id]
            except (OSError, KeyError, ValueError, TypeError) as error:
                raise ResultsFileError(
                    f"{path}: the data of deformable body {key} in the results file is damaged "
                    f"({error})",
                    item=f"file '{path}'",
                ) from error
    error: FlexmbdError | None = None
    last = f"{raw['time'][-1]:g} s" if readable else "its start"
    if readable < count:
        why = f"; {disorder}" if disorder else ""
        error = ResultsFileError(
            f"{path} is damaged: {readable} of its {count} records could be read (up to "
            f"t = {last}){why}",
            item=f"file '{path}'",
        )
    elif statistics_lost:
        error = ResultsFileError(
            f"{path} is damaged: its {count} records could be read, its statistics could not",
            item=f"file '{path}'",
        )
    elif not isinstance(status, dict) or status.get("state") != "complete":
        state = status.get("state") if isinstance(status, dict) else None
        if state not in ("failed", "interrupted"):
            error = errors.SimulationInterrupted(
                f"{path}: the run did not finish (killed or still running); records up to "
                f"t = {last} are in the file"
            )
        else:
            kind = getattr(errors, str(status.get("error")), None)
            if not (isinstance(kind, type) and issubclass(kind, FlexmbdError)):
                kind = errors.SimulationError
            error = kind(str(status.get("message", "")))
            item, failed_at = status.get("item"), status.get("time")
            error.item = item if isinstance(item, str) else None
            error.time = float(failed_at) if isinstance(failed_at, int | float) else None
    return Result(raw, layout, error=error, flexible=flexible)
