"""Invariants of motion (seed eqs. 16-18): the kinetic energy of a body in the floating frame,
written with the invariants, against a brute-force sum over mass points, for random states;
modal invariants with a complete basis against the nodal ones."""

import numpy as np
import pytest

import flexmbd.fe.preprocess as pp
from flexmbd._core import Material, Section
from flexmbd.rotation import rotation

MATERIAL = Material(7.0e10, 0.33, 2700.0)


def kinetic_energy_from_invariants(inv, r_dot, a, w, q, q_dot):
    """T = 1/2 m R'.R' + R'.A (w x s + I1 q') + 1/2 w.J w + w.c + 1/2 q'.M_ff q' with
    s = s0 + I1 q, J = tr(Jc) I - Jc, Jc_kl = J0_kl + (Ibar_kl + Ibar_lk) q + q I_kl q and
    c_i = eps_ijk (Ibar_jk q' + q I_jk q') (DESIGN.md, "Equations of motion of one body")."""
    i1, ibar, ikl = inv["i1"], inv["ibar"], inv["i_kl"]
    s = inv["first_moment"] + i1 @ q
    jc = np.empty((3, 3))
    for k in range(3):
        for j in range(3):
            jc[k, j] = (
                inv["second_moment"][k, j] + (ibar[k, j] + ibar[j, k]) @ q + q @ (ikl[k][j] @ q)
            )
    inertia = np.trace(jc) * np.eye(3) - jc
    coupling = np.zeros(3)
    eps = {(0, 1, 2): 1, (1, 2, 0): 1, (2, 0, 1): 1, (0, 2, 1): -1, (2, 1, 0): -1, (1, 0, 2): -1}
    for (i, j, k), sign in eps.items():
        coupling[i] += sign * (ibar[j, k] @ q_dot + q @ (ikl[j][k] @ q_dot))
    m_ff = sum(ikl[k][k] for k in range(3))
    return (
        0.5 * inv["mass"] * r_dot @ r_dot
        + r_dot @ (a @ (np.cross(w, s) + i1 @ q_dot))
        + 0.5 * w @ inertia @ w
        + w @ coupling
        + 0.5 * q_dot @ (m_ff @ q_dot)
    )


def kinetic_energy_brute_force(weights, positions, shape, r_dot, a, w, q, q_dot):
    u = positions + (shape @ q).reshape(-1, 3)
    v = r_dot + (np.cross(w, u) + (shape @ q_dot).reshape(-1, 3)) @ a.T
    return 0.5 * np.sum(weights * np.sum(v * v, axis=1))


def random_state(rng, n):
    a = rotation(rng.normal(size=3), rng.uniform(0, np.pi))
    return (
        rng.normal(size=3),
        a,
        rng.normal(size=3) * 3,
        rng.normal(size=n) * 0.05,
        rng.normal(size=n),
    )


def curved_beam():
    # A beam along a circular arc in the x-y plane: the sections turn from element to element.
    angles = np.linspace(0.0, np.pi / 2, 7)
    nodes = np.column_stack([np.cos(angles), np.sin(angles), 0.1 * angles])
    elements = {"beam2": np.column_stack([np.arange(6), np.arange(1, 7)])}
    return nodes, elements, dict(section=Section.rectangle(0.02, 0.04), orientation=(0.0, 0.0, 1.0))


@pytest.mark.parametrize("mass", ["lumped", "consistent"])
def test_beam_kinetic_energy_from_invariants_equals_the_sum_over_mass_points(mass, assert_close):
    nodes, elements, props = curved_beam()
    nodal = pp.assemble(nodes, elements, MATERIAL, mass=mass, **props)
    weights, positions, shape = pp.mass_points(nodes, elements, MATERIAL, mass=mass, **props)
    rng = np.random.default_rng(7)
    n = nodal.stiffness.shape[0]
    for _ in range(5):
        state = random_state(rng, n)
        t_inv = kinetic_energy_from_invariants(nodal.invariants, *state)
        t_sum = kinetic_energy_brute_force(weights, positions, shape, *state)
        assert_close(t_inv, t_sum, rel=1e-12, what="kinetic energy")


def test_reference_conditions_and_modal_invariants_keep_the_kinetic_energy(assert_close):
    nodes, elements, props = curved_beam()
    nodal = pp.assemble(nodes, elements, MATERIAL, **props)
    weights, positions, shape = pp.mass_points(nodes, elements, MATERIAL, **props)
    n = nodal.stiffness.shape[0]
    free = pp.reference_dofs("clamped", len(nodes), 6, [0])
    restricted = pp.restrict_invariants(nodal.invariants, free)
    rng = np.random.default_rng(11)
    # A complete, non-orthogonal basis of the free coordinates (seed eq. 18 with all modes).
    basis = rng.normal(size=(len(free), len(free)))
    full = np.zeros((n, len(free)))
    full[free] = basis
    modal = pp.modal_invariants(nodal.invariants, full)
    for _ in range(3):
        r_dot, a, w, qm, qm_dot = random_state(rng, len(free))
        qm *= 0.1
        q_free, q_free_dot = basis @ qm, basis @ qm_dot
        q, q_dot = np.zeros(n), np.zeros(n)
        q[free], q_dot[free] = q_free, q_free_dot
        t_sum = kinetic_energy_brute_force(weights, positions, shape, r_dot, a, w, q, q_dot)
        t_free = kinetic_energy_from_invariants(restricted, r_dot, a, w, q_free, q_free_dot)
        t_modal = kinetic_energy_from_invariants(modal, r_dot, a, w, qm, qm_dot)
        assert_close(t_free, t_sum, rel=1e-11, what="kinetic energy, free coordinates")
        assert_close(t_modal, t_sum, rel=1e-10, what="kinetic energy, modal")
