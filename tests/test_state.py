"""Starting states: flexmbd.State, runs from equilibrium and from steady rotation, and no
silent corrections of the initial conditions (events, warnings, strict refusal)."""

from __future__ import annotations

import dataclasses
import logging
import warnings

import numpy as np
import pytest
import scipy.linalg
import scipy.sparse.linalg as spla
from conftest import clamped_steel_beam, constraint_parts, turntable_pendulum

import flexmbd as fm
from flexmbd.errors import (
    EquilibriumError,
    InitialConditionsError,
    InitialCorrectionWarning,
    InvalidModelError,
    InvalidParameterError,
)
from flexmbd.fe import Material, Section, build_body, shapes, straight_beam
from flexmbd.fe.stress import recover_stresses
from flexmbd.model_file import load_model, simulate_model

GRAVITY = np.array([0.0, -9.81, 0.0])


@pytest.fixture(scope="module")
def link():
    """A tapered aluminium link (Gmsh tet10), its root face 40 x 20 mm centred on the origin
    and meshed unevenly (the average of its nodes is 2 mm off the centre), clamped to the body
    frame at that face: the body data and the mesh."""
    mesh = shapes.tapered_link(
        0.3,
        (0.04, 0.02),
        (0.02, 0.01),
        size=0.03,
        order=2,
        tip_offset=(0.005, 0.0),
        size_field="0.008 + 2.0 * (y + 0.02) * (y + 0.02)",
    )
    body = build_body(
        mesh.nodes,
        mesh.elements,
        Material(7.0e10, 0.33, 2700.0),
        node_sets=mesh.node_sets,
        reference="clamped",
        reference_nodes="root",
    )
    return body, mesh


def hinged_arm(body, weights="auto"):
    """The link horizontal along x, hinged about z at the centre of its root face (the global
    origin), held at angle 0 by an angle driver, under gravity along -y."""
    system = fm.System(gravity=GRAVITY)
    arm = system.add_flexible_body(body, name="arm")
    root = system.add_node_set_marker(arm, "root", weights=weights, name="root")
    ground = system.add_marker(system.ground)
    system.add_revolute_joint(ground, root, name="hinge")
    drive = system.add_angle_driver(ground, root, fm.Constant(0.0), name="drive")
    return system.compile(), arm, drive


def static_solution(body):
    """The static deflection under gravity by scipy on the same K and M (the reference
    conditions hold the root face): elastic coordinates, nodal displacements, and the gravity
    torque about the hinge of the deformed link."""
    free = body.reference["free_dofs"]
    load = body.mass @ np.tile(GRAVITY, body.node_count)
    q = spla.spsolve(body.stiffness[free][:, free].tocsc(), load[free])
    u = np.zeros(body.dof_count)
    u[free] = q
    deformed = body.nodes + u.reshape(-1, 3)
    scalar = body.mass[0::3, 0::3]  # M = M_s (x) I_3
    first_moment = np.asarray(scalar.sum(axis=0)).ravel() @ deformed
    return q, u, np.cross(first_moment, GRAVITY)


def test_a_driven_arm_started_from_equilibrium_is_the_static_fe_solution(link, assert_close):
    body, _ = link
    model, arm, drive = hinged_arm(body)
    q_static, u_static, torque = static_solution(body)
    eq = fm.equilibrium(model)
    # Relative to the largest displacement (the z components are round-off of it).
    scale = np.abs(q_static).max()
    assert_close(eq.elastic_coordinates(arm), q_static, abs=1e-8 * scale, what="equilibrium")
    with warnings.catch_warnings():
        warnings.simplefilter("error", InitialCorrectionWarning)
        result = fm.simulate(model, 0.01, 1e-3, initial_state=eq)
    # The hinge at the true face centre closes without a gap: nothing was corrected.
    assert result.events == []
    q0 = result.elastic_coordinates(arm)[0]
    assert_close(q0, q_static, abs=1e-8 * scale, what="first elastic coordinates")
    # The driving torque at t = 0 is the static torque (the drive holds the link's weight).
    # (about the hinge axis z; the hinge takes the rest).
    assert_close(result.reaction_torque(drive)[0][2], -torque[2], rel=1e-6, what="torque")
    # ... and the stresses are the static stresses.
    static_stress = recover_stresses(body, u_static)[0]
    stress = result.stresses(arm, [0])[0]
    stress_scale = np.abs(static_stress).max()
    assert_close(stress, static_stress, abs=1e-8 * stress_scale, what="stresses")
    # No start-up transient.
    q = result.elastic_coordinates(arm)
    assert_close(q, q_static, abs=1e-6 * scale, what="elastic coordinates")
    # From the given (undeformed) state the arm first drops: no torque at t = 0.
    dropping = fm.simulate(model, 0.002, 1e-3)
    first_torque = dropping.reaction_torque(drive)[0][2]
    assert_close(first_torque, 0.0, abs=1e-6 * abs(torque[2]), what="torque at t = 0")


def test_a_hinge_at_the_node_average_leaves_a_gap_that_is_reported_or_refused(link):
    body, _ = link
    model, _, _ = hinged_arm(body, weights="uniform")
    with pytest.warns(InitialCorrectionWarning, match="joint 'hinge'.*violate it by 2.2"):
        result = fm.simulate(model, 0.002, 1e-3)
    messages = [e["message"] for e in result.events if e["kind"] == "initial correction"]
    assert any("joint 'hinge' (revolute)" in m for m in messages)
    assert any("body 'arm'" in m and "position by up to 2.2" in m for m in messages)
    with pytest.raises(InitialConditionsError, match="refused.*joint 'hinge'") as error:
        fm.simulate(model, 0.002, 1e-3, initial_conditions="strict")
    assert error.value.result is not None and len(error.value.result.time) == 0


def rotating_rod(speed: float, elements: int = 20, length: float = 10.0):
    """A rod (circular section, r = 5 cm) clamped to its body frame at the hub, turned about z
    at constant `speed` by an angle driver, with the geometric stiffness of its beams."""
    nodes, conn = straight_beam(length, elements)
    body = build_body(
        nodes,
        conn,
        Material(7.0e10, 0.3, 2700.0),
        section=Section.circle(0.05),
        reference="clamped",
        reference_nodes=[0],
    )
    system = fm.System()
    rod = system.add_flexible_body(body, name="rod", geometric_stiffness=True)
    hub = system.add_node_marker(rod, int(body.node_ids[0]), name="hub")
    ground = system.add_marker(system.ground)
    system.add_revolute_joint(ground, hub, name="hinge")
    system.add_angle_driver(ground, hub, fm.Polynomial([0.0, speed]), name="drive")
    return system.compile(), rod, int(body.node_ids[-1])


def test_a_steady_rotation_start_has_no_transient_and_is_the_rotating_rod_solution(
    assert_close,
):
    speed, length = 10.0, 10.0
    model, rod, tip = rotating_rod(speed, length=length)
    start = fm.steady_rotation(model)
    assert_close(start.angular_velocity(rod), (0, 0, speed), rel=1e-12, what="angular velocity")
    stretch = start.node_displacements(rod, [tip])[0, 0]
    # R1: u(x) = sin(a x) / (a cos(a L)) - x, a = W sqrt(rho / E).
    a = speed * np.sqrt(2700.0 / 7.0e10)
    exact = np.tan(a * length) / a - length
    assert_close(stretch, exact, rel=1e-3, what="tip stretch")
    result = fm.simulate(model, 1.0, 2.5e-4, initial_state="steady-rotation", output_interval=0.01)
    assert result.events == []
    tips = result.node_displacements(rod, [tip])[:, 0, 0]
    assert_close(tips, stretch, rel=1e-6, what="tip stretch")
    # From the given state (unstretched, at rest) the rod overshoots to about twice.
    with pytest.warns(InitialCorrectionWarning, match="body 'rod'.*velocities"):
        given = fm.simulate(model, 0.05, 5e-4, output_interval=5e-4)
    assert given.node_displacements(rod, [tip])[:, 0, 0].max() > 1.5 * stretch


