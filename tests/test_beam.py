"""Beam bodies from the preprocessor against reference R1 (Euler-Bernoulli beams, exact) and
the Rayleigh beam (rotary inertia, closed form)."""

import numpy as np
import pytest

import flexmbd.fe.preprocess as pp
from flexmbd._core import Material, Section
from flexmbd.errors import InvalidModelError

E, RHO, L = 2.0e11, 7850.0, 1.0
MATERIAL = Material(E, 0.3, RHO)
CANTILEVER = [1.8751040687, 4.6940911330, 7.8547574382, 10.9955407349]
FREE_FREE = [4.7300407449, 7.8532046241, 10.9956078380, 14.1371654913]


def euler_bernoulli(beta_l, inertia, area):
    return np.asarray(beta_l) ** 2 * np.sqrt(E * inertia / (RHO * area * L**4)) / (2 * np.pi)


@pytest.mark.parametrize(
    "reference, modes, beta, reference_nodes",
    [
        ("clamped", "fixed-interface", CANTILEVER, [0]),
        ("mean-axis", "free-free", FREE_FREE, []),
    ],
)
def test_r1_frequencies_with_20_elements(reference, modes, beta, reference_nodes, assert_close):
    # A slender section (radius of gyration / L ~ 1e-3), where rotary inertia, which the
    # element includes and Euler-Bernoulli theory neglects, stays below 1e-4 for four modes.
    section = Section.rectangle(0.004, 0.006)
    nodes, elements = pp.straight_beam(L, 20)
    body = pp.build_body(
        nodes,
        elements,
        MATERIAL,
        section=section,
        reference=reference,
        reference_nodes=reference_nodes,
        modes=modes,
        mode_count=14,
    )
    for inertia in (section.iz, section.iy):
        for exact in euler_bernoulli(beta, inertia, section.area):
            nearest = body.frequencies[np.abs(body.frequencies - exact).argmin()]
            assert_close(nearest, exact, rel=1e-3, what="nearest frequency")


def test_rayleigh_beam_rotary_inertia_pinned_pinned(assert_close):
    # w^2 = (E I / rho A) k^4 / (1 + (I / A) k^2), k = n pi / L: a thick section, where the
    # rotary inertia lowers the fourth frequency by 14 %.
    section = Section.rectangle(0.03, 0.05)
    nodes, elements = pp.straight_beam(L, 20)
    nodal = pp.assemble(nodes, elements, MATERIAL, section=section)
    n = len(nodes)
    held = [0, 1, 2, 3, 6 * (n - 1) + 1, 6 * (n - 1) + 2]  # translations, and torsion at one end
    free = np.setdiff1d(np.arange(6 * n), held)
    _, frequencies = pp.fixed_interface_modes(nodal.stiffness, nodal.mass, free, 12)
    k = np.arange(1, 5) * np.pi / L
    for inertia in (section.iz, section.iy):
        exact = np.sqrt(
            E * inertia / (RHO * section.area) * k**4 / (1 + inertia / section.area * k**2)
        )
        for value in exact / (2 * np.pi):
            nearest = frequencies[np.abs(frequencies - value).argmin()]
            assert_close(nearest, value, rel=1e-3, what="nearest frequency")


def test_timoshenko_beam_pinned_pinned_frequencies_converge_to_the_closed_form(assert_close):
    # Simply supported Timoshenko beam, w = W sin kx, phi = P cos kx, k = n pi / L:
    # rho A rho I w^4 - (rho A (E I k^2 + kGA) + rho I kGA k^2) w^2 + kGA E I k^4 = 0. A thick
    # section (L / h = 10), where shear lowers the fourth frequency by 6 to 13 % below the
    # Rayleigh beam (rotary inertia only, previous test). The elements converge to it at second
    # order (a wrong term would converge elsewhere).
    section = Section.rectangle(0.06, 0.1)
    k = np.arange(1, 5) * np.pi / L
    kga = section.shear_factor * E / (2 * 1.3) * section.area
    exact = []
    for inertia in (section.iz, section.iy):
        ra, ri = RHO * section.area, RHO * inertia
        a, b, c = (
            ra * ri,
            ra * (E * inertia * k**2 + kga) + ri * kga * k**2,
            kga * E * inertia * k**4,
        )
        exact.append(np.sqrt((b - np.sqrt(b**2 - 4 * a * c)) / (2 * a)) / (2 * np.pi))
        rayleigh = np.sqrt(E * inertia / ra * k**4 / (1 + inertia / section.area * k**2))
        assert exact[-1][3] < 0.94 * rayleigh[3] / (2 * np.pi)  # the effect tested is large
    exact = np.concatenate(exact)
    errors = []
    for elements in (40, 80):
        nodes, connectivity = pp.straight_beam(L, elements)
        nodal = pp.assemble(
            nodes, connectivity, MATERIAL, section=section, beam_theory="timoshenko"
        )
        n = len(nodes)
        held = [0, 1, 2, 3, 6 * (n - 1) + 1, 6 * (n - 1) + 2]
        free = np.setdiff1d(np.arange(6 * n), held)
        _, frequencies = pp.fixed_interface_modes(nodal.stiffness, nodal.mass, free, 14)
        nearest = frequencies[np.abs(frequencies[:, None] - exact[None, :]).argmin(axis=0)]
        errors.append(nearest / exact - 1.0)
    assert np.all(errors[1] > 0) and errors[1].max() < 3e-4
    assert_close(errors[0] / errors[1], 4.0, rel=0.08, abs=1e-8, what="error ratio")


