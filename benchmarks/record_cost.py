"""The cost of recording every step: time per step of runs that record after each step, the
case where what a record computes (energies, reactions, sensors, the power of the forces no
potential accounts for) weighs most against the step itself.

    python benchmarks/record_cost.py            # best of 3 runs per model

Models: the flexible slider-crank of the examples (R4; 0.05 s), the soft tet4 beam of
`soft_beam.py` at 1k elastic coordinates with structural damping (0.1 s), and a chain of
ten rigid links with a callback force (a viscous drag in Python) on each (1 s).
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
sys.path.insert(0, str(Path(__file__).resolve().parent))

import flexible_models  # noqa: E402

import flexmbd as fm  # noqa: E402


def slider_crank():
    example = fm.examples.flexible_slider_crank()
    return example.system.compile(), 0.05, example.step_size, example.solver


def soft_beam():
    data = flexible_models.soft("1k").body
    system = fm.System(gravity=(0.0, -9.81, 0.0))
    beam = system.add_flexible_body(data, name="beam", rayleigh_damping=(2.0, 1e-4))
    centroid = data.nodes[list(data.node_sets["x0"])].mean(axis=0)
    system.add_revolute_joint(
        system.add_marker(system.ground, position=centroid), system.add_node_set_marker(beam, "x0")
    )
    return system.compile(), 0.1, 1e-3, fm.GeneralizedAlpha(0.9)


def chain():
    system = fm.System(gravity=(0.0, -9.81, 0.0))
    parent, x = system.ground, 0.0
    for k in range(10):
        link = system.add_rigid_body(1.0, (1e-3, 0.1, 0.1), position=(x + 0.5, 0.0, 0.0))
        system.add_revolute_joint(
            system.add_marker(parent, position=(0.5 if k else 0.0, 0.0, 0.0)),
            system.add_marker(link, position=(-0.5, 0.0, 0.0)),
        )

        def drag(t, q, qd):
            return [-0.1 * v for v in qd]

        system.add_callback_force([link], drag)
        parent, x = link, x + 1.0
    return system.compile(), 1.0, 1e-3, fm.GeneralizedAlpha(0.9)


def main() -> None:
    for name, build in [
        ("slider-crank", slider_crank),
        ("soft beam 1k", soft_beam),
        ("chain", chain),
    ]:
        model, end, step, solver = build()
        best, steps = float("inf"), 0
        for _ in range(3):
            started = time.perf_counter()
            result = fm.simulate(model, end, step, solver=solver)
            best = min(best, time.perf_counter() - started)
            steps = int(result.statistics["steps"])
        print(
            f"{name:14s} {steps:6d} steps, {len(result.time)} records: "
            f"{1e3 * best / steps:.4f} ms/step"
        )


if __name__ == "__main__":
    main()