def test_bodies_on_free_hinges_of_a_turning_hub_turn_with_it(assert_close):
    # A hub turning at W about z carries a bob on a free hinge (axis z) at radius R; a
    # second pendulum hangs from the ground apart. In the steady rotation the bob turns
    # rigidly with the hub (the minimum-norm velocities turned it backwards at -1.15 rad/s,
    # and the run swung it by 37 degrees), and the pendulum apart stays at rest.
    radius, arm, speed = 0.3, 0.1, 10.0
    system = fm.System()
    hub = system.add_rigid_body(10.0, (0.1, 0.1, 0.2), name="hub")
    ground, axis = system.add_marker(system.ground), system.add_marker(hub)
    system.add_revolute_joint(ground, axis, name="bearing")
    system.add_angle_driver(ground, axis, fm.Polynomial([0.0, speed]), name="spin")
    bob = system.add_rigid_body(0.5, (1e-6, 1e-6, 1e-6), position=(radius + arm, 0, 0), name="bob")
    pivot = system.add_marker(hub, position=(radius, 0, 0))
    system.add_revolute_joint(pivot, system.add_marker(bob, position=(-arm, 0, 0)), name="pivot")
    apart = system.add_rigid_body(1.0, (0.1, 0.1, 0.1), position=(0, 5, 0), name="apart")
    system.add_revolute_joint(system.add_marker(system.ground, position=(0, 5.5, 0)),
                              system.add_marker(apart, position=(0, 0.5, 0)))  # fmt: skip
    state = fm.steady_rotation(system)
    reach = radius + arm
    assert_close(state.angular_velocity("bob"), (0, 0, speed), abs=1e-12 * speed, what="bob spin")
    assert_close(state.velocity("bob"), (0, speed * reach, 0), abs=1e-12, what="bob velocity")
    offset = system.compile().describe()["bodies"][2]["offset"]
    assert_close(state.accelerations[offset : offset + 3], (-(speed**2) * reach, 0, 0),
                 abs=1e-10, what="centripetal acceleration")  # fmt: skip
    assert_close(state.velocity("apart"), 0.0, abs=1e-15, what="pendulum apart")
    assert_close(state.angular_velocity("apart"), 0.0, abs=1e-15, what="pendulum apart")
    result = fm.simulate(system, 0.3, 1e-3, initial_state=state, output_interval=0.05)
    relative = np.einsum("kji,kjl->kil", result.orientation("hub"), result.orientation("bob"))
    assert_close(np.arctan2(relative[:, 1, 0], relative[:, 0, 0]), 0.0, abs=1e-4,
                 what="bob's angle on the hub")  # fmt: skip


def test_steady_rotation_needs_a_turning_driver_at_constant_speed():
    model, _, _ = rotating_rod(0.0, elements=4)
    with pytest.raises(InvalidModelError, match="no driver moves"):
        fm.steady_rotation(model)
    system = fm.System()
    body = system.add_rigid_body(1.0, (0.1, 0.1, 0.1), position=(1, 0, 0))
    ground = system.add_marker(system.ground)
    hub = system.add_marker(body, position=(-1, 0, 0))
    system.add_revolute_joint(ground, hub)
    system.add_angle_driver(ground, hub, fm.Polynomial([0.0, 1.0, 2.0]), name="spin-up")
    with pytest.raises(InvalidModelError, match="driver 'spin-up' accelerates"):
        fm.steady_rotation(system)


def test_equilibrium_where_the_drivers_have_moved_turns_the_parts_they_drive(assert_close):
    # Found on the spin-up (issue 30): at t = 20 s the hub is 75 rad on; from the model's
    # initial coordinates Newton diverged (relative increment 3e6) and steady_rotation said
    # the driver "accelerates" (it evaluated C_tt at the inconsistent start); then both were
    # refused ("violate driver 'drive'", also model files' `start` with a `start_time`). Now
    # the beam the driver turns is turned to the hub's angle at that time first: the states
    # are those started from coordinates turned by hand.
    example = fm.examples.spin_up(elements=4)
    model = example.system.compile()
    time = 20.0
    angle = 6.0 * (time - 7.5)
    q = np.array(model.initial_coordinates)
    q[3:7] = [np.cos(angle / 2), 0.0, 0.0, np.sin(angle / 2)]
    for analysis in (fm.equilibrium, fm.steady_rotation):
        turned = analysis(model, time)
        by_hand = analysis(model, time, coordinates=q)
        assert_close(turned.coordinates, by_hand.coordinates, abs=1e-9, what=analysis.__name__)
        assert_close(turned.multipliers, by_hand.multipliers, rel=1e-7,
                     abs=1e-9 * np.abs(by_hand.multipliers).max(), what="multipliers")  # fmt: skip
    spin = turned.angular_velocity(example.items["beam"])[2]
    assert_close(spin, 6.0, rel=1e-9, what="angular velocity")


@pytest.mark.parametrize("side", ["second", "first"])
def test_a_driven_part_is_turned_and_shifted_to_its_drivers_whichever_marker_it_carries(
    side, assert_close
):
    # An arm (a rigid body) on a hinge about z turned by an angle driver f = 2 t rad and a
    # slider on it (a prismatic joint along the arm's x axis, driven to 0.3 + 0.1 t m), built
    # at the drivers' start: the equilibrium at t = 1.2 s (the arm 2.4 rad on) has them where
    # the drivers put them, the driver's first marker on the arm or on the ground.
    system = fm.System(gravity=(0.0, 0.0, -9.81))
    arm = system.add_rigid_body(1.0, (0.01, 0.1, 0.1), position=(0.5, 0, 0), name="arm")
    slider = system.add_rigid_body(0.5, (1e-3,) * 3, position=(0.3, 0, 0), name="slider")
    ground, root = system.add_marker(system.ground), system.add_marker(arm, position=(-0.5, 0, 0))
    system.add_revolute_joint(ground, root)
    pair = (ground, root) if side == "second" else (root, ground)
    sign = 1.0 if side == "second" else -1.0
    system.add_angle_driver(*pair, fm.Polynomial([0.0, sign * 2.0]), name="swing")
    along = fm.rotation("y", np.pi / 2)  # (the markers' z along the arm's x)
    rail = system.add_marker(arm, position=(-0.5, 0, 0), orientation=along)
    carriage = system.add_marker(slider, orientation=along)
    system.add_prismatic_joint(rail, carriage)
    system.add_translation_driver(rail, carriage, fm.Polynomial([0.3, 0.1]), name="feed")
    time = 1.2
    state = fm.equilibrium(system, time)
    turn = fm.rotation("z", 2.0 * time)
    assert_close(state.orientation("arm"), turn, abs=1e-9, what="arm")
    assert_close(state.position("arm"), turn @ [0.5, 0, 0], abs=1e-9, what="arm's centre")
    assert_close(state.position("slider"), turn @ [0.3 + 0.1 * time, 0, 0], abs=1e-9,
                 what="slider")  # fmt: skip


def test_a_driven_crank_in_a_loop_is_not_turned_and_the_driver_is_named():
    # Turning a four-bar's crank alone would break its loop: the start stays, and the error
    # names the driver as before.
    example = fm.examples.flexible_slider_crank()
    model = example.system.compile()
    with pytest.raises(InvalidModelError, match=r"violate driver '.*' by"):
        fm.equilibrium(model, 0.013)


@pytest.mark.parametrize("start", [0.0, 0.05])
def test_an_angle_driver_half_a_turn_from_its_joint_is_refused_as_a_run_refuses_it(
    start, assert_close
):
    # A link (2 kg, 1 m) on a hinge held by an angle driver at pi, built at `start` rad:
    # sin(theta - pi) = 0 holds at 0 too, and equilibrium returned the link at 0 (origin at
    # x = +0.5, not -0.5) with the driving torque of the other sign; a run refuses it.
    def link(angle):
        system = fm.System(gravity=GRAVITY)
        turn = np.array([[np.cos(angle), -np.sin(angle), 0], [np.sin(angle), np.cos(angle), 0],
                         [0, 0, 1]])  # fmt: skip
        body = system.add_rigid_body(
            2.0, (1e-4, 1 / 6, 1 / 6), position=tuple(turn @ [0.5, 0, 0]), orientation=turn,
            name="link",
        )  # fmt: skip
        ground, end = (
            system.add_marker(system.ground),
            system.add_marker(body, position=(-0.5, 0, 0)),
        )
        system.add_revolute_joint(ground, end, name="hinge")
        system.add_angle_driver(ground, end, np.pi, name="drive")
        return system

    system = link(start)
    with pytest.raises(InitialConditionsError, match="quarter turn"):
        fm.simulate(system, 0.01, 1e-3)
    with pytest.raises(InitialConditionsError, match="angle driver 'drive'") as raised:
        fm.equilibrium(system)
    assert raised.value.item == "driver 'drive'"
    # Built at the driver's angle: the link points along -x, held against its weight by
    # m g L / 2 = 9.81 N m.
    state = fm.equilibrium(link(np.pi - start))
    assert_close(state.coordinates[:2], [-0.5, 0.0], abs=1e-9, what="origin")
    assert_close(abs(state.multipliers[-1]), 2.0 * 9.81 * 0.5, rel=1e-9, what="torque")


