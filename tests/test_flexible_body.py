"""Deformable bodies in the main processor (seed eq. 15): equivalences with the rigid body and
between nodal and modal coordinates, energy, markers on nodes and node sets, and bad input."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import scipy.sparse as sp

import flexmbd as fm
from flexmbd.fe import Material, Section, build_body, shapes, straight_beam

STEEL = Material(2.1e11, 0.3, 7800.0)


def beam_body(elements: int = 6, length: float = 1.0, **kwargs):
    nodes, conn = straight_beam(length, elements)
    kwargs.setdefault("reference", "clamped")
    kwargs.setdefault("reference_nodes", [0])
    return build_body(nodes, conn, STEEL, section=Section.rectangle(0.02, 0.01), **kwargs)


def rigid_inertia(data):
    """Mass, centre of mass and inertia about it of the undeformed body, from its invariants."""
    inv = data.invariants
    m = inv.mass
    c = np.asarray(inv.first_moment) / m
    j0 = np.asarray(inv.second_moment)
    about_origin = np.trace(j0) * np.eye(3) - j0
    about_center = about_origin - m * (c @ c * np.eye(3) - np.outer(c, c))
    return m, c, about_center


def test_flexible_body_without_elastic_coordinates_moves_like_the_rigid_body():
    free = beam_body().elastic_coordinate_count
    data = beam_body(modes="external", external_modes=np.zeros((free, 0)))
    assert data.elastic_coordinate_count == 0
    mass, center, inertia = rigid_inertia(data)
    orientation = fm.rotation("x", 0.4) @ fm.rotation("z", -0.3)
    hinge_local = np.array([0.5, 0.0, 0.0])
    hinge = orientation @ hinge_local
    results = []
    for kind in ("flexible", "rigid"):
        system = fm.System(gravity=(0.0, -9.81, 0.0))
        common = dict(orientation=orientation, angular_velocity=(0.3, -0.5, 2.0))
        if kind == "flexible":
            body = system.add_flexible_body(data, **common)
            pin = system.add_node_marker(body, 4)  # node 4 is at x = 0.5
        else:
            body = system.add_rigid_body(mass, inertia, center_of_mass=center, **common)
            pin = system.add_marker(body, position=hinge_local)
        system.add_spherical_joint(system.add_marker(system.ground, position=hinge), pin)
        # Tight Newton tolerance: the comparison is of the equations, not of the iterations.
        solver = fm.GeneralizedAlpha(newton_tolerance=1e-12)
        results.append(fm.simulate(system, 0.5, 1e-3, output_interval=0.05, solver=solver))
    flexible, rigid = results
    # Equal to round-off accumulated over 500 steps of a tumbling body (a wrong inertia term
    # would show at 1e-4 and beyond).
    assert np.max(np.abs(flexible.coordinates - rigid.coordinates)) < 1e-9
    assert np.max(np.abs(flexible.total_energy - rigid.total_energy)) < 1e-10 * abs(
        rigid.total_energy[0]
    )


def swinging_beam(data, **kwargs):
    """A beam clamped to a hinge at its root, released horizontally under gravity."""
    system = fm.System(gravity=(0.0, -9.81, 0.0))
    beam = system.add_flexible_body(data, name="beam", **kwargs)
    system.add_revolute_joint(system.add_marker(system.ground), system.add_node_marker(beam, 1))
    return system, beam


def test_modal_body_with_all_modes_matches_the_nodal_body():
    nodal = beam_body()
    modal = beam_body(modes="fixed-interface", mode_count=nodal.elastic_coordinate_count)
    tips = []
    for data in (nodal, modal):
        system, beam = swinging_beam(data)
        result = fm.simulate(system, 0.3, 5e-4, output_interval=0.01)
        tips.append(result.node_positions(beam, [7])[:, 0, :])
    assert np.max(np.abs(tips[0] - tips[1])) < 1e-8
    # The beam swings down and bends.
    assert tips[0][-1, 1] < -0.2


def test_swinging_beam_conserves_energy_at_spectral_radius_one():
    data = beam_body(elements=4)
    system, beam = swinging_beam(data)
    result = fm.simulate(
        system, 0.5, 2e-4, output_interval=0.01, solver=fm.GeneralizedAlpha(spectral_radius=1.0)
    )
    energy = result.total_energy
    scale = np.max(np.abs(result.potential_energy - result.potential_energy[0]))
    assert scale > 1.0  # it did swing
    assert np.max(np.abs(energy - energy[0])) < 1e-5 * scale


def test_elastic_outputs_and_deflection_under_gravity():
    """Static deflection of a cantilever held horizontally by a fixed joint, against
    P L^3 / (8 E I) for its weight (R1), reached by damped motion."""
    data = beam_body(elements=8)
    system = fm.System(gravity=(0.0, -9.81, 0.0))
    beam = system.add_flexible_body(data, rayleigh_damping=(20.0, 0.0))
    system.add_fixed_joint(system.add_marker(system.ground), system.add_node_marker(beam, 1))
    result = fm.simulate(system, 1.5, 2e-3, output_interval=0.05)
    tip = result.node_displacements(beam, [9])[-1, 0]
    w = 7800.0 * 0.02 * 0.01 * 9.81
    ei = 2.1e11 * 0.01 * 0.02**3 / 12  # bending in y: the section is 0.02 m along y
    assert tip[1] == pytest.approx(-w / (8 * ei), rel=2e-3)
    assert result.elastic_coordinates(beam).shape[1] == data.elastic_coordinate_count
    positions = result.node_positions(beam)
    assert positions.shape == (len(result.time), 9, 3)


def test_node_set_marker_of_a_solid_follows_the_face():
    mesh = shapes.box((0.4, 0.05, 0.05), (8, 1, 1), "hex8")
    data = build_body(
        mesh.nodes,
        mesh.elements,
        STEEL,
        node_sets=mesh.node_sets,
        reference="clamped",
        reference_nodes="x0",
    )
    system = fm.System(gravity=(0.0, -9.81, 0.0))
    bar = system.add_flexible_body(data, rayleigh_damping=(50.0, 0.0))
    system.add_fixed_joint(system.add_marker(system.ground), system.add_node_set_marker(bar, "x0"))
    tip = system.add_node_set_marker(bar, "x1")
    sensor = system.add_sensor(tip, "orientation")
    result = fm.simulate(system, 0.6, 2e-3, output_interval=0.05)
    # The end face turns down (negative rotation about z) as the bar sags.
    assert result.sensor(sensor)[-1][1, 0] < -1e-5


def test_bad_flexible_input_names_the_item():
    data = beam_body()
    system = fm.System()
    beam = system.add_flexible_body(data, name="beam")
    with pytest.raises(fm.UnknownItemError, match="no node with id 99"):
        system.add_node_marker(beam, 99)
    # Node ids are integers: 2.7 and True were cut to nodes 2 and 1 without a word.
    for bad in (2.7, True):
        with pytest.raises(fm.InvalidParameterError, match="node id must be an integer"):
            system.add_node_marker(beam, bad)
    output = fm.NodeDisplacement(beam, 2.5, (0.0, 1.0, 0.0))
    with pytest.raises(fm.InvalidParameterError, match="node id must be an integer"):
        fm.linearize(system, "equilibrium", outputs=[output])
    rigid = system.add_rigid_body(1.0, (1, 1, 1))
    with pytest.raises(fm.InvalidModelError, match="not a deformable body"):
        system.add_node_marker(rigid, 1)
    with pytest.raises(fm.UnknownItemError, match="node set"):
        system.add_node_set_marker(beam, "nothing")
    # A line of beam nodes is an interface (its rotation about the line is the nodes' own:
    # test_interface_rotations, where a line of solid nodes is refused).
    system.add_node_set_marker(beam, [1, 2, 3])
    with pytest.raises(fm.InvalidModelError, match="joint connects two different bodies"):
        system.add_revolute_joint(system.add_node_marker(beam, 1), system.add_node_marker(beam, 3))
    with pytest.raises(fm.InvalidParameterError, match="elastic coordinates"):
        system.add_flexible_body(data, elastic_coordinates=np.zeros(3))
    with pytest.raises(fm.InvalidParameterError, match="finite"):
        system.add_flexible_body(
            data, elastic_coordinates=np.full(data.elastic_coordinate_count, np.nan)
        )
    # Body data without invariants of motion is refused when it is made.
    with pytest.raises(fm.InvalidModelError, match="'invariants' has no entries 'mass'"):
        dataclasses.replace(beam_body(), invariants={})
    # ... and by the system if forced past the constructor.
    stripped = beam_body()
    object.__setattr__(stripped, "invariants", {})
    with pytest.raises(fm.InvalidModelError, match="no invariants"):
        system.add_flexible_body(stripped)
    with pytest.raises(fm.InvalidModelError, match="beam and shell elements"):
        mesh = shapes.box((0.4, 0.05, 0.05), (2, 1, 1), "hex8")
        solid = build_body(
            mesh.nodes, mesh.elements, STEEL, reference="clamped", reference_nodes=[0, 1, 2, 3]
        )
        system.add_flexible_body(solid, geometric_stiffness=True)
    with pytest.raises(fm.InvalidModelError, match="modal body"):
        system.add_flexible_body(data, modal_damping=0.01)


@pytest.mark.parametrize(
    "parameter, value",
    [
        ("elastic_coordinates", fm.BodyId(99)),
        ("elastic_coordinates", "abc"),
        ("elastic_velocities", [object()] * 3),
        ("modal_damping", [0.0, float("inf"), 0.0]),
        ("modal_damping", "0.01"),
        ("condense", fm.BodyId(99)),
        ("condense", float("inf")),
        ("condense", 1),
        ("geometric_stiffness", 1),
        ("geometric_stiffness", np.ones((2, 2))),
    ],
    ids=lambda value: value if isinstance(value, str) else type(value).__name__,
)
def test_arguments_of_the_wrong_type_name_the_parameter(parameter, value):
    # Issue 28 (fuzz): an id as elastic_coordinates, a list as modal_damping or a float as
    # condense raised a bare TypeError (float() argument ..., 'float' object is not an
    # instance of 'bool'); a number or an array as geometric_stiffness was taken for its
    # truth value (strings name its kinds: another one than "von-karman" and "corotational"
    # is an InvalidParameterError, tests/test_corotational.py).
    data = beam_body(modes="fixed-interface", mode_count=3)
    system = fm.System()
    with pytest.raises(fm.InvalidParameterError, match=f"body 'rod': {parameter} must be") as info:
        system.add_flexible_body(data, name="rod", **{parameter: value})
    assert info.value.item == parameter
    assert isinstance(info.value, fm.ArgumentTypeError)
    # NumPy's bools are bools.
    system.add_flexible_body(data, condense=np.True_, geometric_stiffness=np.False_)


@pytest.mark.parametrize("parameter", ["elastic_coordinates", "elastic_velocities"])
@pytest.mark.parametrize("length", [0, 2, 4])
def test_elastic_arrays_of_the_wrong_length_name_the_parameter_and_the_lengths(parameter, length):
    # Issue 28 (fuzz): elastic_coordinates=[] was taken by the core for "undeformed" (None):
    # an array of another length than the body's elastic coordinates is refused in Python.
    data = beam_body(modes="fixed-interface", mode_count=3)
    system = fm.System()
    with pytest.raises(
        fm.InvalidParameterError, match=f"body 'rod': {parameter} must have 3 "
    ) as info:
        system.add_flexible_body(data, name="rod", **{parameter: np.zeros(length)})
    assert f"got {length}" in str(info.value)
    assert info.value.item == parameter
    # The right length and None (undeformed, at rest) are taken.
    system.add_flexible_body(data, **{parameter: [0.0, 0.0, 0.0]})
    system.add_flexible_body(data, **{parameter: None})


def with_columns_reversed(matrix) -> sp.csc_matrix:
    """The same matrix in CSC with the entries of each column in reverse order (unsorted
    indices, as a body file or another code may give them)."""
    c = sp.csc_matrix(matrix)
    c.sort_indices()
    order = np.concatenate(
        [
            np.arange(start, end)[::-1]
            for start, end in zip(c.indptr[:-1], c.indptr[1:], strict=True)
        ]
    )
    return sp.csc_matrix((c.data[order], c.indices[order], c.indptr.copy()), shape=c.shape)


def test_unsorted_sparse_matrices_are_taken_without_changing_the_body():
    # Issue 28 (fuzz): add_flexible_body sorted the indices of the body's matrices in place,
    # and a body's arrays are read-only: ValueError 'WRITEBACKIFCOPY base is read-only'.
    data = beam_body()
    invariants = dataclasses.replace(
        data.invariants,
        k_ff=with_columns_reversed(data.invariants.k_ff),
        i_kl=[[with_columns_reversed(m) for m in row] for row in data.invariants.i_kl],
    )
    unsorted = dataclasses.replace(data, invariants=invariants)
    stiffness = unsorted.invariants.k_ff
    assert not stiffness.has_sorted_indices and not stiffness.indices.flags.writeable
    before = stiffness.indices.copy()
    results = []
    for body in (data, unsorted):
        system = fm.System(gravity=(0.0, -9.81, 0.0))
        system.add_flexible_body(body, rayleigh_damping=(0.0, 1e-4))
        results.append(fm.simulate(system, 0.01, 1e-3))
    np.testing.assert_array_equal(unsorted.invariants.k_ff.indices, before)
    np.testing.assert_allclose(results[1].coordinates, results[0].coordinates, atol=1e-12)


def test_body_data_in_other_units_is_refused():
    # Issue 28: a body in millimetres was taken as metres by System.add_flexible_body (only the
    # model-file path checked the units).
    data = beam_body(modes="fixed-interface", mode_count=3)
    millimetres = dataclasses.replace(data, units={"length": "mm", "mass": "kg", "time": "s"})
    system = fm.System()
    with pytest.raises(fm.InvalidModelError, match="body 'rod'.*'length': 'mm'.*not SI") as info:
        system.add_flexible_body(millimetres, name="rod")
    assert info.value.item == "body 'rod'"
    system.add_flexible_body(data, name="rod")


def test_body_data_of_the_wrong_shapes_is_refused_before_the_core():
    # Issue 28: nodes of shape (n, 2) reached the binding and panicked ("index out of
    # bounds"); every array passed to the core is now checked, naming the field.
    data = beam_body(modes="fixed-interface", mode_count=3)
    with pytest.raises(fm.InvalidModelError, match=r"field 'nodes' .*\(7, 2\)"):
        dataclasses.replace(data, nodes=data.nodes[:, :2])
    # The same data forced past the constructor: the system checks it again.
    flat = dataclasses.replace(data)
    object.__setattr__(flat, "nodes", data.nodes[:, :2])
    with pytest.raises(fm.InvalidModelError, match=r"body 'rod': field 'nodes'") as info:
        fm.System().add_flexible_body(flat, name="rod")
    assert info.value.item == "field 'nodes'"

    def with_invariant(key, value):
        return dataclasses.replace(
            data, invariants=dataclasses.replace(data.invariants, **{key: value})
        )

    cases = [
        (with_invariant("i1", np.zeros((3, 2))), fm.InvalidModelError, r"'invariants\[\"i1\"\]'"),
        (with_invariant("ibar", np.zeros((3, 3))), fm.InvalidModelError, "ibar"),
        (with_invariant("first_moment", np.zeros(2)), fm.InvalidModelError, "first_moment"),
        (with_invariant("i_kl", [[np.eye(3)] * 3] * 2), fm.InvalidModelError, "3 lists of 3"),
        (with_invariant("mass", float("nan")), fm.InvalidParameterError, "mass must be finite"),
        (with_invariant("mass", 0.0), fm.InvalidParameterError, "mass must be finite and > 0"),
        (with_invariant("second_moment", -np.eye(3)), fm.InvalidParameterError, "semi-definite"),
        (
            with_invariant("i1", np.full((3, 3), np.inf)),
            fm.InvalidParameterError,
            "non-finite",
        ),
    ]
    for body, error, match in cases:
        with pytest.raises(error, match=match):
            fm.System().add_flexible_body(body, name="rod")


def test_pendulum_of_a_tetrahedral_mesh_conserves_energy():
    """The built-in tetrahedral pendulum (Craig-Bampton, frame on the hinged end face) swings
    without damping: at spectral radius 1 the energy stays constant to 1e-5 of the energy
    exchanged (second order in the step: 1e-5 at h = 1e-3, 2.5e-6 at 5e-4)."""
    example = fm.examples.tetrahedral_pendulum()
    result = fm.simulate(
        example.system,
        example.end_time,
        example.step_size,
        output_interval=example.output_interval,
        solver=example.solver,
    )
    exchanged = np.ptp(result.potential_energy)
    assert exchanged > 2.5  # it swung through the bottom: m g L / 2 = 2.98 J
    assert example.check(result)["energy drift relative to the energy exchanged"] < 1e-5
    # The arm bends: its tip lags behind the rigid rotation of the frame.
    assert np.max(np.abs(result.elastic_coordinates(example.items["arm"]))) > 1e-7


@pytest.mark.parametrize("pin_node", [1, 4])
@pytest.mark.parametrize("modal", [False, True])
def test_condensed_elastic_coordinates_give_the_same_motion(modal, pin_node):
    """Condensing the elastic coordinates out of the linear solves (constant factorized
    iteration matrix, Schur complement) changes the iteration, not the solution: with the
    hinge at the clamped node 1 (a reference marker) and at node 4 (x = 0.5, an elastic
    marker whose joint couples the condensed coordinates with the multipliers)."""
    nodal = beam_body()
    data = (
        beam_body(modes="fixed-interface", mode_count=nodal.elastic_coordinate_count)
        if modal
        else nodal
    )
    tips = []
    for condense in (False, True):
        system = fm.System(gravity=(0.0, -9.81, 0.0))
        # Node ids are 1-based: node k is at x = (k - 1) / 6, placed at the ground hinge.
        x_pin = data.nodes[pin_node - 1, 0]
        beam = system.add_flexible_body(
            data, position=(-x_pin, 0.0, 0.0), condense=condense, rayleigh_damping=(0.0, 1e-4)
        )
        pin = system.add_node_marker(beam, pin_node)
        system.add_revolute_joint(system.add_marker(system.ground), pin)
        result = fm.simulate(system, 0.3, 5e-4, output_interval=0.01)
        tips.append(result.node_positions(beam, [7])[:, 0, :])
    assert np.max(np.abs(tips[0] - tips[1])) < 1e-8


@pytest.mark.parametrize("jacobian", ["modified", "full"])
def test_multipliers_of_condensed_bodies_converge_with_every_jacobian(jacobian):
    """A condensed body's iteration matrix is approximate even when factorized at the current
    iterate, so the multipliers are tested with every Jacobian setting: a solid bar of 960
    elastic coordinates hinged at its clamped face gives the hinge force of a run at tolerance
    1e-10 to a few times the default tolerance 1e-6 (without the test, `jacobian="full"` took
    its second iterate's multipliers, off by 1.2e-5)."""
    mesh = shapes.box((1.0, 0.05, 0.05), (20, 3, 3), "tet4")
    data = build_body(
        mesh.nodes,
        mesh.elements,
        Material(7.0e10, 0.33, 2700.0),
        node_sets=mesh.node_sets,
        reference="clamped",
        reference_nodes="x0",
    )
    assert data.elastic_coordinate_count >= 300  # condensed by default

    def hinge_force(solver):
        system = fm.System(gravity=(0.0, -9.81, 0.0))
        bar = system.add_flexible_body(data)
        centroid = data.nodes[mesh.node_sets["x0"]].mean(axis=0)
        hinge = system.add_node_set_marker(bar, "x0")
        system.add_revolute_joint(system.add_marker(system.ground, position=centroid), hinge)
        return fm.simulate(system, 0.05, 1e-3, output_interval=1e-3, solver=solver).multipliers

    reference = hinge_force(fm.GeneralizedAlpha(0.9, newton_tolerance=1e-10))
    multipliers = hinge_force(fm.GeneralizedAlpha(0.9, jacobian=jacobian))
    error = np.max(np.abs(multipliers - reference)) / np.max(np.abs(reference))
    assert error < 5e-6, error


def test_iteration_matrices_age_five_steps_or_one_with_condensed_bodies():
    """The Newton matrix is refreshed after serving 5 steps; with condensed bodies at every
    step (their elastic block is the exact constant A: only the reference coupling ages, with
    the rotation, and its refresh costs no solve with A, less than the iteration a matrix of
    the last step adds)."""
    data = beam_body()
    refreshes, iterations = {}, {}
    for condense in (False, True):
        system = fm.System(gravity=(0.0, -9.81, 0.0))
        beam = system.add_flexible_body(data, condense=condense, rayleigh_damping=(0.0, 1e-4))
        pin = system.add_node_marker(beam, 4)
        system.add_revolute_joint(system.add_marker(system.ground, position=data.nodes[3]), pin)
        result = fm.simulate(system, 0.1, 5e-4, output_interval=0.01)
        assert result.statistics["steps"] == 200
        refreshes[condense] = result.statistics["factorizations"]
        iterations[condense] = result.statistics["newton_iterations"]
    assert 40 <= refreshes[False] <= 45 and refreshes[True] == 200, refreshes
    assert iterations[True] < iterations[False], iterations


def test_a_soft_condensed_beam_keeps_its_steps_and_the_motion_of_the_direct_solves(assert_close):
    """The soft tet beam of issue 30 (E = 1e8, rho = 1000, 1 x 0.1 x 0.1 m, here 270 elastic
    coordinates, condensed), pinned at its clamped face and released horizontal: the condensed
    iteration matrix contracts slowly (ratios of increments 0.01 to 0.3, one of them now and
    then above 1), which the step-size control took for divergence: 63 steps were rejected
    in 1 s at h = 1e-3. Judged by the contraction rate over two increments, the run keeps
    h = 1e-3 throughout, and its tip follows the uncondensed run at that fixed step (exact
    Newton matrices, sparse LU) to the Newton tolerance, and a run at h = 2.5e-4 to the
    error of the step (1.1e-4 m over a swing of 1 m)."""
    mesh = shapes.box((1.0, 0.1, 0.1), (10, 2, 2), "tet4")
    data = build_body(
        mesh.nodes,
        mesh.elements,
        Material(1.0e8, 0.3, 1000.0),
        node_sets=mesh.node_sets,
        reference="clamped",
        reference_nodes="x0",
    )
    centroid = data.nodes[mesh.node_sets["x0"]].mean(axis=0)
    tip_nodes = data.node_ids[mesh.node_sets["x1"]]

    def tip(condense, step, control, error_fraction=None):
        system = fm.System(gravity=(0.0, -9.81, 0.0))
        beam = system.add_flexible_body(data, condense=condense)
        hinge = system.add_node_set_marker(beam, "x0")
        system.add_revolute_joint(system.add_marker(system.ground, position=centroid), hinge)
        solver = fm.GeneralizedAlpha(
            0.9, step_control=control, newton_error_fraction=error_fraction
        )
        result = fm.simulate(system, 1.0, step, output_interval=0.05, solver=solver)
        return result.node_positions(beam, tip_nodes).mean(axis=1), result.statistics

    soft, stats = tip(True, 1e-3, "newton")
    assert stats["rejected_steps"] <= 2 and stats["steps"] <= 1002, stats
    # The coarse stage of the condensed solves (gyroscopic block, switched on by the first
    # slow steps) takes the iterations from 4.92 to 2.87 per step.
    assert stats["newton_iterations"] <= 3.2 * stats["steps"], stats
    direct, _ = tip(False, 1e-3, "fixed")
    assert_close(soft, direct, abs=1e-6, what="condensed tip against the direct solves")
    # Newton's tolerance at 3 % of the step's own error: 2.20 iterations per step, the tip
    # 5e-8 m from the direct solves' (the step's error: 1.1e-4 m, below).
    loose, loose_stats = tip(True, 1e-3, "newton", 0.03)
    assert loose_stats["newton_iterations"] <= 2.4 * loose_stats["steps"], loose_stats
    assert loose_stats["rejected_steps"] == 0, loose_stats
    assert_close(loose, direct, abs=1e-6, what="tip at Newton's tolerance of the step's error")
    finer, _ = tip(False, 2.5e-4, "fixed")
    assert_close(soft, finer, abs=2e-4, what="tip against the run at h = 2.5e-4")
    # The swing is large: a wrong motion could not pass the tolerances above.
    assert np.ptp(direct[:, 1]) > 0.9


def test_scalar_mass_products_of_solids_give_the_same_motion(monkeypatch):
    """Bodies of solids use the scalar mass matrix M_s (I_kl = M_s (x) e_k e_l^T) for the
    products of the inertia force; the general invariant products give the same motion."""
    import flexmbd.system

    mesh = shapes.box((0.4, 0.04, 0.04), (8, 2, 2), "tet4")
    data = build_body(
        mesh.nodes,
        mesh.elements,
        STEEL,
        node_sets=mesh.node_sets,
        reference="clamped",
        reference_nodes="x0",
    )
    assert flexmbd.system._scalar_mass(data, data.reference.free_dofs) is not None
    tips = []
    for fast in (True, False):
        if not fast:
            monkeypatch.setattr(flexmbd.system, "_scalar_mass", lambda body, free: None)
        system = fm.System(gravity=(0.0, -9.81, 0.0))
        bar = system.add_flexible_body(data)
        hinge = system.add_node_set_marker(bar, "x0")
        system.add_revolute_joint(system.add_marker(system.ground), hinge)
        result = fm.simulate(system, 0.1, 5e-4, output_interval=0.01)
        tips.append(result.node_positions(bar, [data.node_ids[-1]])[:, 0])
    assert np.max(np.abs(tips[0] - tips[1])) < 1e-10


def test_free_flying_deformable_body_keeps_its_momentum_and_energy():
    """A free-free beam in the mean-axis frame, thrown spinning and vibrating, with no forces:
    its centre of mass moves on a straight line at constant speed and its energy is conserved
    (spectral radius 1); the elastic vibration is excited and stays bounded."""
    nodes, conn = straight_beam(1.0, 8)
    data = build_body(
        nodes,
        conn,
        STEEL,
        section=Section.rectangle(0.02, 0.01),
        reference="mean-axis",
        modes="free-free",
        mode_count=4,
    )
    system = fm.System()
    velocity, spin = np.array([0.3, -0.2, 0.1]), np.array([0.4, 1.5, -2.0])
    q_f = np.zeros(data.elastic_coordinate_count)
    q_f[0] = 1e-3
    body = system.add_flexible_body(
        data,
        position=(0.1, 0.2, 0.3),
        velocity=velocity,
        angular_velocity=spin,
        elastic_coordinates=q_f,
    )
    result = fm.simulate(system, 1.0, 1e-4, output_interval=0.01, solver=fm.GeneralizedAlpha(1.0))
    inv = data.invariants
    s = np.asarray(inv.first_moment)[None, :] + np.einsum(
        "kj,tj->tk", np.asarray(inv.i1), result.elastic_coordinates(body)
    )
    com = result.position(body) + np.einsum("tij,tj->ti", result.orientation(body), s) / inv.mass
    v_com = np.gradient(com, result.time, axis=0)[1:-1]
    assert np.max(np.abs(v_com - v_com[0])) < 1e-6
    energy = result.total_energy
    assert np.max(np.abs(energy - energy[0])) < 1e-6 * energy[0]
    assert 1e-5 < np.max(np.abs(result.elastic_coordinates(body))) < 1e-2


# Typed invariants and reference conditions (issue 29) ------------------------------------------

INVARIANT_FIELDS = ("mass", "first_moment", "second_moment", "i1", "ibar", "i_kl", "k_ff", "m_ff")
REFERENCE_FIELDS = ("kind", "nodes", "free_dofs")
INTERFACE_FIELDS = ("interfaces", "interface_kind", "mode_count", "interface_weights")


def craig_bampton_body():
    mesh = shapes.box((0.4, 0.05, 0.05), (4, 1, 1), "hex8")
    return build_body(
        mesh.nodes,
        mesh.elements,
        STEEL,
        node_sets=mesh.node_sets,
        reference="interface",
        modes="craig-bampton",
        mode_count=3,
        interfaces=["x0", "x1"],
        interface_kind="rbe3",
    )


def test_invariants_and_reference_conditions_are_typed_fields():
    from flexmbd.fe import Invariants, ReferenceConditions
    from flexmbd.fe.body import FrozenList

    for data in (beam_body(), beam_body(modes="fixed-interface", mode_count=3)):
        inv, reference = data.invariants, data.reference
        assert isinstance(inv, Invariants) and isinstance(reference, ReferenceConditions)
        assert dataclasses.is_dataclass(inv) and dataclasses.is_dataclass(reference)
        assert tuple(f.name for f in dataclasses.fields(inv)) == INVARIANT_FIELDS
        assert tuple(f.name for f in dataclasses.fields(reference)) == (
            *REFERENCE_FIELDS,
            *INTERFACE_FIELDS,
        )
        n_f = data.elastic_coordinate_count
        assert isinstance(inv.mass, float) and inv.mass == pytest.approx(7800 * 0.02 * 0.01)
        assert inv.first_moment.shape == (3,) and inv.second_moment.shape == (3, 3)
        assert inv.i1.shape == (3, n_f) and inv.ibar.shape == (3, 3, n_f)
        assert inv.k_ff.shape == inv.m_ff.shape == (n_f, n_f)
        assert isinstance(inv.i_kl, FrozenList) and len(inv.i_kl) == 3
        assert all(isinstance(row, FrozenList) and len(row) == 3 for row in inv.i_kl)
        assert all(matrix.shape == (n_f, n_f) for row in inv.i_kl for matrix in row)
        assert reference.kind == "clamped"
        np.testing.assert_array_equal(reference.nodes, [0])
        assert reference.free_dofs.dtype == np.int64 and reference.free_dofs[0] == 6
        assert all(getattr(reference, name) is None for name in INTERFACE_FIELDS)
    reference = craig_bampton_body().reference
    assert reference.kind == "interface" and reference.interface_kind == "rbe3"
    assert reference.mode_count == 3
    assert len(reference.interfaces) == len(reference.interface_weights) == 2
    for members, weights in zip(reference.interfaces, reference.interface_weights, strict=True):
        assert members.shape == weights.shape and weights.sum() == pytest.approx(1.0)


def test_typed_invariants_and_reference_conditions_are_immutable():
    data = craig_bampton_body()
    inv, reference = data.invariants, data.reference
    with pytest.raises(fm.FrozenBodyError, match="invariants.k_ff") as info:
        inv.k_ff = 2.0 * inv.k_ff
    assert isinstance(info.value, dataclasses.FrozenInstanceError)
    assert info.value.item == "invariants.k_ff"
    with pytest.raises(AttributeError):
        reference.kind = "none"
    with pytest.raises(fm.FrozenBodyError, match="reference.free_dofs"):
        del reference.free_dofs
    with pytest.raises(fm.FrozenBodyError, match="invariants of a FlexibleBodyData"):
        inv["mass"] = 1.0
    with pytest.raises(fm.FrozenBodyError, match="reference of a FlexibleBodyData"):
        del reference["kind"]
    for change in (
        lambda: inv.update(mass=1.0),
        lambda: inv.pop("mass"),
        lambda: reference.setdefault("extra", 1),
        lambda: reference.clear(),
        lambda: inv.i_kl.append([]),
        lambda: inv.i_kl[0].__setitem__(0, None),
        lambda: reference.interfaces.append(np.zeros(1, dtype=np.int64)),
    ):
        with pytest.raises(fm.FrozenBodyError):
            change()
    for array in (inv.first_moment, inv.second_moment, inv.i1, inv.ibar, inv.k_ff, inv.i_kl[1][2]):
        assert not array.flags.writeable
    for array in (reference.nodes, reference.free_dofs, *reference.interface_weights):
        with pytest.raises(ValueError, match="read-only"):
            array[0] = 0
    # Mutable copies stay possible and leave the body as it is.
    copy = dict(inv)
    copy["mass"] = 1.0
    assert inv.mass == data.invariants["mass"] != 1.0


def test_typed_parts_read_as_the_old_dictionaries():
    from collections.abc import Mapping

    data = beam_body()
    inv, reference = data.invariants, data.reference
    assert isinstance(inv, Mapping) and isinstance(reference, Mapping)
    assert list(inv) == list(inv.keys()) == list(INVARIANT_FIELDS) and len(inv) == 8
    assert all(inv[name] is getattr(inv, name) for name in INVARIANT_FIELDS)
    assert dict(inv.items())["k_ff"] is inv.k_ff
    assert inv.get("k_ff") is inv.k_ff and "k_ff" in inv and inv.get("nothing") is None
    assert {**inv}["i1"] is inv.i1
    with pytest.raises(KeyError):
        inv["nothing"]
    with pytest.raises(KeyError):
        inv[0]
    # Optional entries that are None are not keys, as in the old dictionaries.
    assert list(reference) == list(REFERENCE_FIELDS) and len(reference) == 3
    assert "interfaces" not in reference and reference.get("interfaces") is None
    assert reference.get("interfaces", ()) == ()
    with pytest.raises(KeyError):
        reference["interfaces"]
    np.testing.assert_array_equal(reference["free_dofs"], reference.free_dofs)
    cb = craig_bampton_body().reference
    assert list(cb) == [*REFERENCE_FIELDS, *INTERFACE_FIELDS]
    assert cb["interface_kind"] == "rbe3" and cb.get("mode_count") == 3
    assert dict(cb)["interface_weights"] is cb.interface_weights


def test_body_data_made_from_dicts_gets_the_typed_parts():
    from flexmbd.fe import Invariants, ReferenceConditions

    data = craig_bampton_body()
    # The dict form of older code: plain dicts, the arrays writable copies.
    invariants = {name: value for name, value in data.invariants.items()}
    invariants["i1"] = np.array(data.invariants.i1)
    reference = {"kind": "interface", "nodes": np.array(data.reference.nodes)}
    reference["free_dofs"] = np.array(data.reference.free_dofs)
    reference["interfaces"] = [np.array(members) for members in data.reference.interfaces]
    made = dataclasses.replace(data, invariants=invariants, reference=reference)
    assert isinstance(made.invariants, Invariants)
    assert isinstance(made.reference, ReferenceConditions)
    assert made.invariants.k_ff is data.invariants.k_ff  # read-only already: not copied
    assert not made.invariants.i1.flags.writeable and invariants["i1"].flags.writeable
    assert not made.reference.free_dofs.flags.writeable
    assert made.reference.interface_kind is None and made.reference.mode_count is None
    assert made.elastic_coordinate_count == data.elastic_coordinate_count
    # The typed objects are made from dicts directly too, and by keywords.
    assert Invariants.from_mapping(invariants).k_ff is data.invariants.k_ff
    assert Invariants.from_mapping(data.invariants) is data.invariants
    direct = ReferenceConditions(kind="none", nodes=np.zeros(0, dtype=np.int64), free_dofs=[1])
    assert direct.free_dofs == [1] and direct.interfaces is None
    with pytest.raises(fm.FrozenBodyError):
        direct.free_dofs.append(2)


@pytest.mark.parametrize(
    "field, change, match",
    [
        ("invariants", {"k_ff": None}, "'invariants' has no entry 'k_ff'"),
        ("invariants", {"mass": None, "i_kl": None}, "'invariants' has no entries 'mass', 'i_kl'"),
        ("invariants", {"stiffness": 1.0}, "'invariants' has unknown entry 'stiffness'"),
        ("reference", {"free_dofs": None}, "'reference' has no entry 'free_dofs'"),
        ("reference", {"kind": None}, "'reference' has no entry 'kind'"),
        ("reference", {"interface": [0]}, "'reference' has unknown entry 'interface'"),
    ],
)
def test_dicts_with_missing_or_unknown_entries_are_refused_naming_them(field, change, match):
    data = beam_body()
    values = dict(getattr(data, field))
    for key, value in change.items():
        if value is None:
            del values[key]
        else:
            values[key] = value
    with pytest.raises(fm.InvalidModelError, match=match) as info:
        dataclasses.replace(data, **{field: values})
    assert info.value.item == f"field '{field}'"
    # A value None is as missing; the message lists what is needed.
    if None in change.values():
        values = dict(getattr(data, field), **change)
        with pytest.raises(fm.InvalidModelError, match=match) as info:
            dataclasses.replace(data, **{field: values})
        assert "needs 'mass'" in str(info.value) or "needs 'kind'" in str(info.value)


def test_body_data_parts_of_the_wrong_type_are_refused():
    from flexmbd.fe import Invariants, ReferenceConditions

    data = beam_body()
    for field, value in (("invariants", None), ("invariants", [1, 2]), ("reference", "clamped")):
        with pytest.raises(fm.InvalidModelError, match=f"field '{field}' must be") as info:
            dataclasses.replace(data, **{field: value})
        assert info.value.item == f"field '{field}'"
    with pytest.raises(fm.InvalidModelError, match="'invariants' has no entry 'm_ff'"):
        dataclasses.replace(data.invariants, m_ff=None)
    with pytest.raises(TypeError):
        Invariants(1.0)  # keywords only
    with pytest.raises(TypeError):
        ReferenceConditions(kind="none", nodes=[])  # free_dofs is required


def test_replaced_invariants_are_still_checked_against_the_nodal_matrices():
    data = beam_body(modes="fixed-interface", mode_count=3)
    softer = dataclasses.replace(data.invariants, k_ff=0.5 * data.invariants.k_ff)
    with pytest.raises(fm.InvalidModelError, match="with_stiffness_scale") as info:
        dataclasses.replace(data, invariants=softer)
    assert info.value.item == "invariants['k_ff']"
    with pytest.raises(fm.InvalidModelError, match="m_ff"):
        dataclasses.replace(
            data, invariants={**data.invariants, "m_ff": 2.0 * data.invariants.m_ff}
        )
    scaled = data.with_stiffness_scale(2.0)
    np.testing.assert_allclose(scaled.invariants.k_ff, 2.0 * data.invariants.k_ff, rtol=1e-15)
    assert scaled.invariants.m_ff is data.invariants.m_ff


def test_typed_parts_pickle_and_copy_frozen():
    import copy
    import pickle

    from flexmbd.fe import Invariants, ReferenceConditions

    data = craig_bampton_body()
    for part in (data.invariants, data.reference):
        for other in (pickle.loads(pickle.dumps(part)), copy.deepcopy(part), copy.copy(part)):
            assert type(other) is type(part) and list(other) == list(part)
            with pytest.raises(fm.FrozenBodyError):
                other["kind" if isinstance(part, ReferenceConditions) else "mass"] = 1
    for other in (pickle.loads(pickle.dumps(data)), copy.deepcopy(data)):
        assert isinstance(other.invariants, Invariants)
        assert isinstance(other.reference, ReferenceConditions)
        assert not other.invariants.i1.flags.writeable
        assert not other.reference.interface_weights[0].flags.writeable
        np.testing.assert_array_equal(other.invariants.k_ff, data.invariants.k_ff)
        assert other.reference.mode_count == 3


@pytest.mark.parametrize(
    ("frame_joint", "motions"),
    [(None, "all 6"), ("spherical", "rotation about body axis x, .*y, .*z"), ("fixed", None)],
)
def test_a_body_whose_frame_nothing_fixes_is_named(frame_joint, motions):
    # Reference conditions "none" with nodal coordinates leave the frame free in the body:
    # pinned at a node only, the acceleration system is singular (it said "no pivot in
    # column 31"). A joint on a marker of the frame holds it (a fixed one wholly, a
    # spherical one its translations only).
    from flexmbd.system import unheld_frames

    system = fm.System(gravity=(0.0, -9.81, 0.0))
    beam = system.add_flexible_body(beam_body(4, reference="none", reference_nodes=[]), name="beam")
    system.add_revolute_joint(system.add_marker(system.ground), system.add_node_marker(beam, 1))
    if frame_joint is not None:
        add = getattr(system, f"add_{frame_joint}_joint")
        add(system.add_marker(system.ground), system.add_marker(beam))
    model = system.compile()
    found = unheld_frames(model, np.asarray(model.initial_coordinates))
    if motions is None:
        assert found == []
        fm.simulate(model, 2e-3, 1e-3)
        return
    with pytest.raises(
        fm.SingularMatrixError, match=f"body 'beam': nothing fixes its frame.*{motions}"
    ) as caught:
        fm.simulate(model, 2e-3, 1e-3)
    # Refused before the run (the factorization took the round-off pivots of such a
    # matrix for true ones), so no records.
    assert caught.value.item == "body 'beam'" and caught.value.result is None
    # Equilibrium and linearization refuse it too (an equilibrium was found, and modes of
    # 12.2 and 132.8 Hz reported for a beam of 8.18 Hz).
    with pytest.raises(fm.SingularMatrixError, match="body 'beam': nothing fixes its frame"):
        fm.equilibrium(model)
    with pytest.raises(fm.SingularMatrixError, match="body 'beam': nothing fixes its frame"):
        fm.linearize_at_rest(system)
    # A clamped body's frame is fixed in it.
    clamped = fm.System()
    clamped.add_flexible_body(beam_body(4), name="beam")
    compiled = clamped.compile()
    assert unheld_frames(compiled, np.asarray(compiled.initial_coordinates)) == []
