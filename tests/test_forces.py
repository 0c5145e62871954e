"""Applied forces against closed-form solutions."""

import numpy as np
import pytest

import flexmbd as fm


def test_spring_damper_oscillator_matches_the_damped_solution(assert_close):
    # Point mass on a spring-damper to the ground along x: x'' + 2 zeta w x' + w^2 x = 0.
    mass, k, c, x0 = 2.0, 50.0, 1.2, 0.1
    w = np.sqrt(k / mass)
    zeta = c / (2 * np.sqrt(k * mass))
    wd = w * np.sqrt(1 - zeta**2)
    system = fm.System()
    body = system.add_point_mass(mass, position=(1.0 + x0, 0, 0))
    system.add_spring_damper(
        system.add_marker(system.ground),
        system.add_marker(body),
        stiffness=k,
        damping=c,
        rest_length=1.0,
    )
    result = fm.simulate(system, 3.0, 1e-4, output_interval=0.01)
    t = result.time
    exact = x0 * np.exp(-zeta * w * t) * (np.cos(wd * t) + zeta * w / wd * np.sin(wd * t))
    assert_close(result.position(body)[:, 0] - 1.0, exact, rel=1e-7, abs=1e-6, what="x - 1")


def test_spring_energy_is_conserved_without_damping(assert_close):
    system = fm.System(gravity=(0.0, -9.81, 0.0))
    body = system.add_rigid_body(1.0, (0.1, 0.2, 0.3), position=(0.3, -1.0, 0.2))
    system.add_spring_damper(
        system.add_marker(system.ground),
        system.add_marker(body, position=(0.1, 0.1, 0)),
        stiffness=80.0,
        rest_length=0.5,
        preload=2.0,
    )
    result = fm.simulate(system, 2.0, 1e-4, output_interval=0.01, solver=fm.GeneralizedAlpha(1.0))
    energy = result.total_energy
    scale = np.max(np.abs(result.kinetic_energy))
    assert_close(energy, energy[0], abs=1e-6 * scale, what="total energy")


def test_rotational_spring_oscillates_at_sqrt_k_over_j(assert_close):
    j, k, theta0 = 0.5, 8.0, 0.3
    system = fm.System()
    body = system.add_rigid_body(1.0, (0.2, 0.2, j), orientation=fm.rotation("z", theta0))
    base = system.add_marker(system.ground)
    hub = system.add_marker(body)
    system.add_revolute_joint(base, hub)
    system.add_rotational_spring_damper(base, hub, stiffness=k)
    result = fm.simulate(system, 2.0, 1e-4, output_interval=0.01, solver=fm.GeneralizedAlpha(1.0))
    x = result.orientation(body)[:, :, 0]
    angle = np.arctan2(x[:, 1], x[:, 0])
    exact = theta0 * np.cos(np.sqrt(k / j) * result.time)
    assert_close(angle, exact, rel=1e-7, abs=2e-6, what="angle")


def test_rotational_spring_counts_full_turns(assert_close):
    # Driven three turns against a torsional spring: the torque grows with the total angle.
    k = 2.0
    system = fm.System()
    body = system.add_rigid_body(1.0, (0.2, 0.2, 0.3))
    base = system.add_marker(system.ground)
    hub = system.add_marker(body)
    system.add_revolute_joint(base, hub)
    drive = system.add_angle_driver(base, hub, fm.Polynomial([0.0, 6 * np.pi]))
    system.add_rotational_spring_damper(base, hub, stiffness=k)
    result = fm.simulate(system, 1.0, 1e-3, output_interval=0.01)
    # Constant speed: the drive balances the spring, k * angle (after the start-up layer of the
    # index-3 multipliers, see test_drivers.py).
    # A lost turn would be off by 2 pi k = 12.6 N m.
    torque = result.reaction_torque(drive)[20:, 2]
    assert_close(torque, k * 6 * np.pi * result.time[20:], rel=2e-5, what="driving torque")