def pendulum(offset: float = 0.01):
    """A rigid link hinged at the origin, placed `offset` above where the hinge closes."""
    system = fm.System(gravity=GRAVITY)
    link = system.add_rigid_body(
        1.0, (1e-4, 1 / 12, 1 / 12), position=(0.5, offset, 0), name="link"
    )
    end = system.add_marker(link, position=(-0.5, 0, 0))
    system.add_revolute_joint(system.add_marker(system.ground), end, name="hinge")
    return system, link


@pytest.mark.parametrize("solver", [None, fm.ExplicitSolver("rk4")], ids=["alpha", "rk4"])
def test_initial_corrections_are_events_warnings_and_log_records(solver, caplog):
    system, _ = pendulum()
    with caplog.at_level(logging.WARNING, logger="flexmbd"):
        with pytest.warns(InitialCorrectionWarning) as record:
            result = fm.simulate(system, 0.01, 1e-3, solver=solver)
    kinds = {e["kind"] for e in result.events}
    assert "initial correction" in kinds
    text = " | ".join(str(w.message) for w in record)
    assert "joint 'hinge' (revolute): the given positions violate it by 1.000e-2" in text
    assert "body 'link'" in text and "position by up to 5.000e-3" in text
    assert any("joint 'hinge'" in r.getMessage() for r in caplog.records)
    with pytest.raises(InitialConditionsError, match="refused"):
        fm.simulate(system, 0.01, 1e-3, solver=solver, initial_conditions="strict")
    # Consistent positions: nothing to report, and strict runs.
    consistent, _ = pendulum(0.0)
    with warnings.catch_warnings():
        warnings.simplefilter("error", InitialCorrectionWarning)
        fm.simulate(consistent, 0.01, 1e-3, solver=solver, initial_conditions="strict")


def two_link_arm(shoulder_offset: float) -> fm.System:
    """Two aluminium hex8 links 1 x 0.1 x 0.05 m (Craig-Bampton, interfaces x0 and x1, rbe2)
    hinged in series, the shoulder's ground marker `shoulder_offset` below the centroid of
    the first link's interface x0."""
    mesh = fm.fe.shapes.box((1.0, 0.1, 0.05), (10, 1, 1), "hex8")
    body = fm.fe.build_body(
        mesh.nodes,
        mesh.elements,
        fm.fe.Material(7e10, 0.33, 2700.0),
        node_sets=mesh.node_sets,
        reference="interface",
        modes="craig-bampton",
        mode_count=4,
        interfaces=["x0", "x1"],
    )
    system = fm.System(gravity=GRAVITY)
    first = system.add_flexible_body(body, name="link1")
    second = system.add_flexible_body(body, name="link2", position=(1.0, 0.0, 0.0))
    pivot = system.add_marker(system.ground, position=(0.0, 0.05 - shoulder_offset, 0.025))
    system.add_revolute_joint(pivot, system.add_node_set_marker(first, "x0", coupling="rbe2"))
    system.add_revolute_joint(
        system.add_node_set_marker(first, "x1", coupling="rbe2"),
        system.add_node_set_marker(second, "x0", coupling="rbe2"),
    )
    return system


@pytest.mark.parametrize(
    "solver", [None, fm.ExplicitSolver("tr-bdf2", "partitioning")], ids=["alpha", "tr-bdf2"]
)
def test_initial_corrections_move_deformable_bodies_rather_than_bend_them(solver):
    # The shoulder's marker 5 cm off the interface: the correction moved the links by about
    # 4 cm and bent the first by 7 mm of its interface coordinates (minimum norm over all
    # coordinates), 9 kJ of strain energy in an aluminium link: generalized-alpha diverged at
    # t = 0.67 s. Now the elastic coordinates' changes weigh 1e6 times more: the links move
    # and turn, undeformed, and swing as a double pendulum.
    end = 0.2 if solver is None else 2e-3  # TR-BDF2 (the dense correction): its start
    with pytest.warns(InitialCorrectionWarning) as record:
        result = fm.simulate(two_link_arm(0.05), end, 1e-3, output_interval=1e-3, solver=solver)
    assert not any("elastic coordinates" in str(w.message) for w in record)
    for link in ("link1", "link2"):
        assert np.abs(result.elastic_coordinates(link)[0]).max() < 1e-7  # 7.3e-3 before
        assert np.abs(result.elastic_coordinates(link)).max() < 1e-4
    assert result.constraint_violation.max() < 1e-9
    # The hinge is where its marker says: the first link's interface centroid moved onto it.
    corrected = result.state(0)
    assert abs(corrected.position("link1")[1] - (-0.05)) < 2e-3


@pytest.mark.parametrize(
    "solver", [None, fm.ExplicitSolver("tr-bdf2", "partitioning")], ids=["alpha", "tr-bdf2"]
)
def test_a_violation_only_a_deformation_removes_is_still_corrected(solver, assert_close):
    # A 1 m steel beam pinned at both ends to points 1.001 m apart: no motion of its frame
    # meets both, so the correction stretches it by 1 mm (its axial elastic coordinate).
    data = clamped_steel_beam(1.0, 4, Section.circle(0.01))
    system = fm.System()
    beam = system.add_flexible_body(data, name="beam")
    system.add_spherical_joint(system.add_marker(system.ground), system.add_node_marker(beam, 1))
    far = system.add_marker(system.ground, position=(1.001, 0.0, 0.0))
    system.add_spherical_joint(far, system.add_node_marker(beam, 5))
    with pytest.warns(InitialCorrectionWarning, match="elastic coordinates"):
        result = fm.simulate(system, 2e-3, 1e-3, output_interval=1e-3, solver=solver)
    tip = result.state(0).node_positions("beam")[-1]
    assert_close(tip, [1.001, 0.0, 0.0], abs=1e-9, what="stretched end")


@pytest.mark.parametrize(
    "solver",
    [None, fm.ExplicitSolver("rk4", "projection"), fm.ExplicitSolver("tr-bdf2", "partitioning")],
    ids=["alpha", "rk4", "tr-bdf2"],
)
def test_elastic_velocities_of_a_start_are_kept_where_no_joint_moves_them(solver, assert_close):
    # A beam welded to the ground at its frame, started vibrating: no constraint involves its
    # elastic velocities, so the consistent initial conditions keep them. The velocity
    # projection in the metric W of the corrections (elastic changes weighing 1e6) had q_dot
    # on its right-hand side instead of W q_dot: generalized-alpha started the beam with
    # 1e-6 of them (5e-8 for 0.05) and warned of an initial correction.
    data = clamped_steel_beam(1.0, 6, Section.rectangle(0.02, 0.01))
    system = fm.System()
    beam = system.add_flexible_body(data, name="beam")
    system.add_fixed_joint(system.add_marker(system.ground), system.add_node_marker(beam, 1))
    start = fm.State.of_model(system)
    rates = np.zeros(data.elastic_coordinate_count)
    rates[1::6] = 0.05 * np.arange(1, 7) / 6.0  # the nodes' lateral velocities grow outward
    start = start.with_elastic_velocities(beam, rates)
    with warnings.catch_warnings():
        warnings.simplefilter("error", InitialCorrectionWarning)
        result = fm.simulate(
            system, 1e-4, 1e-5, output_interval=1e-5, initial_state=start, solver=solver
        )
    assert_close(result.elastic_velocities(beam)[0], rates, abs=1e-15)
    # A run restarted from a later state continues the run.
    k = 5
    rest = fm.simulate(
        system, 1e-4, 1e-5, output_interval=1e-5, initial_state=result.state(k), solver=solver
    )
    assert_close(rest.elastic_velocities(beam)[0], result.elastic_velocities(beam)[k], abs=1e-15)


