"""Cost of the second order of point masses turning with their nodes (`attached.rs`): a steel
beam of 10 elements hinged at one end, swinging under gravity, with 1 or 10 point masses
that have a rotary inertia and an offset. Prints the time of one residual and of one Newton
matrix (`Model.evaluate`, mean of 1,000 after 100) and of a 1 s run at h = 1e-3, with the
term and with the masses moving linearly (the term left out, as before it existed).

`--plate`: the time to add an 80 x 80 quad4 plate (38,880 coordinates) with one offset mass
to a System, the masses taken from the body's record (`FlexibleBodyData.point_masses`) and,
as for a body file of an earlier flexmbd without one, from its mass matrix beyond its
elements' (assembled again).

    python benchmarks/point_masses.py [--plate]
"""

import dataclasses
import os
import sys
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

import flexmbd as fm  # noqa: E402
import flexmbd.system as system_module  # noqa: E402
from flexmbd.fe import Material, Section, build_body, shapes, straight_beam  # noqa: E402


def model(masses: int, second_order: bool) -> fm._core.Model:
    nodes, elements = straight_beam(1.0, 10)
    equipment = (0.5, np.diag([1e-3, 2e-3, 3e-3]), np.array([0.05, 0.03, 0.02]))
    body = build_body(
        nodes, elements, Material(2.1e11, 0.3, 7800.0), section=Section.circle(0.01),
        reference="clamped", reference_nodes=[0],
        point_masses={k: equipment for k in range(1, masses + 1)} or None,
    )  # fmt: skip
    kept = system_module._attached_masses
    if not second_order:
        system_module._attached_masses = lambda body, basis: []
    try:
        system = fm.System(gravity=(0.0, -9.81, 0.0))
        beam = system.add_flexible_body(body, name="beam")
        system.add_revolute_joint(system.add_marker(system.ground), system.add_node_marker(beam, 1))
        return system.compile()
    finally:
        system_module._attached_masses = kept


def evaluation(compiled: fm._core.Model, **coefficients: float) -> float:
    """Seconds per `evaluate` at the start state."""
    state = fm.State.of_model(compiled)
    args = (
        state.time,
        state.coordinates,
        state.velocities,
        np.zeros(compiled.coordinate_count),
        np.zeros(compiled.constraint_count),
    )
    for _ in range(100):
        compiled.evaluate(*args, **coefficients)
    began = time.perf_counter()
    for _ in range(1000):
        compiled.evaluate(*args, **coefficients)
    return (time.perf_counter() - began) / 1000


def main() -> None:
    evaluation(model(1, True))  # (warm-up: the first model's evaluations were slower)
    print(
        "| masses | second order | residual (us) | Newton matrix (us) | 1 s run (ms) | its/step |"
    )
    print("|---|---|---|---|---|---|")
    for masses in (1, 10):
        for second_order in (True, False):
            compiled = model(masses, second_order)
            residual = evaluation(compiled)
            matrix = evaluation(compiled, mass=1.0, velocity=1.0, position=1.0)
            fm.simulate(compiled, 0.01, 1e-3)
            began = time.perf_counter()
            result = fm.simulate(compiled, 1.0, 1e-3, output_interval=0.1)
            run = time.perf_counter() - began
            stats = result.statistics
            print(
                f"| {masses} | {'yes' if second_order else 'no'} | {1e6 * residual:.1f} | "
                f"{1e6 * matrix:.1f} | {1e3 * run:.1f} | "
                f"{stats['newton_iterations'] / stats['steps']:.2f} |"
            )


def plate() -> None:
    mesh = shapes.plate((1.0, 1.0), 80)
    body = build_body(
        mesh.nodes, mesh.elements, Material(7e10, 0.33, 2700.0), shell=0.005,
        node_sets=mesh.node_sets, reference="clamped", reference_nodes="x0",
        point_masses={len(mesh.nodes) - 1: (0.5, np.diag([1e-3, 1e-3, 2e-3]), (0, 0, 0.02))},
    )  # fmt: skip
    unrecorded = dataclasses.replace(body, point_masses=None)
    print(f"plate: {body.elastic_coordinate_count} coordinates; seconds to add it, three times")
    for name, data in (("recorded", body), ("not recorded", unrecorded)):
        times = []
        for _ in range(3):
            began = time.perf_counter()
            fm.System().add_flexible_body(data)
            times.append(time.perf_counter() - began)
        print(f"{name}: {', '.join(f'{t:.2f}' for t in times)}")


if __name__ == "__main__":
    plate() if "--plate" in sys.argv[1:] else main()
