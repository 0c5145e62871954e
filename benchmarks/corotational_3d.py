"""The co-rotational beam in 3D (`geometric_stiffness="corotational"`): the 45-degree bend
of Bathe and Bolourchi (1979), a classic test of beams under large 3D rotations with bending
and torsion together.

    python benchmarks/corotational_3d.py      # a few seconds

A cantilever bent into a 45-degree arc of radius 100 in the x-y plane (from the origin along
+x, curving towards +y), square section 1 x 1 (E = 1e7, nu = 0, J = 0.1406), clamped at the
origin, under a dead tip load of 600 along +z (applied in 12 load steps of static
equilibrium). Published tip displacements (in these axes, the arc curving towards +y):
Bathe and Bolourchi (-23.5, -13.4, 53.4), Simo and Vu-Quoc 1986 (-23.48, -13.50, 53.37),
Cardona and Geradin 1988 (-23.67, -13.73, 53.50). Prints the tip displacement of
1. one nodal body with the co-rotational beam, 8 / 16 / 32 elements;
2. one nodal body with the von Karman strain (`geometric_stiffness=True`);
3. the arc split into deformable bodies (von Karman) joined by fixed joints, each carrying a
   smaller share of the rotation (a second formulation that approaches the exact beam as
   the bodies get shorter).
"""

from __future__ import annotations

import time

import numpy as np

import flexmbd as fm
from flexmbd.fe import Material, Section, build_body

RADIUS, LOAD, STEPS = 100.0, 600.0, 12


def arc_nodes(elements: int) -> np.ndarray:
    phi = np.linspace(0, np.pi / 4, elements + 1)
    return np.c_[RADIUS * np.sin(phi), RADIUS * (1 - np.cos(phi)), np.zeros(elements + 1)]


def body_data(nodes: np.ndarray) -> fm.fe.FlexibleBodyData:
    count = len(nodes) - 1
    return build_body(
        nodes,
        {"beam2": np.c_[np.arange(count), np.arange(1, count + 1)]},
        Material(1e7, 0.0, 1.0),
        section=Section(1.0, 1 / 12, 1 / 12, 0.1406),
        orientation=(0, 0, 1),
        reference="clamped",
        reference_nodes=[0],
    )


def tip_displacement(bodies: int, per_body: int, kind) -> tuple[np.ndarray, float]:
    nodes = arc_nodes(bodies * per_body)
    system = fm.System()
    parts = [
        system.add_flexible_body(
            body_data(nodes[b * per_body : (b + 1) * per_body + 1]), geometric_stiffness=kind
        )
        for b in range(bodies)
    ]
    system.add_fixed_joint(system.add_marker(system.ground), system.add_node_marker(parts[0], 1))
    for inner, outer in zip(parts, parts[1:], strict=False):
        system.add_fixed_joint(
            system.add_node_marker(inner, per_body + 1), system.add_node_marker(outer, 1)
        )
    tip = system.add_node_marker(parts[-1], per_body + 1)
    system.add_point_force(tip, (0.0, 0.0, fm.UserFunction(lambda t: LOAD * t)))
    model = system.compile()
    start = time.perf_counter()
    coordinates = None
    for k in range(1, STEPS + 1):
        state = fm.equilibrium(model, k / STEPS, coordinates=coordinates, max_iterations=200)
        coordinates = state.coordinates
    seconds = time.perf_counter() - start
    return state.node_positions(parts[-1])[-1] - nodes[-1], seconds


def main() -> None:
    print(
        "published: Simo and Vu-Quoc (-23.48, -13.50, 53.37), Cardona and Geradin "
        "(-23.67, -13.73, 53.50)"
    )
    for label, kind in (("co-rotational", "corotational"), ("von Karman", True)):
        for elements in (8, 16, 32):
            tip, seconds = tip_displacement(1, elements, kind)
            print(
                f"one body, {label}, {elements:2d} elements: tip {np.round(tip, 3)}; "
                f"{seconds:.2f} s"
            )
    for bodies, per_body in ((8, 2), (16, 2), (32, 1)):
        tip, seconds = tip_displacement(bodies, per_body, True)
        print(
            f"{bodies} bodies x {per_body} elements, von Karman: tip {np.round(tip, 3)}; "
            f"{seconds:.2f} s"
        )


if __name__ == "__main__":
    main()
