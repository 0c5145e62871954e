"""Nastran OP2 results (``OUTPUT2``, binary): the real eigenvalues and eigenvectors of a normal
modes analysis (SOL 103), read with flexmbd's own reader.

    from flexmbd.fe import read_op2
    results = read_op2("bracket.op2")
    results.cycles            # natural frequencies (Hz) of the eigenvalue table
    results.eigenvectors      # (modes, grids, 6): T1 T2 T3 R1 R2 R3 of each grid

An OP2 file is a sequence of Fortran unformatted records (a byte count, the bytes, the same
byte count), in either byte order, of 4-byte words (32-bit files: integers and single precision
reals) or 8-byte words (64-bit files: 64-bit integers and double precision reals; the byte
counts stay 4 bytes). A record of one word is a *marker*. After an optional file header
(marker 3, a date, marker 7, ``NASTRAN FORT TAPE ID CODE -``, marker 2, the version, markers -1
and 0) come the data blocks (*tables*), each:

    marker 2, the name (8 characters)
    marker -1, marker 7, a header record of 7 words
    marker -2, marker 1, marker 0, the records of subtable 2 (name and date)
    marker -3, marker 1, marker 0, the records of subtable 3 (the identification record)
    marker -4, marker 1, marker 0, the records of subtable 4 (the data)
    ... (subtables 3 and 4 repeat for each mode, time or load case)
    marker -k, marker 1, marker 0, marker 0 (the end of the table)

and marker 0 ends the file. A subtable's records are each a marker n > 0 followed by a record
of n words; consecutive ones form one logical record (long records are split).

Tables read:

- ``LAMA`` (real eigenvalues): subtable 4 holds 7 words per mode: mode number, extraction
  order, eigenvalue (rad^2/s^2), radians (rad/s), cycles (Hz), generalized mass, generalized
  stiffness.
- ``OUGV1`` / ``BOUGV1`` (and ``OUG1``, ``BOUG1``, ``OPHIG``, ``BOPHIG``): each pair of
  subtables 3 and 4 with table code 7 (eigenvectors) is one mode. Identification record
  (146 words): word 1 approach code x 10 + device code (approach 2: real eigenvalues), word 2
  table code + 1000 x sort code (bits: 1 complex, 2 sort2, 4 random), word 4 the subcase,
  words 5-7 mode number, eigenvalue and cycles, word 9 the format (1 real), word 10 the words
  per grid (8 for real data). Data: per grid, id x 10 + device code, the point type (1 grid,
  2 scalar point, ...), T1 T2 T3 R1 R2 R3. ``BOUGV1`` is in the basic coordinate system,
  ``OUGV1`` in each grid's displacement system (GRID field CD).

Every other table (geometry, stresses, forces, matrices, ...) and every other table code in
the displacement tables is skipped. See ``docs/preprocessor.md``, "Nastran OP2 results"."""

from __future__ import annotations

import dataclasses
import os
import struct
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .._checks import integers_array
from .._checks import number as real_number
from ..errors import (
    InvalidModelError,
    InvalidParameterError,
    MissingFileError,
    UnknownItemError,
)
from ._memory import check_fits
from .body import FlexibleBodyData, _replace

#: Tables whose eigenvector subtables (table code 7) are read; the basic-system ones first.
EIGENVECTOR_TABLES = ("BOUGV1", "BOPHIG", "BOUG1", "OUGV1", "OPHIG", "OUG1")

#: Displacement tables in SORT2 order: their eigenvectors are refused.
SORT2_TABLES = ("OUGV2", "BOUGV2", "OUG2", "BOUG2", "OPHIG2")

#: Eigenvalue tables of real modes.
EIGENVALUE_TABLES = ("LAMA",)

#: Memory taken per byte of file: the file's bytes, and the eigenvectors as float64 (twice the
#: bytes of their single precision values in 32-bit files).
MEMORY_PER_BYTE = 4.0

#: Table code of eigenvectors in the displacement tables.
EIGENVECTOR_CODE = 7

#: Approach code of real eigenvalue analyses (SOL 103).
REAL_EIGENVALUES = 2

_APPROACHES = {
    1: "statics",
    2: "real eigenvalues",
    3: "differential stiffness",
    5: "frequency response",
    6: "transient",
    7: "pre-buckling",
    8: "buckling (post-buckling eigenvalues)",
    9: "complex eigenvalues",
    10: "nonlinear statics",
    11: "geometric nonlinear statics",
}


