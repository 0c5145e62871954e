"""Writes the OP2 fixtures of tests/test_op2.py: small Nastran decks (``block.bdf``, a free
hex8 block; ``beam.bdf``, a CBAR cantilever) and OP2 files of their normal modes.

Not run by the tests or CI; run it again only to change the fixtures:

    python3.11 -m venv /tmp/pynenv && /tmp/pynenv/bin/pip install pyNastran scipy
    PYTHONPATH=python python tests/data/nastran/make_op2.py [--pynastran /tmp/pynenv/bin/python]

It runs in two stages, because pyNastran pins numpy < 2 and so cannot share flexmbd's
environment:

1. (flexmbd's environment) writes the decks, reads them with `flexmbd.fe.read_nastran`,
   takes the nodal K and M of flexmbd's preprocessor and solves K x = w^2 M x densely with
   scipy.linalg.eigh (not flexmbd's own eigensolver): mass-normalized modes, the rigid-body
   modes of the free block included, zeros at the beam's clamped grid. Saves them to
   ``modes.npz`` (deleted afterwards).
2. (``--write``, pyNastran's environment) writes the OP2 files:
   - ``block.op2``, ``beam.op2``: pyNastran's writer (32-bit, little-endian): LAMA and the
     eigenvectors (BOUGV1 for the block, OUGV1 for the beam);
   - ``block_geometry.op2``: pyNastran's writer with the deck's geometry tables (GEOM1,
     GEOM2, EPT, MPT), a static displacement table (OUGV1, table code 1) and the eigenvectors,
     without LAMA (pyNastran's writer leaves it out);
   - ``block_big.op2`` (32-bit, big-endian) and ``block_64.op2`` (64-bit, little-endian): the
     layout written here by hand (pyNastran writes neither: its markers are native-endian
     and 32-bit).
   Every file is read back with pyNastran's reader, which must find the eigenvalues and
   eigenvectors that were written.
"""

from __future__ import annotations

import argparse
import os
import struct
import subprocess
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
MODES = HERE / "modes.npz"
BLOCK_MODES = 14  # 6 rigid + 8 elastic
BEAM_MODES = 6


def block_deck() -> str:
    """A free steel block 0.3 x 0.05 x 0.02 m of 6 x 2 x 1 hex8, grid ids 1000 + 7 k."""
    nx, ny, nz = 6, 2, 1
    size = (0.3, 0.05, 0.02)
    lines = ["SOL 103", "CEND", "METHOD = 1", "DISPLACEMENT(SORT1) = ALL", "BEGIN BULK"]
    ids = {}
    k = 0
    for kz in range(nz + 1):
        for ky in range(ny + 1):
            for kx in range(nx + 1):
                gid = 1000 + 7 * k
                ids[kx, ky, kz] = gid
                x = (size[0] * kx / nx, size[1] * ky / ny, size[2] * kz / nz)
                lines.append(f"GRID,{gid},,{x[0]!r},{x[1]!r},{x[2]!r}")
                k += 1
    eid = 1
    for kz in range(nz):
        for ky in range(ny):
            for kx in range(nx):
                corners = [
                    (kx, ky, kz), (kx + 1, ky, kz), (kx + 1, ky + 1, kz), (kx, ky + 1, kz),
                    (kx, ky, kz + 1), (kx + 1, ky, kz + 1), (kx + 1, ky + 1, kz + 1),
                    (kx, ky + 1, kz + 1),
                ]  # fmt: skip
                lines.append(f"CHEXA,{eid},1," + ",".join(str(ids[c]) for c in corners[:6]))
                lines.append("," + ",".join(str(ids[c]) for c in corners[6:]))
                eid += 1
    lines += ["PSOLID,1,1", "MAT1,1,2.1e11,,0.3,7800.", "EIGRL,1,,,14", "PARAM,POST,-1"]
    lines.append("ENDDATA")
    return "\n".join(lines) + "\n"


