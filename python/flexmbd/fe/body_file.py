"""Versioned HDF5 files of :class:`FlexibleBodyData`: one file per deformable body, written once
by the preprocessor and read at every model build.

Layout (``version`` 1)
----------------------
Root attributes:

* ``format = "flexmbd-body"``: marks the file as a flexmbd body file;
* ``version``: the data layout version (:data:`~flexmbd.fe.body.BODY_DATA_VERSION` of the
  writer); a reader refuses files with a newer version;
* ``units``: the ``units`` field as a JSON object, e.g. ``{"length": "m", "mass": "kg",
  "time": "s"}``;
* ``writer``: ``"flexmbd <version>"``, for information only.

Every other field of :class:`FlexibleBodyData` is a member of the root group with the field's
name (``damping``, ``shell`` and ``point_masses``, added later to version 1, may be missing: they
then read as None: undamped, no shell section, point masses not recorded).
``reference`` (a :class:`~flexmbd.fe.body.ReferenceConditions`) and ``invariants`` (an
:class:`~flexmbd.fe.body.Invariants`) are stored as ``dict`` groups of their entries, one member
per field in field order (the optional fields of the reference conditions that are None are
left out), and read back as dicts that the body's constructor turns into the typed objects.
Each member carries an attribute ``type`` that says how it reads back:

* ``ndarray``: a dataset with the array's dtype and shape (float64 and int64 for the body
  fields); arrays of at least :data:`COMPRESSION_THRESHOLD_BYTES` are chunked and compressed
  (gzip + shuffle by default).
* ``sparse``: a group with the datasets ``data``, ``indices``, ``indptr`` (``row``, ``col``,
  ``data`` for COO) and ``shape`` (int64, (2,)), and the attributes ``format`` (``"csc"``,
  ``"csr"``, ``"coo"``, ...) and ``container`` (``"matrix"`` for ``scipy.sparse.*_matrix``,
  ``"array"`` for ``*_array``). Other formats than CSC, CSR and COO are stored as CSC and
  converted back on reading.
* ``none``: an empty dataset (null dataspace): the value is ``None``.
* ``dict``: a group, one member per key, in key order (HDF5 link creation order).
* ``list``, ``tuple``: a group with the members ``"0"``, ``"1"``, ... (``invariants/i_kl``
  is a list of 3 lists of 3 matrices, each an ``ndarray`` or ``sparse`` member).
* ``float``, ``int``, ``bool``, ``str``: a scalar dataset (float64, int64, bool, UTF-8
  string) that reads back as the Python type.
* ``scalar``: a 0-d dataset that reads back as a NumPy scalar of the same dtype.

Dictionary keys become HDF5 names with ``%`` and ``/`` percent-encoded (``%25``, ``%2F``) and
the key ``"."`` written ``%2E``. Nothing in the file is executed or unpickled on reading.

A round trip is exact: arrays bit-identical with their dtype and shape (C order), sparse
matrices with the same format, index arrays, values and shape, dictionary keys in order, and
``None`` kept. CSC and CSR matrices read back canonical (indices sorted, no duplicates): one
stored otherwise (unsorted indices, duplicate entries, which add up) reads back as the same
matrix with its entries sorted and its duplicates summed.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import pickle
import threading
from collections import OrderedDict
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import h5py
import numpy as np
import scipy.sparse as sp

from .._core import __version__
from .._hdf5 import global_heap_damage
from ..errors import (
    FlexmbdError,
    InvalidModelError,
    InvalidParameterError,
    MissingFileError,
    ModelError,
)
from .body import (
    BODY_DATA_VERSION,
    FlexibleBodyData,
    Invariants,
    ReferenceConditions,
    check_body,
)

#: Value of the root attribute ``format`` of a body file.
BODY_FILE_FORMAT = "flexmbd-body"

#: Arrays of at least this many bytes are chunked and compressed.
COMPRESSION_THRESHOLD_BYTES = 64 * 1024

# Fields kept as root attributes rather than members.
_ATTRIBUTE_FIELDS = ("units", "version")
# Fields added to layout version 1 after its first files: missing ones read as their default.
_LATER_FIELDS = ("damping", "shell", "point_masses")
_TYPE = "type"
_NUMERIC_KINDS = "biufc"
# A dataset may declare more bytes than the file stores (compression) by at most this factor
# (deflate's limit is about 1032) plus _UNCHECKED_BYTES: a larger one is damaged.
_MAX_COMPRESSION = 2048
_UNCHECKED_BYTES = 1 << 20


def save_body(
    data: FlexibleBodyData, path: str | os.PathLike[str], *, compression: str | None = "gzip"
) -> None:
    """Write ``data`` to the HDF5 body file ``path`` (layout in the module docstring).

    The file is written next to ``path`` under a temporary name and then renamed, so an
    existing file is replaced only by a complete one; an existing file that is not a flexmbd
    body file is not replaced (an `InvalidParameterError`).

    Args:
        data: the body; ``data.version`` must be :data:`BODY_DATA_VERSION`.
        path: destination file (conventionally ``*.h5``).
        compression: ``"gzip"`` (default, readable by every HDF5 tool), ``"lzf"`` (faster,
            h5py only) or ``None``, applied to arrays of at least
            :data:`COMPRESSION_THRESHOLD_BYTES`.

    Raises:
        InvalidParameterError: ``data`` is not a :class:`FlexibleBodyData`, has another
            layout version, or holds a value that cannot be stored (an object array, a
            non-string dictionary key, ...); the message names the field.
    """
    if not isinstance(data, FlexibleBodyData):
        raise InvalidParameterError(
            f"save_body expects a FlexibleBodyData, got {type(data).__name__}", item="body data"
        )
    if data.version != BODY_DATA_VERSION:
        raise InvalidParameterError(
            f"body data has layout version {data.version}, this flexmbd writes version "
            f"{BODY_DATA_VERSION}",
            item="field 'version'",
        )
    if compression not in ("gzip", "lzf", None):
        raise InvalidParameterError(
            f"compression must be 'gzip', 'lzf' or None, got {compression!r}",
            item="compression",
        )
    units = _check_units(data.units)

    path = Path(path)
    if path.exists() and not is_body_file(path):
        # (`flexmbd preprocess mesh.inp -o model.yaml` replaced the model file)
        raise InvalidParameterError(
            f"{path} exists and is not a flexmbd body file: it is not replaced (give another "
            "name, or delete it first)",
            item=f"file '{path}'",
        )
    temporary = path.with_name(f".{path.name}.{os.getpid()}.{threading.get_ident()}.tmp")
    try:
        with h5py.File(temporary, "w", track_order=True) as file:
            _write_body(file, data, units, compression)
        os.replace(temporary, path)
    finally:
        if temporary.exists():
            temporary.unlink()


def is_body_file(path: Path) -> bool:
    """Whether `path` is a flexmbd body file (its ``format`` attribute says so)."""
    if not path.is_file():
        return False
    try:
        with h5py.File(path, "r") as file:
            found = file.attrs.get("format")
    except (OSError, ValueError, KeyError, RuntimeError):
        return False
    if isinstance(found, bytes):
        found = found.decode("utf-8", "replace")
    return bool(found == BODY_FILE_FORMAT)


def load_body(path: str | os.PathLike[str]) -> FlexibleBodyData:
    """Read a body file written by :func:`save_body`.

    The body read is checked (:func:`flexmbd.fe.body.check_body`): shapes that fit each other,
    finite nodes, modes and invariants, a positive mass and a positive semi-definite second
    moment of mass. The file is opened without SWMR, so that a truncated file fails at once;
    its global heaps (variable-length strings) and the datatypes of its string attributes are
    checked before HDF5 reads them, as HDF5 loops or crashes on damaged ones.

    Raises:
        MissingFileError: ``path`` does not exist (also a FileNotFoundError).
        InvalidModelError: ``path`` is not a flexmbd body file (not HDF5, or the ``format``
            attribute is missing or different), was written by a newer flexmbd (version
            greater than :data:`BODY_DATA_VERSION`), is damaged (truncated, a field missing,
            of an unknown ``type``, of the wrong dtype or shape, unreadable) or holds values
            that do not make a body (NaN nodes or modes, a non-positive mass, ...); the
            message names the file and the field.
    """
    path = Path(path)
    if not path.exists():
        raise MissingFileError("body file", path)
    item = f"file '{path}'"
    try:
        is_hdf5 = path.is_file() and h5py.is_hdf5(path)
    except OSError as error:
        raise InvalidModelError(f"{path}: cannot read the body file ({error})", item=item) from None
    if not is_hdf5:
        raise InvalidModelError(f"{path} is not a flexmbd body file (not an HDF5 file)", item=item)
    damage = global_heap_damage(path)
    if damage is not None:
        raise InvalidModelError(
            f"{path}: cannot read the body file, it is truncated or damaged ({damage})", item=item
        )
    try:
        file = h5py.File(path, "r")
    except OSError as error:
        raise InvalidModelError(
            f"{path}: cannot open the body file, it is truncated or damaged ({error})", item=item
        ) from None
    with file:
        return read_body_group(file, path)


def write_body_group(
    group: h5py.Group, data: FlexibleBodyData, *, compression: str | None = "gzip"
) -> None:
    """Write ``data`` into an open HDF5 group (the layout of a body file, in that group): how
    results files keep the deformable bodies of their model."""
    _write_body(group, data, _check_units(data.units), compression)


def copy_body_group(parent: h5py.Group, name: str, data: FlexibleBodyData) -> None:
    """Write ``data`` as the group ``parent[name]`` (the layout of :func:`write_body_group`),
    by HDF5's object copy from a group this process wrote before for a body of the same
    content: a body is a hundred small datasets, and copying them is about a tenth of the
    time of writing them, which is what a study's cases that share a body spend per results
    file. Bodies of more than :data:`_TEMPLATE_BYTES` are written directly."""
    _TEMPLATES.copy(parent, name, data, _content_key(data))


def copy_body_groups(parent: h5py.Group, bodies: Mapping[str, FlexibleBodyData]) -> None:
    """Write each body of `bodies` (name -> data) as the group ``parent[name]``, as
    :func:`copy_body_group` does, storing each distinct body once: a body of the same content
    as one written before (two identical links of a chain) becomes an HDF5 hard link to that
    body's group, so the file holds its data once and reads it back under both names."""
    written: dict[str, str] = {}
    keys: dict[int, tuple[int, str]] = {}
    for name, data in bodies.items():
        # The same object twice is hashed once.
        key = keys.get(id(data)) or _content_key(data)
        keys[id(data)] = key
        first = written.get(key[1])
        if first is None:
            _TEMPLATES.copy(parent, name, data, key)
            written[key[1]] = name
        else:
            parent[name] = parent[first]


