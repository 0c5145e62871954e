"""Compact solids (issue 30, item b): how one solve with the factorized elastic iteration
matrix grows with the size of a compact 3D part, where bars (the other benchmarks) are long
and thin.

A 1 m aluminium cube of tet4 elements (k x k x k cells), clamped at face x0; the matrix
K_ff + c M_ff (c = 1e8 1/s^2, the scale of beta' at h ~ 1e-4 s) is factorized by the
preprocessor's sparse symmetric factor with geometric nested dissection on one thread, as
the condensed solver's is; the mean of 10 solves is timed.

    python benchmarks/compact_solid.py                 # k = 6, 10, 14, 20, 26 (about 40 s)
    python benchmarks/compact_solid.py --cells 6 10 14
    python benchmarks/compact_solid.py --run           # also the time per step in a run
    python benchmarks/compact_solid.py --metis         # also METIS's ordering (pip install pymetis)

With --run, the same cube swings as a pendulum (a revolute joint about z at the centre of its
clamped face, gravity along -y) with generalized-alpha, h = 1e-4 s, its elastic coordinates
condensed: the time per step is the difference of a 2-step and a 2 + N-step run over N (the
factorizations and initial conditions cancel), with the solves with the factor per step.

With --metis, the same matrix is also factorized in the order of METIS's nested dissection of
the mesh's node graph (`pymetis`, not a dependency of flexmbd), each node's coordinates
together, to compare the factor's entries and the solve with the geometric ordering's. The
"GB/s" column is the factor's bytes read twice (forward and backward substitution) over the
time of one solve.
"""

from __future__ import annotations

import argparse
import os
import time
from typing import Any

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import scipy.sparse as sp  # noqa: E402

from flexmbd import _core  # noqa: E402
from flexmbd.fe import Material, build_body, shapes  # noqa: E402
from flexmbd.fe.modal import factorize, lower_triangle  # noqa: E402

ALUMINIUM = Material(7.0e10, 0.33, 2700.0)


def clamped_cube(cells: int) -> Any:
    """The 1 m aluminium tet4 cube of cells^3 cells, clamped at its face x0."""
    mesh = shapes.box((1.0, 1.0, 1.0), (cells, cells, cells), "tet4")
    return build_body(
        mesh.nodes,
        mesh.elements,
        ALUMINIUM,
        node_sets=mesh.node_sets,
        reference="clamped",
        reference_nodes="x0",
    )