def test_states_have_accessors_by_body_make_changed_copies_and_are_immutable(link, assert_close):
    body, _ = link
    model, arm, drive = hinged_arm(body)
    given = fm.State.of_model(model)
    assert given.time == 0.0 and np.all(given.elastic_coordinates(arm) == 0)
    assert_close(given.orientation(arm), np.eye(3), rel=1e-7, what="orientation")
    eq = fm.equilibrium(model)
    moved = given.with_elastic_coordinates(arm, eq.elastic_coordinates(arm))
    assert moved.accelerations is None and np.all(moved.velocities == given.velocities)
    # Starting from the edited state is starting from equilibrium (the same coordinates).
    a = fm.simulate(model, 0.003, 1e-3, initial_state=moved)
    b = fm.simulate(model, 0.003, 1e-3, initial_state=eq)
    assert_close(a.coordinates, b.coordinates, abs=1e-15, what="coordinates")
    # Node displacements of a state and of a result agree.
    tip = body.node_ids[np.argmax(body.nodes[:, 0])]
    displacements = eq.node_displacements(arm, [tip])
    assert_close(displacements, b.node_displacements(arm, [tip])[0], rel=1e-9, what="tip")
    # A result's last state continues the run.
    last = b.state()
    assert_close(last.time, 0.003, rel=1e-6, abs=1e-12, what="last time")
    c = fm.simulate(model, 0.005, 1e-3, initial_state=last)
    assert_close(c.time[0], 0.003, rel=1e-6, abs=1e-12, what="first time")
    assert c.events == []
    multipliers = b.joint_multipliers(drive)[0]
    assert_close(eq.joint_multipliers(drive), multipliers, rel=1e-7, what="multipliers")
    with pytest.raises(dataclasses.FrozenInstanceError):
        eq.time = 1.0
    with pytest.raises(ValueError, match="read-only"):
        eq.coordinates[0] = 1.0
    with pytest.raises(InvalidParameterError, match="expected 3 finite values"):
        eq.with_position(arm, [0.0, 1.0])
    with pytest.raises(InvalidParameterError, match="start_time 1.0 differs"):
        fm.simulate(model, 2.0, 1e-3, initial_state=eq, start_time=1.0)
    with pytest.raises(InvalidParameterError, match="initial_state must be"):
        fm.simulate(model, 1.0, 1e-3, initial_state="relaxed")
    short = dataclasses.replace(eq, coordinates=eq.coordinates[:-1], velocities=eq.velocities[:-1])
    with pytest.raises(InvalidParameterError, match="coordinates given for a model of"):
        fm.simulate(model, 0.01, 1e-3, initial_state=short)


def test_an_equilibrium_that_does_not_converge_names_its_residual_and_bodies():
    model, _, _ = rotating_rod(10.0, elements=4)
    with pytest.raises(EquilibriumError, match="no convergence in 1 iterations") as error:
        fm.equilibrium(model, max_iterations=1, tolerance=1e-300)
    assert error.value.residual > 0 and error.value.bodies == ["rod"]
    assert isinstance(error.value, fm.NewtonDivergedError)


def test_model_files_start_from_equilibrium(tmp_path, assert_close):
    text = """
name: held-link
gravity: [0, -9.81, 0]
bodies:
  - name: arm
    type: flexible
    box: {lengths: [0.3, 0.02, 0.02], divisions: [6, 1, 1], element: hex8}
    material: {young_modulus: 7.0e+10, poisson_ratio: 0.33, density: 2700.0}
    reference: clamped
    reference_nodes: x0
    position: [0.0, -0.01, -0.01]
joints:
  - {name: hinge, type: revolute, marker1: {body: ground}, marker2: {body: arm, node_set: x0}}
  - name: drive
    type: angle-driver
    marker1: {body: ground}
    marker2: {body: arm, node_set: x0}
    angle: {type: constant, value: 0.0}
simulation: {end_time: 0.002, step_size: 1.0e-3, start: equilibrium}
outputs:
  - {joint: drive, quantity: reaction_torque}
"""
    path = tmp_path / "held.yaml"
    path.write_text(text)
    model = load_model(path)
    assert model.start == "equilibrium"
    result = simulate_model(model)
    arm = model.bodies["arm"]
    eq = fm.equilibrium(model.system)
    q0 = result.elastic_coordinates(arm)[0]
    assert_close(q0, eq.elastic_coordinates(arm), rel=1e-7, what="elastic coordinates")
    assert np.abs(eq.elastic_coordinates(arm)).max() > 0


def test_equilibrium_eliminating_large_nodal_bodies_equals_the_direct_solve(
    link, monkeypatch, assert_close
):
    # The link's 7,731 elastic coordinates are eliminated through a sparse Cholesky factor of
    # their block; with the limit raised, the whole Newton matrix goes to scipy's sparse LU.
    import flexmbd.analysis as analysis

    body, _ = link
    model, arm, drive = hinged_arm(body)
    assert body.elastic_coordinate_count >= analysis.ELIMINATE_ABOVE
    eliminated = fm.equilibrium(model)
    monkeypatch.setattr(analysis, "ELIMINATE_ABOVE", 10**9)
    direct = fm.equilibrium(model)
    scale = np.abs(direct.coordinates).max()
    assert_close(eliminated.coordinates, direct.coordinates, abs=1e-12 * scale, what="coordinates")
    multipliers = direct.joint_multipliers(drive)
    assert_close(eliminated.joint_multipliers(drive), multipliers, rel=1e-10, what="multipliers")


# Stability of equilibria ----------------------------------------------------------------------
def test_a_double_pendulum_released_horizontal_settles_hanging_not_upright(assert_close):
    # Newton's method alone ends with both links upright (stable=False keeps that answer and
    # says it is unstable in both hinge angles); the default seeks the stable equilibrium:
    # both links hanging, each stretched by the weight below it. Axial displacements of
    # linear bar elements under their consistent loads are exact at the nodes:
    # lower link d2 = m g L / (2 EA), upper d1 = (m g L + m g L / 2) / (EA).
    example = fm.examples.flexible_double_pendulum(elements=4)
    model = example.system.compile()
    upright = fm.equilibrium(model, stable=False)
    assert upright.stable is False and upright.unstable_directions == 2
    assert_close(upright.orientation("upper link")[:, 0], [0, 1, 0], abs=1e-9)
    hanging = fm.equilibrium(model)
    assert hanging.stable is True and hanging.unstable_directions == 0
    for link in ("upper link", "lower link"):
        assert_close(hanging.orientation(link)[:, 0], [0, -1, 0], abs=1e-9)
    ea = 7.0e10 * np.pi * 0.005**2
    weight = 2700.0 * np.pi * 0.005**2 * 1.0 * 9.81
    tip = hanging.node_positions("lower link")[-1]
    expected = 2.0 + (weight + weight / 2) / ea + weight / 2 / ea
    assert_close(tip[1], -expected, rel=1e-9)
    assert fm.equilibrium(model, stable=True).coordinates == pytest.approx(hanging.coordinates)


def test_the_stability_of_an_equilibrium_agrees_with_its_linearization(assert_close):
    # A01's point mass on its link (a spherical pendulum): hanging, stable, the linearized
    # motion swings at sqrt(g / l) in both free directions; upright, two unstable directions,
    # and the linearization grows at sqrt(g / l) in both.
    model = fm.examples.pendulum().system.compile()
    hanging = fm.equilibrium(model)  # from the horizontal, where it has no stiffness
    assert hanging.stable is True and hanging.unstable_directions == 0
    assert_close(hanging.coordinates, [0, -1, 0], abs=1e-12)
    upright = fm.equilibrium(model, coordinates=[0.01, 1.0, 0.0], stable=False)
    assert upright.stable is False and upright.unstable_directions == 2
    assert_close(upright.coordinates, [0, 1, 0], abs=1e-12)
    rate = np.sqrt(9.81)
    growing = np.sort(fm.linearize(model, upright).eigenvalues()[0].real)
    assert_close(growing, [-rate, -rate, rate, rate], rel=1e-9)
    swinging = fm.linearize(model, hanging).eigenvalues()[0]
    assert_close(np.sort(np.abs(swinging.imag)), [rate] * 4, rel=1e-9)
    assert_close(swinging.real, np.zeros(4), abs=1e-9)
    # The default from near the top still finds the hanging state; asked for, an exact
    # upright start has no way down (its gradient is zero) and is refused.
    assert_close(fm.equilibrium(model, coordinates=[0.01, 1, 0]).coordinates, [0, -1, 0], abs=1e-12)
    with pytest.raises(EquilibriumError, match="stable equilibrium"):
        fm.equilibrium(model, coordinates=upright.coordinates, stable=True, max_iterations=5)
    with pytest.raises(InvalidParameterError, match="stable"):
        fm.equilibrium(model, stable="yes")


def test_a_pendulum_on_a_cart_driven_at_constant_speed_swings_as_at_rest(assert_close):
    # Galilean invariance: a cart driven along x at 3 m/s carries a pendulum (1 m, point-like
    # bob) that swings at sqrt(g / L). The equilibrium's accelerations of round-off (1e-30)
    # made the step of the moving basis (sqrt(v^2 + 2 a turn) - v) / a cancel to 0, and the
    # matrices NaN.
    along_x = np.array([[0, 0, 1], [0, 1, 0], [-1, 0, 0]], float)  # marker z along global x
    system = fm.System(gravity=GRAVITY)
    cart = system.add_rigid_body(2.0, (0.1, 0.1, 0.1), name="cart")
    rail = system.add_marker(system.ground, orientation=along_x)
    carried = system.add_marker(cart, orientation=along_x)
    system.add_prismatic_joint(rail, carried, name="rail")
    system.add_translation_driver(rail, carried, fm.Polynomial([0.0, 3.0]), name="drive")
    bob = system.add_rigid_body(1.0, (1e-6, 1e-6, 1e-6), position=(0, -1, 0), name="bob")
    hinge = system.add_marker(bob, position=(0, 1, 0))
    system.add_revolute_joint(system.add_marker(cart), hinge, name="hinge")
    state = fm.equilibrium(system)
    assert_close(state.velocities[0], 3.0, rel=1e-12)
    frequency = np.sqrt(9.81 / (1.0 + 1e-6)) / (2 * np.pi)  # m g L / (m L^2 + I)
    assert_close(fm.linearize(system, state).frequencies(), [frequency], rel=1e-9)


