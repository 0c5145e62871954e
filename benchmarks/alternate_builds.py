"""One round of an old-versus-new comparison of two builds (issue 29): a few figures of the
flexmbd on sys.path. Alternate the builds, round after round, so that both see the same
machine state:

    PYTHONPATH=/path/to/old/checkout/python python benchmarks/alternate_builds.py old
    python benchmarks/alternate_builds.py new

Figures: A02 N = 40 with generalized-alpha (rho 0.9, h = 1e-3 s, 1 s) in steps/s; Andrews'
mechanism with dopri5 + projection (0.03 s) in s; the flexible slider-crank (0.02 s) in
steps/s; the nodal 1k tet4 pendulum bar (0.1 s) in us/step; A02 N = 20 with RK4 in joint
coordinates (0.2 s) in s. Best of 3 runs (2 for the last).
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
sys.path.insert(0, str(Path(__file__).resolve().parent))

import flexible_models as models  # noqa: E402

import flexmbd as fm  # noqa: E402


def best(run, repeat: int = 3):
    times, result = [], None
    for _ in range(repeat):
        start = time.perf_counter()
        result = run()
        times.append(time.perf_counter() - start)
    return min(times), result


def main() -> None:
    out = {}
    four_bar = fm.examples.four_bar(40).system.compile()
    solver = fm._core.GeneralizedAlpha(0.9)
    wall, r = best(lambda: fm.simulate(four_bar, 1.0, 1e-3, output_interval=1.0, solver=solver))
    out["A02 N=40 steps/s"] = round(r.statistics["steps"] / wall)
    example = fm.examples.EXAMPLES["andrews"]()
    andrews = example.system.compile()
    dopri = fm._core.ExplicitSolver("dopri5", "projection")
    wall, _ = best(lambda: fm.simulate(andrews, 0.03, example.step_size, solver=dopri))
    out["Andrews dopri5 s"] = round(wall, 4)
    example = fm.examples.EXAMPLES["flexible-slider-crank"]()
    crank = example.system.compile()
    wall, r = best(lambda: fm.simulate(crank, 0.02, example.step_size, solver=example.solver))
    out["slider-crank steps/s"] = round(r.statistics["steps"] / wall)
    model = models.nodal("1k")
    system = fm.System(gravity=models.GRAVITY)
    bar = system.add_flexible_body(model.body, name="bar")
    hinge = system.add_node_set_marker(bar, "x0")
    centroid = model.body.nodes[models.nodes_of(model, "x0")].mean(axis=0)
    system.add_revolute_joint(system.add_marker(system.ground, position=centroid), hinge)
    pendulum = system.compile()
    wall, r = best(lambda: fm.simulate(pendulum, 0.1, 1e-3))
    out["nodal 1k us/step"] = round(1e6 * wall / r.statistics["steps"], 1)
    twenty = fm.examples.four_bar(20).system.compile()
    rk4 = fm._core.ExplicitSolver("rk4", "joint-coordinates")
    wall, _ = best(lambda: fm.simulate(twenty, 0.2, 1e-3, output_interval=0.2, solver=rk4), 2)
    out["A02 N=20 rk4 joint s"] = round(wall, 3)
    print(sys.argv[1] if len(sys.argv) > 1 else "this build", out, flush=True)


if __name__ == "__main__":
    main()