@dataclass
class Op2Results:
    """The normal modes of an OP2 file (one subcase).

    Attributes:
        path: the file read.
        mode_numbers: (m,) mode numbers of the eigenvalue table (LAMA), in its order.
        eigenvalues: (m,) eigenvalues w^2 (rad^2/s^2 in SI).
        radians: (m,) circular frequencies (rad/s).
        cycles: (m,) natural frequencies (Hz).
        generalized_mass: (m,) phi^T M phi of each mode.
        generalized_stiffness: (m,) phi^T K phi of each mode.
        eigenvector_modes: (k,) mode numbers of the eigenvectors, in the file's order.
        node_ids: (n,) ids of the points of the eigenvectors (grid and scalar points), as in
            the file (the device code removed).
        point_types: (n,) 1 for grids, 2 for scalar points, other Nastran point codes.
        eigenvectors: (k, n, 6) T1 T2 T3 R1 R2 R3 of every point in every mode (scalar
            points: the value in T1).
        table: the name of the eigenvector table read ("BOUGV1", "OUGV1", ...); "" without
            eigenvectors.
        basic: whether the eigenvectors are in the basic system (the B... tables); otherwise
            each grid's displacement system (CD).
        subcase: the subcase of the eigenvectors (0 without).
        word_size: 4 (32-bit file) or 8 (64-bit file).
        byte_order: "little" or "big".
        tables: the names of all tables in the file, in order (the skipped ones included).
        version: the Nastran version of the file header ("" without a header).

    When the file has no LAMA table, the eigenvalue arrays come from the eigenvectors'
    identification records (mode number, eigenvalue, cycles; radians from the eigenvalue,
    the generalized mass and stiffness NaN).
    """

    path: Path
    mode_numbers: NDArray[np.int64]
    eigenvalues: NDArray[np.float64]
    radians: NDArray[np.float64]
    cycles: NDArray[np.float64]
    generalized_mass: NDArray[np.float64]
    generalized_stiffness: NDArray[np.float64]
    eigenvector_modes: NDArray[np.int64]
    node_ids: NDArray[np.int64]
    point_types: NDArray[np.int64]
    eigenvectors: NDArray[np.float64]
    table: str = ""
    basic: bool = True
    subcase: int = 0
    word_size: int = 4
    byte_order: str = "little"
    tables: list[str] = field(default_factory=list)
    version: str = ""

    def mode(self, number: int) -> NDArray[np.float64]:
        """The eigenvector (n, 6) of mode `number`. Raises `UnknownItemError` naming the mode
        if the file has no eigenvector for it."""
        hits = np.flatnonzero(self.eigenvector_modes == number)
        if len(hits) == 0:
            raise UnknownItemError(
                f"{self.path}: no eigenvector of mode {number} (modes "
                f"{_listing(self.eigenvector_modes)})",
                item=f"mode {number}",
            )
        return self.eigenvectors[hits[0]]

    def summary(self) -> str:
        """A few lines: the tables, the modes and their frequencies."""
        lines = [
            f"OP2 results {self.path.name}: {self.word_size * 8}-bit, {self.byte_order}-endian"
            + (f", {self.version}" if self.version else ""),
            f"  tables: {', '.join(self.tables)}",
        ]
        if self.table:
            system = "basic system" if self.basic else "displacement systems (CD)"
            lines.append(
                f"  eigenvectors: {self.table}, subcase {self.subcase}, "
                f"{len(self.eigenvector_modes)} modes x {len(self.node_ids)} points ({system})"
            )
        else:
            lines.append("  eigenvectors: none")
        count = len(self.mode_numbers)
        lines.append(f"  {count} modes:   mode   frequency (Hz)   generalized mass")
        for number, hz, mass in zip(
            self.mode_numbers, self.cycles, self.generalized_mass, strict=True
        ):
            lines.append(f"  {int(number):>18d}   {hz:14.6g}   {mass:16.6g}")
        return "\n".join(lines)


def read_op2(path: str | os.PathLike[str], subcase: int | None = None) -> Op2Results:
    """Reads the real eigenvalues (LAMA) and eigenvectors (OUGV1 / BOUGV1, table code 7) of a
    Nastran OP2 file (see the module docstring). With several subcases of eigenvectors,
    `subcase` picks one.

    Raises `MissingFileError`; `InvalidModelError` naming the file, the table and the byte
    offset of a malformed record (a truncated file, a record whose byte counts differ, an
    unexpected marker), of complex, SORT2, random or buckling eigenvectors, of a file without
    eigenvectors or eigenvalues, and of a file that would not fit in the available memory
    (estimated before it is read); `UnknownItemError` for a `subcase` that is not in the
    file."""
    path = Path(path)
    if not path.is_file():
        raise MissingFileError("OP2 file", path)
    check_fits(path, path.stat().st_size, MEMORY_PER_BYTE, "OP2 file")
    reader = _Reader(path, path.read_bytes())
    return reader.results(subcase)


def _listing(values: NDArray[np.int64] | list[int], shown: int = 10) -> str:
    items = [str(int(v)) for v in values[:shown]]
    return ", ".join(items) + (", ..." if len(values) > shown else "")


@dataclass
class _Mode:
    """One eigenvector subtable pair."""

    subcase: int
    number: int
    eigenvalue: float
    cycles: float
    ids: NDArray[np.int64]
    types: NDArray[np.int64]
    values: NDArray[np.float64]