def test_force_in_marker_axes_turns_with_the_body(assert_close):
    # A tangential force F at radius r on a hinged disc (marker axes turn with it): constant
    # torque F r, theta = F r t^2 / (2 J). The same force in global axes would stop
    # accelerating the disc as it turns.
    f, r, j = 2.0, 0.5, 0.4
    system = fm.System()
    disc = system.add_rigid_body(1.0, (0.2, 0.2, j))
    hinge = system.add_revolute_joint(system.add_marker(system.ground), system.add_marker(disc))
    rim = system.add_marker(disc, position=(r, 0, 0))
    system.add_point_force(rim, (0.0, f, 0.0), frame="marker")
    result = fm.simulate(system, 1.0, 1e-3, output_interval=0.01)
    x = result.orientation(disc)[:, :, 0]
    angle = np.unwrap(np.arctan2(x[:, 1], x[:, 0]))
    assert_close(angle, f * r * result.time**2 / (2 * j), rel=1e-7, abs=1e-6, what="angle")
    assert_close(result.reaction_torque(hinge)[:, 2], 0.0, abs=1e-9, what="hinge torque")


def test_torque_spins_up_a_free_body(assert_close):
    j, tau = 0.3, 1.2
    system = fm.System()
    body = system.add_rigid_body(1.0, (0.5, 0.4, j))
    system.add_torque(system.add_marker(body), (0.0, 0.0, tau))
    # Sensors on a marker of their own (its Jacobians are set up for the sensors alone).
    off_center = system.add_marker(body, position=(0.2, 0.0, 0.0))
    spin = system.add_sensor(off_center, "angular_velocity")
    speed = system.add_sensor(off_center, "velocity")
    result = fm.simulate(system, 1.0, 1e-3, output_interval=0.1)
    omega = tau / j * result.time
    assert_close(result.angular_velocity(body)[:, 2], omega, rel=1e-5, what="angular velocity")
    spin_values = result.sensor(spin)
    assert_close(spin_values, np.outer(omega, (0, 0, 1)), rel=1e-5, abs=1e-12, what="spin sensor")
    speed_values = np.linalg.norm(result.sensor(speed), axis=1)
    assert_close(speed_values, 0.2 * omega, rel=1e-5, what="speed sensor")


def test_callback_force_acts_on_the_listed_coordinates(assert_close):
    # A linear spring written as a callback: same motion as the built-in spring.
    mass, k = 1.0, 40.0

    def spring(t, q, qd):
        return -k * (q - np.array([1.0, 0.0, 0.0]))

    system = fm.System()
    body = system.add_point_mass(mass, position=(1.05, 0, 0))
    system.add_callback_force([body], spring)
    result = fm.simulate(system, 1.0, 1e-4, output_interval=0.01)
    exact = 0.05 * np.cos(np.sqrt(k / mass) * result.time)
    assert_close(result.position(body)[:, 0] - 1.0, exact, rel=1e-7, abs=1e-6, what="x - 1")


def test_torques_on_a_point_mass_are_refused():
    # A point mass has no rotation: a torque on it was dropped without a word, and the
    # reaction of a torsional spring on it too (a wheel's angular momentum swung +0.2 to -0.2).
    system = fm.System()
    point = system.add_point_mass(1.0, position=(1.0, 0.0, 0.0), name="p")
    wheel = system.add_rigid_body(1.0, (0.2, 0.2, 0.2), name="wheel")
    on_point = system.add_marker(point)
    with pytest.raises(fm.InvalidModelError, match="a torque acts on 'p', a point mass"):
        system.add_torque(on_point, (0.0, 0.0, 5.0), name="tq")
    with pytest.raises(fm.InvalidModelError, match="rotational spring-damper acts on 'p'"):
        system.add_rotational_spring_damper(system.add_marker(wheel), on_point, stiffness=1.0)
    system.add_point_force(on_point, (0.0, 0.0, 5.0))  # forces are its loads
