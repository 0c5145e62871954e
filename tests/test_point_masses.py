"""Concentrated masses of a deformable body (`build_body`'s `point_masses`, Nastran's CONM2):
frequencies of a cantilever with a tip mass and a shaft with a tip disk against their analytic
characteristic equations, invariants against those derived from the whole mass matrix and
against a brute-force sum over mass points (masses offset from their nodes), a swinging beam
with an offset mass against the same beam carrying a rigid body, the body's variants keep
them, and bad input is named."""

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.optimize import brentq

import flexmbd as fm
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
        ({3: (1.0, None, 2.0, 3.0)}, r"point_masses\[3\]: a mass, \(mass, inertia\) or"),
        ({3: (1.0, None, (0.0, np.nan, 0.0))}, r"point_masses\[3\]: the offset must be three"),
        ({3: (1.0, None, (0.0, 1.0))}, r"point_masses\[3\]: the offset must be three finite"),
        ([(3, 1.0)], r"point_masses: a mapping node index -> mass"),
    ],
)
def test_bad_point_masses_are_named(masses, match):
    with pytest.raises(InvalidParameterError, match=match):
        cantilever(masses)


def test_a_rotary_inertia_or_an_offset_at_a_node_without_rotations_is_refused():
    mesh = shapes.box((1.0, 0.1, 0.1), (4, 1, 1), "tet4")
    with pytest.raises(InvalidParameterError, match=r"point_masses\[5\]: a rotary inertia needs"):
        pp.build_body(mesh.nodes, mesh.elements, STEEL, point_masses={5: (1.0, np.eye(3))})
    with pytest.raises(InvalidParameterError, match=r"point_masses\[5\]: an offset of the centre"):
        pp.build_body(mesh.nodes, mesh.elements, STEEL, point_masses={5: (1.0, None, (0, 0, 1))})


def _rigid_parts(seed):
    """Offset masses with rotary inertias about their centres: node -> (m, J, e)."""
    rng = np.random.default_rng(seed)
    parts = {}
    for node in (1, 3):
        axes = np.linalg.qr(rng.standard_normal((3, 3)))[0]
        mass = rng.uniform(0.5, 2.0)
        second = mass * axes @ np.diag(rng.uniform(0.1, 1.0, 3)) @ axes.T  # int s s^T dm
        parts[node] = (mass, np.trace(second) * np.eye(3) - second, rng.standard_normal(3))
    return parts


def _skew(v):
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def test_offset_masses_give_the_invariants_of_their_mass_points(assert_close):
    # Each offset mass as six mass points m/6 at c +- sqrt(3 lambda_k / m) v_k, which have its
    # centre c = x_i + e and second moments P = sum lambda_k v_k v_k^T about it; a point x moves
    # with its node as u_i + theta_i x (x - x_i): S(x) = [I, -(x - x_i)~] on the node's six
    # coordinates. The invariants are sums over the points.
    nodes = np.random.default_rng(4).standard_normal((4, 3))
    parts = _rigid_parts(5)
    n = 6 * len(nodes)
    sums = {
        "mass": 0.0,
        "first_moment": np.zeros(3),
        "second_moment": np.zeros((3, 3)),
        "i1": np.zeros((3, n)),
        "ibar": np.zeros((3, 3, n)),
    }
    i_kl, mass_matrix = np.zeros((3, 3, n, n)), np.zeros((n, n))
    for node, (m, inertia, offset) in parts.items():
        moments, axes = np.linalg.eigh(0.5 * np.trace(inertia) * np.eye(3) - inertia)
        for k in range(3):
            for sign in (1.0, -1.0):
                x = nodes[node] + offset + sign * np.sqrt(3 * moments[k] / m) * axes[:, k]
                shape = np.zeros((3, n))
                shape[:, 6 * node : 6 * node + 3] = np.eye(3)
                shape[:, 6 * node + 3 : 6 * node + 6] = -_skew(x - nodes[node])
                dm = m / 6
                sums["mass"] += dm
                sums["first_moment"] += dm * x
                sums["second_moment"] += dm * np.outer(x, x)
                sums["i1"] += dm * shape
                sums["ibar"] += dm * np.einsum("a,bc->abc", x, shape)
                i_kl += dm * np.einsum("ac,bd->abcd", shape, shape)
                mass_matrix += dm * shape.T @ shape
    entries = pp.point_mass_entries(parts, len(nodes), 6)
    exact = pp.point_mass_invariants(nodes, entries)
    for name, expected in sums.items():
        assert_close(exact[name], expected, abs=1e-13 * np.abs(expected).max(), what=name)
    for a in range(3):
        for b in range(3):
            assert_close(exact["i_kl"][a][b].toarray(), i_kl[a, b], abs=1e-13, what=f"I_{a}{b}")
    matrix = pp.point_mass_matrix(parts, len(nodes), 6).toarray()
    assert_close(matrix, mass_matrix, abs=1e-13 * np.abs(mass_matrix).max(), what="mass matrix")
    # Without offsets the masses are lumped: the invariants derived from the mass matrix alone
    # (rotational_matrix_invariants) are exact too, and agree.
    centred = {node: (m, inertia) for node, (m, inertia, _) in parts.items()}
    derived = pp.rotational_matrix_invariants(nodes, pp.point_mass_matrix(centred, len(nodes), 6))
    exact = pp.point_mass_invariants(nodes, pp.point_mass_entries(centred, len(nodes), 6))
    for name in ("first_moment", "second_moment", "i1", "ibar"):
        assert_close(exact[name], derived[name], abs=1e-13, what=f"{name} without offsets")
    for a in range(3):
        for b in range(3):
            difference = exact["i_kl"][a][b] - derived["i_kl"][a][b]
            assert abs(difference).max() < 1e-13