def beam_deck() -> str:
    """A steel CBAR cantilever 1 m of 8 elements along x, clamped at grid 11 (SPC1 1), grid
    ids 11, 13, ..., rectangular section 0.02 x 0.01 m."""
    lines = ["SOL 103", "CEND", "METHOD = 1", "SPC = 1", "DISPLACEMENT(SORT1) = ALL"]
    lines.append("BEGIN BULK")
    count = 8
    for k in range(count + 1):
        lines.append(f"GRID,{11 + 2 * k},,{k / count!r},0.,0.")
    for k in range(count):
        lines.append(f"CBAR,{101 + k},7,{11 + 2 * k},{13 + 2 * k},0.,1.,0.")
    lines.append("PBARL,7,1,,BAR,,,,,\n,0.02,0.01")
    lines += ["MAT1,1,2.1e11,,0.3,7800.", "SPC1,1,123456,11", "EIGRL,1,,,6", "PARAM,POST,-1"]
    lines.append("ENDDATA")
    return "\n".join(lines) + "\n"


# Stage 1: the modes, in flexmbd's environment -------------------------------------------------


def solve(deck_path: Path, count: int, held: list[int]) -> dict[str, np.ndarray]:
    """The `count` lowest modes of the deck (nodal K, M of flexmbd's preprocessor; dense
    scipy eigh), mass-normalized, with the grids `held` clamped: (count, grids, 6)."""
    import scipy.linalg as sla

    from flexmbd.fe import read_nastran

    deck = read_nastran(deck_path)
    body = deck.body()
    d = body.dofs_per_node
    ids = np.asarray(body.node_ids)
    k = body.stiffness.toarray()
    m = body.mass.toarray()
    held_dofs = [int(np.flatnonzero(ids == g)[0]) * d + c for g in held for c in range(d)]
    free = np.setdiff1d(np.arange(len(ids) * d), held_dofs)
    values, vectors = sla.eigh(k[np.ix_(free, free)], m[np.ix_(free, free)])
    values, vectors = values[:count], vectors[:, :count]
    full = np.zeros((len(ids) * d, count))
    full[free] = vectors
    shapes = np.zeros((count, len(ids), 6))
    shapes[:, :, :d] = full.T.reshape(count, len(ids), d)
    # A sign convention: the largest component of each mode positive.
    for j in range(count):
        flat = shapes[j].ravel()
        if flat[np.argmax(np.abs(flat))] < 0:
            shapes[j] *= -1
    return {"ids": ids, "eigenvalues": values, "shapes": shapes}


def stage_one(pynastran: str) -> None:
    (HERE / "block.bdf").write_text(block_deck())
    (HERE / "beam.bdf").write_text(beam_deck())
    block = solve(HERE / "block.bdf", BLOCK_MODES, [])
    beam = solve(HERE / "beam.bdf", BEAM_MODES + 0, [11])
    gaps = np.diff(block["eigenvalues"][6:]) / block["eigenvalues"][7:]
    print("block frequencies (Hz):", np.sqrt(np.abs(block["eigenvalues"])) / 2 / np.pi)
    print("beam frequencies (Hz):", np.sqrt(beam["eigenvalues"]) / 2 / np.pi)
    assert np.min(gaps) > 1e-3, f"nearly repeated block eigenvalues: {gaps}"
    np.savez(
        MODES,
        **{f"block_{k}": v for k, v in block.items()},
        **{f"beam_{k}": v for k, v in beam.items()},
    )
    try:
        subprocess.run([pynastran, __file__, "--write"], check=True)
    finally:
        MODES.unlink()
    for name in sorted(HERE.glob("*.op2")):
        print(f"{name.name}: {name.stat().st_size} bytes")


# Stage 2: the OP2 files, in pyNastran's environment ------------------------------------------


def lama_rows(values: np.ndarray) -> list[tuple]:
    """(mode, order, eigenvalue, radians, cycles, generalized mass, stiffness) per mode."""
    rows = []
    for j, value in enumerate(values):
        radians = np.sqrt(abs(value))
        rows.append((j + 1, j + 1, value, radians, radians / (2 * np.pi), 1.0, value))
    return rows


