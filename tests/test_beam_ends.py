"""Offsets and released end coordinates (pin flags) of beam elements (`flexmbd.fe.beam_ends`):
the offset cantilever against beam theory and against the beam meshed on its offset axis with
a rigid tie written here, the invariants against sums over mass points on the offset axis, a
hinge in a propped cantilever and pinned ends against beam theory, mechanisms refused, the
geometric stiffness of an offset blade against the blade meshed on its axis."""

import numpy as np
import pytest
import scipy.linalg

import flexmbd as fm
import flexmbd.fe.preprocess as pp
from flexmbd._core import Material, Section
from flexmbd.campbell import campbell
from flexmbd.errors import InvalidModelError, InvalidParameterError
from flexmbd.fe import load_body, recover_stresses, save_body

E, RHO = 2.1e11, 7800.0
STEEL = Material(E, 0.3, RHO)
SECTION = Section.rectangle(0.02, 0.01)  # iy = 0.02 * 0.01^3 / 12 (bending along z)


def cross_matrix(v):
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def rigid_tie(conn, offsets, node_count):
    """T (12 n_beams, 6 n): the axis ends of each beam (its own two nodes, end a then b) from
    its grids, u_end = u + theta x w, theta_end = theta, written column by column: the motion
    of the point w off a node under a unit translation e_k is e_k, under a unit rotation
    about e_k it is e_k x w."""
    tie = np.zeros((12 * len(conn), 6 * node_count))
    for e, pair in enumerate(conn):
        for end, node in enumerate(pair):
            rows, cols = 12 * e + 6 * end, 6 * node
            for k in range(3):
                unit = np.eye(3)[k]
                tie[rows : rows + 3, cols + k] = unit
                tie[rows : rows + 3, cols + 3 + k] = np.cross(unit, offsets[e, end])
                tie[rows + 3 + k, cols + 3 + k] = 1.0
    return tie


def on_offset_axes(nodes, conn, offsets):
    """The beams meshed on their offset axes, each on two nodes of its own."""
    axis_nodes = (nodes[conn] + offsets).reshape(-1, 3)
    return axis_nodes, {"beam2": np.arange(2 * len(conn)).reshape(-1, 2)}


