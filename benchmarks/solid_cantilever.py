"""Solid meshes of a cantilever converge to the beam solution: the table of the preprocessor issue.

A steel bar 1 x 0.1 x 0.1 m (E = 210 GPa, nu = 0.3), clamped at x = 0 (every node of the face
held: the body's reference conditions), carries 1 kN along z spread evenly over the nodes of
the end face. The tip deflection (mean over the end face) of tet4, tet10, hex8, hex8i, hex20,
hex20r, hex27, wedge6, wedge15, wedge18, pyramid5, pyramid13 and pyramid14 box meshes of
10 n x n x n cells is compared with Timoshenko beam theory,
w = P L^3 / (3 E I) + P L / (kappa G A) with kappa = 5/6 (Euler-Bernoulli alone: the first
term). The nodal clamp is stiffer than a beam's built-in end (it also holds the cross-section's
Poisson contraction), so the finest meshes settle slightly below the beam value.

    python benchmarks/solid_cantilever.py             # n = 1, 2, 4, 6, 8 (about 20 s)
    python benchmarks/solid_cantilever.py --sizes 1 2 4
"""

from __future__ import annotations

import argparse
import sys
import time

import numpy as np

from flexmbd.errors import InvalidModelError
from flexmbd.fe import Material, build_body, shapes
from flexmbd.fe.preprocess import static_displacements

E, NU, RHO, LENGTH, WIDTH, LOAD = 2.1e11, 0.3, 7800.0, 1.0, 0.1, 1000.0


def tip_deflection(element: str, n: int) -> tuple[float, int, float]:
    """Mean tip deflection, number of nodes and seconds (assembly and solve)."""
    mesh = shapes.box((LENGTH, WIDTH, WIDTH), (10 * n, n, n), element)
    start = time.perf_counter()
    body = build_body(
        mesh.nodes,
        mesh.elements,
        Material(E, NU, RHO),
        node_sets=mesh.node_sets,
        reference="clamped",
        reference_nodes="x0",
    )
    tip = mesh.node_sets["x1"]
    forces = np.zeros(body.dof_count)
    forces[3 * tip + 2] = LOAD / len(tip)
    w = static_displacements(body, forces)[3 * tip + 2].mean()
    return float(w), len(mesh.nodes), time.perf_counter() - start


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[1, 2, 4, 6, 8])
    parser.add_argument(
        "--elements",
        nargs="+",
        default=list(shapes.BOX_ELEMENTS),
    )
    args = parser.parse_args(argv)
    inertia, area = WIDTH**4 / 12, WIDTH**2
    bending = LOAD * LENGTH**3 / (3 * E * inertia)
    shear = LOAD * LENGTH / (5 / 6 * E / (2 * (1 + NU)) * area)
    exact = bending + shear
    print(f"Timoshenko tip deflection {exact:.6e} m (Euler-Bernoulli {bending:.6e} m)")
    print("| element | cells | nodes | tip deflection (m) | vs Timoshenko | seconds |")
    print("|---|---|---|---|---|---|")
    for element in args.elements:
        for n in args.sizes:
            try:
                w, nodes, seconds = tip_deflection(element, n)
            except InvalidModelError as error:  # hex20r one element deep: hourglass modes
                print(f"| {element} | {10 * n} x {n} x {n} | refused: {str(error)[:60]}... |")
                continue
            print(
                f"| {element} | {10 * n} x {n} x {n} | {nodes} | {w:.5e} | "
                f"{100 * (w / exact - 1):+.2f} % | {seconds:.2f} |"
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
