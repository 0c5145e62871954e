"""Every joint type in a mechanism with a closed-form solution. (Their Jacobians, Hessians and
gamma are checked against finite differences in crates/flexmbd-core/tests/jacobians.rs.)"""

import numpy as np
import pytest
from conftest import relative_drift

import flexmbd as fm

G = 9.81


def angle_about(a: np.ndarray, axis: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """Rotation angle of body x axes (columns 0 of `a`) about `axis` from `reference`."""
    x = a[:, :, 0]
    y_ref = np.cross(axis, reference)
    return np.unwrap(np.arctan2(x @ y_ref, x @ reference))


def test_revolute_pendulum_small_oscillation_period(assert_close):
    # Rod pinned at one end: T = 2 pi sqrt(2 L / (3 g)) for small amplitude.
    length, mass, theta0 = 1.0, 2.0, 1e-3
    system = fm.System(gravity=(0.0, -G, 0.0))
    a0 = fm.rotation("z", -np.pi / 2 + theta0)
    rod = system.add_rigid_body(
        mass,
        (1e-6, mass * length**2 / 12, mass * length**2 / 12),
        position=a0 @ [length / 2, 0, 0],
        orientation=a0,
    )
    pivot = system.add_marker(system.ground)
    end = system.add_marker(rod, position=(-length / 2, 0, 0))
    system.add_revolute_joint(pivot, end)
    result = fm.simulate(system, 3.0, 1e-3, output_interval=1e-3, solver=fm.GeneralizedAlpha(1.0))
    theta = angle_about(result.orientation(rod), np.array([0, 0, 1.0]), np.array([0, -1.0, 0]))
    period = 2 * np.pi * np.sqrt(2 * length / (3 * G))
    # Zero crossings going negative are one period apart.
    crossings = result.time[1:][(theta[:-1] > 0) & (theta[1:] <= 0)]
    assert_close(np.diff(crossings).mean(), period, rel=1e-4, what="period")
    assert_close(result.position(rod)[:, 2], 0.0, abs=1e-12, what="z")


def test_prismatic_block_slides_down_an_incline(assert_close):
    alpha, mass = 0.4, 3.0
    down = np.array([np.cos(alpha), -np.sin(alpha), 0.0])
    frame = np.column_stack([[0, 0, 1.0], np.cross(down, [0, 0, 1.0]), down])  # z along the slope
    system = fm.System(gravity=(0.0, -G, 0.0))
    block = system.add_rigid_body(mass, (0.1, 0.2, 0.3), orientation=frame)
    rail = system.add_marker(system.ground, orientation=frame)
    slider = system.add_marker(block)
    joint = system.add_prismatic_joint(rail, slider)
    result = fm.simulate(system, 1.0, 1e-3, output_interval=0.1)
    s = result.position(block) @ down
    assert_close(s, 0.5 * G * np.sin(alpha) * result.time**2, rel=1e-7, abs=1e-9, what="slide")
    force = result.reaction_force(joint)  # in the slider's axes: z along the slope
    assert_close(force[:, 2], 0.0, abs=1e-9, what="force along the slope")
    normal = np.linalg.norm(force, axis=1)
    assert_close(normal, mass * G * np.cos(alpha), rel=1e-7, what="normal force")
    # No rotation.
    assert_close(result.orientation(block)[-1], frame, rel=1e-7, abs=1e-12, what="orientation")


def test_cylindrical_joint_spins_and_slides_freely_along_its_axis(assert_close):
    system = fm.System(gravity=(0.0, 0.0, -G))
    body = system.add_rigid_body(1.0, (0.2, 0.2, 0.5), angular_velocity=(0, 0, 3.0))
    shaft = system.add_marker(system.ground)
    sleeve = system.add_marker(body)
    system.add_cylindrical_joint(shaft, sleeve)
    solver = fm.GeneralizedAlpha(1.0, newton_tolerance=1e-9)
    result = fm.simulate(system, 1.0, 1e-3, output_interval=0.1, solver=solver)
    z = result.position(body)[:, 2]
    assert_close(z, -0.5 * G * result.time**2, rel=1e-7, abs=1e-9, what="z")
    spin = result.angular_velocity(body)[:, 2]
    assert_close(spin, 3.0, rel=1e-7, abs=1e-9, what="angular velocity")
    assert_close(result.position(body)[:, :2], 0.0, abs=1e-12, what="x, y")


def test_planar_joint_free_flight_in_plane_and_support_out_of_plane(assert_close):
    mass = 2.0
    system = fm.System(gravity=(0.0, -G, -G))
    body = system.add_rigid_body(
        mass, (0.1, 0.2, 0.3), velocity=(1.0, 2.0, 0.0), angular_velocity=(0, 0, 1.5)
    )
    plane = system.add_marker(system.ground)
    puck = system.add_marker(body)
    joint = system.add_planar_joint(plane, puck)
    result = fm.simulate(system, 1.0, 1e-3, output_interval=0.1)
    t = result.time
    position = result.position(body)
    assert_close(position[:, 0], t, rel=1e-7, abs=1e-9, what="x")
    assert_close(position[:, 1], 2 * t - 0.5 * G * t**2, rel=1e-7, abs=1e-9, what="y")
    assert_close(position[:, 2], 0.0, abs=1e-12, what="z")
    spin = result.angular_velocity(body)[:, 2]
    assert_close(spin, 1.5, rel=1e-7, abs=1e-9, what="angular velocity")
    # The plane carries the out-of-plane weight (force on the body along +z in body axes...).
    force = result.reaction_force(joint)
    world_force = np.einsum("nij,nj->ni", result.orientation(body), force)
    expected = np.tile([0, 0, mass * G], (len(t), 1))
    assert_close(world_force, expected, rel=1e-7, abs=1e-8, what="plane reaction")


def test_universal_joint_transmits_the_cardan_velocity_ratio_and_driving_torque(assert_close):
    # Input shaft about z driven at w1; output shaft about an axis tilted by beta. With
    # tan(theta2) = tan(theta1) / cos(beta):
    #   w2 = w1 cos(beta) / (1 - sin^2(beta) cos^2(theta1)),
    # and the driving torque supplies the output shaft's kinetic energy: tau w1 = J2 w2 dw2/dt.
    # The output shaft is held by the cross (at the origin) and an in-line joint on its axis,
    # so that no equation is redundant.
    beta, w1, j2 = 0.5, 2.0, 0.3
    axis2 = np.array([np.sin(beta), 0.0, np.cos(beta)])
    frame2 = np.column_stack([[np.cos(beta), 0, -np.sin(beta)], [0, 1.0, 0], axis2])
    system = fm.System()
    shaft1 = system.add_rigid_body(1.0, (0.1, 0.1, 0.2))
    shaft2 = system.add_rigid_body(1.0, (0.1, 0.1, j2), orientation=frame2)
    g1 = system.add_marker(system.ground)
    bearing = system.add_marker(system.ground, position=axis2, orientation=frame2)
    s1 = system.add_marker(shaft1)
    s2 = system.add_marker(shaft2)
    system.add_revolute_joint(g1, s1)
    drive = system.add_angle_driver(g1, s1, fm.Polynomial([0.0, w1]))
    system.add_universal_joint(s1, s2)
    system.add_inline_joint(bearing, system.add_marker(shaft2, position=(0, 0, 1.0)))
    result = fm.simulate(system, 2.0, 5e-4, output_interval=0.01)
    theta1 = w1 * result.time
    expected_w2 = w1 * np.cos(beta) / (1 - np.sin(beta) ** 2 * np.cos(theta1) ** 2)
    w2 = result.angular_velocity(shaft2) @ axis2
    assert_close(w2, expected_w2, rel=1e-6, what="output speed")
    # The output shaft turns about its axis only.
    off_axis = np.cross(result.angular_velocity(shaft2), axis2)
    assert_close(off_axis, 0.0, abs=1e-8, what="off-axis angular velocity")
    dw2 = np.gradient(expected_w2, result.time)
    expected_tau = j2 * expected_w2 * dw2 / w1
    tau = result.reaction_torque(drive)[:, 2]
    inner = slice(5, -5)  # np.gradient is one-sided at the ends
    scale = np.abs(expected_tau).max()
    assert_close(tau[inner], expected_tau[inner], rel=1e-7, abs=2e-3 * scale, what="torque")


def test_spherical_double_pendulum_conserves_energy():
    system = fm.System(gravity=(0.0, -G, 0.0))
    inertia = (0.01, 0.1, 0.1)
    a = fm.rotation((0.2, 0.1, 1.0), 1.0)
    b = fm.rotation((1.0, 0.3, 0.0), 2.0)
    first = system.add_rigid_body(1.0, inertia, position=a @ [0.5, 0, 0], orientation=a)
    second = system.add_rigid_body(
        0.5,
        inertia,
        position=a @ [1.0, 0, 0] + b @ [0.5, 0, 0],
        orientation=b,
        angular_velocity=(0.0, 2.0, 1.0),
    )
    pivot = system.add_marker(system.ground)
    system.add_spherical_joint(pivot, system.add_marker(first, position=(-0.5, 0, 0)))
    system.add_spherical_joint(
        system.add_marker(first, position=(0.5, 0, 0)),
        system.add_marker(second, position=(-0.5, 0, 0)),
    )
    result = fm.simulate(system, 2.0, 5e-5, output_interval=0.01, solver=fm.GeneralizedAlpha(1.0))
    assert relative_drift(result.total_energy) < 1e-6
    assert result.constraint_violation.max() < 1e-10


@pytest.mark.parametrize("joint", ["fixed", "revolute", "prismatic", "cylindrical", "universal"])
def test_joint_holds_a_weight_in_static_equilibrium(joint, assert_close):
    # A body hanging from the ground by one joint whose free directions are horizontal or
    # absent: it stays at rest, the joint carries the weight.
    mass = 1.5
    system = fm.System(gravity=(0.0, -G, 0.0))
    body = system.add_rigid_body(mass, (0.1, 0.1, 0.1), position=(0, -1.0, 0))
    # Marker z axes horizontal: the free translations and rotations are horizontal.
    frame = fm.rotation("y", np.pi / 2)
    ground = system.add_marker(system.ground, orientation=frame)
    hook = system.add_marker(body, position=(0, 1.0, 0), orientation=frame)
    j = getattr(system, f"add_{joint}_joint")(ground, hook)
    result = fm.simulate(system, 0.5, 1e-3, output_interval=0.1)
    assert_close(result.position(body)[-1], [0, -1.0, 0], rel=1e-7, abs=1e-10, what="position")
    force = np.einsum("ij,nj->ni", frame, result.reaction_force(j))  # marker axes -> global
    expected = np.tile([0, mass * G, 0], (len(result), 1))
    assert_close(force, expected, rel=1e-7, abs=1e-9, what="joint force")