@pytest.mark.parametrize("speed", [2.0, 5.0])
def test_the_stability_of_a_steady_rotation_counts_the_spin_softening(speed, assert_close):
    # A pendulum hinged on the axis of a turntable: hanging, its stiffness in the turning
    # frame is g - W^2 (per unit m L^2). Newton's matrix, in absolute coordinates, has no spin
    # softening, and called it stable at 5 rad/s, where it diverges at +-sqrt(W^2 - g).
    system = turntable_pendulum(speed)
    state = fm.steady_rotation(system)
    assert (state.stable, state.unstable_directions) == (
        (True, 0) if speed**2 < 9.81 else (False, 1)
    )
    rate = np.sqrt((speed**2 - 9.81 + 0j) / (1.0 + 1e-6))
    values = fm.linearize(system, state).eigenvalues()[0]
    assert_close(np.sort(values.real), np.sort([rate.real, -rate.real]), abs=1e-7)
    assert_close(np.sort(values.imag), np.sort([rate.imag, -rate.imag]), abs=1e-7)


@pytest.mark.parametrize(
    ("speed", "damping", "stable"),
    [(5.0, 0.0, True), (5.0, 0.5, True), (15.0, 0.0, True), (15.0, 0.5, False)],
)
def test_a_rotor_above_its_critical_speed_is_held_by_its_gyroscopic_terms(
    speed, damping, stable, assert_close
):
    # A mass on isotropic springs (k, damping c) in the plane of a turntable spun at W, above
    # sqrt(k / m) = 10 rad/s: in the turning frame its stiffness k - m W^2 is negative in two
    # directions, and the Coriolis terms hold it (undamped, it whirls at +-sqrt(k / m) +- W);
    # damping that turns with it makes it unstable (one whirl grows). The inertia of the
    # stiffness called every run above 10 rad/s unstable in 2 directions.
    mass, k, arm, rotary = 1.0, 100.0, 10.0, 5.0
    system = fm.System()
    table = system.add_rigid_body(10.0, (1, 1, 1), name="table")
    fixed, turning = system.add_marker(system.ground), system.add_marker(table)
    system.add_revolute_joint(fixed, turning)
    system.add_angle_driver(fixed, turning, fm.Polynomial([0.0, speed]), name="drive")
    slider = system.add_rigid_body(mass, (0.01, 0.01, 0.01), name="slider")
    carried, centre = system.add_marker(table), system.add_marker(slider)
    system.add_planar_joint(carried, centre)
    system.add_rotational_spring_damper(carried, centre, stiffness=rotary)
    for anchor in [(-arm, 0, 0), (0, -arm, 0)]:  # (unstressed: no stiffness across)
        system.add_spring_damper(
            system.add_marker(table, position=anchor), centre,
            stiffness=k, damping=damping, rest_length=arm,
        )  # fmt: skip
    model = system.compile()
    state = fm.steady_rotation(model)
    assert (state.stable, state.unstable_directions) == (stable, 0 if stable else 1)
    # z = x + i y: m z_dd + (c + 2 i m W) z_dot + (k - m W^2) z = 0, and its conjugate; the
    # slider's turn about the table's axis: sqrt(rotary / 0.01).
    roots = np.roots([mass, damping + 2j * mass * speed, k - mass * speed**2])
    expected = np.concatenate([roots, roots.conj(), [10j * np.sqrt(5.0), -10j * np.sqrt(5.0)]])
    values = fm.linearize(model, state).eigenvalues()[0]
    values, expected = values[np.argsort(values.imag)], expected[np.argsort(expected.imag)]
    assert_close(values.real, expected.real, abs=1e-6, what="Re s")
    assert_close(values.imag, expected.imag, abs=1e-6, what="Im s")


@pytest.mark.parametrize("load", [5.0, 15.0, 19.5, 21.0])
def test_becks_column_is_stable_until_it_flutters(load):
    # A clamped rod under a compressive follower force at its tip (Beck 1952): no divergence
    # at any load, flutter from 20.05 EI / L^2. Its stiffness is not symmetric, and the
    # inertia of its symmetric part called it unstable from 15 EI / L^2 (and neutral at 10).
    section = Section.circle(0.01)
    flexural = 2.1e11 * section.iy
    system = fm.System()
    column = system.add_flexible_body(
        clamped_steel_beam(1.0, 20, section), geometric_stiffness=True, name="column"
    )
    system.add_fixed_joint(system.add_marker(system.ground), system.add_node_marker(column, 1))
    tip = system.add_node_marker(column, 21)
    system.add_point_force(tip, [-load * flexural, 0.0, 0.0], frame="marker")
    state = fm.equilibrium(system, stable=False)
    if load < 20.05:
        assert (state.stable, state.unstable_directions) == (True, 0)
    else:  # flutter in both planes of bending: two growing complex pairs
        assert (state.stable, state.unstable_directions) == (False, 2)


@pytest.mark.parametrize(
    "build",
    [fm.examples.four_bar_spatial, fm.examples.bricard, lambda: fm.examples.bricard(np.pi / 2)],
    ids=["spatial four-bar", "Bricard", "Bricard, turned frames"],
)
def test_mechanisms_with_redundant_joints_have_an_equilibrium(build, assert_close):
    # The spatial four-bar (3 redundant equations) and Bricard's mechanism (1, which of them
    # a round-off tie) made Newton's matrix singular; the redundant rows are now left out, as
    # the runs leave them out. Checked by the dynamics: released there, nothing moves.
    example = build()
    state = fm.equilibrium(example.system)
    assert state.stable is True and state.residual < 1e-12
    sought = fm.equilibrium(example.system, stable=True)
    assert_close(sought.coordinates, state.coordinates, abs=1e-12, what="stable=True")
    result = fm.simulate(example.system, 0.5, 1e-3, output_interval=0.05, initial_state=state)
    names = [b["name"] for b in example.system.compile().describe()["bodies"][1:]]
    speed = max(float(np.abs(result.velocity(name)).max()) for name in names)
    assert speed < 1e-9
    # The linearization about it has the mechanism's one frequency, which a run started there
    # with a small velocity along its motion (the null space of C_q) swings at.
    model = example.system.compile()
    frequencies = fm.linearize(model, state).frequencies()
    assert len(frequencies) == 1
    nq = model.coordinate_count
    jacobian = constraint_parts(model, state.coordinates)[1]
    motion = scipy.linalg.null_space(jacobian)[:, 0] * 1e-3
    swinging = fm.State(
        0.0, state.coordinates, motion, np.zeros(nq), state.multipliers, layout=state.layout
    )
    periods = 5
    run = fm.simulate(
        model, periods / frequencies[0], 2e-3, output_interval=2e-3, initial_state=swinging
    )
    x = run.position(names[0])[:, 0]
    upward = np.flatnonzero(np.diff(np.sign(x - x.mean())) > 0)
    measured = 1.0 / np.mean(np.diff(run.time[upward]))
    assert len(upward) >= periods - 1
    assert_close(measured, frequencies[0], rel=2e-3, what="frequency of the swing")


def door_on_two_hinges(upper_ground: float) -> fm.System:
    """A 10 kg door (centre 0.5 m from its hinge axis, the global y axis) on two revolute
    joints about that axis at heights 0.2 and 1.8 m; the upper one's ground point at height
    `upper_ground`. Gravity -9.81 along y and -1 along z (so that the door has a way to hang)."""
    system = fm.System(gravity=(0.0, -9.81, -1.0))
    door = system.add_rigid_body(10.0, (1.0, 1.0, 1.0), position=(0.5, 1.0, 0.0), name="door")
    vertical = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])  # z along y
    for name, ground, hinge in (("lower", 0.2, -0.8), ("upper", upper_ground, 0.8)):
        system.add_revolute_joint(
            system.add_marker(system.ground, position=(0.0, ground, 0.0), orientation=vertical),
            system.add_marker(door, position=(-0.5, hinge, 0.0), orientation=vertical),
            name=f"{name} hinge",
        )
    return system


