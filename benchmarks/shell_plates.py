"""Flat shells converge to the classical plate and beam values: the tables of the shells issue.

Unit square aluminium plates (E = 70 GPa, nu = 0.3, rho = 2700 kg/m^3) of thickness t meshed
with n x n "quad4" (MITC4) or "tri3" (DKT, alternating diagonals) shells:

- simply supported (w = 0 on the edges; membrane and drilling coordinates held, which do not
  couple to bending in a flat plate): the first frequency against the exact Kirchhoff value
  w = 2 pi^2 sqrt(D / (rho t a^4)), D = E t^3 / (12 (1 - nu^2));
- clamped (every coordinate of the edge nodes held): lambda_1 = w a^2 sqrt(rho t / D) against
  35.99 (Leissa, Vibration of Plates, 1969);
- a cantilever strip 1 x 0.05 m, t = 2 mm, 20 x 2 elements, clamped at x = 0, 1 N along z at
  the tip: the tip deflection against P L^3 / (3 E I).

Thin plates (t / a = 1e-3) converge like thick ones (t / a = 1e-2): no shear locking.

    python benchmarks/shell_plates.py                  # n = 4, 8, 16, 32 (about 30 s)
    python benchmarks/shell_plates.py --sizes 4 8
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import scipy.linalg as sla

from flexmbd.fe import Material, assemble, build_body, shapes
from flexmbd.fe.preprocess import static_displacements

E, NU, RHO = 7e10, 0.3, 2700.0
MATERIAL = Material(E, NU, RHO)


def plate_modulus(t: float) -> float:
    return E * t**3 / (12 * (1 - NU**2))


def edges(mesh) -> np.ndarray:
    return np.unique(np.concatenate([mesh.node_sets[k] for k in ("x0", "x1", "y0", "y1")]))


def simply_supported(element: str, n: int, t: float) -> float:
    """First frequency over the exact one."""
    mesh = shapes.plate((1.0, 1.0), n, element)
    count = len(mesh.nodes)
    held = [6 * i + c for i in range(count) for c in (0, 1, 5)]
    held += [6 * i + 2 for i in edges(mesh)]
    free = np.setdiff1d(np.arange(6 * count), held)
    body = assemble(mesh.nodes, mesh.elements, MATERIAL, shell=t)
    k = body.stiffness[free][:, free].toarray()
    m = body.mass[free][:, free].toarray()
    value = sla.eigh(k, m, eigvals_only=True, subset_by_index=[0, 0])[0]
    exact = 2 * np.pi**2 * np.sqrt(plate_modulus(t) / (RHO * t))
    return float(np.sqrt(value) / exact)


def clamped(element: str, n: int, t: float) -> float:
    """lambda_1 of the clamped plate."""
    mesh = shapes.plate((1.0, 1.0), n, element)
    body = build_body(
        mesh.nodes,
        mesh.elements,
        MATERIAL,
        shell=t,
        reference="clamped",
        reference_nodes=edges(mesh),
        modes="fixed-interface",
        mode_count=1,
    )
    return float(2 * np.pi * body.frequencies[0] * np.sqrt(RHO * t / plate_modulus(t)))


def strip(element: str) -> float:
    """Tip deflection of the cantilever strip over beam theory."""
    t, width = 2e-3, 0.05
    mesh = shapes.plate((1.0, width), (20, 2), element)
    body = build_body(
        mesh.nodes,
        mesh.elements,
        MATERIAL,
        shell=t,
        node_sets=mesh.node_sets,
        reference="clamped",
        reference_nodes="x0",
    )
    tip = mesh.node_sets["x1"]
    forces = np.zeros(body.dof_count)
    forces[6 * tip + 2] = 1.0 / len(tip)
    u = static_displacements(body, forces)
    return float(u[6 * tip + 2].mean() / (1.0 / (3 * E * width * t**3 / 12)))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[4, 8, 16, 32])
    args = parser.parse_args()
    for t in (1e-2, 1e-3):
        print(f"\nt / a = {t:g}: simply supported w / w_exact - 1, clamped lambda_1 (35.99)")
        print(f"{'n':>4} {'quad4 SS':>10} {'tri3 SS':>10} {'quad4 C':>9} {'tri3 C':>9} {'s':>6}")
        for n in args.sizes:
            start = time.perf_counter()
            row = [simply_supported(e, n, t) - 1 for e in ("quad4", "tri3")]
            row += [clamped(e, n, t) for e in ("quad4", "tri3")]
            seconds = time.perf_counter() - start
            print(
                f"{n:4d} {row[0]:10.2e} {row[1]:10.2e} {row[2]:9.3f} {row[3]:9.3f} {seconds:6.1f}"
            )
    print("\ncantilever strip 20 x 2, tip deflection / (P L^3 / 3 E I):")
    for element in ("quad4", "tri3"):
        print(f"  {element}: {strip(element):.4f}")


if __name__ == "__main__":
    main()
