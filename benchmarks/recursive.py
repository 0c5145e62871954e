"""Time per step of the joint-coordinate formulations (issue 6) as the elastic coordinates of a
chain of three deformable links grow from about 10 to 10,000 per link.

The model is `examples.flexible_robot_arm(elements)`: three nodal beams (6 elastic coordinates
per node, the first node clamped to the body frame), the base joint driven, shoulder and elbow
free, all hinges at deformed beam-node markers. Per formulation and size it prints the time of
one classical Runge-Kutta step (4 evaluations of the accelerations and the kinematics), from
two runs of `--steps` and 2 x `--steps` steps of 1e-9 s (stable for the finest meshes): their
difference, so that set-up, factorization of M_ff and initial conditions are excluded; best
of `--repeat`. Then the fitted growth exponent of the time per step in the number of elastic
coordinates:

- augmented: the explicit solver with projection, augmented formulation (seed eq. 26, dense;
  up to 2000 coordinates);
- joint-space: joint coordinates, (B^T M B) p_dd = B^T (f - M gamma_B) with B formed (dense;
  up to 2000 coordinates);
- coupled: joint coordinates, the loosely coupled sparse system of seed eq. 40 (sparse LU);
- decoupled: joint coordinates, seed eq. 41 (M_ff factorized once; reduced system of constant
  size).

Also printed: the size of the system solved per evaluation (`reduced_system_size`).

    python benchmarks/recursive.py                   # all sizes
    python benchmarks/recursive.py --elements 2 17 167 --repeat 1
    python benchmarks/recursive.py --markdown        # the table for benchmarks/README.md
"""

from __future__ import annotations

import argparse
import os
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

import flexmbd as fm  # noqa: E402

DENSE_LIMIT = 2000
# Eq. 40's sparse LU grows fast (6 s per step at 9021 coordinates): larger models are skipped.
COUPLED_LIMIT = 10000
FORMULATIONS = {
    "augmented": ("projection", "augmented"),
    "joint-space": ("joint-coordinates", "joint-space"),
    "coupled": ("joint-coordinates", "coupled"),
    "decoupled": ("joint-coordinates", "decoupled"),
}


def run(model, strategy, formulation, steps, h=1e-9):
    solver = fm.ExplicitSolver("rk4", strategy, formulation=formulation)
    start = time.perf_counter()
    result = fm.simulate(model, steps * h, h, output_interval=steps * h, solver=solver)
    return time.perf_counter() - start, result


def time_per_step(model, strategy, formulation, steps, repeat):
    best = np.inf
    size = 0
    for _ in range(repeat):
        t1, _ = run(model, strategy, formulation, steps)
        t2, result = run(model, strategy, formulation, 2 * steps)
        best = min(best, (t2 - t1) / steps)
        size = result.statistics["reduced_system_size"]
    return best, size


def exponent(sizes, times):
    """Least-squares slope of log(time) over log(size) (sizes with a measured time)."""
    pairs = [(s, t) for s, t in zip(sizes, times, strict=True) if np.isfinite(t) and t > 0]
    if len(pairs) < 2:
        return np.nan
    x, y = np.log([p[0] for p in pairs]), np.log([p[1] for p in pairs])
    return float(np.polyfit(x, y, 1)[0])


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--elements", type=int, nargs="+", default=[2, 5, 17, 50, 167, 500, 1667])
    parser.add_argument("--formulations", nargs="+", default=list(FORMULATIONS))
    parser.add_argument("--steps", type=int, default=5)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--markdown", action="store_true")
    args = parser.parse_args()

    rows = []
    for elements in args.elements:
        example = fm.examples.flexible_robot_arm(elements=elements)
        model = example.system.compile()
        per_link = 6 * elements
        row = {"elements": elements, "per link": per_link, "coordinates": model.coordinate_count}
        for name in args.formulations:
            strategy, formulation = FORMULATIONS[name]
            limit = {"augmented": DENSE_LIMIT, "joint-space": DENSE_LIMIT, "coupled": COUPLED_LIMIT}
            if model.coordinate_count > limit.get(name, np.inf):
                row[name] = (np.nan, 0)
                continue
            row[name] = time_per_step(model, strategy, formulation, args.steps, args.repeat)
            print(
                f"  {per_link:6d} elastic coordinates per link, {name:11s}: "
                f"{1e3 * row[name][0]:9.3f} ms per step (system size {row[name][1]})",
                flush=True,
            )
        rows.append(row)

    sizes = [r["per link"] for r in rows]
    header = "| elastic coordinates per link | model coordinates | " + " | ".join(
        f"{name} (ms/step; system size)" for name in args.formulations
    )
    print()
    print(header + " |")
    print("|" + "---|" * (2 + len(args.formulations)))
    for r in rows:
        cells = []
        for name in args.formulations:
            t, size = r[name]
            if not np.isfinite(t):
                cells.append("not run (size)")
            else:
                cells.append(f"{1e3 * t:.3f}; {size if size else '-'}")
        print(f"| {r['per link']} | {r['coordinates']} | " + " | ".join(cells) + " |")
    fits = [exponent(sizes, [r[name][0] for r in rows]) for name in args.formulations]
    print("| fitted growth exponent, all sizes | | " + " | ".join(f"{f:.2f}" for f in fits) + " |")
    # The asymptotic range: 1000 elastic coordinates per link and more (fixed costs of the
    # kinematics and of the reduced system no longer dominate).
    large = [k for k, s in enumerate(sizes) if s >= 1000]
    tail = [
        exponent([sizes[k] for k in large], [rows[k][name][0] for k in large])
        for name in args.formulations
    ]
    print(
        "| fitted growth exponent, >= 1000 per link | | "
        + " | ".join("-" if not np.isfinite(f) else f"{f:.2f}" for f in tail)
        + " |"
    )
    if not args.markdown:
        for name, f in zip(args.formulations, fits, strict=True):
            print(f"{name}: time per step grows with exponent {f:.2f} in the elastic coordinates")


if __name__ == "__main__":
    main()
