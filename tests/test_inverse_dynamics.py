"""Inverse dynamics (issue 33): the efforts of prescribed joint motions against closed forms,
the work-energy balance and the replay of the efforts on the free mechanism for the space
crane, and the rigid limit of its deformable booms."""

from __future__ import annotations

import numpy as np
import pytest

import flexmbd as fm

J = 0.5


def arm():
    system = fm.System()
    body = system.add_rigid_body(2.0, (0.1, 0.1, J), name="arm")
    ground, own = system.add_marker(system.ground), system.add_marker(body)
    system.add_revolute_joint(ground, own, name="hinge")
    profile = fm.Step(0.1, 0.9, 0.0, 1.3, shape="cycloidal")
    system.add_angle_driver(ground, own, profile, name="drive")
    return system, profile


def test_the_effort_of_a_prescribed_rotation_is_inertia_times_acceleration(assert_close):
    system, profile = arm()
    inverse = fm.inverse_dynamics(system, 1.2, 2.5e-4)
    expected = [J * profile.derivatives(t)[2] for t in inverse.time]
    assert_close(inverse.efforts["drive"], expected, rel=0, abs=1e-6 * J * 60, what="torque")
    assert inverse.units == {"drive": "N m"}
    replayed = inverse.replay()
    angle = inverse.joint_coordinates(replayed)["drive"]
    assert_close(angle, inverse.prescribed("drive", replayed.time), rel=0, abs=1e-6,
                 what="replayed angle")  # fmt: skip


def test_a_prescribed_slide_needs_mass_times_acceleration(assert_close):
    mass = 3.0
    system = fm.System()
    slider = system.add_rigid_body(mass, (0.1, 0.1, 0.1), name="slider")
    ground, own = system.add_marker(system.ground), system.add_marker(slider)
    system.add_prismatic_joint(ground, own, name="rail")
    profile = fm.Trapezoidal(0.0, 1.0, 0.0, 0.4, blend=0.5)
    system.add_translation_driver(ground, own, profile, name="push")
    inverse = fm.inverse_dynamics(system, 1.0, 1e-3)
    expected = [mass * profile.derivatives(t)[2] for t in inverse.time]
    # The trapezoid's acceleration jumps at mid-time: compare away from the jump.
    away = np.abs(inverse.time - 0.5) > 2e-3
    assert_close(inverse.efforts["push"][away], np.array(expected)[away], rel=0, abs=1e-6,
                 what="force")  # fmt: skip
    assert inverse.units == {"push": "N"}


@pytest.mark.parametrize("strategy", ["partitioning", "joint-coordinates"])
def test_adaptive_solvers_record_at_most_every_step_size(strategy, assert_close):
    # With every joint driven their error control sees nothing: dopri5's steps grew fivefold
    # each (a cycloidal lift of 1 s recorded at 7 times, its replay 0.07 m off).
    system = fm.System(gravity=(0, -9.81, 0))
    slider = system.add_rigid_body(3.0, (0.1, 0.1, 0.1), name="slider")
    up = fm.rotation("x", -np.pi / 2)
    ground = system.add_marker(system.ground, orientation=up)
    own = system.add_marker(slider, orientation=up)
    system.add_prismatic_joint(ground, own, name="guide")
    lift = fm.Step(0, 1, 0, 0.4, shape="cycloidal")
    system.add_translation_driver(ground, own, lift, name="lift")
    solver = fm.ExplicitSolver("dopri5", strategy)
    inverse = fm.inverse_dynamics(system, 1.0, 1e-3, solver=solver)
    assert len(inverse.time) == 1001
    expected = [3.0 * (lift.derivatives(t)[2] + 9.81) for t in inverse.time]
    assert_close(inverse.efforts["lift"], expected, rel=1e-9, what="force")
    replay = inverse.replay()
    error = inverse.joint_coordinates(replay)["lift"] - inverse.prescribed("lift", replay.time)
    assert np.abs(error).max() < 1e-9
    # A largest step of the user's own stays.
    capped = fm.ExplicitSolver("dopri5", strategy, max_step_size=0.01)
    assert len(fm.inverse_dynamics(system, 1.0, 1e-3, solver=capped).time) < 1001


@pytest.fixture(scope="module")
def cranes():
    options = {"elements": 4, "duration": 20.0}
    runs = {}
    for name, extra in (
        ("flexible", {}),
        ("no modes", {"mode_count": 0}),
        ("rigid", {"rigid": True}),
    ):
        crane = fm.examples.space_crane(**options, **extra)
        runs[name] = fm.inverse_dynamics(crane.system, crane.end_time, crane.step_size)
    return runs