class _Reader:
    """The reader of one OP2 file: `at` is the byte offset of the next record."""

    def __init__(self, path: Path, data: bytes):
        self.path, self.data, self.at = path, data, 0
        self.table = "(file header)"
        self.order, self.word = self._layout()
        e = "<" if self.order == "little" else ">"
        self.int_code, self.real_code = ("i", "f") if self.word == 4 else ("q", "d")
        self.length = struct.Struct(e + "i")
        self.marker_struct = struct.Struct(e + self.int_code)
        self.ints = np.dtype(e + self.int_code)
        self.reals = np.dtype(e + self.real_code)
        self.version = ""
        self.tables: list[str] = []
        self.lama: list[NDArray[np.float64]] = []
        self.modes: dict[str, list[_Mode]] = {}

    # Records ---------------------------------------------------------------------------------

    def fail(self, message: str, at: int | None = None) -> InvalidModelError:
        offset = self.at if at is None else at
        return InvalidModelError(
            f"{self.path}: table {self.table}, byte {offset}: {message}",
            item=f"table {self.table} of '{self.path}'",
        )

    def _layout(self) -> tuple[str, int]:
        """(byte order, word size) from the first record: a marker of one word."""
        head = self.data[:4]
        if len(head) < 4:
            raise self.fail(f"{len(self.data)} bytes: not an OP2 file", at=0)
        for order in ("little", "big"):
            count = int.from_bytes(head, order, signed=True)
            if count in (4, 8):
                return order, count
        raise self.fail(
            f"the first record has {int.from_bytes(head, 'little', signed=True)} bytes (little-"
            f"endian) or {int.from_bytes(head, 'big', signed=True)} (big-endian), not a marker "
            "of 4 or 8: not an OP2 file (Fortran unformatted records)",
            at=0,
        )

    def record(self) -> tuple[int, memoryview]:
        """(offset, bytes) of the next Fortran record."""
        start = self.at
        data = self.data
        if start + 4 > len(data):
            raise self.fail("the file ends inside a record's byte count (a truncated file)")
        (count,) = self.length.unpack_from(data, start)
        end = start + 4 + count
        if count < 0 or end + 4 > len(data):
            raise self.fail(
                f"a record of {count} bytes, but the file ends at byte {len(data)} (a truncated "
                "file)"
                if count >= 0
                else f"a record of {count} bytes"
            )
        (closing,) = self.length.unpack_from(data, end)
        if closing != count:
            raise self.fail(f"the record begins with byte count {count} and ends with {closing}")
        self.at = end + 4
        return start, memoryview(data)[start + 4 : end]

    def marker(self) -> int:
        start, body = self.record()
        if len(body) != self.word:
            raise self.fail(
                f"expected a marker (one {self.word}-byte word), found a record of "
                f"{len(body)} bytes",
                at=start,
            )
        return int(self.marker_struct.unpack(body)[0])

    def expect(self, *markers: int) -> None:
        for value in markers:
            start = self.at
            found = self.marker()
            if found != value:
                raise self.fail(f"expected marker {value}, found {found}", at=start)

    def text(self, body: memoryview) -> str:
        raw = bytes(body)
        if self.word == 8 and len(raw) % 8 == 0:
            # 64-bit files write four characters per word, padded (or eight in one).
            halves = [raw[k : k + 4] for k in range(0, len(raw), 8)]
            pads = [raw[k + 4 : k + 8] for k in range(0, len(raw), 8)]
            if all(p.strip(b" \x00") == b"" for p in pads):
                raw = b"".join(halves)
        return raw.decode("latin-1").strip(" \x00")

    # Structure ------------------------------------------------------------------------------

    def header(self) -> None:
        """The file header, if the file has one (marker 3: PARAM,POST,-1)."""
        start = self.at
        first = self.marker()
        if first != 3:
            self.at = start  # no header (PARAM,POST,-2): the first table follows
            return
        self.record()  # the date (or one word)
        self.expect(7)
        self.record()  # "NASTRAN FORT TAPE ID CODE -" (other writers: their own)
        start = self.at
        marker = self.marker()
        if marker > 0:
            _, version = self.record()
            self.version = self.text(version)
            self.expect(-1, 0)
        elif marker != -1:
            raise self.fail(f"expected marker 2 (the version) or -1, found {marker}", at=start)
        else:
            self.expect(0)

    def tables_(self) -> None:
        while True:
            self.table = "(between tables)"
            if self.at == len(self.data):
                return  # the file ends without its closing marker 0: accepted
            start = self.at
            marker = self.marker()
            if marker == 0:
                if self.at != len(self.data):
                    self.table = "(after the end of file marker)"
                    raise self.fail(
                        f"{len(self.data) - self.at} bytes after the end of file marker 0"
                    )
                return
            if marker < 1:
                raise self.fail(
                    f"expected marker 2 and a table name, found marker {marker}", at=start
                )
            _, name = self.record()
            self.table = self.text(name)[:8].strip() or "(unnamed)"
            self.tables.append(self.table)
            self.expect(-1)
            start = self.at
            if self.marker() < 1:  # the header record's length: 7 words
                raise self.fail("expected the length of the table's header record", at=start)
            self.record()
            subtables = self.subtables()
            if self.table in EIGENVALUE_TABLES:
                self.eigenvalue_table(subtables)
            elif self.table in EIGENVECTOR_TABLES or self.table in SORT2_TABLES:
                self.eigenvector_table(subtables)

    def subtables(self) -> list[tuple[int, bytes]]:
        """(offset, logical record) of subtables 2, 3, ... of the current table. Only the
        tables read keep their bytes."""
        keep = self.table in EIGENVALUE_TABLES + EIGENVECTOR_TABLES + SORT2_TABLES
        out: list[tuple[int, bytes]] = []
        number = -2
        start = self.at
        marker = self.marker()
        while True:
            if marker != number:
                raise self.fail(
                    f"expected marker {number} (subtable {-number}), found {marker}", at=start
                )
            self.expect(1, 0)
            start = self.at
            marker = self.marker()
            if marker == 0:
                return out
            begin = self.at
            parts: list[memoryview] = []
            while marker > 0:
                at, body = self.record()
                if len(body) != marker * self.word:
                    raise self.fail(
                        f"marker {marker} announces {marker * self.word} bytes, the record has "
                        f"{len(body)}",
                        at=at,
                    )
                if keep:
                    parts.append(body)
                start = self.at
                marker = self.marker()
            out.append((begin, b"".join(parts)))
            if marker == 0:
                return out  # the end of the table right after the data
            number -= 1

    # Tables ---------------------------------------------------------------------------------

    def eigenvalue_table(self, subtables: list[tuple[int, bytes]]) -> None:
        if len(subtables) < 3:
            offset = subtables[-1][0] if subtables else self.at
            raise self.fail(
                f"{len(subtables)} subtables, expected 3 (eigenvalues in the third)", at=offset
            )
        for offset, data in subtables[2::2]:
            per = 7 * self.word
            if len(data) % per:
                raise self.fail(
                    f"{len(data)} bytes of eigenvalues, not a multiple of 7 words per mode",
                    at=offset,
                )
            rows = np.frombuffer(data, dtype=self.reals).reshape(-1, 7).astype(np.float64)
            numbers = np.frombuffer(data, dtype=self.ints).reshape(-1, 7)[:, 0].astype(np.float64)
            rows[:, 0] = numbers
            if not np.all(np.isfinite(rows[:, 2:])):
                raise self.fail("non-finite eigenvalues", at=offset)
            self.lama.append(rows)

    def eigenvector_table(self, subtables: list[tuple[int, bytes]]) -> None:
        w = self.word
        pairs = subtables[1:]
        if len(pairs) % 2:
            raise self.fail(
                f"{len(pairs)} subtables after the name: expected pairs of an identification "
                "record and its data",
                at=pairs[-1][0],
            )
        for k in range(0, len(pairs), 2):
            offset, ident = pairs[k]
            data_offset, data = pairs[k + 1]
            if len(ident) < 10 * w:
                raise self.fail(
                    f"an identification record of {len(ident)} bytes, expected 146 words", at=offset
                )
            words = np.frombuffer(ident[: 10 * w], dtype=self.ints)
            reals = np.frombuffer(ident[: 10 * w], dtype=self.reals)
            acode, tcode, _, subcase, number = (int(v) for v in words[:5])
            table_code, sort_code = tcode % 1000, tcode // 1000
            approach = acode // 10
            format_code, num_wide = int(words[8]), int(words[9])
            if table_code != EIGENVECTOR_CODE:
                continue  # displacements, velocities, ...: not modes
            what = f"the eigenvectors of mode {number} (subcase {subcase})"
            if approach != REAL_EIGENVALUES:
                kind = _APPROACHES.get(approach, f"approach code {approach}")
                raise self.fail(
                    f"{what} are of a {kind} analysis; flexmbd reads the real eigenvectors of a "
                    "normal modes analysis (SOL 103, approach code 2)",
                    at=offset,
                )
            if sort_code & 1 or format_code in (2, 3) or num_wide == 14:
                raise self.fail(
                    f"{what} are complex (sort code {sort_code}, format code {format_code}, "
                    f"{num_wide} words per point); flexmbd reads real eigenvectors only",
                    at=offset,
                )
            if sort_code & 2 or self.table.endswith("2"):
                raise self.fail(
                    f"{what} are in SORT2 order (by point); write them in SORT1 "
                    "(DISPLACEMENT(SORT1) in the case control)",
                    at=offset,
                )
            if sort_code & 4:
                raise self.fail(f"{what} are random response results", at=offset)
            if num_wide != 8:
                raise self.fail(
                    f"{what}: {num_wide} words per point, expected 8 (id, type, 6 values)",
                    at=offset,
                )
            if len(data) % (8 * w):
                raise self.fail(
                    f"{what}: {len(data)} bytes, not a multiple of 8 words per point",
                    at=data_offset,
                )
            ints = np.frombuffer(data, dtype=self.ints).reshape(-1, 8)
            values = np.frombuffer(data, dtype=self.reals).reshape(-1, 8)[:, 2:].astype(np.float64)
            if not np.all(np.isfinite(values)):
                bad = int(np.flatnonzero(~np.all(np.isfinite(values), axis=1))[0])
                raise self.fail(
                    f"{what}: non-finite values at point {int(ints[bad, 0]) // 10}",
                    at=data_offset,
                )
            mode = _Mode(
                subcase=subcase,
                number=number,
                eigenvalue=float(reals[5]),
                cycles=float(reals[6]),
                ids=ints[:, 0].astype(np.int64) // 10,
                types=ints[:, 1].astype(np.int64),
                values=values,
            )
            self.modes.setdefault(self.table, []).append(mode)

    # Results ---------------------------------------------------------------------------------

    def results(self, subcase: int | None) -> Op2Results:
        self.header()
        self.tables_()
        self.table = "(results)"
        chosen = next((name for name in EIGENVECTOR_TABLES if name in self.modes), "")
        modes = self.modes.get(chosen, [])
        subcases = sorted({m.subcase for m in modes})
        if subcase is not None:
            if subcase not in subcases:
                raise UnknownItemError(
                    f"{self.path}: no eigenvectors of subcase {subcase} (subcases: "
                    f"{_listing(subcases) or 'none'})",
                    item=f"subcase {subcase}",
                )
        elif len(subcases) > 1:
            raise InvalidModelError(
                f"{self.path}: eigenvectors of subcases {_listing(subcases)}: choose one "
                "(read_op2(path, subcase=...))",
                item=f"file '{self.path}'",
            )
        elif subcases:
            subcase = subcases[0]
        lama_index = subcases.index(subcase) if subcases and len(self.lama) == len(subcases) else 0
        modes = [m for m in modes if m.subcase == subcase]
        if not modes and not self.lama:
            raise InvalidModelError(
                f"{self.path}: no real eigenvalues (LAMA) and no eigenvectors (OUGV1, BOUGV1 "
                f"with table code 7) in the tables {', '.join(self.tables) or '(none)'}: not "
                "the results of a normal modes analysis (SOL 103) with DISPLACEMENT output",
                item=f"file '{self.path}'",
            )
        if modes:
            ids, types = modes[0].ids, modes[0].types
            for mode in modes[1:]:
                if len(mode.ids) != len(ids) or np.any(mode.ids != ids):
                    raise InvalidModelError(
                        f"{self.path}: table {chosen}: mode {mode.number} has other points "
                        f"({len(mode.ids)}) than mode {modes[0].number} ({len(ids)})",
                        item=f"table {chosen} of '{self.path}'",
                    )
            vectors = np.stack([m.values for m in modes])
            numbers = np.array([m.number for m in modes], dtype=np.int64)
        else:
            ids = types = np.zeros(0, dtype=np.int64)
            vectors = np.zeros((0, 0, 6))
            numbers = np.zeros(0, dtype=np.int64)
        if self.lama:
            rows = self.lama[lama_index]
            lama = [rows[:, k] for k in (0, 2, 3, 4, 5, 6)]
        else:
            eig = np.array([m.eigenvalue for m in modes])
            lama = [
                numbers.astype(np.float64),
                eig,
                np.sqrt(np.abs(eig)),
                np.array([m.cycles for m in modes]),
                np.full(len(modes), np.nan),
                np.full(len(modes), np.nan),
            ]
        return Op2Results(
            path=self.path,
            mode_numbers=lama[0].astype(np.int64),
            eigenvalues=lama[1],
            radians=lama[2],
            cycles=lama[3],
            generalized_mass=lama[4],
            generalized_stiffness=lama[5],
            eigenvector_modes=numbers,
            node_ids=ids,
            point_types=types,
            eigenvectors=vectors,
            table=chosen,
            basic=chosen.startswith("B"),
            subcase=int(subcase or 0),
            word_size=self.word,
            byte_order=self.order,
            tables=list(self.tables),
            version=self.version,
        )


