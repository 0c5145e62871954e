"""Joint coordinates through the singular configurations of closed loops (issue 30): IFToMM A02,
the N-four-bar with N = 2 (reference R5), in joint coordinates with its two in-line joints cut,
against the exact B0 at t = 10 s. The cranks lie flat twice per turn (20 times in 10 s): there
two singular values of C_cut B pass through zero.

Prints B0's position and velocity errors at t = 10 s:

- RK4 at fixed steps h (records every 0.04 s, a multiple of every h, so that the steps are not
  cut to land on records);
- Dormand-Prince 5(4) from h = 1e-3 at relative tolerances rtol (absolute 1e-2 rtol), records
  every 1 s (the step size is free);

with the function evaluations, the Newton iterations of the projections onto the cut joints
and the wall time of each run.

    python benchmarks/joint_coordinates_singular.py
    python benchmarks/joint_coordinates_singular.py --steps 2e-3 1e-3 --tolerances 1e-8
    python benchmarks/joint_coordinates_singular.py --markdown   # tables for benchmarks/README.md
"""

from __future__ import annotations

import argparse
import os
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import flexmbd as fm  # noqa: E402

STEPS = [8e-3, 4e-3, 2e-3, 1e-3, 5e-4, 2.5e-4]
TOLERANCES = [1e-6, 1e-7, 1e-8, 1e-9, 1e-10]


def run(example, solver, step_size, output_interval):
    start = time.perf_counter()
    try:
        result = fm.simulate(
            example.system, 10.0, step_size, output_interval=output_interval, solver=solver
        )
    except fm.FlexmbdError as error:
        return {"failed": str(error).splitlines()[0], "seconds": time.perf_counter() - start}
    errors = example.check(result)
    stats = result.statistics
    return {
        "position": errors["B0 position error at t = 10 s"],
        "velocity": errors["B0 velocity error at t = 10 s"],
        "steps": stats["steps"],
        "rejected": stats.get("rejected_steps", 0),
        "evaluations": stats["function_evaluations"],
        "newton": stats["newton_iterations"],
        "seconds": time.perf_counter() - start,
    }


def row(label, r, markdown):
    if "failed" in r:
        cells = [label, "failed", r["failed"][:60], "", "", "", f"{r['seconds']:.1f}"]
    else:
        cells = [
            label,
            f"{r['position']:.2e}",
            f"{r['velocity']:.2e}",
            f"{r['steps']} ({r['rejected']})",
            str(r["evaluations"]),
            str(r["newton"]),
            f"{r['seconds']:.1f}",
        ]
    if markdown:
        return "| " + " | ".join(cells) + " |"
    return "  ".join(f"{c:>14}" for c in cells)


def header(first, markdown):
    cells = [first, "B0 position", "B0 velocity", "steps (rej.)", "evaluations", "Newton", "s"]
    if markdown:
        return "| " + " | ".join(cells) + " |\n|" + "---|" * len(cells)
    return "  ".join(f"{c:>14}" for c in cells)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=float, nargs="*", default=STEPS)
    parser.add_argument("--tolerances", type=float, nargs="*", default=TOLERANCES)
    parser.add_argument("--formulation", default="joint-space", help="joint-space or decoupled")
    parser.add_argument("--markdown", action="store_true")
    args = parser.parse_args()
    example = fm.examples.four_bar(2)
    print(f"RK4, {args.formulation}:")
    print(header("h", args.markdown))
    for h in args.steps:
        solver = fm.ExplicitSolver("rk4", "joint-coordinates", formulation=args.formulation)
        print(row(f"{h:g}", run(example, solver, h, 0.04), args.markdown), flush=True)
    print(f"\nDormand-Prince 5(4), {args.formulation}:")
    print(header("rtol", args.markdown))
    for tolerance in args.tolerances:
        solver = fm.ExplicitSolver(
            "dopri5",
            "joint-coordinates",
            formulation=args.formulation,
            relative_tolerance=tolerance,
            absolute_tolerance=1e-2 * tolerance,
        )
        print(row(f"{tolerance:g}", run(example, solver, 1e-3, 1.0), args.markdown), flush=True)


if __name__ == "__main__":
    main()