def test_masses_at_one_node_combine_into_one(assert_close):
    parts = list(_rigid_parts(6).values()) + [(0.0, np.diag([1.0, 2.0, 2.5]), np.ones(3))]
    one = pp.combined_point_mass(parts)
    whole = sum(pp.point_mass_matrix({0: part}, 1, 6).toarray() for part in parts)
    assert_close(pp.point_mass_matrix({0: one}, 1, 6).toarray(), whole, abs=1e-13, what="M")


def test_a_swinging_beam_with_an_offset_mass_moves_as_with_a_rigid_body_fixed_to_its_node(
    assert_close,
):
    # A flexible steel beam pinned at one end swings under gravity with an equipment mass whose
    # centre is offset from the tip node: as a point mass of the body (its invariants), and as
    # a rigid body fixed to the tip node's marker (which turns with the node's rotations).
    mass, offset = 0.5, np.array([0.05, 0.03, 0.02])
    inertia = np.array([[1e-3, 1e-4, 0.0], [1e-4, 2e-3, 0.0], [0.0, 0.0, 3e-3]])

    def tip_path(point_masses, rigid):
        nodes, elements = pp.straight_beam(1.0, 10)
        body = pp.build_body(
            nodes, elements, STEEL, section=Section.circle(0.01), reference="clamped",
            reference_nodes=[0], point_masses=point_masses,
        )  # fmt: skip
        system = fm.System(gravity=(0.0, -9.81, 0.0))
        beam = system.add_flexible_body(body, name="beam")
        system.add_revolute_joint(system.add_marker(system.ground), system.add_node_marker(beam, 1))
        if rigid:
            part = system.add_rigid_body(mass, inertia, position=nodes[10] + offset)
            tip = system.add_node_marker(beam, 11)
            system.add_fixed_joint(tip, system.add_marker(part, position=-offset))
        result = fm.simulate(system.compile(), 0.5, 2.5e-4, output_interval=0.01)
        return result.node_positions(beam, [11])[:, 0]

    reference = tip_path(None, rigid=True)
    # The two converge as h^2 (h = 1e-3, 2.5e-4, 6.25e-5: 2.0e-6, 1.3e-7, 2.0e-8 m). With the
    # mass turning with the node's rotation linearly (no second order: `attached.rs`) they
    # stayed 6.6e-7 m apart; the invariants of the mass matrix alone, lumped at the node,
    # were 7.6e-5 m off at h = 1e-3; the mass at the node 2.7e-2.
    assert_close(tip_path({10: (mass, inertia, offset)}, rigid=False), reference, abs=3e-7)