#: The bodies' bytes that the templates of :func:`copy_body_group` keep in memory at most.
_TEMPLATE_BYTES = 64 << 20
#: How many body templates :func:`copy_body_group` keeps (the most recently used).
_TEMPLATE_COUNT = 16


class _Templates:
    """Body groups written once in memory (an HDF5 file of the "core" driver per body), keyed
    by a digest of the body's content (its pickle, array buffers hashed in place: two bodies
    built alike have the same key), the most recently used kept."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._files: OrderedDict[str, tuple[h5py.File, int]] = OrderedDict()
        self._process = os.getpid()

    def copy(
        self, parent: h5py.Group, name: str, data: FlexibleBodyData, content: tuple[int, str]
    ) -> None:
        """Writes `data` as ``parent[name]``; `content` is its :func:`_content_key`."""
        size, key = content
        if size > _TEMPLATE_BYTES:
            write_body_group(parent.create_group(name), data)
            return
        with self._lock:
            if self._process != os.getpid():
                # A forked child does not share the parent's HDF5 handles.
                self._files.clear()
                self._process = os.getpid()
            entry = self._files.get(key)
            if entry is None:
                template = h5py.File(f"flexmbd-body-{key}", "w", driver="core", backing_store=False)
                try:
                    write_body_group(template.create_group("body"), data)
                except BaseException:
                    template.close()
                    raise
                entry = (template, size)
                self._files[key] = entry
                while len(self._files) > _TEMPLATE_COUNT or (
                    len(self._files) > 1
                    and sum(s for _, s in self._files.values()) > _TEMPLATE_BYTES
                ):
                    self._files.popitem(last=False)[1][0].close()
            self._files.move_to_end(key)
            template = entry[0]
            template.copy(template["body"], parent, name=name)


def _content_key(data: FlexibleBodyData) -> tuple[int, str]:
    """The size of a body's arrays (bytes) and a digest of its content."""
    buffers: list[pickle.PickleBuffer] = []
    frame = pickle.dumps(data, protocol=5, buffer_callback=buffers.append)
    digest = hashlib.sha256(frame)
    size = len(frame)
    for buffer in buffers:
        view = buffer.raw()
        digest.update(view)
        size += view.nbytes
    return size, digest.hexdigest()


