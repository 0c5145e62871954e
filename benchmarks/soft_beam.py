"""A soft deformable body under generalized-alpha: steps, rejections, Newton iterations and
the cost of a step in solves with the elastic factor (issue 30, item a).

The soft tetrahedral beam: tet4, E = 1e8 Pa, nu = 0.3, rho = 1000 kg/m^3, 1 x 0.1 x 0.1 m,
nodal elastic coordinates (no modal reduction), clamped to its body frame at face x0, whose
centroid is pinned to the ground by a revolute joint about global z; released horizontal
(along +x) under gravity (0, -9.81, 0). Generalized-alpha, spectral radius 0.9, the default
Newton step-size control, nominal step 1e-3 s, output every 0.01 s.

    python benchmarks/soft_beam.py                 # 1k and 10k, 2 s each
    python benchmarks/soft_beam.py --size 10k --end 0.5
    python benchmarks/soft_beam.py --newton-tolerance 1e-4   # the solver's default: 1e-6
    python benchmarks/soft_beam.py --newton-error-fraction 0.03   # default 0: off

Printed per size: accepted and rejected steps, smallest step, Newton iterations and
factorizations (of the Newton matrix) per step, the wall time of the run (model building
excluded, initial conditions included), one solve with the factorized elastic iteration
matrix beta' M_ff + K_ff (mean of 50 consecutive solves, one thread), and their ratio: the
cost of a step in solves with the factor.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
sys.path.insert(0, str(Path(__file__).resolve().parent))

import flexible_models  # noqa: E402
import numpy as np  # noqa: E402

import flexmbd as fm  # noqa: E402

GRAVITY = (0.0, -9.81, 0.0)

#: Sizes of the beam: 960 and 9,408 elastic coordinates.
SIZES = flexible_models.SOFT_SIZES

STEP, INTERVAL, SPECTRAL_RADIUS = 1e-3, 0.01, 0.9


def soft_body(size: str) -> fm.fe.FlexibleBodyData:
    """The soft beam of `size`, clamped to its frame at face x0 (`flexible_models.soft`)."""
    return flexible_models.soft(size).body


def soft_beam(body: fm.fe.FlexibleBodyData) -> tuple[fm.System, int]:
    """The pinned beam: the system and the body's id."""
    system = fm.System(gravity=GRAVITY)
    beam = system.add_flexible_body(body, name="beam")
    hinge = system.add_node_set_marker(beam, "x0")
    centroid = body.nodes[np.asarray(body.node_sets["x0"])].mean(axis=0)
    pivot = system.add_marker(system.ground, position=centroid)
    system.add_revolute_joint(pivot, hinge, name="hinge")
    return system, beam


def one_solve(body: fm.fe.FlexibleBodyData, count: int = 50) -> float:
    """Mean time of `count` consecutive solves with the factorized beta' M_ff + K_ff at the
    nominal step (one thread, as in the run)."""
    import scipy.sparse as sp

    from flexmbd.fe.modal import factorize

    rho = SPECTRAL_RADIUS
    alpha_m, alpha_f = (2 * rho - 1) / (rho + 1), rho / (rho + 1)
    beta = 0.25 * (0.5 + alpha_f - alpha_m + 0.5) ** 2
    matrix = sp.csc_matrix(body.invariants.k_ff) + sp.csc_matrix(body.invariants.m_ff) * (
        (1 - alpha_m) / ((1 - alpha_f) * beta * STEP**2)
    )
    factor = factorize(
        matrix, dofs=body.reference.free_dofs, nodes=body.nodes, dofs_per_node=3, threads=1
    )
    rhs = np.random.default_rng(1).standard_normal(matrix.shape[0])
    factor.solve(rhs)
    best = np.inf
    for _ in range(3):
        start = time.perf_counter()
        for _ in range(count):
            factor.solve(rhs)
        best = min(best, (time.perf_counter() - start) / count)
    return best


def run(
    size: str,
    end: float,
    newton_tolerance: float | None = None,
    newton_error_fraction: float | None = None,
) -> dict:
    body = soft_body(size)
    system, beam = soft_beam(body)
    compiled = system.compile()
    solver = fm.GeneralizedAlpha(
        SPECTRAL_RADIUS,
        newton_tolerance=newton_tolerance,
        newton_error_fraction=newton_error_fraction,
    )
    start = time.perf_counter()
    result = fm.simulate(compiled, end, STEP, output_interval=INTERVAL, solver=solver)
    wall = time.perf_counter() - start
    stats = result.statistics
    solve = one_solve(body)
    tip_nodes = body.node_ids[np.asarray(body.node_sets["x1"])]
    tip = result.node_positions(beam, tip_nodes).mean(axis=1)
    steps = int(stats["steps"])
    return {
        "size": size,
        "elastic": body.elastic_coordinate_count,
        "end": end,
        "steps": steps,
        "rejected": int(stats["rejected_steps"]),
        "min_step": float(stats["min_step_size"]),
        "newton": stats["newton_iterations"] / steps,
        "factorizations": int(stats["factorizations"]),
        "wall": wall,
        "solve": solve,
        "solves_per_step": wall / steps / solve,
        "tip": tip[-1],
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", choices=sorted(SIZES), action="append")
    parser.add_argument("--end", type=float, default=2.0)
    parser.add_argument(
        "--newton-tolerance", type=float, help="Newton's tolerance (default: the solver's)"
    )
    parser.add_argument(
        "--newton-error-fraction",
        type=float,
        help="Newton's tolerance as a fraction of the step's error (default: the solver's, off)",
    )
    args = parser.parse_args(argv)
    for size in args.size or list(SIZES):
        r = run(size, args.end, args.newton_tolerance, args.newton_error_fraction)
        print(
            f"soft beam {r['size']} ({r['elastic']} elastic coordinates), {r['end']:g} s: "
            f"{r['steps']} steps, {r['rejected']} rejected, smallest {r['min_step']:.2e} s, "
            f"{r['newton']:.2f} Newton its/step, {r['factorizations']} factorizations "
            f"({r['factorizations'] / r['steps']:.2f}/step), wall {r['wall']:.2f} s "
            f"({1e3 * r['wall'] / r['steps']:.3f} ms/step), one solve {1e3 * r['solve']:.3f} ms: "
            f"{r['solves_per_step']:.1f} solves/step; tip x1 centroid at the end "
            f"({r['tip'][0]:.9f}, {r['tip'][1]:.9f}, {r['tip'][2]:.9f}) m",
            flush=True,
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