def crooked_beam(seed):
    """A beam along a helix-like line with different offsets at every end."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 1.0, 6)
    nodes = np.column_stack([t, 0.2 * np.sin(2 * t), 0.1 * t**2])
    conn = np.column_stack([np.arange(5), np.arange(1, 6)])
    offsets = 0.03 * rng.standard_normal((5, 2, 3))
    return nodes, conn, offsets


@pytest.mark.parametrize("theory", ["euler-bernoulli", "timoshenko"])
def test_an_offset_cantilever_pulled_at_its_tip_grid_bends_as_beam_theory(theory, assert_close):
    # Grids on the x axis, the beam's axis at z = e. An axial force F at the tip grid acts on
    # the axis with the moment -e F about y: the axis stretches F L / EA and bends at the
    # constant moment (theta_y = -e F L / EI, w = e F L^2 / 2 EI, exact for the cubic
    # elements and for Timoshenko's, without shear), and the grid moves u_x = F L / EA + e^2 F
    # L / EI: the offset's e^2 term and the coupling's sign both show.
    length, count, e, force = 1.2, 4, 0.05, 1000.0
    nodes, elements = pp.straight_beam(length, count)
    offsets = np.zeros((count, 2, 3))
    offsets[:, :, 2] = e
    nodal = pp.assemble(
        nodes, elements, STEEL, section=SECTION, orientation=(0.0, 1.0, 0.0),
        beam_theory=theory, beam_offsets=offsets,
    )  # fmt: skip
    k = nodal.stiffness.toarray()
    assert_close(k, k.T, abs=0.0, what="symmetry")
    free = np.arange(6, 6 * (count + 1))
    f = np.zeros(6 * (count + 1))
    f[6 * count] = force
    u = np.zeros_like(f)
    u[free] = np.linalg.solve(k[np.ix_(free, free)], f[free])
    ea, ei = E * SECTION.area, E * SECTION.iy
    tip = u[6 * count : 6 * count + 6]
    assert_close(tip[0], force * length * (1 / ea + e**2 / ei), rel=1e-10, what="u_x")
    assert_close(tip[2], e * force * length**2 / (2 * ei), rel=1e-10, what="w")
    assert_close(tip[4], -e * force * length / ei, rel=1e-10, what="theta_y")
    assert_close(tip[[1, 3, 5]], 0.0, abs=1e-12, what="v, theta_x, theta_z")


@pytest.mark.parametrize("mass", ["consistent", "lumped"])
def test_offset_beams_are_the_beams_on_their_axes_tied_rigidly(mass, assert_close):
    # The same beams meshed on their offset axes (each on nodes of its own) and tied to the
    # grids by the rigid map written here: T^T K T and T^T M T, and so the free-free
    # frequencies of the body.
    nodes, conn, offsets = crooked_beam(3)
    options = dict(section=SECTION, orientation=(0.0, 0.0, 1.0), mass=mass)
    nodal = pp.assemble(nodes, {"beam2": conn}, STEEL, beam_offsets=offsets, **options)
    axis_nodes, axis_elements = on_offset_axes(nodes, conn, offsets)
    reference = pp.assemble(axis_nodes, axis_elements, STEEL, **options)
    tie = rigid_tie(conn, offsets, len(nodes))
    k = tie.T @ reference.stiffness.toarray() @ tie
    m = tie.T @ reference.mass.toarray() @ tie
    assert_close(nodal.stiffness.toarray(), k, abs=1e-12 * np.abs(k).max(), what="K")
    assert_close(nodal.mass.toarray(), m, abs=1e-12 * np.abs(m).max(), what="M")
    body = pp.build_body(
        nodes, {"beam2": conn}, STEEL, beam_offsets=offsets, reference="mean-axis",
        modes="free-free", mode_count=6, **options,
    )  # fmt: skip
    values = scipy.linalg.eigh(k, m, eigvals_only=True)[6:12]
    assert_close(body.frequencies, np.sqrt(values) / (2 * np.pi), rel=1e-8, what="frequencies")
    # Without the offsets the beam is another one: its first frequency is 10 % off.
    plain = pp.build_body(
        nodes, {"beam2": conn}, STEEL, reference="mean-axis", modes="free-free",
        mode_count=6, **options,
    )  # fmt: skip
    assert abs(plain.frequencies[0] / body.frequencies[0] - 1) > 0.05


def test_offset_beam_invariants_are_sums_over_mass_points_on_the_offset_axes(assert_close):
    # The mass points of the beams meshed on their axes (weights, positions) moving with the
    # grids through the rigid tie: S T. Every invariant is a sum over them (seed eqs. 16-17).
    nodes, conn, offsets = crooked_beam(5)
    options = dict(section=SECTION, orientation=(0.0, 0.0, 1.0))
    nodal = pp.assemble(nodes, {"beam2": conn}, STEEL, beam_offsets=offsets, **options)
    axis_nodes, axis_elements = on_offset_axes(nodes, conn, offsets)
    weights, positions, shape = pp.mass_points(axis_nodes, axis_elements, STEEL, **options)
    s = (shape.toarray() @ rigid_tie(conn, offsets, len(nodes))).reshape(len(weights), 3, -1)
    sums = {
        "mass": weights.sum(),
        "first_moment": weights @ positions,
        "second_moment": np.einsum("p,pa,pb->ab", weights, positions, positions),
        "i1": np.einsum("p,pan->an", weights, s),
        "ibar": np.einsum("p,pa,pbn->abn", weights, positions, s),
    }
    for name, expected in sums.items():
        got = nodal.invariants[name]
        assert_close(got, expected, abs=1e-12 * np.abs(expected).max(), what=name)
    for a in range(3):
        for b in range(3):
            expected = np.einsum("p,pm,pn->mn", weights, s[:, a], s[:, b])
            got = nodal.invariants["i_kl"][a][b].toarray()
            assert_close(got, expected, abs=1e-12 * np.abs(expected).max(), what=f"I_{a}{b}")
    # The mass and its centre are those of the offset axes: rho A times their lengths.
    lengths = np.linalg.norm(np.diff(nodes[conn] + offsets, axis=1)[:, 0], axis=1)
    centres = (nodes[conn] + offsets).mean(axis=1)
    assert_close(nodal.invariants["mass"], RHO * SECTION.area * lengths.sum(), rel=1e-13)
    assert_close(
        nodal.invariants["first_moment"], RHO * SECTION.area * lengths @ centres, rel=1e-12
    )
    # The mass points of the preprocessor, with offsets: the same (its brute-force helper).
    w2, x2, s2 = pp.mass_points(nodes, {"beam2": conn}, STEEL, beam_offsets=offsets, **options)
    assert_close(x2, positions, abs=1e-15, what="positions")
    assert_close(s2.toarray(), s.reshape(3 * len(weights), -1), abs=1e-13, what="S T")


def propped_cantilever_with_a_hinge(releases, count=8, length=2.0):
    """K of a cantilever along x clamped at node 0, `releases` (count, 12) on its elements."""
    nodes, elements = pp.straight_beam(length, count)
    return nodes, pp.assemble(
        nodes, elements, STEEL, section=SECTION, orientation=(0.0, 1.0, 0.0),
        beam_releases=releases,
    )  # fmt: skip


def test_a_hinge_in_a_propped_cantilever_bends_as_beam_theory(assert_close):
    # Clamped at x = 0, propped (v = w = 0) at L, a hinge at a = L/2 (pin flags 56 at the end
    # b of the element before it): the span beyond the hinge is simply supported on the hinge
    # and the prop. A load P at c = 3L/4 puts R = P (L - c) / (L - a) on the cantilever, whose
    # end sinks R a^3 / 3 EI; under the load w = that sink (L - c) / (L - a) + P b1^2 b2^2 / 3
    # EI (L - a). The moment vanishes on both sides of the hinge and is R a at the root.
    count, length, load = 8, 2.0, 500.0
    hinge, loaded = 4, 6
    releases = np.zeros((count, 12), dtype=bool)
    releases[hinge - 1, [10, 11]] = True
    nodes, nodal = propped_cantilever_with_a_hinge(releases, count, length)
    k = nodal.stiffness.toarray()
    held = list(range(6)) + [6 * count + 1, 6 * count + 2]
    free = np.setdiff1d(np.arange(6 * (count + 1)), held)
    f = np.zeros(6 * (count + 1))
    f[6 * loaded + 2] = load
    u = np.zeros_like(f)
    u[free] = np.linalg.solve(k[np.ix_(free, free)], f[free])
    ei = E * SECTION.iy
    a, c = nodes[hinge, 0], nodes[loaded, 0]
    span, b1, b2 = length - a, c - a, length - c
    reaction = load * (length - c) / span
    sink = reaction * a**3 / (3 * ei)
    assert_close(u[6 * hinge + 2], sink, rel=1e-10, what="hinge deflection")
    expected = sink * (length - c) / span + load * b1**2 * b2**2 / (3 * ei * span)
    assert_close(u[6 * loaded + 2], expected, rel=1e-10, what="deflection under the load")
    # (the section forces need a body: held at both ends, as a free one with a hinge is a
    # mechanism; they depend on the displacements alone)
    body = pp.build_body(
        nodes, pp.straight_beam(length, count)[1], STEEL, section=SECTION,
        orientation=(0.0, 1.0, 0.0), beam_releases=releases, reference="clamped",
        reference_nodes=[0, count],
    )  # fmt: skip
    _, forces = recover_stresses(body, u)  # (beams, 2, 6): N Vy Vz T My Mz
    scale = load * length
    assert_close(forces[hinge - 1, 1, 4], 0.0, abs=1e-10 * scale, what="M_y before the hinge")
    assert_close(forces[hinge, 0, 4], 0.0, abs=1e-10 * scale, what="M_y after the hinge")
    assert_close(abs(forces[0, 0, 4]), reaction * a, rel=1e-10, what="root moment")
    # Without the hinge the propped cantilever is 1.8 times stiffer under the load.
    _, whole = propped_cantilever_with_a_hinge(None, count, length)
    u0 = np.linalg.solve(whole.stiffness.toarray()[np.ix_(free, free)], f[free])
    assert u0[list(free).index(6 * loaded + 2)] < 0.6 * expected


def test_pinned_ends_by_pin_flags_vibrate_at_the_pinned_pinned_frequencies(assert_close):
    # End grids held in all six coordinates, the end elements released in theta_y, theta_z
    # (pin flags 56) at the held grids: a pinned-pinned beam in both planes, w_k = (k pi /
    # L)^2 sqrt(E I / rho A) (Euler-Bernoulli: no rotary inertia). With 20 elements and the
    # condensed mass (T^T M T) the first three frequencies are 4.2e-7, 6.8e-6 and 3.4e-5
    # above it (the discretization's error: the same beam pinned by its reference conditions,
    # its end rotations free, has 4.2e-7, 6.75e-6, 3.40e-5).
    count, length = 20, 1.0
    section = Section.rectangle(0.01, 0.006).without_rotary_inertia()
    nodes, elements = pp.straight_beam(length, count)
    releases = np.zeros((count, 12), dtype=bool)
    releases[0, [4, 5]] = releases[-1, [10, 11]] = True
    body = pp.build_body(
        nodes, elements, STEEL, section=section, orientation=(0.0, 1.0, 0.0),
        beam_releases=releases, reference="clamped", reference_nodes=[0, count],
        modes="fixed-interface", mode_count=12,
    )  # fmt: skip
    k = np.pi * np.arange(1, 4) / length
    for inertia in (section.iy, section.iz):
        exact = k**2 * np.sqrt(E * inertia / (RHO * section.area)) / (2 * np.pi)
        nearest = [body.frequencies[np.abs(body.frequencies - f).argmin()] for f in exact]
        assert_close(nearest, exact, rel=[1e-6, 1e-5, 5e-5], what="pinned-pinned frequency")
    # Clamped (without the pin flags) the first frequency is 2.27 times higher.
    clamped = pp.build_body(
        nodes, elements, STEEL, section=section, orientation=(0.0, 1.0, 0.0),
        reference="clamped", reference_nodes=[0, count], modes="fixed-interface", mode_count=1,
    )  # fmt: skip
    assert clamped.frequencies[0] > 2.2 * body.frequencies[0]


def portal_frame(releases):
    """Two columns (along z, clamped at their feet) and a crossbar along x; `releases` of the
    crossbar's one element (12 bools), the columns' none."""
    nodes = np.array([[0, 0, 0], [0, 0, 1], [1, 0, 1], [1, 0, 0]], dtype=float)
    conn = np.array([[0, 1], [1, 2], [3, 2]])
    every = np.zeros((3, 12), dtype=bool)
    every[1] = releases
    return nodes, {"beam2": conn}, every


def test_torsion_released_at_both_ends_of_a_crossbar_is_no_mechanism_of_a_frame(assert_close):
    # Pin flags 4 at both ends of the crossbar: its twist is free (K_rr singular), but the
    # columns hold the nodes, so the frame is no mechanism. The crossbar's twist follows the
    # mean of its nodes' twists: the mass still moves with every rigid motion of the frame
    # (the rigid part of M equals the frame's without releases, polar inertia included).
    released = np.zeros(12, dtype=bool)
    released[[3, 9]] = True
    nodes, elements, releases = portal_frame(released)
    section = Section.rectangle(0.04, 0.02)
    options = dict(section=section, orientation=(0.0, 1.0, 0.0))
    body = pp.build_body(
        nodes, elements, STEEL, beam_releases=releases, reference="clamped",
        reference_nodes=[0, 3], **options,
    )  # fmt: skip
    assert body.section["releases"].tolist() == releases.tolist()
    pinned = pp.assemble(nodes, elements, STEEL, beam_releases=releases, **options)
    whole = pp.assemble(nodes, elements, STEEL, **options)
    rigid = pp.rigid_modes(nodes - nodes.mean(axis=0), 6)
    inertia = rigid.T @ whole.mass @ rigid
    assert_close(rigid.T @ pinned.mass @ rigid, inertia, abs=1e-12 * np.abs(inertia).max())
    # The crossbar's own stiffness has lost G J / L: twisting the crossbar's nodes against
    # each other takes only the columns' bending.
    twist = np.zeros(24)
    twist[6 * 1 + 3], twist[6 * 2 + 3] = 1.0, -1.0
    assert twist @ pinned.stiffness @ twist < twist @ whole.stiffness @ twist


def test_a_release_that_leaves_a_mechanism_is_refused():
    # A hinge in a cantilever (pin flags 56 at the end b of its first element): the outer part
    # turns freely, named by its element.
    nodes, elements = pp.straight_beam(1.0, 3)
    releases = np.zeros((3, 12), dtype=bool)
    releases[0, [10, 11]] = True
    with pytest.raises(
        InvalidModelError, match=r"mechanism.*pin flags PA, PB\) of elements 1 let it"
    ):
        pp.build_body(
            nodes, elements, STEEL, section=SECTION, beam_releases=releases,
            reference="clamped", reference_nodes=[0],
        )  # fmt: skip


@pytest.mark.parametrize(
    ("options", "match"),
    [
        ({"beam_offsets": np.zeros((2, 2, 3))}, r"beam_offsets must be finite numbers of shape"),
        ({"beam_offsets": np.full((3, 2, 3), np.nan)}, r"beam_offsets must be finite"),
        ({"beam_releases": np.zeros((3, 6), dtype=bool)}, r"beam_releases must have shape"),
        ({"beam_releases": np.full((3, 12), 0.5)}, r"beam_releases must be bools"),
    ],
)
def test_bad_offsets_and_releases_are_named(options, match):
    nodes, elements = pp.straight_beam(1.0, 3)
    with pytest.raises(InvalidParameterError, match=match):
        pp.build_body(nodes, elements, STEEL, section=SECTION, **options)


def test_offsets_without_beams_are_refused():
    from flexmbd.fe import shapes

    mesh = shapes.box((1.0, 0.2, 0.2), (2, 1, 1), "hex8")
    with pytest.raises(InvalidParameterError, match="beam_offsets: the mesh has no beam"):
        pp.build_body(mesh.nodes, mesh.elements, STEEL, beam_offsets=np.zeros((0, 2, 3)))


def test_variants_and_body_files_keep_offsets_and_releases(tmp_path, assert_close):
    released = np.zeros(12, dtype=bool)
    released[[3, 9]] = True
    nodes, elements, releases = portal_frame(released)
    offsets = np.zeros((3, 2, 3))
    offsets[1, :, 2] = 0.03  # the crossbar above the columns' tops
    body = pp.build_body(
        nodes, elements, STEEL, section=SECTION, orientation=(0.0, 1.0, 0.0),
        beam_offsets=offsets, beam_releases=releases, reference="clamped",
        reference_nodes=[0, 3], modes="fixed-interface", mode_count=4,
    )  # fmt: skip
    stiffer = body.with_material(young_modulus=2 * E)
    assert_close(stiffer.frequencies, np.sqrt(2) * body.frequencies, rel=1e-9)
    nodal = body.with_modes(None)
    assert_close(nodal.stiffness.toarray(), body.stiffness.toarray(), abs=0.0, what="K")
    path = tmp_path / "frame.h5"
    save_body(body, path)
    loaded = load_body(path)
    assert_close(loaded.section["offsets"], offsets, abs=0.0, what="offsets")
    assert loaded.section["releases"].tolist() == releases.tolist()
    assert_close(loaded.with_material(young_modulus=2 * E).frequencies, stiffer.frequencies,
                 rel=1e-12)  # fmt: skip


def blade(offsets, speed):
    """A cantilever turned about global z at `speed` by the driver "hub": grids on x with
    `offsets` (the axis at z = e), or None with its nodes on the axis itself."""
    count, e = 10, 0.04
    nodes, elements = pp.straight_beam(1.0, count)
    given = None
    if offsets:
        given = np.zeros((count, 2, 3))
        given[:, :, 2] = e
    else:
        nodes = nodes + [0.0, 0.0, e]
    data = pp.build_body(
        nodes, elements, Material(7.0e10, 0.3, 2700.0), section=Section.rectangle(0.01, 0.002),
        orientation=(0.0, 1.0, 0.0), beam_offsets=given, reference="clamped", reference_nodes=[0],
    )  # fmt: skip
    system = fm.System()
    beam = system.add_flexible_body(data, geometric_stiffness=True, name="blade")
    hub, root = system.add_marker(system.ground), system.add_node_marker(beam, 1)
    system.add_revolute_joint(hub, root, name="bearing")
    system.add_angle_driver(hub, root, fm.Polynomial([0.0, speed]), name="hub")
    return system


def test_the_geometric_stiffness_of_an_offset_blade_is_that_of_its_axis(assert_close):
    # Grids on the hub's plane, the axis 40 mm above it (offsets along the spin axis): the
    # same blade as the one meshed on its axis. Spun at 60 rad/s (the first flap frequency
    # rises from 1.65 to 10.1 Hz by the centrifugal stiffening, which reads each element's
    # axial strain through the offset tie), both have the same frequencies (1e-11 measured).
    speeds = [0.0, 60.0]
    offset = campbell(blade(True, 0.0), "hub", speeds, modes=4)
    axis = campbell(blade(False, 0.0), "hub", speeds, modes=4)
    assert_close(offset.frequencies, axis.frequencies, rel=1e-9, what="frequencies")
    assert offset.frequencies[1, 0] > 5 * offset.frequencies[0, 0]
    # The co-rotational forces do not take offsets: refused by name.
    data = pp.build_body(
        *pp.straight_beam(1.0, 2), STEEL, section=SECTION, beam_offsets=np.ones((2, 2, 3)) * 0.01,
        reference="clamped", reference_nodes=[0],
    )  # fmt: skip
    with pytest.raises(InvalidModelError, match="corotational' does not take beams with offsets"):
        fm.System().add_flexible_body(data, geometric_stiffness="corotational")