_TEMPLATES = _Templates()


def _write_body(
    group: h5py.Group, data: FlexibleBodyData, units: dict[str, str], compression: str | None
) -> None:
    group.attrs["format"] = BODY_FILE_FORMAT
    group.attrs["version"] = np.int64(BODY_DATA_VERSION)
    group.attrs["units"] = json.dumps(units)
    group.attrs["writer"] = f"flexmbd {__version__}"
    writer = _Writer(compression)
    for field in dataclasses.fields(FlexibleBodyData):
        if field.name in _ATTRIBUTE_FIELDS:
            continue
        writer.write(group, field.name, getattr(data, field.name), field.name)


def read_body_group(file: h5py.Group, path: Path) -> FlexibleBodyData:
    """Read a body from an open HDF5 group written like a body file (``path`` names the file
    in error messages) and check it (see :func:`load_body`)."""
    item = f"file '{path}'"
    try:
        return _read_body_group(file, path)
    except InvalidModelError:
        raise
    except (FlexmbdError, OSError, KeyError, RuntimeError, ValueError, TypeError) as error:
        # What the field readers do not catch: HDF5 errors on the root group itself, ...
        raise InvalidModelError(
            f"{path}: the body file is damaged ({type(error).__name__}: {error})", item=item
        ) from None