def spinning_shaft(speed, disk, rigid, **options):
    """A steel shaft (10 beam elements, 1 m) driven at `speed` about its axis x at node 1,
    with the mass `disk` = (mass, inertia, offset) at its free end: a point mass of the body,
    or (`rigid`) a rigid body fixed to the end node's marker."""
    nodes, elements = pp.straight_beam(LENGTH, 10)
    body = pp.build_body(
        nodes, elements, STEEL, section=SECTION, reference="clamped", reference_nodes=[0],
        point_masses=None if rigid else {10: disk}, **options,
    )  # fmt: skip
    system = fm.System()
    shaft = system.add_flexible_body(body, name="shaft")
    along_x = fm.rotation("y", np.pi / 2)
    hub = system.add_marker(system.ground, orientation=along_x)
    root = system.add_node_marker(shaft, 1, orientation=along_x)
    system.add_revolute_joint(hub, root)
    system.add_angle_driver(hub, root, fm.Polynomial([0.0, speed]))
    if rigid:
        mass, inertia, offset = disk
        part = system.add_rigid_body(
            mass, inertia, position=nodes[10] + offset, angular_velocity=(speed, 0.0, 0.0)
        )
        system.add_fixed_joint(
            system.add_node_marker(shaft, 11), system.add_marker(part, position=-np.asarray(offset))
        )
    return system


def rotor_roots(system):
    """The 16 smallest nonzero eigenvalues about the steady rotation (the equilibrium at
    rest)."""
    turning = any(call[0] == "add_angle_driver" for call in system.building_calls)
    state = fm.steady_rotation(system) if turning else fm.equilibrium(system)
    values = fm.linearize(system, state).eigenvalues()[0]
    values = values[np.abs(values) > 1e-6]
    return values[np.argsort(np.abs(values))][:16]


@pytest.mark.parametrize("speed", [50.0, 100.0, 150.0])
def test_a_disc_on_a_spinning_shaft_turns_with_it_as_a_rigid_body(speed, assert_close):
    # A disc at the end of a shaft turning about its axis: torsion sqrt(G J_t / (L I_p)), the
    # same at every speed (twisting about the spin axis changes nothing). Held as a point mass
    # turning with the node's small rotation linearly, the disc's points moved out along
    # their tangents and the centrifugal force softened the torsion by I_p W^2: 83.0 rad/s
    # instead of 129.9 at 100 rad/s, none left above 130 (a false divergence), and the
    # whirl frequencies off by up to 131 % at 150 rad/s. With the second order of the turn
    # (`body/flexible/attached.rs`) every root is the rigid disc's (fixed to the end node's
    # marker) to 1.5e-8.
    from scipy.optimize import linear_sum_assignment

    polar = SECTION.torsion_constant
    disc_inertia = E / (2 * (1 + NU)) * polar / LENGTH / 130.0**2  # torsion at 130 rad/s
    disk = (1.0, np.diag([disc_inertia, disc_inertia / 2, disc_inertia / 2]), np.zeros(3))
    point = rotor_roots(spinning_shaft(speed, disk, rigid=False))
    rigid = rotor_roots(spinning_shaft(speed, disk, rigid=True))
    distance = np.abs(point[:, None] - rigid[None, :])
    rows, columns = linear_sum_assignment(distance)
    assert_close(distance[rows, columns] / np.abs(rigid[columns]), 0.0, abs=1e-7, what="roots")
    torsion = np.sqrt(E / (2 * (1 + NU)) * polar / (LENGTH * disc_inertia))
    nearest = np.min(np.abs(np.abs(point.imag) - torsion)) / torsion
    assert nearest < 2e-3  # (the shaft's own inertia lowers it a little: 129.92 to 129.97)