def test_the_work_of_the_crane_torques_is_the_change_of_energy(cranes):
    inverse = cranes["flexible"]
    energy = inverse.result.total_energy - inverse.result.total_energy[0]
    balance = np.abs(inverse.work() - energy).max() / np.abs(energy).max()
    assert balance < 1e-6
    # The booms bend: strain energy is part of the balance, and the torques differ from the
    # rigid crane's by far more than the tolerances.
    rigid = cranes["rigid"]
    assert np.abs(inverse.efforts["turret drive"] - rigid.efforts["turret drive"]).max() > 100.0
    # An unknown driver is named (it was a bare KeyError).
    with pytest.raises(fm.UnknownItemError, match=r"no driver named 'nope' \(drivers: 'turret"):
        inverse.work("nope")


def test_replaying_the_crane_torques_on_the_free_crane_gives_the_prescribed_angles(cranes):
    inverse = cranes["flexible"]
    replayed = inverse.replay()
    angles = inverse.joint_coordinates(replayed)
    assert set(angles) == {"turret drive", "shoulder drive", "elbow drive"}
    for name, angle in angles.items():
        error = np.abs(angle - inverse.prescribed(name, replayed.time)).max()
        assert error < 1e-6, (name, error)
    assert np.ptp(angles["elbow drive"]) > 0.9  # it moved


def test_booms_without_modes_need_the_torques_of_rigid_bodies(cranes):
    for name, torque in cranes["rigid"].efforts.items():
        difference = np.abs(cranes["no modes"].efforts[name] - torque).max()
        assert difference <= 1e-9 * np.abs(torque).max(), name


def test_bad_inverse_dynamics_requests_are_refused():
    system, _ = arm()
    with pytest.raises(fm.InvalidParameterError, match="no driver named 'crank'"):
        fm.inverse_dynamics(system, 1.0, 1e-3, drivers=["crank"])
    with pytest.raises(fm.InvalidParameterError, match="output_interval"):
        fm.inverse_dynamics(system, 1.0, 1e-3, output_interval=0.01)
    with pytest.raises(fm.InvalidParameterError, match="flexmbd.System"):
        fm.inverse_dynamics(system.compile(), 1.0, 1e-3)
    bare = fm.System()
    bare.add_rigid_body(1.0, (1.0, 1.0, 1.0))
    with pytest.raises(fm.InvalidModelError, match="no named angle or translation drivers"):
        fm.inverse_dynamics(bare, 1.0, 1e-3)


def test_efforts_need_a_joint_on_the_drivers_markers():
    system = fm.System()
    body = system.add_rigid_body(1.0, (0.1, 0.1, 0.1))
    ground, own = system.add_marker(system.ground), system.add_marker(body)
    system.add_spherical_joint(ground, own)
    system.add_angle_driver(ground, own, fm.Step(0.0, 1.0, 0.0, 1.0), name="drive")
    with pytest.raises(fm.InvalidModelError, match="drives no revolute or cylindrical joint"):
        system.with_drivers_as_efforts({"drive": 0.0})
    with pytest.raises(fm.UnknownItemError, match="no driver named 'other'"):
        system.with_drivers_as_efforts({"other": 0.0})


def test_joints_after_a_replaced_driver_keep_their_actuators(assert_close):
    """An actuator added after a driver refers to a joint whose id moves down when the driver
    is replaced: the copy renumbers it."""
    system = fm.System()
    first = system.add_rigid_body(1.0, (0.1, 0.1, J), name="first")
    second = system.add_rigid_body(1.0, (0.1, 0.1, J), position=(0, 0, 1), name="second")
    g, a = system.add_marker(system.ground), system.add_marker(first)
    system.add_revolute_joint(g, a, name="hinge 1")
    system.add_angle_driver(g, a, fm.Step(0.0, 1.0, 0.0, 0.5), name="drive")
    b = system.add_marker(first, position=(0, 0, 1))
    c = system.add_marker(second)
    hinge = system.add_revolute_joint(b, c, name="hinge 2")
    system.add_joint_actuator(hinge, 0.2, proportional_gain=50.0, derivative_gain=5.0)
    copy = system.with_drivers_as_efforts({"drive": 0.0})
    calls = [c for c in copy.building_calls if c[0] == "add_joint_actuator"]
    assert calls[0][1][0] == fm.JointId(1)  # hinge 2, after hinge 1 (the driver is gone)
    assert calls[1][2]["name"] == "drive effort" and calls[1][1][0] == fm.JointId(0)