# Bodies from a deck and its modes ---------------------------------------------------------------

#: Relative eigenvalue below which a mode is a rigid-body motion (its Rayleigh quotient with
#: the body's K and M, against max diag K / max diag M; as in `modal.free_free_modes`).
RIGID_EIGENVALUE = 1e-10

#: Largest entry of a mode on a coordinate the reference conditions hold, relative to the
#: mode's largest entry.
HELD_MOTION = 1e-6

#: Largest mass coupling (normalized) of a mode with a rigid motion in a mean-axis body.
MEAN_AXIS_COUPLING = 1e-3

#: build_body options that body_from_nastran sets itself.
_OWN_OPTIONS = ("modes", "mode_count", "external_modes", "interfaces", "interface_kind")


def body_from_nastran(
    deck: Any,
    results: Op2Results | str | os.PathLike[str],
    modes: int | Sequence[int] | None = None,
    *,
    reference: str = "mean-axis",
    reference_nodes: str | Sequence[int] = (),
    subcase: int | None = None,
    frequency_tolerance: float | None = 0.05,
    **options: Any,
) -> FlexibleBodyData:
    """A modal body from a Nastran deck and the normal modes of its OP2 results: the mesh,
    material and sections of `deck` (a :class:`~flexmbd.fe.nastran.NastranDeck` or the path
    of a bulk data file) through the preprocessor, with the eigenvectors of `results` (an
    :class:`Op2Results` or the path of an OP2 file, read with `subcase`) as the modal basis
    (``modes="external"``).

    - The eigenvectors are mapped onto the body's coordinates by grid id and component:
      T1-T3 for solids, T1-T3 and R1-R3 for bodies of beams or shells (6 per node). Grids of
      the results that are not nodes of the body (an RBE's reference grid, a CONM2 point)
      are ignored; eigenvectors in the grids' displacement systems (OUGV1) are turned to the
      basic system with the deck's CORD2R systems.
    - Rigid-body modes (those whose Rayleigh quotient with the body's K and M vanishes:
      below ``RIGID_EIGENVALUE`` max diag K / max diag M) are left out: the body frame
      carries the rigid motion.
    - `modes`: None (every elastic mode of the file), a count (the first ones), or the mode
      numbers to keep.
    - `reference`: the body frame, as in `build_body`: "mean-axis" (free-free modes, the
      default), "clamped" at `reference_nodes` (a node set such as ``"spc1"`` or node
      indices) for the modes of a constrained analysis, ... The modes must vanish on the
      coordinates the reference conditions hold.
    - `frequency_tolerance`: the largest relative difference between the frequency of each
      mode with the body's K and M (its Rayleigh quotient) and the frequency of the OP2 file,
      to catch a deck that is not the one analysed, other units, or another mass formulation
      (Nastran lumps the mass of most elements unless ``PARAM,COUPMASS,1``: pass
      ``mass="lumped"``). None skips the check.
    - `options`: `build_body`'s (``mass``, ``beam_theory``, ``precision``, ...).

    The body's k_ff and m_ff are B^T K B and B^T M B with flexmbd's K and M; its
    ``frequencies`` are the file's (Hz).

    Raises `UnknownItemError` naming a grid of the body that has no eigenvector, a mode
    number that is not in the file, a node set that does not exist; `InvalidModelError` for a
    file without eigenvectors, a mode that moves a held coordinate (naming the mode, grid and
    component), a rigid-body mode asked for by number, fewer elastic modes than asked for,
    and a frequency beyond `frequency_tolerance` (naming the mode and both frequencies);
    `InvalidParameterError` for build_body options that this function sets itself."""
    from . import preprocess
    from .nastran import NastranDeck, read_nastran

    if frequency_tolerance is not None:
        frequency_tolerance = real_number(frequency_tolerance, "frequency_tolerance")
        if frequency_tolerance < 0:
            raise InvalidParameterError(
                f"frequency_tolerance must be >= 0 (a relative difference) or None (no check), "
                f"got {frequency_tolerance}",
                item="frequency_tolerance",
            )
    if modes is not None and not isinstance(modes, int | np.integer):
        if isinstance(modes, str | bytes) or not isinstance(modes, Sequence | np.ndarray):
            raise InvalidParameterError(
                f"modes must be None, a count or a list of mode numbers, got {modes!r:.60}",
                item="modes",
            )
        modes = [int(v) for v in integers_array(modes, "modes").ravel()]
    elif isinstance(modes, bool):
        raise InvalidParameterError(
            f"modes must be None, a count or a list of mode numbers, got {modes!r}", item="modes"
        )
    if not isinstance(deck, NastranDeck):
        deck = read_nastran(deck)
    if not isinstance(results, Op2Results):
        results = read_op2(results, subcase)
    for key in _OWN_OPTIONS:
        if key in options:
            raise InvalidParameterError(
                f"{key}: body_from_nastran sets it (the modes are the OP2 file's); give "
                "`modes` (a count or mode numbers) instead",
                item=key,
            )
    where = f"{results.path}"
    if results.eigenvectors.shape[0] == 0:
        raise InvalidModelError(
            f"{where}: no eigenvectors (tables {', '.join(results.tables)}): request them with "
            "DISPLACEMENT(SORT1) = ALL in the case control of the SOL 103 run",
            item=f"file '{where}'",
        )
    nodal = deck.body(**options)
    ids = np.asarray(nodal.node_ids, dtype=np.int64)
    d = nodal.dofs_per_node
    shapes = _shapes_on_nodes(results, ids, deck.displacement_systems)  # (k, n, 6)
    count = shapes.shape[0]
    phi = shapes[:, :, :d].reshape(count, len(ids) * d).T  # (n d, k)

    # Rayleigh quotients with the body's own K and M: rigid modes and the frequency check.
    k_phi = nodal.stiffness @ phi
    m_phi = nodal.mass @ phi
    generalized_k = np.einsum("ij,ij->j", phi, k_phi)
    generalized_m = np.einsum("ij,ij->j", phi, m_phi)
    if np.any(generalized_m <= 0):
        bad = int(results.eigenvector_modes[int(np.argmin(generalized_m))])
        raise InvalidModelError(
            f"{where}: mode {bad} does not move the body's nodes (zero generalized mass)",
            item=f"mode {bad}",
        )
    quotient = generalized_k / generalized_m
    scale = float(nodal.stiffness.diagonal().max() / nodal.mass.diagonal().max())
    rigid = quotient < RIGID_EIGENVALUE * scale
    numbers = results.eigenvector_modes
    chosen = _chosen_modes(modes, numbers, rigid, where)

    node_sets = nodal.node_sets
    if reference == "interface":
        raise InvalidParameterError(
            "reference: 'interface' frames are for Craig-Bampton bodies; use 'clamped' at "
            "the interface nodes",
            item="reference",
        )
    held_nodes = preprocess._node_indices(reference_nodes, node_sets, "reference_nodes")
    kind = "none" if reference == "mean-axis" else reference
    free = preprocess.reference_dofs(kind, len(ids), d, held_nodes)
    held = np.setdiff1d(np.arange(len(ids) * d), free)
    basis = phi[:, chosen]
    if len(held):
        size = np.max(np.abs(basis), axis=0)
        moved = np.abs(basis[held]) > HELD_MOTION * size
        if np.any(moved):
            row, column = (int(v[0]) for v in np.nonzero(moved))
            dof = int(held[row])
            component = ("T1", "T2", "T3", "R1", "R2", "R3")[dof % d]
            mode = int(numbers[chosen[column]])
            raise InvalidModelError(
                f"{where}: mode {mode} moves grid {int(ids[dof // d])} in {component} "
                f"({basis[row, column]:.3e}, {size[column]:.3e} at most), which the reference "
                f"conditions ({reference!r}) hold: the modes are not those of a model "
                "constrained there",
                item=f"grid {int(ids[dof // d])}",
            )

    if reference == "mean-axis":
        _check_mean_axis(nodal, basis, numbers[chosen], where)

    frequencies = _file_frequencies(results, numbers[chosen])
    if frequency_tolerance is not None:
        own = np.sqrt(np.clip(quotient[chosen], 0.0, None)) / (2.0 * np.pi)
        off = np.abs(own - frequencies) > float(frequency_tolerance) * np.abs(frequencies)
        if np.any(off):
            j = int(np.flatnonzero(off)[0])
            mode = int(numbers[chosen[j]])
            raise InvalidModelError(
                f"{where}: mode {mode} has {frequencies[j]:.6g} Hz in the OP2 file and "
                f"{own[j]:.6g} Hz with the deck's stiffness and mass (more than "
                f"{frequency_tolerance:.3g} apart): the deck is not the one analysed, its units "
                "differ, or Nastran used another mass matrix (lumped unless PARAM,COUPMASS,1: "
                "pass mass='lumped'); frequency_tolerance=None skips this check",
                item=f"mode {mode}",
            )
    # A mean-axis frame is the frame of reference "none" (every coordinate kept) with modes
    # that satisfy the Tisserand conditions, checked above.
    body = nodal.with_modes(
        "external",
        len(chosen),
        reference="none" if reference == "mean-axis" else reference,
        reference_nodes=reference_nodes,
        external_modes=basis[free],
    )
    metadata = dict(body.metadata)
    metadata["source"] = f"{results.path} ({results.table}, modes "
    metadata["source"] += f"{', '.join(str(int(m)) for m in numbers[chosen])})"
    return _replace(
        body,
        frequencies=frequencies,
        metadata=metadata,
        reference=dataclasses.replace(body.reference, kind=reference),
    )