def test_an_offset_mass_has_its_pendulum_stiffness_under_gravity(assert_close):
    # A shaft hanging from a hinge with a mass 0.15 m below its lower end (and a rotary
    # inertia): at the equilibrium the end does not turn, and the mass adds the stiffness
    # m g e of its own pendulum to the end's rotations. Turning with the node linearly it
    # lacked it (frequencies up to 7.8e-4 off); now they are those of the same mass as a
    # rigid body fixed to the end node's marker, also in a modal body with every mode (the
    # node's rows from the modal matrix).
    from scipy.optimize import linear_sum_assignment

    mass, inertia, offset = 2.0, np.diag([1e-3, 2e-3, 3e-3]), np.array([0.15, 0.0, 0.0])
    down = fm.rotation("z", -np.pi / 2)  # (body x along global -y)

    def roots(rigid, **options):
        nodes, elements = pp.straight_beam(LENGTH, 10)
        body = pp.build_body(
            nodes, elements, STEEL, section=SECTION, reference="clamped", reference_nodes=[0],
            point_masses=None if rigid else {10: (mass, inertia, offset)}, **options,
        )  # fmt: skip
        system = fm.System(gravity=(0.0, -9.81, 0.0))
        shaft = system.add_flexible_body(body, orientation=down, name="shaft")
        system.add_revolute_joint(
            system.add_marker(system.ground), system.add_node_marker(shaft, 1)
        )
        if rigid:
            part = system.add_rigid_body(
                mass, inertia, position=down @ (nodes[10] + offset), orientation=down
            )
            end = system.add_node_marker(shaft, 11)
            system.add_fixed_joint(end, system.add_marker(part, position=-offset))
        return rotor_roots(system)

    rigid = roots(True)
    for options in ({}, {"modes": "fixed-interface", "mode_count": 60}):
        point = roots(False, **options)
        distance = np.abs(point[:, None] - rigid[None, :])
        rows, columns = linear_sum_assignment(distance)
        relative = distance[rows, columns] / np.abs(rigid[columns])
        assert_close(relative, 0.0, abs=1e-8, what=f"roots {options}")


def test_a_tumbling_beam_with_an_offset_mass_conserves_energy():
    # The second order of the masses' turn is Lagrange's equations of their points' kinetic
    # energy and gravity (the output's energies hold the same terms): a free beam tumbling
    # under gravity with an offset mass keeps its energy to the explicit solver's tolerance
    # (dopri5, 1e-8: 3.7e-12 of E over 0.3 s), and the run agrees with generalized-alpha.
    nodes, elements = pp.straight_beam(1.0, 8)
    inertia = np.array([[4e-3, 5e-4, 0.0], [5e-4, 2e-3, 1e-4], [0.0, 1e-4, 3e-3]])
    body = pp.build_body(
        nodes, elements, Material(7e10, 0.33, 2700.0), section=Section.rectangle(0.02, 0.01),
        reference="clamped", reference_nodes=[0],
        point_masses={8: (0.8, inertia, np.array([0.04, 0.05, -0.03]))},
    )  # fmt: skip
    system = fm.System(gravity=(0.0, -9.81, 0.0))
    system.add_flexible_body(body, angular_velocity=(3.0, 1.0, 20.0), name="beam")
    solver = fm.ExplicitSolver("dopri5", relative_tolerance=1e-8, absolute_tolerance=1e-8)
    result = fm.simulate(system, 0.1, 1e-4, output_interval=0.01, solver=solver)
    energy = result.total_energy
    assert np.ptp(energy) < 1e-10 * abs(energy[0])


def test_the_variants_of_a_body_keep_its_offset_masses(assert_close):
    masses = {20: (0.5 * ROD_MASS, np.diag([1e-4, 2e-4, 3e-4]), (0.02, -0.01, 0.03))}
    heavier = cantilever(masses).with_material(density=2 * RHO)
    nodes, elements = pp.straight_beam(LENGTH, 20)
    fresh = pp.build_body(
        nodes, elements, Material(E, NU, 2 * RHO), section=SECTION, reference="clamped",
        reference_nodes=[0], point_masses=masses,
    )  # fmt: skip
    for name in ("mass", "first_moment", "second_moment", "i1", "ibar"):
        expected = np.asarray(getattr(fresh.invariants, name))
        got = getattr(heavier.invariants, name)
        assert_close(got, expected, abs=1e-12 * np.abs(expected).max(), what=name)
    assert abs(heavier.mass - fresh.mass).max() < 1e-12 * abs(fresh.mass).max()