def test_a_replay_starts_with_the_speed_the_drivers_prescribe(assert_close):
    # An arm driven as theta = 2 t moves at the start: the replay started from the model's
    # velocities (at rest) and ended at -0.15 rad for 1.0 (found by a fault hunt).
    system = fm.System(gravity=(0.0, -9.81, 0.0))
    body = system.add_rigid_body(1.0, (1e-4, 1 / 12, 1 / 12), position=(0.5, 0, 0), name="arm")
    pivot, end = system.add_marker(system.ground), system.add_marker(body, position=(-0.5, 0, 0))
    system.add_revolute_joint(pivot, end, name="hinge")
    system.add_angle_driver(pivot, end, fm.Polynomial([0.0, 2.0]), name="motor")
    inverse = fm.inverse_dynamics(system, 0.5, 1e-3, drivers="motor")  # one name: no list
    replayed = inverse.replay()
    assert_close(replayed.angular_velocity("arm")[0], [0.0, 0.0, 2.0], abs=1e-12, what="start")
    angle = inverse.joint_coordinates(replayed)["motor"]
    assert_close(angle, inverse.prescribed("motor", replayed.time), abs=1e-5, what="angle")


@pytest.mark.parametrize("effort", ["spline", "user"])
def test_a_driver_on_the_hinges_markers_in_the_other_order_is_replayed(effort, assert_close):
    # The driver measures the angle of the ground marker from the arm's, the hinge that of the
    # arm's from the ground's: the arm turns the other way, with the same effort in the
    # driver's sense, which acts on the hinge negated (such drivers were refused: "drives no
    # revolute or cylindrical joint").
    system, profile = arm()
    swapped = fm.System()
    body = swapped.add_rigid_body(2.0, (0.1, 0.1, J), name="arm")
    ground, own = swapped.add_marker(swapped.ground), swapped.add_marker(body)
    swapped.add_revolute_joint(ground, own, name="hinge")
    swapped.add_angle_driver(own, ground, profile, name="drive")
    inverse = fm.inverse_dynamics(swapped, 1.2, 2.5e-4)
    expected = fm.inverse_dynamics(system, 1.2, 2.5e-4).efforts["drive"]
    assert_close(inverse.efforts["drive"], expected, rel=0, abs=1e-9, what="torque")
    if effort == "spline":
        replayed = inverse.replay()
    else:  # a function the copy negates by a wrapper
        table = inverse.effort_functions()["drive"]
        free = swapped.with_drivers_as_efforts({"drive": fm.UserFunction(table)})
        replayed = fm.simulate(free, 1.2, 2.5e-4, output_interval=0.01)
    turn = replayed.orientation("arm")
    angle = -np.arctan2(turn[:, 1, 0], turn[:, 0, 0])  # the ground's from the arm's
    assert_close(angle, inverse.prescribed("drive", replayed.time), rel=0, abs=1e-5,
                 what="replayed angle")  # fmt: skip


def test_ids_of_joints_a_removed_driver_moved_are_refused_in_the_copy(assert_close):
    # A driver added before its hinge: removing it moves the hinge from joint 1 to joint 0 and
    # the elbow from 2 to 1. The copy kept the system's identity, so the shoulder's id was
    # taken as the elbow's (its reaction was the elbow's force).
    system = fm.System(gravity=(0, -9.81, 0))
    a = system.add_rigid_body(2.0, (1e-4, 1 / 6, 1 / 6), position=(0.5, 0, 0), name="a")
    b = system.add_rigid_body(1.0, (1e-4, 0.05, 0.05), position=(1.4, 0, 0), name="b")
    pivot, root = system.add_marker(system.ground), system.add_marker(a, position=(-0.5, 0, 0))
    tip, end = (
        system.add_marker(a, position=(0.5, 0, 0)),
        system.add_marker(b, position=(-0.4, 0, 0)),
    )
    system.add_angle_driver(pivot, root, fm.Step(0, 1, 0, 1.0), name="d1")
    shoulder = system.add_revolute_joint(pivot, root, name="shoulder")
    system.add_revolute_joint(tip, end, name="elbow")
    system.add_angle_driver(tip, end, fm.Step(0, 1, 0, -0.5), name="d2")
    inverse = fm.inverse_dynamics(system, 0.5, 1e-3)
    replayed = inverse.replay()
    with pytest.raises(fm.UnknownItemError, match="joint 'shoulder' of another System.*'elbow'"):
        replayed.reaction_force(shoulder)
    assert_close(replayed.reaction_force("shoulder")[-1],
                 inverse.result.reaction_force(shoulder)[-1], rel=1e-3)  # fmt: skip
    assert_close(replayed.position(a)[-1], inverse.result.position(a)[-1], abs=1e-5)  # bodies hold