def _check_mean_axis(
    nodal: FlexibleBodyData, basis: NDArray[np.float64], numbers: NDArray[np.int64], where: str
) -> None:
    """Raises `InvalidModelError` unless the modes are mass-orthogonal to the rigid motions
    (the Tisserand conditions of a mean-axis frame) within ``MEAN_AXIS_COUPLING``."""
    from .modal import rigid_modes

    rigid = rigid_modes(np.asarray(nodal.nodes, dtype=float), nodal.dofs_per_node)
    m_rigid = nodal.mass @ rigid
    coupling = rigid.T @ (nodal.mass @ basis)
    norms = np.sqrt(np.einsum("ij,ij->j", rigid, m_rigid))[:, None] * np.sqrt(
        np.einsum("ij,ij->j", basis, nodal.mass @ basis)
    )
    relative = np.abs(coupling) / norms
    if relative.max() > MEAN_AXIS_COUPLING:
        motion, column = np.unravel_index(int(np.argmax(relative)), relative.shape)
        names = ("x translation", "y translation", "z translation")
        names += ("x rotation", "y rotation", "z rotation")
        mode = int(numbers[column])
        raise InvalidModelError(
            f"{where}: mode {mode} is not mass-orthogonal to the rigid {names[motion]} of the "
            f"body (coupling {relative.max():.2e} > {MEAN_AXIS_COUPLING:g}): not a free-free "
            "mode of this mesh and mass matrix, so not a mean-axis frame; use "
            "reference='none' (the modes as they are) or the constraints of the analysis "
            "(reference='clamped')",
            item=f"mode {mode}",
        )