@pytest.mark.parametrize(
    ("mass", "inertia", "count"),
    [
        (0.8, [[4e-3, 5e-4, 0.0], [5e-4, 2e-3, 1e-4], [0.0, 1e-4, 3e-3]], 4),
        (1.5, np.diag([2e-3, 3e-3, 1e-3]), 4),  # (a flat disc: one second moment zero)
        (1.0, np.diag([1.0, 0.0, 0.0]), 7),  # (no mass distribution has it: P indefinite)
        (0.0, np.diag([1e-3, 5e-4, 5e-4]), 7),
        (2.0, np.zeros((3, 3)), 1),
    ],
)
def test_mass_points_have_the_mass_centre_and_second_moments(mass, inertia, count, assert_close):
    # The second order of a mass's turn depends on its mass, centre and second moments
    # P = tr(J)/2 I - J only; the points that stand for it must have them.
    from flexmbd.system import mass_points

    offset = np.array([0.04, -0.05, 0.03])
    masses, points = mass_points(mass, np.asarray(inertia), offset)
    assert len(masses) == count and points.shape == (count, 3)
    arms = points - offset
    assert_close(masses.sum(), mass, abs=1e-15, what="mass")
    assert_close(masses @ points, mass * offset, abs=1e-15, what="first moment")
    second = np.einsum("p,pi,pj->ij", masses, arms, arms)
    expected = np.trace(inertia) / 2 * np.eye(3) - np.asarray(inertia)
    assert_close(second, expected, abs=1e-15, what="second moments")


def test_a_body_records_its_point_masses_and_is_added_without_assembling_again(
    tmp_path, monkeypatch, assert_close
):
    # build_body records its point masses (`FlexibleBodyData.point_masses`), kept by the body
    # file and the variants; adding the body takes its offset masses from the record instead
    # of assembling the elements again to tell them from the mass matrix (which doubled the
    # time to add a large shell plate). A body file of an earlier flexmbd (no record) still
    # gives the same attached masses from its mass matrix.
    import dataclasses

    import h5py

    import flexmbd.fe.body_variants as variants
    from flexmbd.system import _attached_masses

    inertia, offset = np.diag([1e-4, 2e-4, 3e-4]), np.array([0.02, -0.01, 0.03])
    body = cantilever({20: (0.4, inertia, offset), 5: 0.3}, modes="fixed-interface", mode_count=6)
    record = body.point_masses
    assert record["nodes"].tolist() == [20, 5]
    assert_close(record["mass"], [0.4, 0.3], rel=1e-15, what="masses")
    assert_close(record["inertia"][0], inertia, abs=1e-18, what="inertia")
    assert_close(record["offset"], [offset, np.zeros(3)], abs=1e-18, what="offsets")
    assert cantilever().point_masses["nodes"].shape == (0,)
    for variant in (
        body.with_material(density=2 * RHO),
        body.with_modes(None),
        body.with_stiffness_scale(2.0),
    ):
        assert variant.point_masses["nodes"].tolist() == [20, 5]
        assert_close(variant.point_masses["inertia"], record["inertia"], abs=0.0)
    path = tmp_path / "beam.h5"
    fm.fe.save_body(body, path)
    loaded = fm.fe.load_body(path)
    assert_close(loaded.point_masses["offset"], record["offset"], abs=0.0, what="file")

    def basis(data):
        full = np.zeros((data.dof_count, data.elastic_coordinate_count))
        full[data.reference.free_dofs] = data.modes
        return sp.csr_matrix(full)

    def forbidden(*args, **kwargs):
        raise AssertionError("the elements were assembled again")

    with monkeypatch.context() as patch:
        patch.setattr(variants, "_assembled", forbidden)
        recorded = _attached_masses(loaded, basis(loaded))
        fm.System().add_flexible_body(loaded)
    assert len(recorded) == 1
    # Without the record (dataclasses.replace, or a file without the member): the same.
    with h5py.File(path, "r+") as file:
        del file["point_masses"]
    older = fm.fe.load_body(path)
    assert older.point_masses is None
    for other in (older, dataclasses.replace(body, point_masses=None)):
        derived = _attached_masses(other, basis(other))
        assert len(derived) == 1
        for got, expected in zip(derived[0], recorded[0], strict=True):
            assert_close(got, expected, abs=1e-12 * max(np.abs(expected).max(), 1.0))


