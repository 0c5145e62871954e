"""Preprocessing a deformable body: a steel bar meshed with 10-node tetrahedra.

The bar (1 x 0.1 x 0.1 m) is clamped to its body frame at the face x = 0 and has an interface
at the face x = 1, where a joint or a force would act in a simulation. The preprocessor
computes the stiffness and mass matrices, the invariants of motion, a classic Craig-Bampton
basis (12 fixed-interface eigenmodes + one static mode per coordinate of the 25 nodes of the
face x = 1; "rbe2" and "rbe3" interfaces would give 6) and writes the body file. The example
checks:

- mass and inertia about the centre of mass against the analytic values of the block;
- the reduced body's first frequencies against the unreduced finite-element model clamped at
  x = 0 (a Rayleigh-Ritz basis: from above, and close for the low modes), with the
  Euler-Bernoulli cantilever values next to them (the solid adds shear and 3D effects at the
  clamp);
- that the body file reads back identical.
"""

import tempfile
from pathlib import Path

import numpy as np

from flexmbd.fe import Material, build_body, load_body, save_body, shapes
from flexmbd.fe.modal import fixed_interface_modes
from flexmbd.fe.preprocess import reference_dofs

LENGTHS = (1.0, 0.1, 0.1)
STEEL = Material(2.1e11, 0.3, 7800.0)


def main() -> int:
    mesh = shapes.box(LENGTHS, (20, 2, 2), "tet10")
    body = build_body(
        mesh.nodes,
        mesh.elements,
        STEEL,
        node_sets=mesh.node_sets,
        reference="interface",
        modes="craig-bampton",
        mode_count=12,
        interfaces=["x0", "x1"],
        interface_kind="nodal",
    )
    print(
        f"{body.node_count} nodes, {len(mesh.elements['tet10'])} tet10, "
        f"{body.elastic_coordinate_count} modal coordinates"
    )

    # Rigid-body inertia of the undeformed body from the invariants.
    a, b, c = LENGTHS
    mass = STEEL.density * a * b * c
    inv = body.invariants
    centre = inv.first_moment / inv.mass
    j0 = inv.second_moment - inv.mass * np.outer(centre, centre)
    inertia = np.trace(j0) * np.eye(3) - j0
    exact = mass / 12 * np.diag([b * b + c * c, a * a + c * c, a * a + b * b])
    mass_error = abs(inv.mass / mass - 1)
    inertia_error = np.abs(inertia - exact).max() / exact.max()
    print(f"mass {inv.mass:.4f} kg (exact {mass:.4f}), centre {np.round(centre, 12)}")
    print(f"inertia about the centre: largest relative error {inertia_error:.1e}")

    # The unreduced model: the same mesh clamped at x = 0, its first eigenfrequencies.
    free = reference_dofs("clamped", body.node_count, 3, mesh.node_sets["x0"])
    _, full = fixed_interface_modes(body.stiffness, body.mass, free, 6, nodes=mesh.nodes)
    reduced = body.frequencies[:6]
    beam = (
        np.array([1.8751040687, 1.8751040687, 4.6940911330, 4.6940911330]) ** 2
        / (2 * np.pi)
        * np.sqrt(STEEL.young_modulus * b * b / 12 / (STEEL.density * a**4))
    )
    print("mode  reduced (Hz)  full FE (Hz)  Euler-Bernoulli (Hz)")
    for i in range(6):
        eb = f"{beam[i]:12.2f}" if i < 2 else ""
        print(f"{i + 1:4d}  {reduced[i]:12.2f}  {full[i]:12.2f}  {eb}")
    frequency_error = np.abs(reduced[:5] / full[:5] - 1).max()
    upper_bound = bool(np.all(reduced >= full * (1 - 1e-12)))
    print(
        f"reduced vs full, first 5 modes: largest relative difference {frequency_error:.1e}, "
        f"upper bounds: {upper_bound}"
    )

    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "bar.h5"
        save_body(body, path)
        loaded = load_body(path)
        same = np.array_equal(loaded.modes, body.modes) and all(
            np.array_equal(getattr(loaded.invariants, k), getattr(inv, k))
            for k in ("i1", "ibar", "k_ff", "m_ff")
        )
        print(f"body file: {path.stat().st_size / 1024:.0f} KiB, reads back identical: {same}")
    ok = max(mass_error, inertia_error) < 1e-12 and frequency_error < 1e-3 and upper_bound
    return 0 if ok and same else 1


if __name__ == "__main__":
    raise SystemExit(main())