def cantilever_solution(load, **modal):
    section = Section.rectangle(0.01, 0.02)
    nodes, elements = pp.straight_beam(L, 20)
    body = pp.build_body(
        nodes,
        elements,
        MATERIAL,
        section=section,
        reference="clamped",
        reference_nodes=[0],
        **modal,
    )
    n = len(nodes)
    return section, pp.static_displacements(body, load(n)), n


def test_r1_static_tip_load(assert_close):
    p = 100.0

    def load(n):
        f = np.zeros(6 * n)
        f[6 * (n - 1) + 1] = p
        return f

    section, u, n = cantilever_solution(load)
    ei = E * section.iz
    assert_close(u[6 * (n - 1) + 1], p * L**3 / (3 * ei), rel=1e-6, what="tip deflection")
    assert_close(u[6 * (n - 1) + 5], p * L**2 / (2 * ei), rel=1e-6, what="tip rotation")
    # A modal body with every fixed-interface mode gives the same static solution; a body
    # without reference conditions has none.
    _, modal, _ = cantilever_solution(load, modes="fixed-interface", mode_count=120)
    assert_close(modal, u, abs=1e-9 * np.abs(u).max(), what="modal static displacements")
    free_body = pp.build_body(*pp.straight_beam(L, 4), MATERIAL, section=section)
    with pytest.raises(InvalidModelError, match="free to move rigidly"):
        pp.static_displacements(free_body, np.ones(free_body.dof_count))


def test_r1_static_uniform_load(assert_close):
    q, le = 50.0, L / 20

    def load(n):
        # Consistent nodal loads of a uniform load along z: q Le / 2 and moments -+ q Le^2 / 12
        # about y (theta_y = -dw/dx).
        f = np.zeros(6 * n)
        for a in range(n - 1):
            f[6 * a + 2] += q * le / 2
            f[6 * (a + 1) + 2] += q * le / 2
            f[6 * a + 4] += -q * le**2 / 12
            f[6 * (a + 1) + 4] += q * le**2 / 12
        return f

    section, u, n = cantilever_solution(load)
    assert_close(
        u[6 * (n - 1) + 2], q * L**4 / (8 * E * section.iy), rel=1e-6, what="tip deflection"
    )


def test_beam_invariants_are_the_rigid_inertia_of_the_bar(assert_close):
    # Bar along x from (0.2, 0, 0): mass rho A L, centre of mass at its middle, inertia about
    # the centre of mass diag(rho L (Iy + Iz), m L^2/12 + rho L Iy, m L^2/12 + rho L Iz).
    section = Section.rectangle(0.02, 0.05)
    nodes, elements = pp.straight_beam(L, 8, start=(0.2, 0.0, 0.0))
    for mass in ("consistent", "lumped"):
        nodal = pp.assemble(nodes, elements, MATERIAL, section=section, mass=mass)
        inv = nodal.invariants
        m = RHO * section.area * L
        assert_close(inv["mass"], m, rel=1e-12, what="mass")
        c = inv["first_moment"] / inv["mass"]
        assert_close(c, [0.7, 0.0, 0.0], rel=1e-7, abs=1e-12, what="centre of mass")
        j0 = inv["second_moment"] - m * np.outer(c, c)
        inertia = np.trace(j0) * np.eye(3) - j0
        expected = np.diag(
            [
                RHO * L * (section.iy + section.iz),
                m * L**2 / 12 + RHO * L * section.iy,
                m * L**2 / 12 + RHO * L * section.iz,
            ]
        )
        if mass == "consistent":
            assert_close(inertia, expected, rel=1e-10, abs=1e-14, what="inertia")
        else:
            # Point masses at the nodes: the bar of 8 segments has the inertia of the nodes.
            xs = np.linspace(0.2, 1.2, 9) - 0.7
            weights = np.full(9, m / 8)
            weights[[0, -1]] /= 2
            assert_close(inertia[1, 1], np.sum(weights * xs**2), rel=1e-2, what="inertia[1, 1]")
        # M_ff = sum_k I_kk, and I1 sums the mass per translation.
        m_sum = sum(inv["i_kl"][k][k] for k in range(3))
        assert_close(m_sum.toarray(), nodal.mass.toarray(), abs=1e-12 * m, what="sum of I_kk")
        for k in range(3):
            assert_close(inv["i1"][k, k::6].sum(), m, rel=1e-12, what="I1 mass")
