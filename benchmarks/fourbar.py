"""IFToMM A02 N-four-bar (N = 40 by default: 81 rigid bodies, 121 joints) in flexmbd, side by
side with Exudyn if it is installed: steps per second, Newton iterations per step,
factorizations, and the error of B0 against the reference.

Both codes build the same 3D model (benchmarks/exudyn_fourbar.py describes it) and integrate it
with implicit index-3 generalized-alpha at the same step size. The reference is the exact
reduction of the mechanism to one degree of freedom (all cranks stay parallel), integrated
finely; for N = 2 it reproduces the published IFToMM values.

    python benchmarks/fourbar.py                  # N = 40, h = 1e-3, 2 s, best of 3
    python benchmarks/fourbar.py --n 2 --end 10   # the published benchmark case

Timings are wall-clock times of the simulation call only (model building excluded, initial
conditions included, as on the Exudyn side); numpy's BLAS threads are limited to one so that
they do not compete for the two cores.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
sys.path.insert(0, str(Path(__file__).resolve().parent))

import exudyn_fourbar  # noqa: E402

import flexmbd as fm  # noqa: E402

CONFIGS = {
    # name: GeneralizedAlpha arguments
    "modified-rho0.99": {"spectral_radius": 0.99, "jacobian": "modified"},
    "modified-rho0.9": {"spectral_radius": 0.9, "jacobian": "modified"},
    "step-rho0.99": {"spectral_radius": 0.99, "jacobian": "step"},
    "full-rho0.99": {"spectral_radius": 0.99, "jacobian": "full"},
    "modified-lu-rho0.99": {"spectral_radius": 0.99, "jacobian": "modified", "linear_solver": "lu"},
    # No numerical dissipation: velocity projection and consistent accelerations every step.
    "modified-rho1": {"spectral_radius": 1.0, "jacobian": "modified"},
}


def run_flexmbd(n: int, step: float, end: float, config: str, repeat: int) -> dict:
    """Best of `repeat` runs of one configuration."""
    example = fm.examples.four_bar(n)
    model = example.system.compile()
    solver = fm.GeneralizedAlpha(**CONFIGS[config])
    best = None
    for _ in range(repeat):
        start = time.perf_counter()
        result = fm.simulate(model, end, step, output_interval=end, solver=solver)
        wall = time.perf_counter() - start
        if best is None or wall < best[0]:
            best = (wall, result)
    wall, result = best
    stats = result.statistics
    p = result.sensor(example.items["B0 position"])[-1]
    v = result.sensor(example.items["B0 velocity"])[-1]
    return {
        "tool": "flexmbd",
        "config": config,
        "steps": stats["steps"],
        "wall_time": wall,
        "steps_per_second": stats["steps"] / wall,
        "newton_iterations_per_step": stats["newton_iterations"] / stats["steps"],
        "factorizations": stats["factorizations"],
        "b0_position": (float(p[0]), float(p[1])),
        "b0_velocity": (float(v[0]), float(v[1])),
    }


def run_exudyn(n: int, step: float, end: float, config: str, repeat: int) -> dict | None:
    """Best of `repeat` runs of Exudyn in fresh interpreters; None without Exudyn."""
    try:
        import exudyn  # noqa: F401
    except ImportError:
        return None
    best = None
    for _ in range(repeat):
        res = exudyn_fourbar.run_isolated(n, step, end, config)
        if best is None or res["wall_time"] < best["wall_time"]:
            best = res
    best = dict(best)
    best["tool"] = "exudyn " + best.get("exudyn_version", "")
    best["factorizations"] = round(best["jacobians_per_step"] * best["steps"])
    return best


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--n", type=int, default=40)
    parser.add_argument("--step", type=float, default=1e-3)
    parser.add_argument("--end", type=float, default=2.0)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--configs", nargs="*", default=list(CONFIGS))
    parser.add_argument("--exudyn-config", default=exudyn_fourbar.FASTEST_CONFIG)
    parser.add_argument("--no-exudyn", action="store_true")
    args = parser.parse_args(argv)

    reference = exudyn_fourbar.reference_b0(args.n, args.end)
    rows = [run_flexmbd(args.n, args.step, args.end, c, args.repeat) for c in args.configs]
    exudyn_row = None
    if not args.no_exudyn:
        exudyn_row = run_exudyn(args.n, args.step, args.end, args.exudyn_config, args.repeat)
        if exudyn_row is not None:
            rows.append(exudyn_row)

    print(
        f"A02 N-four-bar, N = {args.n} ({2 * args.n + 1} bodies), h = {args.step:g} s, "
        f"t = 0 .. {args.end:g} s, best of {args.repeat}"
    )
    header = (
        f"{'tool':<16} {'config':<36} {'steps':>6} {'wall [s]':>9} {'steps/s':>8} "
        f"{'its/step':>8} {'factor.':>7} {'B0 pos err':>10} {'B0 vel err':>10}"
    )
    print(header)
    print("-" * len(header))
    for r in rows:
        ep, ev = exudyn_fourbar.b0_errors(r, reference)
        print(
            f"{r['tool']:<16} {r['config']:<36} {r['steps']:>6} {r['wall_time']:>9.3f} "
            f"{r['steps_per_second']:>8.0f} {r['newton_iterations_per_step']:>8.2f} "
            f"{r['factorizations']:>7} {ep:>10.2e} {ev:>10.2e}"
        )
    if exudyn_row is None:
        if not args.no_exudyn:
            print("(exudyn not installed: `pip install exudyn` for the side-by-side run)")
    else:
        ours = rows[:-1]
        exudyn_rate = exudyn_row["steps_per_second"]
        same = [r for r in ours if r["config"] == "modified-rho0.99"]
        if same:
            print(
                f"flexmbd modified-rho0.99 / Exudyn {exudyn_row['config']} (same spectral radius): "
                f"{same[0]['steps_per_second'] / exudyn_rate:.2f}x the steps per second"
            )
        fastest = max(ours, key=lambda r: r["steps_per_second"])
        print(
            f"fastest flexmbd ({fastest['config']}) / Exudyn: "
            f"{fastest['steps_per_second'] / exudyn_rate:.2f}x the steps per second"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