def test_inconsistent_redundant_joints_are_named():
    # The upper hinge's ground point 5 cm above its door point: its 'y' equation repeats the
    # lower hinge's with another value. (A run says so too: InitialConditionsError.)
    with pytest.raises(
        InvalidModelError, match="inconsistent joints.*'upper hinge' equation 'y'"
    ) as error:
        fm.equilibrium(door_on_two_hinges(1.85))
    assert error.value.item == "upper hinge"
    # Where they agree, the door turns about the hinges to hang along -z (5 redundant rows).
    state = fm.equilibrium(door_on_two_hinges(1.8))
    assert state.stable is True
    assert state.position("door") == pytest.approx([0.0, 1.0, -0.5], abs=1e-9)


def test_redundant_hinges_share_the_load_with_minimum_norm_multipliers(assert_close):
    # The door hangs on two hinges along y: their 'y' equations repeat each other, and by
    # default the lower hinge carries the whole weight (the upper one's rows left out, their
    # multipliers 0). Minimum-norm multipliers of the same constraint forces share it, as the
    # runs' redundant_constraints="minimum-norm" does.
    system = door_on_two_hinges(1.8)
    weight = 10.0 * 9.81
    y = 1  # the hinges' equation 'y' (x, y, z, axis x, axis y)
    removed = fm.equilibrium(system)
    assert_close(abs(removed.joint_multipliers("lower hinge")[y]), weight, rel=1e-9)
    assert removed.joint_multipliers("upper hinge")[y] == 0.0
    shared = fm.equilibrium(system, redundant_constraints="minimum-norm")
    assert_close(shared.coordinates, removed.coordinates, abs=1e-12)
    lower, upper = (shared.joint_multipliers(h)[y] for h in ("lower hinge", "upper hinge"))
    assert_close(lower + upper, -weight, rel=1e-9)
    assert 0.4 * weight < -upper < 0.6 * weight
    assert np.linalg.norm(shared.multipliers) < np.linalg.norm(removed.multipliers)
    # The same constraint forces: C_q^T lambda unchanged.
    model = system.compile()
    jacobian = constraint_parts(model, shared.coordinates)[1]
    assert_close(jacobian.T @ shared.multipliers, jacobian.T @ removed.multipliers, abs=1e-9)
    # The run's minimum-norm multipliers (the core's SVD) from that state, which it keeps.
    settings = fm.GeneralizedAlpha(redundant_constraints="minimum-norm")
    run = fm.simulate(system, 0.01, 1e-3, initial_state=shared, solver=settings)
    assert_close(run.multipliers[-1], shared.multipliers, abs=1e-6)
    with pytest.raises(InvalidModelError, match="redundant constraint equations.*'upper hinge'"):
        fm.equilibrium(system, redundant_constraints="error")
    with pytest.raises(InvalidParameterError, match="redundant_constraints"):
        fm.equilibrium(system, redundant_constraints="share")


def test_a_symmetric_shaft_in_two_bearings_loads_each_with_half_its_weight(assert_close):
    # Bearings at x = -0.5 and 0.5 (revolute about x), the shaft's centre between them: the
    # minimum-norm multipliers are symmetric, each bearing carries m g / 2 and no moment.
    system = fm.System(gravity=(0.0, -9.81, 0.0))
    axis_x = np.array([[0.0, 0.0, -1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]])  # z along x
    shaft = system.add_rigid_body(10.0, (0.1, 0.5, 0.5), name="shaft")
    for k, x in enumerate((-0.5, 0.5)):
        system.add_revolute_joint(
            system.add_marker(system.ground, position=(x, 0.0, 0.0), orientation=axis_x),
            system.add_marker(shaft, position=(x, 0.0, 0.0), orientation=axis_x),
            name=f"bearing {k}",
        )
    state = fm.equilibrium(system, redundant_constraints="minimum-norm")
    for bearing in ("bearing 0", "bearing 1"):
        assert_close(state.joint_multipliers(bearing), [0, -49.05, 0, 0, 0], abs=1e-9)


def test_a_free_body_with_nothing_acting_is_in_equilibrium_where_it_is():
    # No gravity, no load: the state is balanced as given, though nothing holds the body
    # (its six free directions made Newton's matrix singular, and the equilibrium refused).
    system = fm.System()
    system.add_rigid_body(2.0, (0.1, 0.2, 0.3), position=(1.0, 2.0, 3.0), name="probe")
    model = system.compile()
    state = fm.equilibrium(model)
    assert np.array_equal(state.coordinates, model.initial_coordinates)
    assert state.residual == 0.0 and state.iterations == 1
    # With gravity it is refused, naming the body.
    system.gravity = GRAVITY
    with pytest.raises(InvalidModelError, match="body 'probe'"):
        fm.equilibrium(system)


def test_linearize_takes_the_names_of_its_states():
    # As simulate's initial_state does; another string was an AttributeError of the str.
    example = fm.examples.pendulum()
    named = fm.linearize(example.system, "equilibrium").frequencies()
    assert named == pytest.approx(fm.linearize(example.system).frequencies(), rel=1e-12)
    with pytest.raises(InvalidModelError, match="no driver moves"):
        fm.linearize(example.system, "steady-rotation")
    with pytest.raises(InvalidParameterError, match="'equilibrium' or 'steady-rotation'"):
        fm.linearize(example.system, "rest")


def test_linearize_refuses_a_state_without_accelerations():
    # State.of_model has coordinates and velocities only; linearize handed its None to the
    # core, which refused "argument 'accelerations': 'None' is not an instance of 'ndarray'".
    model = fm.examples.pendulum().system.compile()
    with pytest.raises(InvalidParameterError, match="no accelerations and multipliers") as error:
        fm.linearize(model, fm.State.of_model(model))
    assert error.value.item == "state"


def test_an_equilibrium_that_cannot_exist_names_the_free_body():
    # A body that nothing holds, and a slider on a vertical guide without a spring: the
    # error names the body and the motion that nothing resists.
    system = fm.System(gravity=GRAVITY)
    system.add_rigid_body(1.0, (0.1, 0.1, 0.1), position=(1.0, 0.0, 0.0), name="hub")
    with pytest.raises(
        InvalidModelError,
        match="6 directions.*body 'hub' \\(translation in any direction, rotation about any",
    ) as error:
        fm.equilibrium(system)
    assert error.value.item == "hub"
    vertical = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])  # z along y
    system = fm.System(gravity=GRAVITY)
    slider = system.add_rigid_body(1.0, (0.1, 0.1, 0.1), name="slider")
    system.add_prismatic_joint(
        system.add_marker(system.ground, orientation=vertical),
        system.add_marker(slider, orientation=vertical),
        name="guide",
    )
    with pytest.raises(
        InvalidModelError, match="1 direction .*'slider' \\(translation along \\(0, 1, 0\\)\\)"
    ):
        fm.equilibrium(system)
    # With a spring along the guide it hangs 9.81 / 100 below.
    system.add_spring_damper(
        system.add_marker(system.ground, position=(0.0, 1.0, 0.0)),
        system.add_marker(slider),
        stiffness=100.0,
        rest_length=1.0,
    )
    assert fm.equilibrium(system).position("slider")[1] == pytest.approx(-9.81 / 100.0, rel=1e-9)


def test_a_flexible_panel_released_horizontal_hangs_from_its_hinged_edge(assert_close):
    # A 0.3 x 0.1 m shell panel hinged along its edge y = 0 (global x) and horizontal: its
    # rotation about the hinge has no stiffness there but for the elastic coupling's tiny
    # pivot, so Newton's first step is huge and it diverges (stable=False says so); the
    # default then seeks the stable state: the panel hanging below its edge, the centroid of
    # its (uniform) nodes at z = -0.05 m, less its elastic droop.
    mesh = fm.fe.shapes.plate((0.3, 0.1), (6, 2), "quad4")
    body = fm.fe.build_body(
        mesh.nodes,
        mesh.elements,
        fm.fe.Material(7e10, 0.3, 2700.0),
        shell=2e-3,
        node_sets=mesh.node_sets,
        reference="clamped",
        reference_nodes="y0",
        modes="fixed-interface",
        mode_count=6,
    )
    system = fm.System(gravity=(0.0, 0.0, -9.81))
    panel = system.add_flexible_body(body, name="panel")
    axis_x = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])
    system.add_revolute_joint(
        system.add_marker(system.ground, position=(0.15, 0.0, 0.0), orientation=axis_x),
        system.add_node_set_marker(panel, "y0", orientation=axis_x, coupling="rbe2"),
        name="hinge",
    )
    model = system.compile()
    with pytest.raises(EquilibriumError, match="no convergence"):
        fm.equilibrium(model, stable=False)
    hanging = fm.equilibrium(model)
    assert hanging.stable is True
    centroid = hanging.node_positions("panel").mean(axis=0)
    assert_close(centroid, [0.15, 0.0, -0.05], abs=1e-6, what="centroid")