def _shapes_on_nodes(
    results: Op2Results, ids: NDArray[np.int64], systems: dict[int, NDArray[np.float64]]
) -> NDArray[np.float64]:
    """The eigenvectors (k, n, 6) of the grids `ids`, in the basic system."""
    grids = results.point_types == 1
    position = {int(g): k for k, g in enumerate(results.node_ids) if grids[k]}
    missing = [int(g) for g in ids if int(g) not in position]
    if missing:
        raise UnknownItemError(
            f"{results.path}: table {results.table} has no eigenvector of grid {missing[0]}, a "
            f"node of the deck's elements ({len(missing)} grids missing: "
            f"{_listing(missing)}): the results are not those of this mesh",
            item=f"grid {missing[0]}",
        )
    shapes = results.eigenvectors[:, [position[int(g)] for g in ids], :].copy()
    if not results.basic:
        for k, g in enumerate(ids):
            axes = systems.get(int(g))
            if axes is not None and not np.all(np.isfinite(axes)):
                raise InvalidModelError(
                    f"{results.path}: the eigenvectors of {results.table} are in the grids' "
                    f"displacement systems, and that of grid {int(g)} (GRID field CD) is not a "
                    "rectangular CORD2R system of the deck: write them in the basic system "
                    "(BOUGV1)",
                    item=f"grid {int(g)}",
                )
            if axes is not None:
                shapes[:, k, :3] = shapes[:, k, :3] @ axes.T
                shapes[:, k, 3:] = shapes[:, k, 3:] @ axes.T
    return shapes


