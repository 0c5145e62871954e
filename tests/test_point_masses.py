"""Concentrated masses of a deformable body (`build_body`'s `point_masses`, Nastran's CONM2):
frequencies of a cantilever with a tip mass and a shaft with a tip disk against their analytic
characteristic equations, invariants against those derived from the whole mass matrix, the
body's variants keep them, and bad input is named."""

import numpy as np
import pytest
from scipy.optimize import brentq

import flexmbd.fe.preprocess as pp
from flexmbd._core import Material, Section
from flexmbd.errors import InvalidParameterError
from flexmbd.fe import shapes

E, NU, RHO, LENGTH, RADIUS = 2.1e11, 0.3, 7800.0, 1.0, 0.01
STEEL = Material(E, NU, RHO)
# Euler-Bernoulli (no rotary inertia of the section), as the characteristic equations.
SECTION = Section.circle(RADIUS).without_rotary_inertia()
ROD_MASS = RHO * SECTION.area * LENGTH


def cantilever(point_masses=None, **options):
    nodes, elements = pp.straight_beam(LENGTH, 20)
    return pp.build_body(
        nodes,
        elements,
        STEEL,
        section=SECTION,
        reference="clamped",
        reference_nodes=[0],
        point_masses=point_masses,
        **options,
    )


def test_a_cantilever_with_a_tip_mass_bends_at_its_analytic_frequency(assert_close):
    # 1 + cos(l) cosh(l) + mu l (cos(l) sinh(l) - sin(l) cosh(l)) = 0, mu = m_tip / (rho A L),
    # omega = l^2 sqrt(E I / (rho A L^4)) (clamped-free Euler-Bernoulli beam with a tip mass).
    tip = 0.5 * ROD_MASS
    mu = tip / ROD_MASS

    def characteristic(x):
        return (
            1 + np.cos(x) * np.cosh(x) + mu * x * (np.cos(x) * np.sinh(x) - np.sin(x) * np.cosh(x))
        )

    root = brentq(characteristic, 0.5, 2.0)
    analytic = root**2 * np.sqrt(E * SECTION.iy / (RHO * SECTION.area * LENGTH**4)) / (2 * np.pi)
    body = cantilever({20: tip}, modes="fixed-interface", mode_count=2)
    assert_close(body.frequencies, analytic, rel=1e-6, what="first bending frequency (Hz)")
    bare = cantilever(modes="fixed-interface", mode_count=2)
    assert bare.frequencies[0] > 1.3 * analytic  # (the mass matters: 11.5 Hz without it)
    assert_close(body.invariants.mass, ROD_MASS + tip, rel=1e-12, what="mass")


def test_a_shaft_with_a_tip_disk_twists_at_its_analytic_frequency(assert_close):
    # A rotary inertia J about the axis at the free end of a clamped shaft:
    # l tan(l) = rho J_p L / J, omega = l sqrt(G / rho) / L.
    polar = SECTION.torsion_constant
    disk = 3.0 * RHO * polar * LENGTH
    root = brentq(lambda x: x * np.tan(x) - RHO * polar * LENGTH / disk, 1e-6, np.pi / 2 - 1e-9)
    analytic = root * np.sqrt(E / (2 * (1 + NU)) / RHO) / LENGTH / (2 * np.pi)
    inertia = np.diag([disk, disk / 2, disk / 2])  # a thin disk in the y-z plane
    body = cantilever({20: (1e-9, inertia)}, modes="fixed-interface", mode_count=12)
    nearest = body.frequencies[np.argmin(np.abs(body.frequencies - analytic))]
    assert_close(nearest, analytic, rel=1e-4, what="first torsion frequency (Hz)")
    # Without the disk the first torsion frequency is sqrt(G / rho) / (4 L): 804 Hz.
    bare = cantilever(modes="fixed-interface", mode_count=12).frequencies
    quarter_wave = np.sqrt(E / (2 * (1 + NU)) / RHO) / (4 * LENGTH)
    assert_close(bare[np.argmin(np.abs(bare - quarter_wave))], quarter_wave, rel=5e-4)
    assert np.min(np.abs(bare - analytic)) > 0.05 * analytic
    # The disk is in the body's second moment J0 = int x x^T dm: its points at x = L (mass
    # 1e-9) spread over y and z, int y^2 dm = int z^2 dm = J / 2 (tr(J)/2 I - J).
    extra = np.diag([1e-9 * LENGTH**2, disk / 2, disk / 2])
    assert_close(
        body.invariants.second_moment - cantilever().invariants.second_moment,
        extra,
        abs=1e-15,
        what="second moment of the disk",
    )


