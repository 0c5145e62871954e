"""The same models under every solver (issue 5): generalized-alpha, and Runge-Kutta 4 and
Dormand-Prince 5(4) with the seed's three strategies and both formulations, and in joint
coordinates (issue 6, first part: rigid trees with cut joints).

Prints, per model and solver: accepted steps, function evaluations (explicit: evaluations of
the equations of motion; generalized-alpha: Newton iterations), run time (simulation call
only, best of ``--repeat``), the final and the largest constraint violation, and the model's
own accuracy measure (the example's ``check``: error against the reference solution, or
energy drift for Bricard's mechanism).

    python benchmarks/solvers.py                 # all models, 1 run each
    python benchmarks/solvers.py --repeat 3 --models a01 a02
    python benchmarks/solvers.py --markdown      # the table for benchmarks/README.md

Exudyn has no counterpart: its explicit solvers accept no joints ("Explicit solvers are in
general only applicable for systems without constraints", Exudyn docs, ExplicitSolvers.rst).
"""

from __future__ import annotations

import argparse
import os
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import flexmbd as fm  # noqa: E402

# name: (builder, end time, fixed RK4 step, Dormand-Prince tolerance)
MODELS = {
    "a01": (fm.examples.pendulum, 10.0, 1e-3, 1e-10),
    "a02": (lambda: fm.examples.four_bar(2), 10.0, 1e-3, 1e-10),
    "andrews": (fm.examples.andrews, 0.03, 5e-6, 1e-10),
    "four-bar-spatial": (fm.examples.four_bar_spatial, 10.0, 1e-3, 1e-11),
    "bricard": (fm.examples.bricard, 10.0, 1e-3, 1e-11),
}


def solvers(example, rk4_step, tolerance):
    """(label, solver, step size) for every configuration."""
    tol = {"relative_tolerance": tolerance, "absolute_tolerance": 1e-2 * tolerance}
    yield "generalized-alpha (example's settings)", example.solver, example.step_size
    baumgarte = (20.0, 20.0)
    for method, step in [("rk4", rk4_step), ("dopri5", rk4_step)]:
        options = tol if method == "dopri5" else {}
        yield (
            f"{method} integrate-all, Baumgarte (20, 20)",
            fm.ExplicitSolver(method, "integrate-all", baumgarte=baumgarte, **options),
            step,
        )
        for strategy in ["partitioning", "projection"]:
            for formulation in ["augmented", "embedding"]:
                yield (
                    f"{method} {strategy}, {formulation}",
                    fm.ExplicitSolver(method, strategy, formulation=formulation, **options),
                    step,
                )
        yield (
            f"{method} joint coordinates",
            fm.ExplicitSolver(method, "joint-coordinates", **options),
            step,
        )


def run(example, end, step, solver, repeat):
    best, result, error = float("inf"), None, None
    for _ in range(repeat):
        start = time.perf_counter()
        try:
            result = fm.simulate(
                example.system, end, step, output_interval=example.output_interval, solver=solver
            )
            error = None
        except fm.SimulationError as failure:
            result, error = failure.result, failure
        except fm.FlexmbdError as refused:  # a model the solver does not take
            return None, refused, float("nan")
        best = min(best, time.perf_counter() - start)
    return result, error, best


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--models", nargs="*", default=list(MODELS), choices=list(MODELS))
    parser.add_argument("--repeat", type=int, default=1)
    parser.add_argument("--markdown", action="store_true", help="print Markdown tables")
    args = parser.parse_args()
    for name in args.models:
        builder, end, rk4_step, tolerance = MODELS[name]
        example = builder()
        model = example.system.compile()
        title = (
            f"{name}: {example.description}; {model.coordinate_count} coordinates, "
            f"{model.constraint_count} constraint equations, {end} s"
        )
        if args.markdown:
            print(f"\n#### {title}\n")
            print(
                "| solver | steps | evaluations | time (s) | final viol. | max viol. | accuracy |"
            )
            print("|---|---|---|---|---|---|---|")
        else:
            print(f"\n{title}")
        for label, solver, step in solvers(example, rk4_step, tolerance):
            result, error, seconds = run(example, end, step, solver, args.repeat)
            if result is None:
                message = f"not supported ({str(error).removeprefix('invalid model: ')})"
                if args.markdown:
                    print(f"| {label} | - | - | - | - | - | {message} |", flush=True)
                else:
                    print(f"  {label:42s} {message}", flush=True)
                continue
            stats = result.statistics
            evaluations = stats.get("function_evaluations") or stats.get("newton_iterations")
            violation = result.constraint_violation
            if error is None:
                checked = example.check(result) if example.check else {}
                accuracy = max(checked.values()) if checked else float("nan")
                accuracy_text = f"{accuracy:.2e}"
            else:
                accuracy_text = f"failed at t = {result.time[-1]:.4g} s: {type(error).__name__}"
            cells = [
                label,
                f"{stats['steps']}",
                f"{evaluations}",
                f"{seconds:.2f}",
                f"{violation[-1]:.1e}",
                f"{violation.max():.1e}",
                accuracy_text,
            ]
            if args.markdown:
                print("| " + " | ".join(cells) + " |", flush=True)
            else:
                print(
                    f"  {cells[0]:42s} steps {cells[1]:>7s}  evals {cells[2]:>7s}  "
                    f"{cells[3]:>6s} s  viol {cells[4]} (max {cells[5]})  accuracy {cells[6]}",
                    flush=True,
                )


if __name__ == "__main__":
    main()