def test_a_neutral_equilibrium_is_not_called_stable():
    # A free rigid body without gravity was reported stable=True: its stiffness is zero in
    # all six free directions. A pendulum hanging is stable with no neutral direction.
    system = fm.System()
    system.add_rigid_body(1.0, (1.0, 2.0, 3.0), name="free")
    free = fm.equilibrium(system.compile())
    assert free.stable is None
    assert (free.unstable_directions, free.neutral_directions) == (0, 6)
    system = fm.System(gravity=(0.0, -9.81, 0.0))
    bob = system.add_point_mass(1.0, position=(0.0, -1.0, 0.0), name="bob")
    system.add_distance_joint(system.add_marker(system.ground), system.add_marker(bob), 1.0)
    hanging = fm.equilibrium(system.compile())
    assert hanging.stable is True
    assert (hanging.unstable_directions, hanging.neutral_directions) == (0, 0)


@pytest.mark.parametrize("strict", [False, True])
def test_a_run_continued_from_its_recorded_state_is_not_an_initial_correction(strict, assert_close):
    # Generalized-alpha enforces the positions; its velocities drift off the velocity
    # constraints within the step's error (4.3e-6 for the pendulum after 1 s). Continuing
    # from result.state(), as the docs show, warned of an initial correction, and strict
    # initial conditions refused it. The projection is now a "continuation" event.
    system = fm.examples.pendulum().system
    first = fm.simulate(system, 1.0, 1e-3, output_interval=0.1)
    conditions = "strict" if strict else "correct"
    with warnings.catch_warnings():
        warnings.simplefilter("error", InitialCorrectionWarning)
        rest = fm.simulate(
            system, 2.0, 1e-3, output_interval=0.1, initial_state=first.state(),
            initial_conditions=conditions,
        )  # fmt: skip
    events = [e for e in rest.events if e["kind"] == "continuation"]
    assert len(events) == 1 and "recorded state projected" in events[0]["message"]
    whole = fm.simulate(system, 2.0, 1e-3, output_interval=0.1)
    assert_close(rest.coordinates[-1], whole.coordinates[-1], abs=1e-5, what="end state")
    # A recorded state changed by hand is given again: its corrections are reported.
    changed = first.state().with_velocity(1, first.state().velocity(1) * 1.01)
    assert not changed.recorded
    if strict:
        with pytest.raises(fm.InitialConditionsError, match="refused"):
            fm.simulate(system, 1.1, 1e-3, initial_state=changed, initial_conditions="strict")
    else:
        with pytest.warns(InitialCorrectionWarning):
            fm.simulate(system, 1.1, 1e-3, initial_state=changed)


def test_an_equilibrium_state_has_the_section_forces_of_its_beams(assert_close):
    # Regression: a State had no section_forces (the stresses error pointed there), so a
    # static root moment needed a dummy run. Cantilever of 1 m, 10 N at its tip: M = P L.
    from flexmbd.fe import Material, build_body, straight_beam

    nodes, elements = straight_beam(1.0, 8)
    data = build_body(
        nodes, elements, Material(2.1e11, 0.3, 7800.0), section=Section.circle(0.01),
        reference="clamped", reference_nodes=[0],
    )  # fmt: skip
    system = fm.System()
    beam = system.add_flexible_body(data, name="beam")
    system.add_fixed_joint(system.add_marker(system.ground), system.add_node_marker(beam, 1))
    system.add_point_force(system.add_node_marker(beam, 9), (0.0, -10.0, 0.0))
    forces = fm.equilibrium(system).section_forces(beam)
    assert forces.shape == (8, 2, 6)
    assert_close(np.abs(forces[0, 0, [1, 5]]), [10.0, 10.0], rel=1e-9, what="V_y, M_z at root")
    assert_close(np.abs(forces[-1, 1, 5]), 0.0, abs=1e-9, what="M_z at the tip")


def test_equilibrium_balances_a_driver_accelerating_from_rest(assert_close):
    # theta = (alpha / 2) t^2: at t = 0 the driver has no rate, only an acceleration, and was
    # taken for a still one (multiplier 0, undeformed arm; the run then swung the tip by
    # 5.7 mm). The equilibrium now carries the arm's inertia J alpha and its deformation: a
    # run from it stays steady (found by a fault hunt).
    from flexmbd.fe import Material, Section, build_body, straight_beam

    nodes, elements = straight_beam(1.0, 8)
    material, section = Material(7e10, 0.33, 2700.0), Section.circle(0.01)
    data = build_body(nodes, elements, material, section=section, reference="clamped",
                      reference_nodes=[0])  # fmt: skip
    system = fm.System()
    arm = system.add_flexible_body(data, name="arm")
    pivot, root = system.add_marker(system.ground), system.add_node_marker(arm, 1)
    system.add_revolute_joint(pivot, root, name="hinge")
    alpha = 20.0
    system.add_angle_driver(pivot, root, fm.Polynomial([0.0, 0.0, alpha / 2]), name="motor")
    equilibrium = fm.equilibrium(system)
    inertia = 2700.0 * np.pi * 1e-4 / 3  # rho A L^3 / 3 about the root
    assert_close(equilibrium.joint_multipliers("motor"), [-inertia * alpha], rel=1e-3)
    result = fm.simulate(system, 0.05, 1e-4, initial_state=equilibrium, output_interval=1e-3,
                         solver=fm.GeneralizedAlpha(1.0))  # fmt: skip
    tip = result.node_displacements(arm, [8])[:, 0, 1]
    assert tip[0] < -2e-3 and np.ptp(tip) < 1e-3 * abs(tip[0])


def wound_wheel(rest_angle=0.0, speed=10.0):
    """A wheel (J = 1) on a hinge about z, turning at `speed`, on a torsion spring of 0.5 N m
    per rad: in 1 s it winds the spring by more than a turn."""
    system = fm.System()
    wheel = system.add_rigid_body(1.0, (1, 1, 1), angular_velocity=(0, 0, speed), name="wheel")
    markers = system.add_marker(system.ground), system.add_marker(wheel)
    system.add_revolute_joint(*markers, name="hinge")
    system.add_rotational_spring_damper(*markers, stiffness=0.5, rest_angle=rest_angle,
                                        name="spring")  # fmt: skip
    return system


def test_a_run_continued_from_a_record_keeps_the_springs_wound(tmp_path, assert_close):
    # The spring's angle is unwrapped over the run (a discrete variable). A state recorded
    # after more than half a turn carries it: continued from it (in memory or read back from
    # the results file), the wheel went on from the wrapped angle and ended at 4.45 rad/s
    # instead of 1.56.
    system = wound_wheel()
    whole = fm.simulate(system, 2.0, 1e-3, output_interval=0.1)
    half = fm.simulate(system, 1.0, 1e-3, output_interval=0.1, results_file=tmp_path / "a.h5")
    angle = half.state(-1).discrete[0]
    assert angle > 2 * np.pi and half.discrete.shape == (len(half), 1)
    assert_close(whole.discrete[len(half) - 1], [angle], rel=1e-6, what="unwrapped angle")
    ending = whole.state(-1).angular_velocity("wheel")
    for state in (half.state(-1), fm.read_results(tmp_path / "a.h5").state(-1)):
        assert_close(state.discrete, [angle], rel=0, what="the recorded angle")
        rest = fm.simulate(system, 2.0, 1e-3, output_interval=0.1, initial_state=state)
        assert_close(rest.state(-1).angular_velocity("wheel"), ending, abs=1e-6)


def test_an_equilibrium_beyond_half_a_turn_of_a_spring(assert_close):
    # A spring's rest angle of 3.5 rad: its equilibrium is at the wrapped angle 3.5 - 2 pi.
    # Newton's iterates unwrapped the angle against the start and never reached 3.5
    # (diverged); the state carries the unwrapped angle, so a run from it stays at rest.
    system = wound_wheel(rest_angle=3.5, speed=0.0)
    state = fm.equilibrium(system)
    turn = state.orientation("wheel")
    assert_close(np.arctan2(turn[1, 0], turn[0, 0]), 3.5 - 2 * np.pi, abs=1e-9, what="angle")
    assert_close(state.discrete, [3.5], abs=1e-9, what="unwrapped angle")
    result = fm.simulate(system, 1.0, 1e-3, initial_state="equilibrium")
    assert np.max(result.kinetic_energy) < 1e-20
    assert_close(result.discrete[-1], [3.5], abs=1e-9)