def _chosen_modes(
    modes: int | Sequence[int] | None,
    numbers: NDArray[np.int64],
    rigid: NDArray[np.bool_],
    where: str,
) -> NDArray[np.int64]:
    """Indices of the eigenvectors kept."""
    elastic = np.flatnonzero(~rigid)
    if modes is None:
        if len(elastic) == 0:
            raise InvalidModelError(
                f"{where}: every mode of the file is a rigid-body motion", item=f"file '{where}'"
            )
        return elastic
    if isinstance(modes, int | np.integer) and not isinstance(modes, bool):
        if modes < 1 or modes > len(elastic):
            raise InvalidModelError(
                f"{where}: {modes} elastic modes asked for, the file has {len(elastic)} "
                f"(and {int(rigid.sum())} rigid-body modes)",
                item=f"file '{where}'",
            )
        return elastic[: int(modes)]
    out = []
    for number in modes:
        hits = np.flatnonzero(numbers == int(number))
        if len(hits) == 0:
            raise UnknownItemError(
                f"{where}: no eigenvector of mode {number} (modes {_listing(numbers)})",
                item=f"mode {number}",
            )
        if rigid[hits[0]]:
            raise InvalidModelError(
                f"{where}: mode {number} is a rigid-body motion; the body frame carries it",
                item=f"mode {number}",
            )
        out.append(int(hits[0]))
    if not out:
        raise InvalidParameterError("modes: no mode numbers given", item="modes")
    return np.array(out, dtype=np.int64)


def _file_frequencies(results: Op2Results, numbers: NDArray[np.int64]) -> NDArray[np.float64]:
    """The frequencies (Hz) of the file's eigenvalue table for mode `numbers`."""
    index = {int(m): k for k, m in enumerate(results.mode_numbers)}
    out = []
    for number in numbers:
        if int(number) not in index:
            raise UnknownItemError(
                f"{results.path}: mode {int(number)} has an eigenvector but is not in the "
                "eigenvalue table (LAMA)",
                item=f"mode {int(number)}",
            )
        out.append(results.cycles[index[int(number)]])
    return np.array(out, dtype=np.float64)


__all__ = [
    "EIGENVALUE_TABLES",
    "EIGENVECTOR_TABLES",
    "Op2Results",
    "body_from_nastran",
    "read_op2",
]