@pytest.mark.parametrize(
    ("change", "match"),
    [
        ({"nodes": np.array([21, 5])}, r"point_masses\[\"nodes\"\].*node index 21"),
        ({"mass": np.array([0.4, -0.3])}, r"point_masses\[\"mass\"\].*>= 0"),
        ({"offset": np.zeros((2, 2))}, r"point_masses\[\"offset\"\].*expected \(2, 3\)"),
        ({"inertia": np.full((2, 3, 3), np.nan)}, r"point_masses\[\"inertia\"\].*finite"),
        ({"offsets": np.zeros((2, 3))}, r"point_masses.*must be None or a dict"),
        (
            {"inertia": np.array([np.zeros((3, 3)), [[1.0, 2.0, 0], [0, 1.0, 0], [0, 0, 1.0]]])},
            r"point_masses\[\"inertia\"\]': entry 1 must be symmetric and positive semi-definite",
        ),
        (
            {"inertia": np.array([np.zeros((3, 3)), np.diag([1.0, -1.0, 1.0])])},
            r"point_masses\[\"inertia\"\]': entry 1 must be symmetric and positive semi-definite",
        ),
    ],
)
def test_a_bad_record_of_point_masses_is_named(change, match):
    from flexmbd.errors import ModelError
    from flexmbd.fe.body import check_body

    body = cantilever({20: 0.4, 5: 0.3})
    record = {key: np.array(value) for key, value in body.point_masses.items()}
    record.update(change)
    if "offsets" in change:
        del record["offset"]
    values = {item: getattr(body, item) for item in body.__dataclass_fields__}
    with pytest.raises(ModelError, match=match):
        check_body({**values, "point_masses": record})


def test_a_record_of_a_solid_holds_no_inertias_or_offsets():
    from flexmbd.errors import ModelError
    from flexmbd.fe.body import check_body

    mesh = shapes.box((1.0, 0.1, 0.1), (4, 1, 1), "tet4")
    solid = pp.build_body(mesh.nodes, mesh.elements, STEEL, point_masses={5: 2.0})
    assert solid.point_masses["nodes"].tolist() == [5]
    values = {item: getattr(solid, item) for item in solid.__dataclass_fields__}
    record = {key: np.array(value) for key, value in solid.point_masses.items()}
    record["offset"] = np.array([[0.0, 0.1, 0.0]])
    with pytest.raises(ModelError, match=r"point_masses\[\"offset\"\]' must be zero: .* no rotat"):
        check_body({**values, "point_masses": record})


def test_an_overflowing_point_mass_is_named():
    # m = 1e200 at 1e200 m: the mass block overflowed, and the error blamed m_ff against
    # dataclasses.replace.
    with pytest.raises(InvalidParameterError, match=r"point_masses\[4\]: the mass block overflows"):
        cantilever({4: (1e200, None, (1e200, 0.0, 0.0))})


@pytest.mark.parametrize(
    ("mass", "inertia", "offset", "match"),
    [
        (1.0, np.full((3, 3), np.nan), np.zeros(3), r"inertia must be a finite symmetric"),
        (1.0, np.ones((2, 2)), np.zeros(3), r"inertia must be a finite symmetric"),
        (1.0, [[1.0, 2.0, 0], [0, 1.0, 0], [0, 0, 1.0]], np.zeros(3), r"finite symmetric"),
        (1.0, np.eye(3), (0.0, 1.0), r"offset must be three finite numbers"),
        (float("nan"), np.eye(3), np.zeros(3), r"mass must be finite"),
    ],
)
def test_mass_points_refuse_bad_input(mass, inertia, offset, match):
    from flexmbd.system import mass_points

    with pytest.raises(InvalidParameterError, match=match):
        mass_points(mass, inertia, offset)