def test_a_steady_rotation_from_a_runs_coordinates_and_at_high_speed(assert_close):
    # The test for an accelerating driver took the residual of the driver's equation
    # sin(theta - f) times f'^2 (a run's 3e-12 at 20 rad/s, round-off at 1000 rad/s) for an
    # acceleration: "driver 'hub' accelerates" for a constant speed. A blade (3 kg, its centre
    # 1.2 m beyond a lag hinge 0.3 m off the axis): w_lag = W sqrt(e m r / I_hinge).
    def rotor(speed):
        turn = fm.rotation("z", 0.7)  # where the driver starts
        system = fm.System(gravity=(0, 0, 0))
        hub = system.add_rigid_body(10.0, (1, 1, 2), orientation=turn, name="hub")
        spin = system.add_marker(system.ground), system.add_marker(hub)
        system.add_revolute_joint(*spin)
        system.add_angle_driver(*spin, fm.Polynomial([0.7, speed]), name="hub")
        blade = system.add_rigid_body(3.0, (0.01,) * 3, position=turn @ [1.5, 0, 0],
                                      orientation=turn, name="blade")  # fmt: skip
        system.add_revolute_joint(system.add_marker(hub, position=(0.3, 0, 0)),
                                  system.add_marker(blade, position=(-1.2, 0, 0)))  # fmt: skip
        return system

    ratio = np.sqrt(0.3 * 3.0 * 1.2 / (0.01 + 3.0 * 1.2**2))
    for speed in (20.0, 1000.0):
        system = rotor(speed)
        found = fm.linearize(system, fm.steady_rotation(system)).frequencies()
        assert_close(2 * np.pi * found, [ratio * speed], rel=1e-6, what=f"lag at {speed:g}")
    system = rotor(20.0)
    result = fm.simulate(system, 0.3, 1e-3, initial_state="steady-rotation", output_interval=0.1)
    later = fm.steady_rotation(system, time=0.3, coordinates=result.state(-1).coordinates)
    found = fm.linearize(system, later).frequencies()
    assert_close(2 * np.pi * found, [ratio * 20.0], rel=1e-6, what="from the run's coordinates")


def test_an_equilibrium_from_a_recorded_state_keeps_its_springs_wound(assert_close):
    # A pendulum (m g L = 4.9 N m) on a weak torsion spring (0.5 N m/rad) wound by a torque
    # that is then released settles on a wound branch (k theta + m g L sin theta = 0 at 5.67
    # rad). From the state's coordinates alone the spring was unwound: another equilibrium,
    # 0.62 rad away.
    m, length, g, k = 1.0, 0.5, 9.81, 0.5
    system = fm.System(gravity=(0, -g, 0))
    bob = system.add_rigid_body(m, (1e-3,) * 3, position=(0, -length, 0), name="bob")
    pair = system.add_marker(system.ground), system.add_marker(bob, position=(0, length, 0))
    system.add_revolute_joint(*pair)
    system.add_rotational_spring_damper(*pair, stiffness=k, damping=0.15, name="spring")
    system.add_torque(pair[1], (0.0, 0.0, fm.Step(4.0, 4.2, 8.0, 0.0)), name="winder")
    settled = fm.simulate(system, 60.0, 5e-3, output_interval=0.5).state()
    theta = settled.discrete[0]
    assert 5.0 < theta < 6.0 and abs(k * theta + m * g * length * np.sin(theta)) < 1e-5
    state = fm.equilibrium(system, settled.time, coordinates=settled)
    assert_close(state.discrete, [theta], abs=1e-5, what="the spring's angle")
    assert_close(state.orientation("bob"), settled.orientation("bob"), abs=1e-5)
    assert state.stable


def test_an_equilibrium_search_on_its_way_asks_for_more_iterations():
    # A wheel on a spring whose rest angle is 20 rad away: the search for a stable
    # equilibrium turns it by about 0.2 rad per iteration and needs about 102. The error was
    # the first Newton iteration's divergence (increment 2e2, residual 2e4).
    system = wound_wheel(rest_angle=20.0, speed=0.0)
    with pytest.raises(EquilibriumError, match="on its way.*raise max_iterations"):
        fm.equilibrium(system)
    assert fm.equilibrium(system, max_iterations=400).discrete[0] == pytest.approx(20.0)


def test_a_run_continued_from_a_drifted_recorded_state_is_a_continuation():
    # Integrating every coordinate (tr-bdf2), the Euler parameters' norm drifts by 5.9e-6 in
    # 1 s: continuing from the recorded state warned of an initial correction, and strict
    # initial conditions refused it. It is the integrator's own drift, as the velocities'.
    system = fm.System(gravity=(0, 0, 0))
    wheel = system.add_rigid_body(1.0, (0.5, 0.5, 1.0), angular_velocity=(0, 0, 8.0))
    pair = system.add_marker(system.ground), system.add_marker(wheel)
    system.add_revolute_joint(*pair)
    system.add_rotational_spring_damper(*pair, stiffness=2.0)
    solver = fm.ExplicitSolver("tr-bdf2", "integrate-all")
    first = fm.simulate(system, 1.0, 1e-3, output_interval=0.1, solver=solver)
    with warnings.catch_warnings():
        warnings.simplefilter("error", InitialCorrectionWarning)
        rest = fm.simulate(system, 1.2, 1e-3, output_interval=0.1, solver=solver,
                           initial_state=first.state(), initial_conditions="strict")  # fmt: skip
    said = [e["message"] for e in rest.events if e["kind"] == "continuation"]
    assert any("positions of the recorded state" in m for m in said), said


def test_a_recorded_state_of_another_model_is_an_initial_correction(tmp_path):
    # A pendulum's recorded state started a pendulum hinged 0.3 m further: the run moved the
    # bob onto the other hinge as the integrator's "drift", with no warning, and strict
    # initial conditions accepted it (found by a fault hunt). On another System the state is
    # a given one; from a results file (no System known) a move beyond the drift allowance
    # of the core (1e-3) is an initial correction all the same.
    def pendulum(x):
        system = fm.System(gravity=(0, -9.81, 0))
        bob = system.add_point_mass(1.0, position=(x + 1.0, 0.0, 0.0), name="bob")
        hinge = system.add_marker(system.ground, position=(x, 0.0, 0.0))
        system.add_distance_joint(hinge, system.add_marker(bob), 1.0, name="rod")
        return system

    first = fm.simulate(
        pendulum(0.0), 0.3, 1e-3, output_interval=0.1, results_file=tmp_path / "a.h5"
    )
    stored = fm.read_results(tmp_path / "a.h5").state(-1)
    assert stored.recorded and stored.system_identity is None
    for state in (first.state(-1), stored):
        with pytest.warns(InitialCorrectionWarning) as caught:
            fm.simulate(pendulum(0.3), 0.4, 1e-3, initial_state=state)
        assert any("joint 'rod'" in str(w.message) for w in caught)
        with pytest.raises(fm.InitialConditionsError, match="refused"):
            fm.simulate(pendulum(0.3), 0.4, 1e-3, initial_state=state, initial_conditions="strict")
    # The same System built again, from the file's state: still a continuation.
    with warnings.catch_warnings():
        warnings.simplefilter("error", InitialCorrectionWarning)
        fm.simulate(pendulum(0.0), 0.4, 1e-3, initial_state=stored, initial_conditions="strict")


def test_a_point_mass_on_a_prismatic_joint_has_an_equilibrium(assert_close):
    # The joint's three rotation equations are identically zero for a point mass: the runs
    # remove them as redundant, the equilibrium kept them in Newton's matrix ("3 directions
    # without stiffness", though the joint and the spring hold every direction).
    m, k, f0, g = 2.0, 800.0, 5.0, 9.81
    turn = fm.rotation("x", np.pi / 2)  # the slide along global y
    system = fm.System(gravity=(0, -g, 0))
    mass = system.add_point_mass(m, position=(0, -1.0, 0))
    system.add_spring_damper(system.add_marker(system.ground), system.add_marker(mass),
                             stiffness=k, rest_length=1.0, preload=f0)  # fmt: skip
    system.add_prismatic_joint(system.add_marker(system.ground, orientation=turn),
                               system.add_marker(mass, orientation=turn))  # fmt: skip
    state = fm.equilibrium(system)
    assert_close(state.position(mass), [0, -(1 + (m * g - f0) / k), 0], abs=1e-12)
    found = fm.linearize(system, state).frequencies()
    assert_close(2 * np.pi * found, [np.sqrt(k / m)], rel=1e-9, what="frequency")