def _read_body_group(file: h5py.Group, path: Path) -> FlexibleBodyData:
    item = f"file '{path}'"
    version = _check_header(file, path)
    reader = _Reader(path)
    values: dict[str, Any] = {"version": version}
    try:
        values["units"] = json.loads(_read_string_attribute(file, "units", path))
    except json.JSONDecodeError as error:
        raise InvalidModelError(
            f"{path}: the 'units' attribute is not valid JSON ({error})", item=item
        ) from None
    if not isinstance(values["units"], dict):
        raise InvalidModelError(f"{path}: the 'units' attribute is not a JSON object", item=item)
    for field in dataclasses.fields(FlexibleBodyData):
        if field.name in _ATTRIBUTE_FIELDS:
            continue
        if field.name not in file:
            if field.name in _LATER_FIELDS:
                continue  # written by an earlier flexmbd: the field's default
            raise InvalidModelError(f"{path}: the body file has no field '{field.name}'", item=item)
        values[field.name] = reader.read_member(file, field.name, field.name)
    # The values are checked before they become a body (whose construction computes with them).
    try:
        check_body(values)
        return FlexibleBodyData(**values)
    except ModelError as error:
        raise InvalidModelError(f"{path}: {error}", item=item) from None
    except (ValueError, TypeError, IndexError, ArithmeticError) as error:
        raise InvalidModelError(
            f"{path}: the fields do not make a body ({type(error).__name__}: {error})", item=item
        ) from None