def test_point_masses_of_a_solid_give_the_invariants_of_its_whole_mass_matrix(assert_close):
    # Two ways: the elements' invariants plus those of the masses, and all of them derived
    # from M = M_s (x) I_3 of elements and masses together (body_from_matrices).
    mesh = shapes.box((1.0, 0.1, 0.1), (4, 1, 1), "tet4")
    masses = {5: 2.0, 7: 1.5, 9: 0.25}
    options = dict(node_sets=mesh.node_sets, reference="clamped", reference_nodes="x0")
    built = pp.build_body(mesh.nodes, mesh.elements, STEEL, point_masses=masses, **options)
    nodal = pp.assemble(mesh.nodes, mesh.elements, STEEL)
    whole = nodal.mass + pp.point_mass_matrix(masses, len(mesh.nodes), 3)
    derived = pp.body_from_matrices(mesh.nodes, nodal.stiffness, whole, **options)
    for name in ("mass", "first_moment", "second_moment", "i1", "ibar"):
        expected = np.asarray(getattr(derived.invariants, name))
        assert_close(
            getattr(built.invariants, name), expected, abs=1e-12 * np.abs(expected).max(), what=name
        )
    for k in range(3):
        for j in range(3):
            difference = built.invariants.i_kl[k][j] - derived.invariants.i_kl[k][j]
            assert abs(difference).max() < 1e-12 * 81.0
    assert_close(built.invariants.mass, 78.0 + 3.75, rel=1e-12, what="mass")


def test_the_variants_of_a_body_keep_its_point_masses(assert_close):
    masses = {20: (0.5 * ROD_MASS, np.diag([1e-4, 2e-4, 3e-4]))}
    nodal = cantilever(masses)
    # Modes of the nodal body: those of a body built with them.
    assert_close(
        nodal.with_modes("fixed-interface", 4).frequencies,
        cantilever(masses, modes="fixed-interface", mode_count=4).frequencies,
        rel=1e-10,
        what="frequencies",
    )
    # Another density: the beam's mass doubles, the point mass does not.
    heavier = nodal.with_material(density=2 * RHO)
    assert_close(heavier.invariants.mass, 2 * ROD_MASS + 0.5 * ROD_MASS, rel=1e-12, what="m")
    # And back from modes to nodal coordinates.
    back = nodal.with_modes("fixed-interface", 3).with_modes(None)
    assert abs(back.mass - nodal.mass).max() == 0.0
    # A solid too (masses without rotary inertia).
    mesh = shapes.box((1.0, 0.1, 0.1), (4, 1, 1), "tet4")
    options = dict(node_sets=mesh.node_sets, reference="clamped", reference_nodes="x0")
    solid = pp.build_body(mesh.nodes, mesh.elements, STEEL, point_masses={5: 2.0}, **options)
    assert_close(solid.with_material(density=1000.0).invariants.mass, 10.0 + 2.0, rel=1e-12)


@pytest.mark.parametrize(
    "masses, match",
    [
        ({21: 1.0}, r"point_masses\[21\]: node index 21 out of range 0..20"),
        ({3: -1.0}, r"point_masses\[3\]: the mass must be finite and >= 0, got -1"),
        ({3: float("nan")}, r"point_masses\[3\]: the mass must be finite"),
        ({3: "heavy"}, r"point_masses\[3\] mass must be a number"),
        ({3: (1.0, np.ones((2, 2)))}, r"point_masses\[3\]: the inertia must be a finite \(3, 3\)"),
        ({3: (1.0, np.diag([1.0, -1.0, 1.0]))}, r"symmetric and positive semi-definite"),
        ({3: (1.0, 2.0, 3.0)}, r"point_masses\[3\]: a mass or \(mass, inertia\)"),
        ([(3, 1.0)], r"point_masses: a mapping node index -> mass"),
    ],
)
def test_bad_point_masses_are_named(masses, match):
    with pytest.raises(InvalidParameterError, match=match):
        cantilever(masses)


def test_a_rotary_inertia_at_a_node_without_rotations_is_refused():
    mesh = shapes.box((1.0, 0.1, 0.1), (4, 1, 1), "tet4")
    with pytest.raises(InvalidParameterError, match=r"point_masses\[5\]: a rotary inertia needs"):
        pp.build_body(mesh.nodes, mesh.elements, STEEL, point_masses={5: (1.0, np.eye(3))})