def measure(cells: int, metis: bool = False) -> tuple[Any, ...]:
    """Unknowns, factor entries, seconds to factorize, seconds per solve and bytes of the
    factor; with `metis` also the entries, seconds to factorize and per solve in METIS's
    order."""
    body = clamped_cube(cells)
    matrix = sp.csc_matrix(body.invariants.k_ff) + 1e8 * sp.csc_matrix(body.invariants.m_ff)
    start = time.perf_counter()
    factor = factorize(
        matrix, dofs=body.reference.free_dofs, nodes=body.nodes, dofs_per_node=3, threads=1
    )
    seconds = time.perf_counter() - start
    row = (matrix.shape[0], factor.factor_nnz, seconds, solve_time(factor), factor.factor_bytes)
    if not metis:
        return row
    lower = lower_triangle(matrix)
    start = time.perf_counter()
    other = _core.SymmetricFactor(
        matrix.shape[0],
        lower.indptr.astype(np.int64),
        lower.indices.astype(np.int64),
        np.ascontiguousarray(lower.data, dtype=float),
        ordering=metis_ordering(matrix, np.asarray(body.reference.free_dofs) // 3),
        threads=1,
    )
    return (*row, other.factor_nnz, time.perf_counter() - start, solve_time(other))


def solve_time(factor: Any) -> float:
    """Seconds per solve with `factor`: the mean of 10 after one."""
    rhs = np.ones(factor.dim)
    factor.solve(rhs)
    start = time.perf_counter()
    for _ in range(10):
        factor.solve(rhs)
    return (time.perf_counter() - start) / 10


def metis_ordering(matrix: Any, dof_nodes: Any) -> Any:
    """The elimination order (position -> unknown) of METIS's nested dissection of the node
    graph of `matrix` (unknown k on node dof_nodes[k]), each node's unknowns together."""
    try:
        import pymetis
    except ImportError:
        raise SystemExit("--metis needs pymetis: pip install pymetis") from None
    nodes, node_of = np.unique(dof_nodes, return_inverse=True)
    n = matrix.shape[0]
    gather = sp.csr_matrix((np.ones(n), (node_of, np.arange(n))), shape=(len(nodes), n))
    graph = (gather @ (abs(matrix) > 0).astype(float) @ gather.T).tocsr()
    graph.setdiag(0)
    graph.eliminate_zeros()
    adjacency = pymetis.CSRAdjacency(graph.indptr.tolist(), graph.indices.tolist())
    order, _ = pymetis.nested_dissection(adjacency=adjacency)
    unknowns = np.argsort(node_of, kind="stable")  # (grouped by node, in node order)
    first = np.searchsorted(node_of[unknowns], np.arange(len(nodes)))
    counts = np.bincount(node_of, minlength=len(nodes))
    return np.concatenate([unknowns[first[v] : first[v] + counts[v]] for v in order]).astype(
        np.int64
    )


def run_step(cells: int, extra: int) -> tuple[float, float, float]:
    """Seconds per step of the swinging cube (condensed), Newton iterations per step and
    factorizations of the longer run."""
    import flexmbd as fm

    body = clamped_cube(cells)
    system = fm.System(gravity=(0.0, -9.81, 0.0))
    cube = system.add_flexible_body(body, condense=True, name="cube")
    centre = (0.0, 0.5, 0.5)  # of the clamped face x0, in the body frame (= global here)
    system.add_revolute_joint(
        system.add_marker(system.ground, position=centre), system.add_marker(cube, position=centre)
    )
    model = system.compile()
    h = 1e-4
    walls, result = [], None
    for count in (2, 2 + extra):
        start = time.perf_counter()
        result = fm.simulate(model, count * h, h, output_interval=count * h)
        walls.append(time.perf_counter() - start)
    stats = result.statistics
    return (
        (walls[1] - walls[0]) / extra,
        stats["newton_iterations"] / stats["steps"],
        stats["factorizations"],
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cells", type=int, nargs="+", default=[6, 10, 14, 20, 26])
    parser.add_argument("--run", action="store_true", help="also the time per step of a run")
    parser.add_argument("--steps", type=int, default=20, help="extra steps of --run")
    parser.add_argument("--metis", action="store_true", help="also METIS's ordering (pymetis)")
    args = parser.parse_args(argv)
    rows = [measure(k, args.metis) for k in args.cells]
    head = "| cells | unknowns | factor entries | factorize (s) | one solve (ms) | GB/s |"
    rule = "|---|---|---|---|---|---|"
    if args.metis:
        head += " METIS: entries | factorize (s) | one solve (ms) |"
        rule += "---|---|---|"
    print(head)
    print(rule)
    for k, (n, nnz, factor, solve, size, *other) in zip(args.cells, rows, strict=True):
        line = f"| {k}^3 | {n} | {nnz / 1e6:.2f}M | {factor:.2f} | {1e3 * solve:.2f} | "
        line += f"{2 * size / solve / 1e9:.1f} |"
        if other:
            line += f" {other[0] / 1e6:.2f}M | {other[1]:.2f} | {1e3 * other[2]:.2f} |"
        print(line)
    n = np.log([r[0] for r in rows])
    if len(rows) >= 2:
        for name, column in (("factor entries", 1), ("one solve", 3)):
            y = np.log([r[column] for r in rows])
            print(
                f"growth exponent of {name}: fit {np.polyfit(n, y, 1)[0]:.2f}, "
                f"last pair {(y[-1] - y[-2]) / (n[-1] - n[-2]):.2f}"
            )
    if args.run:
        steps = [run_step(k, args.steps) for k in args.cells]
        print("| cells | unknowns | time per step (ms) | Newton iterations per step | "
              "solves per step (step / one solve) |")  # fmt: skip
        print("|---|---|---|---|---|")
        for k, row, (per_step, newton, _) in zip(args.cells, rows, steps, strict=True):
            print(f"| {k}^3 | {row[0]} | {1e3 * per_step:.2f} | {newton:.2f} | "
                  f"{per_step / row[3]:.1f} |")  # fmt: skip
        if len(rows) >= 2:
            y = np.log([s[0] for s in steps])
            print(
                f"growth exponent of the time per step: fit {np.polyfit(n, y, 1)[0]:.2f}, "
                f"last pair {(y[-1] - y[-2]) / (n[-1] - n[-2]):.2f}"
            )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