def write_with_pynastran(path: Path, ids, values, shapes, table: str, geometry=None) -> None:
    """An OP2 of LAMA (unless `geometry`) and the eigenvectors, by pyNastran's writer."""
    from pyNastran.op2.op2 import OP2
    from pyNastran.op2.op2_geom import OP2Geom
    from pyNastran.op2.tables.lama_eigenvalues.lama_objects import RealEigenvalues
    from pyNastran.op2.tables.oug.oug_displacements import RealDisplacementArray
    from pyNastran.op2.tables.oug.oug_eigenvectors import RealEigenvectorArray
    from pyNastran.op2.writer.op2_writer import write_op2_header

    grid = np.column_stack([ids, np.ones(len(ids))]).astype("int32")
    vectors = RealEigenvectorArray.add_modal_case(
        table,
        grid,
        shapes.astype("float32"),
        1,
        np.arange(1, len(values) + 1, dtype="int32"),
        values.astype("float32"),
        (np.sqrt(np.abs(values)) / (2 * np.pi)).astype("float32"),
        is_sort1=True,
        title="flexmbd fixture",
    )
    # add_modal_case keeps the displacement's table code 1: eigenvectors are 7.
    vectors.table_code = vectors.data_code["table_code"] = 7
    if geometry is not None:
        from pyNastran.bdf.bdf import read_bdf

        deck = read_bdf(str(geometry), xref=False, debug=False)
        model = OP2Geom(mode="nx")
        for key in ("nodes", "elements", "properties", "materials"):
            setattr(model, key, getattr(deck, key))
        model.eigenvectors[1] = vectors
        static = RealDisplacementArray.add_static_case(
            "OUGV1", grid, 1e-3 * shapes[6:7].astype("float32"), 2, is_sort1=True
        )
        model.displacements[2] = static
        model.write_op2(str(path), post=-1, endian=b"<", nastran_format="nx")
        return
    lama = RealEigenvalues("flexmbd fixture", "LAMA", len(values))
    for j, row in enumerate(lama_rows(values)):
        lama.add_f06_line(row, j)
    model = OP2(mode="nx")
    with open(path, "wb") as out:
        ascii_log = open(os.devnull, "w")  # noqa: SIM115
        write_op2_header(model, out, ascii_log, struct.Struct("<3i"), post=-1, endian=b"<")
        for result in (lama, vectors):
            end = result.write_op2(out, ascii_log, -1, True, (1, 1, 2026), endian=b"<")
            out.write(struct.pack("<9i", 4, end, 4, 4, 1, 4, 4, 0, 4))
            out.write(struct.pack("<3i", 4, 0, 4))
        out.write(struct.pack("<3i", 4, 0, 4))
        ascii_log.close()


