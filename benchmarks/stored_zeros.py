"""Zeros stored in the assembled matrices of shells and beams: the core's assembly stores each
element's whole pattern, and the uncoupled membrane and bending, drilling and axial terms of
flat shells and beams leave most of it zero (a quad4 plate: 57 % of the stiffness entries, 83 %
of the mass entries, 94 % of the I_kl entries). The preprocessor now drops them, and
`System.add_flexible_body` drops those of bodies read from older files.

A quad4 aluminium plate 1 x 1 m (t = 5 mm) of n x n elements clamped along its edge x = 0 to
its frame, hinged there to the ground about global y and released horizontal under gravity,
and a steel beam of 200 elements hinged the same way: the time to add the body to a System
and of a 0.2 s run at h = 1e-3 (generalized-alpha), with the zeros dropped and kept (the
preprocessor's and the boundary's conversions as before), and the largest difference of the
final coordinates.

    python benchmarks/stored_zeros.py [--sizes 20 40]
"""

from __future__ import annotations

import argparse
import os
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import scipy.sparse as sp  # noqa: E402

import flexmbd as fm  # noqa: E402
import flexmbd.fe.preprocess as preprocess  # noqa: E402
import flexmbd.system as system_module  # noqa: E402
from flexmbd.fe import Material, Section, build_body, shapes, straight_beam  # noqa: E402


def _kept_csc(parts: tuple) -> sp.csc_matrix:
    data, indices, indptr, shape = parts
    return sp.csc_matrix((data, indices, indptr), shape=shape)


def _kept_csc_tuple(m, n):
    c = sp.csc_matrix(m, dtype=float)
    if not c.has_canonical_format:
        c = c.copy()
        c.sum_duplicates()
    ints = np.int64
    return (np.ascontiguousarray(c.data), c.indices.astype(ints), c.indptr.astype(ints), n)


def body(kind: str, size: int):
    if kind == "plate":
        mesh = shapes.plate((1.0, 1.0), size)
        return build_body(
            mesh.nodes, mesh.elements, Material(7e10, 0.33, 2700.0), shell=0.005,
            node_sets=mesh.node_sets, reference="clamped", reference_nodes="x0",
        )  # fmt: skip
    nodes, elements = straight_beam(1.0, size)
    return build_body(
        nodes, elements, Material(2.1e11, 0.3, 7800.0), section=Section.rectangle(0.02, 0.01),
        reference="clamped", reference_nodes=[0],
    )  # fmt: skip


def run(kind: str, size: int, keep_zeros: bool) -> tuple[float, float, int, np.ndarray]:
    kept = preprocess._csc, system_module._csc_tuple
    if keep_zeros:
        preprocess._csc, system_module._csc_tuple = _kept_csc, _kept_csc_tuple
    try:
        data = body(kind, size)
        system = fm.System(gravity=(0.0, 0.0, -9.81))
        began = time.perf_counter()
        part = system.add_flexible_body(data, name=kind)
        added = time.perf_counter() - began
        axis = fm.rotation("x", -np.pi / 2)  # (the markers' z along global y)
        system.add_revolute_joint(
            system.add_marker(system.ground, orientation=axis),
            system.add_marker(part, orientation=axis),
        )
        began = time.perf_counter()
        result = fm.simulate(system, 0.2, 1e-3, output_interval=0.1)
        ran = time.perf_counter() - began
    finally:
        preprocess._csc, system_module._csc_tuple = kept
    entries = data.stiffness.nnz + data.mass.nnz
    return added, ran, entries, np.asarray(result.coordinates[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[20, 40])
    args = parser.parse_args()
    print("| model | coordinates | K + M entries, kept / dropped | add (s), kept / dropped |"
          " 0.2 s run (s), kept / dropped | final difference |")  # fmt: skip
    print("|---|---|---|---|---|---|")
    for kind, size in [("plate", n) for n in args.sizes] + [("beam", 200)]:
        run(kind, size, False)  # (warm-up)
        kept = run(kind, size, True)
        dropped = run(kind, size, False)
        coordinates = body(kind, size).elastic_coordinate_count
        difference = np.abs(kept[3] - dropped[3]).max()
        print(
            f"| {kind} {size} | {coordinates} | {kept[2]} / {dropped[2]} | "
            f"{kept[0]:.3f} / {dropped[0]:.3f} | {kept[1]:.2f} / {dropped[1]:.2f} | "
            f"{difference:.1e} |"
        )


if __name__ == "__main__":
    main()
