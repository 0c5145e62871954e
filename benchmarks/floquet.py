"""Cost of a Floquet analysis (`fm.floquet`): 4 n + 1 runs of one period for n independent
coordinates. Prints the size, the runs and steps, the wall time and the time per step of
the runs, for a rigid pendulum on a shaken support, a flexible steel pendulum (4 beam
elements) and the flexible double pendulum of `fm.examples` (both at rest: exp(s T) is then
the exact answer, and the largest |mu| - 1 shows the differences' error), with the runs
one after the other and two at once (threads; the same monodromy to the last bit).

    python benchmarks/floquet.py
"""

import time

import numpy as np

import flexmbd as fm
from flexmbd.fe import Material, Section, build_body, straight_beam


def shaken_pendulum() -> tuple[fm.System, fm.State | None, float, int]:
    rate = 2 * np.sqrt(9.81)
    return fm.examples.shaken_pendulum(0.05, rate), None, 2 * np.pi / rate, 1600


def flexible_pendulum() -> tuple[fm.System, fm.State | None, float, int]:
    nodes, beams = straight_beam(1.0, 4)
    data = build_body(
        nodes, beams, Material(2.1e11, 0.3, 7800.0), section=Section.rectangle(0.02, 0.01),
        reference="clamped", reference_nodes=[0],
    )  # fmt: skip
    system = fm.System(gravity=(0, -9.81, 0))
    beam = system.add_flexible_body(data, orientation=fm.rotation("z", -np.pi / 2))
    system.add_revolute_joint(system.add_marker(system.ground), system.add_marker(beam))
    return system, fm.equilibrium(system), 0.05, 100


def flexible_double_pendulum() -> tuple[fm.System, fm.State | None, float, int]:
    system = fm.examples.flexible_double_pendulum().system
    return system, fm.equilibrium(system), 0.05, 200


def main() -> None:
    print(
        "| model | n | runs | steps per run | wall, 1 worker (s) | ms per step | wall, 2 "
        "workers (s) | max abs(mu) - 1 |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for name, build in [
        ("rigid pendulum, shaken support", shaken_pendulum),
        ("flexible steel pendulum (4 beams), at rest", flexible_pendulum),
        ("flexible double pendulum, at rest", flexible_double_pendulum),
    ]:
        system, state, period, steps = build()
        model = system.compile()
        state = fm.State.of_model(model) if state is None else state
        walls = []
        for workers in (1, 2):
            began = time.perf_counter()
            analysis = fm.floquet(model, state, period, period / steps, workers=workers)
            walls.append(time.perf_counter() - began)
        wall = walls[0]
        n = analysis.basis.shape[1]
        runs = 4 * n + 1
        growth = float(np.abs(analysis.multipliers).max() - 1.0)
        print(
            f"| {name} | {n} | {runs} | {steps} | {wall:.2f} | {1e3 * wall / (runs * steps):.3f} "
            f"| {walls[1]:.2f} | {growth:.1e} |"
        )


if __name__ == "__main__":
    main()