def _check_units(units: Any) -> dict[str, str]:
    if not isinstance(units, dict) or not all(
        isinstance(key, str) and isinstance(value, str) for key, value in units.items()
    ):
        raise InvalidParameterError(
            f"units must be a dict of str to str, got {units!r}", item="field 'units'"
        )
    return units


def _check_header(file: h5py.File, path: Path) -> int:
    """Check the ``format`` and ``version`` root attributes; return the version."""
    item = f"file '{path}'"
    if _attribute(file, "format", path) is None:
        raise InvalidModelError(
            f"{path} is not a flexmbd body file (no 'format' attribute)", item=item
        )
    found = _attribute(file, "format", path)
    if isinstance(found, bytes):
        found = found.decode("utf-8", "replace")
    if found != BODY_FILE_FORMAT:
        raise InvalidModelError(
            f"{path} is not a flexmbd body file (format {found!r}, expected {BODY_FILE_FORMAT!r})",
            item=item,
        )
    version = _attribute(file, "version", path)
    if (
        version is None
        or np.ndim(version) != 0
        or not np.issubdtype(np.asarray(version).dtype, np.integer)
    ):
        raise InvalidModelError(f"{path}: missing or non-integer 'version' attribute", item=item)
    version = int(version)
    if version > BODY_DATA_VERSION:
        raise InvalidModelError(
            f"{path} was written by a newer flexmbd: version {version} > {BODY_DATA_VERSION}; "
            "update flexmbd to read it",
            item=item,
        )
    if version < 1:
        raise InvalidModelError(f"{path}: invalid body file version {version}", item=item)
    return version


def _attribute(node: h5py.HLObject, name: str, path: Path, where: str = "") -> Any:
    """Attribute `name` of `node` (None when missing), read only after a check that it is a
    scalar number or string: HDF5 crashes (segmentation fault) reading a variable-length
    string attribute whose datatype is damaged."""
    place = f"field '{where}'" if where else "the root group"
    try:
        if name not in node.attrs:
            return None
        attribute = h5py.h5a.open(node.id, name.encode())
        dtype, shape = attribute.dtype, attribute.shape
    except (OSError, KeyError, RuntimeError, ValueError, TypeError) as error:
        raise InvalidModelError(
            f"{path}: attribute '{name}' of {place} cannot be read ({error})",
            item=f"file '{path}'",
        ) from None
    if shape != () or (dtype.kind not in "biuf" and h5py.check_string_dtype(dtype) is None):
        raise InvalidModelError(
            f"{path}: attribute '{name}' of {place} is damaged (dtype {dtype}, shape {shape})",
            item=f"file '{path}'",
        )
    try:
        return node.attrs[name]
    except (OSError, KeyError, RuntimeError, ValueError, TypeError) as error:
        raise InvalidModelError(
            f"{path}: attribute '{name}' of {place} cannot be read ({error})",
            item=f"file '{path}'",
        ) from None


def _read_string_attribute(file: h5py.File, name: str, path: Path) -> str:
    value = _attribute(file, name, path)
    if isinstance(value, bytes):
        value = value.decode("utf-8")
    if not isinstance(value, str):
        raise InvalidModelError(
            f"{path}: missing or non-string '{name}' attribute", item=f"file '{path}'"
        )
    return value


def _encode_name(key: Any, where: str) -> str:
    """HDF5 member name of a dictionary key (reversible, see the module docstring)."""
    if not isinstance(key, str):
        raise InvalidParameterError(
            f"{where}: dictionary keys must be strings, got {key!r}", item=f"field '{where}'"
        )
    if key == "":
        raise InvalidParameterError(f"{where}: empty dictionary key", item=f"field '{where}'")
    if key == ".":
        return "%2E"
    return key.replace("%", "%25").replace("/", "%2F")


def _decode_name(name: str) -> str:
    if name == "%2E":
        return "."
    return name.replace("%2F", "/").replace("%25", "%")