def test_an_inertia_about_a_flat_shells_normal_is_warned_of_with_its_spurious_mode():
    # A clamped plate with a 0.5 kg mass at a free corner: an inertia about the normal (a disc
    # lying on the plate, or the mass's centre offset in the plane) turns with the shells'
    # drilling rotation, held only by its penalty: a first mode at 10.3 Hz, below the plate's
    # 12.7, all its kinetic energy in that rotation. The warning names the node and that
    # frequency; masses that turn with bending (an inertia about an in-plane axis, an offset
    # along the normal) are not warned of.
    import warnings

    from flexmbd.errors import MeshQualityWarning

    mesh = shapes.plate((0.4, 0.3), (8, 6), "quad4")
    corner = int(np.argmin(np.linalg.norm(mesh.nodes - [0.4, 0.3, 0.0], axis=1)))
    options = dict(
        shell=0.004, node_sets=mesh.node_sets, reference="clamped", reference_nodes="x0",
        modes="fixed-interface", mode_count=2,
    )  # fmt: skip
    aluminium = Material(7e10, 0.33, 2700.0)
    for masses in ((0.5, np.diag([1e-3, 2e-3, 0.0])), (0.5, None, (0.0, 0.0, 0.05))):
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            pp.build_body(mesh.nodes, mesh.elements, aluminium, point_masses={corner: masses},
                          **options)  # fmt: skip
    for masses in ((0.5, np.diag([0.0, 0.0, 1e-3])), (0.5, None, (0.05, 0.0, 0.0))):
        with pytest.warns(MeshQualityWarning, match=rf"point_masses\[{corner}\] \(node 63\)") as w:
            body = pp.build_body(
                mesh.nodes, mesh.elements, aluminium, point_masses={corner: masses}, **options
            )
        stated = float(str(w[0].message).split("a mode near ")[1].split(" Hz")[0])
        if masses[1] is not None:  # (alone in the drilling rotation: the body's first mode)
            assert abs(stated - body.frequencies[0]) < 1e-3 * body.frequencies[0]
        assert body.frequencies[0] < 12.0  # (the plate with the mass at the node: 12.68 Hz)


def test_a_runaway_iteration_on_a_tumbling_beam_is_retried_not_accepted():
    # A free beam of 20 elements tumbling at 20 rad/s with 0.8 kg offset at its tip: modified
    # Newton (the symmetrized matrix of this strongly gyroscopic body) ran away and the step
    # was taken as converged, its increments small against the accelerations they reached
    # (q ~ 1e223), or a residual that was not finite ended the run (NonFiniteError at
    # t = 0.01 s). Such steps are now retried (with the exact matrix, or shorter): the run
    # is full Newton's.
    nodes, elements = pp.straight_beam(1.0, 20)
    body = pp.build_body(
        nodes, elements, Material(7e10, 0.33, 2700.0), section=Section.rectangle(0.02, 0.01),
        reference="clamped", reference_nodes=[0],
        point_masses={20: (0.8, np.diag([4e-3, 2e-3, 3e-3]), np.array([0.05, 0.05, -0.03]))},
    )  # fmt: skip
    system = fm.System(gravity=(0.0, -9.81, 0.0))
    system.add_flexible_body(body, angular_velocity=(3.0, 1.0, 20.0), name="beam", condense=False)
    ends = {}
    for jacobian in ("modified", "full"):
        solver = fm.GeneralizedAlpha(jacobian=jacobian, step_control="fixed")
        ends[jacobian] = fm.simulate(system, 0.05, 1e-3, solver=solver).coordinates[-1]
    assert np.abs(ends["modified"] - ends["full"]).max() < 1e-6


def test_a_body_with_an_offset_mass_is_not_condensed_by_default():
    # A free beam of 60 elements (360 coordinates: condensed by default) with 0.8 kg offset
    # 7 cm from its tip, tumbling at 20 rad/s: the condensed solves shrank the steps to
    # 3e-9 s and diverged (at 2 rad/s and h = 1e-4 they contracted at 0.3 from t = 0, with the
    # second order of the turn or without); the body is now solved whole by default.
    nodes, elements = pp.straight_beam(1.0, 60)
    masses = {60: (0.8, np.diag([4e-3, 2e-3, 3e-3]), np.array([0.05, 0.05, -0.03]))}
    body = pp.build_body(
        nodes, elements, Material(7e10, 0.33, 2700.0), section=Section.rectangle(0.02, 0.01),
        reference="clamped", reference_nodes=[0], point_masses=masses,
    )  # fmt: skip
    system = fm.System(gravity=(0.0, -9.81, 0.0))
    system.add_flexible_body(body, angular_velocity=(3.0, 1.0, 20.0), name="beam")
    result = fm.simulate(system, 0.03, 1e-3)
    assert result.success and result.statistics["min_step_size"] > 1e-4
    assert abs(result.total_energy[-1] / result.total_energy[0] - 1) < 1e-3