class Writer:
    """The OP2 layout by hand (see flexmbd/fe/op2.py): byte order `e` ("<" or ">"), word
    size `w` (4 or 8)."""

    def __init__(self, e: str, w: int):
        self.e, self.w = e, w
        self.i, self.f = ("i", "f") if w == 4 else ("q", "d")
        self.out = bytearray()

    def record(self, body: bytes) -> None:
        n = struct.pack(self.e + "i", len(body))
        self.out += n + body + n

    def marker(self, *values: int) -> None:
        for v in values:
            self.record(struct.pack(self.e + self.i, v))

    def text(self, s: bytes) -> bytes:
        if self.w == 4:
            return s
        return b"".join(s[k : k + 4] + b"    " for k in range(0, len(s), 4))

    def words(self, fmt: str, *values) -> bytes:
        fmt = fmt.replace("i", self.i).replace("f", self.f)
        return struct.pack(self.e + fmt, *values)

    def header(self) -> None:
        self.marker(3)
        self.record(self.words("3i", 1, 1, 26))
        self.marker(7)
        self.record(self.text(b"NASTRAN FORT TAPE ID CODE - "))
        self.marker(2)
        self.record(self.text(b"NX8.5   "))
        self.marker(-1, 0)

    def table(self, name: bytes, subtables: list[bytes]) -> None:
        self.marker(2)
        self.record(self.text(name.ljust(8)))
        self.marker(-1, 7)
        self.record(self.words("7i", 102, 0, 0, 0, 512, 0, 0))
        # Subtable 2: the name and the date (32-bit), the name alone (64-bit).
        name2 = self.text(b"OUG1    ")
        records = [name2 + (self.words("5i", 1, 1, 26, 0, 1) if self.w == 4 else b"")]
        records += subtables
        for k, body in enumerate(records):
            self.marker(-2 - k, 1, 0)
            self.marker(len(body) // self.w)
            self.record(body)
        self.marker(-2 - len(records), 1, 0, 0)

    def identification(self, acode, tcode, subcase, mode, value, cycles, num_wide) -> bytes:
        head = self.words("5i2f2i", acode, tcode, 0, subcase, mode, value, cycles, 0, 1)
        head += self.words("i", num_wide) + self.words("40i", *([0] * 40))
        return head + self.text(b"flexmbd fixture".ljust(128)) + self.text(b" " * 256)

    def modes(self, name: bytes, ids, values, shapes) -> None:
        subtables = []
        for j, value in enumerate(values):
            cycles = np.sqrt(abs(value)) / (2 * np.pi)
            subtables.append(self.identification(21, 7, 1, j + 1, value, cycles, 8))
            rows = b"".join(
                self.words("2i6f", int(g) * 10 + 1, 1, *shapes[j, k]) for k, g in enumerate(ids)
            )
            subtables.append(rows)
        self.table(name, subtables)

    def lama(self, values) -> None:
        ident = self.identification(21, 7, 1, 0, 0.0, 0.0, 7)
        rows = b"".join(self.words("2i5f", *row) for row in lama_rows(values))
        self.table(b"LAMA", [ident, rows])


def write_by_hand(path: Path, e: str, w: int, ids, values, shapes) -> None:
    writer = Writer(e, w)
    writer.header()
    writer.lama(values)
    writer.modes(b"BOUGV1", ids, values, shapes)
    writer.marker(0)
    path.write_bytes(bytes(writer.out))


def check_with_pynastran(path: Path, ids, values, shapes, table: str, lama: bool) -> None:
    """pyNastran's reader finds in `path` the eigenvalues and eigenvectors written."""
    from pyNastran.op2.op2 import read_op2
    from pyNastran.op2.op2_geom import read_op2_geom

    reader = read_op2_geom if "geometry" in path.name else read_op2
    model = reader(str(path), debug=False, log=None, mode="nx")
    precision = 1e-6  # pyNastran 1.4 reads 64-bit eigenvectors into float32 too
    if lama:
        (eig,) = model.eigenvalues.values()
        assert np.allclose(eig.eigenvalues, values, rtol=precision, atol=1e-3), path
    (vectors,) = model.eigenvectors.values()
    assert vectors.table_name == table, (vectors.table_name, table)
    assert np.array_equal(vectors.node_gridtype[:, 0], ids), path
    scale = np.max(np.abs(shapes))
    assert np.allclose(vectors.data, shapes, rtol=0, atol=precision * scale), path
    assert np.allclose(vectors.eigns, values, rtol=precision, atol=1e-3), path
    print(f"{path.name}: pyNastran reads {vectors.data.shape} eigenvectors ({table})")


def stage_two() -> None:
    data = np.load(MODES)
    block = [data[f"block_{k}"] for k in ("ids", "eigenvalues", "shapes")]
    beam = [data[f"beam_{k}"] for k in ("ids", "eigenvalues", "shapes")]
    write_with_pynastran(HERE / "block.op2", *block, "BOUGV1")
    check_with_pynastran(HERE / "block.op2", *block, "BOUGV1", True)
    write_with_pynastran(HERE / "beam.op2", *beam, "OUGV1")
    check_with_pynastran(HERE / "beam.op2", *beam, "OUGV1", True)
    geometry = HERE / "block_geometry.op2"
    write_with_pynastran(geometry, *block, "BOUGV1", geometry=HERE / "block.bdf")
    check_with_pynastran(geometry, *block, "BOUGV1", False)
    write_by_hand(HERE / "block_big.op2", ">", 4, *block)
    check_with_pynastran(HERE / "block_big.op2", *block, "BOUGV1", True)
    write_by_hand(HERE / "block_64.op2", "<", 8, *block)
    # pyNastran 1.4 reads a 64-bit LAMA with the 32-bit layout (7 words of 4 bytes per mode):
    # only the eigenvectors (and the eigenvalues of their identification records) are checked.
    check_with_pynastran(HERE / "block_64.op2", *block, "BOUGV1", False)


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--write", action="store_true", help="stage 2 (pyNastran's Python)")
    parser.add_argument("--pynastran", default="/tmp/pynenv/bin/python")
    args = parser.parse_args()
    if args.write:
        stage_two()
    else:
        stage_one(args.pynastran)
    sys.exit(0)