class _Writer:
    """Writes one value as a member of a group, tagged with its ``type``."""

    def __init__(self, compression: str | None):
        self.compression = compression

    def write(self, group: h5py.Group, name: str, value: Any, where: str) -> None:
        # Order matters: NumPy scalars before Python numbers (np.float64 is a float), bool
        # before int (bool is an int).
        if value is None:
            group.create_dataset(name, data=h5py.Empty("f8")).attrs[_TYPE] = "none"
        elif sp.issparse(value):
            self._write_sparse(group, name, value, where)
        elif isinstance(value, np.ndarray):
            self._write_array(group, name, value, where).attrs[_TYPE] = "ndarray"
        elif isinstance(value, np.generic) and value.dtype.kind in _NUMERIC_KINDS:
            group.create_dataset(name, data=value).attrs[_TYPE] = "scalar"
        elif isinstance(value, bool):
            group.create_dataset(name, data=np.bool_(value)).attrs[_TYPE] = "bool"
        elif isinstance(value, int):
            try:
                stored = np.int64(value)
            except OverflowError:
                raise InvalidParameterError(
                    f"{where}: integer {value} does not fit in 64 bits", item=f"field '{where}'"
                ) from None
            group.create_dataset(name, data=stored).attrs[_TYPE] = "int"
        elif isinstance(value, float):
            group.create_dataset(name, data=np.float64(value)).attrs[_TYPE] = "float"
        elif isinstance(value, str):
            dataset = group.create_dataset(name, data=value, dtype=h5py.string_dtype("utf-8"))
            dataset.attrs[_TYPE] = "str"
        elif isinstance(value, Invariants | ReferenceConditions):
            # The layout of the dicts these were: their entries that are set, in field order.
            self.write(group, name, dict(value.items()), where)
        elif isinstance(value, dict):
            subgroup = group.create_group(name, track_order=True)
            subgroup.attrs[_TYPE] = "dict"
            for key, item in value.items():
                self.write(subgroup, _encode_name(key, where), item, f"{where}/{key}")
        elif isinstance(value, list | tuple):
            subgroup = group.create_group(name, track_order=True)
            subgroup.attrs[_TYPE] = "list" if isinstance(value, list) else "tuple"
            for index, item in enumerate(value):
                self.write(subgroup, str(index), item, f"{where}/{index}")
        else:
            raise InvalidParameterError(
                f"{where}: cannot store a value of type {type(value).__name__} in a body file",
                item=f"field '{where}'",
            )

    def _write_array(
        self, group: h5py.Group, name: str, array: np.ndarray, where: str
    ) -> h5py.Dataset:
        if array.dtype.kind not in _NUMERIC_KINDS:
            raise InvalidParameterError(
                f"{where}: cannot store an array of dtype {array.dtype} in a body file "
                "(numeric and bool arrays only)",
                item=f"field '{where}'",
            )
        if (
            self.compression is not None
            and array.ndim >= 1
            and array.nbytes >= COMPRESSION_THRESHOLD_BYTES
        ):
            options: dict[str, Any] = {"compression": self.compression, "shuffle": True}
            if self.compression == "gzip":
                options["compression_opts"] = 4
            return group.create_dataset(name, data=array, chunks=True, **options)
        return group.create_dataset(name, data=array)

    def _write_sparse(self, group: h5py.Group, name: str, matrix: Any, where: str) -> None:
        if matrix.ndim != 2:
            raise InvalidParameterError(
                f"{where}: only 2-D sparse matrices can be stored", item=f"field '{where}'"
            )
        subgroup = group.create_group(name, track_order=True)
        subgroup.attrs[_TYPE] = "sparse"
        subgroup.attrs["format"] = matrix.format
        subgroup.attrs["container"] = "matrix" if sp.isspmatrix(matrix) else "array"
        if matrix.format == "coo":
            arrays = {"row": matrix.row, "col": matrix.col, "data": matrix.data}
        else:
            compressed = matrix if matrix.format in ("csc", "csr") else matrix.tocsc()
            arrays = {
                "data": compressed.data,
                "indices": compressed.indices,
                "indptr": compressed.indptr,
            }
        for key, array in arrays.items():
            self._write_array(subgroup, key, np.asarray(array), f"{where}/{key}")
        subgroup.create_dataset("shape", data=np.asarray(matrix.shape, dtype=np.int64))


class _Reader:
    """Reads a member written by :class:`_Writer`; anything unexpected (a missing member, an
    HDF5 read error, a dtype or shape that does not fit the ``type``, sparse indices out of
    range, a size the file cannot hold) is an `InvalidModelError` naming the file and the
    member."""

    def __init__(self, path: Path):
        self.path = path

    def _damaged(self, where: str, detail: str) -> InvalidModelError:
        return InvalidModelError(
            f"{self.path}: field '{where}' {detail}", item=f"file '{self.path}'"
        )

    def read_member(self, group: h5py.Group, name: str, where: str, raw: str = "") -> Any:
        """The value of member `name` of `group`; with `raw` (dtype kinds), the data of a
        dataset without a ``type`` (the arrays of a sparse matrix)."""
        try:
            node = group[name]
        except (KeyError, OSError, RuntimeError, ValueError, TypeError) as error:
            raise self._damaged(where, f"cannot be opened ({error})") from None
        if raw and not isinstance(node, h5py.Dataset):
            raise self._damaged(where, "should be a dataset, got a group")
        return self.read(node, where, raw)

    def read(self, node: h5py.Group | h5py.Dataset, where: str, raw: str = "") -> Any:
        try:
            if raw:
                return self._read_array(node, where, raw, "numbers")
            return self._read(node, where)
        except InvalidModelError:
            raise
        except (
            OSError,
            KeyError,
            RuntimeError,
            ValueError,
            TypeError,
            IndexError,
            ArithmeticError,
            MemoryError,
        ) as error:
            raise self._damaged(
                where, f"cannot be read ({type(error).__name__}: {error})"
            ) from None

    def _read(self, node: h5py.Group | h5py.Dataset, where: str) -> Any:
        kind = _attribute(node, _TYPE, self.path, where)
        if isinstance(kind, bytes):
            kind = kind.decode("utf-8")
        if kind in ("dict", "list", "tuple", "sparse") and not isinstance(node, h5py.Group):
            raise self._damaged(where, f"has type {kind!r} but is not a group")
        if kind == "dict":
            return {
                _decode_name(name): self.read_member(node, name, f"{where}/{_decode_name(name)}")
                for name in node
            }
        if kind in ("list", "tuple"):
            items = [
                self.read_member(node, str(index), f"{where}/{index}") for index in range(len(node))
            ]
            return items if kind == "list" else tuple(items)
        if kind == "sparse":
            return self._read_sparse(node, where)
        if not isinstance(node, h5py.Dataset):
            raise self._damaged(where, f"has an unknown type {kind!r}")
        if kind == "none":
            return None
        if node.shape is None:
            raise self._damaged(where, "is empty but not marked as None")
        if kind == "ndarray":
            return self._read_array(node, where, _NUMERIC_KINDS, "numbers")
        if kind == "str":
            if node.shape != () or h5py.check_string_dtype(node.dtype) is None:
                raise self._damaged(
                    where, f"should be a string, got dtype {node.dtype} of shape {node.shape}"
                )
            return node.asstr()[()]
        kinds, what = {
            "scalar": (_NUMERIC_KINDS, "a number"),
            "float": ("fiu", "a number"),
            "int": ("iu", "an integer"),
            "bool": ("b", "a bool"),
        }.get(kind, (None, ""))
        if kinds is None:
            raise self._damaged(where, f"has an unknown type {kind!r}")
        if node.shape != ():
            raise self._damaged(where, f"should hold {what}, got shape {node.shape}")
        value = self._read_array(node, where, kinds, what)[()]
        if kind == "scalar":
            return value
        return {"float": float, "int": int, "bool": bool}[kind](value)

    def _read_array(self, dataset: h5py.Dataset, where: str, kinds: str, what: str) -> Any:
        """The data of `dataset`, of one of the dtype `kinds`, after a check that the size it
        declares is stored in the file (a damaged shape would otherwise allocate it)."""
        if dataset.dtype.kind not in kinds:
            raise self._damaged(where, f"should hold {what}, got dtype {dataset.dtype}")
        declared = dataset.size * dataset.dtype.itemsize
        if declared > _UNCHECKED_BYTES:
            stored = dataset.id.get_storage_size()
            if declared > _MAX_COMPRESSION * stored + _UNCHECKED_BYTES:
                raise self._damaged(
                    where,
                    f"declares shape {dataset.shape} ({declared} bytes) but the file stores "
                    f"{stored} bytes of it",
                )
        return dataset[...]

    def _read_sparse(self, group: h5py.Group, where: str) -> Any:
        fmt = _attribute(group, "format", self.path, where)
        container = _attribute(group, "container", self.path, where)
        matrix_class = {
            "matrix": {"csr": sp.csr_matrix, "coo": sp.coo_matrix, "csc": sp.csc_matrix},
            "array": {"csr": sp.csr_array, "coo": sp.coo_array, "csc": sp.csc_array},
        }.get(container if isinstance(container, str) else "")
        if matrix_class is None:
            raise self._damaged(where, f"has an unknown sparse container {container!r}")
        if not isinstance(fmt, str):
            raise self._damaged(where, f"has an unknown sparse format {fmt!r}")
        names = ("row", "col", "data") if fmt == "coo" else ("data", "indices", "indptr")
        for name in (*names, "shape"):
            if name not in group:
                raise self._damaged(where, f"is a sparse matrix without '{name}'")
        shape = self.read_member(group, "shape", f"{where}/shape", raw="iu")
        if (
            not isinstance(shape, np.ndarray)
            or shape.shape != (2,)
            or shape.dtype.kind not in "iu"
            or shape.min() < 0
        ):
            described = shape.tolist() if isinstance(shape, np.ndarray) else shape
            raise self._damaged(where, f"has an invalid shape {described!r}")
        shape = (int(shape[0]), int(shape[1]))
        arrays = []
        for name in names:
            index = name != "data"
            array = self.read_member(group, name, f"{where}/{name}", raw=_NUMERIC_KINDS)
            if (
                not isinstance(array, np.ndarray)
                or array.ndim != 1
                or array.dtype.kind not in ("iu" if index else "fiu")
            ):
                described = (
                    f"dtype {array.dtype}, shape {array.shape}"
                    if isinstance(array, np.ndarray)
                    else type(array).__name__
                )
                raise self._damaged(
                    f"{where}/{name}",
                    f"should be a 1-D {'integer' if index else 'numeric'} array, got {described}",
                )
            arrays.append(array)
        # The constructors check the index arrays against the shape (COO fully, CSC and CSR
        # with `check_format(full_check=True)`): damaged indices would make products read
        # outside the arrays.
        if fmt == "coo":
            row, col, data = arrays
            matrix = matrix_class["coo"]((data, (row, col)), shape=shape)
            # The constructors may change the index dtype: put back the stored arrays.
            matrix.coords, matrix.data = (row, col), data
            return matrix
        data, indices, indptr = arrays
        stored = fmt if fmt in ("csr", "csc") else "csc"
        matrix = matrix_class[stored]((data, indices, indptr), shape=shape)
        matrix.check_format(full_check=True)
        matrix.data, matrix.indices, matrix.indptr = data, indices, indptr
        # Canonical (indices sorted in each column or row, no duplicates: the same matrix): the
        # body makes its arrays read-only, and the code that needs sorted indices would
        # otherwise sort them in place. The arrays were just read: they are this matrix's own.
        if not matrix.has_canonical_format:
            matrix.sum_duplicates()
        if stored != fmt:
            try:
                matrix = matrix.asformat(fmt)
            except ValueError:
                raise self._damaged(where, f"has an unknown sparse format {fmt!r}") from None
        return matrix
