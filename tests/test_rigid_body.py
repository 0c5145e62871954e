"""Rigid bodies: the generalized Newton-Euler equations (seed eq. 15 without elastic
coordinates) against closed-form solutions of rigid-body dynamics."""

import numpy as np
from conftest import relative_drift

import flexmbd as fm


def test_torque_free_symmetric_top_precesses_at_the_analytic_rate(assert_close):
    # Body axes: I1 = I2 = 2, I3 = 5. In the body frame w3 stays constant and (w1, w2) turns
    # at Omega = (I3 - I1) / I1 * w3 (Euler's equations).
    i1, i3 = 2.0, 5.0
    w0 = np.array([0.3, 0.0, 4.0])
    system = fm.System()
    body = system.add_rigid_body(1.5, (i1, i1, i3), angular_velocity=w0)
    result = fm.simulate(system, 2.0, 1e-3, output_interval=0.01, solver=fm.GeneralizedAlpha(1.0))
    a = result.orientation(body)
    w_body = np.einsum("nji,nj->ni", a, result.angular_velocity(body))
    omega = (i3 - i1) / i1 * w0[2]
    t = result.time
    expected = np.stack([0.3 * np.cos(omega * t), 0.3 * np.sin(omega * t), np.full_like(t, 4.0)], 1)
    assert_close(w_body, expected, rel=1e-7, abs=2e-4, what="body angular velocity")
    assert result.constraint_violation.max() < 1e-12


def test_free_asymmetric_body_conserves_energy_and_angular_momentum(assert_close):
    inertia = np.diag([1.0, 2.0, 3.0])
    w0 = np.array([0.1, 3.0, 0.2])  # near the unstable middle axis: tumbling
    system = fm.System()
    body = system.add_rigid_body(1.0, inertia, angular_velocity=w0, velocity=(1.0, 2.0, 0.5))
    result = fm.simulate(system, 5.0, 2e-4, output_interval=0.01, solver=fm.GeneralizedAlpha(1.0))
    assert relative_drift(result.total_energy) < 1e-6
    a = result.orientation(body)
    w = result.angular_velocity(body)
    momentum = np.einsum("nij,jk,nlk,nl->ni", a, inertia, a, w)
    scale = np.linalg.norm(momentum[0])
    assert_close(momentum, momentum[0], abs=1e-6 * scale, what="angular momentum")
    # The centre of mass moves uniformly.
    position = result.position(body)[-1]
    assert_close(position, [5.0, 10.0, 2.5], rel=1e-7, abs=1e-9, what="position")


def test_body_with_offset_centre_of_mass_falls_freely(assert_close):
    system = fm.System(gravity=(0.0, 0.0, -9.81))
    body = system.add_rigid_body(
        2.0,
        (0.1, 0.2, 0.3),
        center_of_mass=(0.4, -0.2, 0.1),
        angular_velocity=(0.0, 0.0, 2.0),
        velocity=(-0.4, -0.8, 0.0),  # centre of mass initially at rest: v = -w x c
    )
    result = fm.simulate(system, 1.0, 1e-4, output_interval=0.1)
    # The centre of mass falls with g; the body spins uniformly about its centre of mass.
    c = np.einsum("nij,j->ni", result.orientation(body), [0.4, -0.2, 0.1])
    com = result.position(body) + c
    expected_z = 0.1 - 0.5 * 9.81 * result.time**2
    assert_close(com[:, 2], expected_z, rel=1e-7, abs=1e-8, what="centre of mass z")
    expected_xy = np.tile([0.4, -0.2], (len(result), 1))
    assert_close(com[:, :2], expected_xy, rel=1e-7, abs=1e-8, what="centre of mass x, y")


def test_angular_velocity_from_euler_parameter_rates_against_finite_differences(assert_close):
    # omega~ = R_dot R^T (global axes) and R^T R_dot (body axes), R_dot by central differences
    # of the rotation matrix along p + t p_dot (p_dot normal to p: |p| stays 1 to first order).
    from flexmbd.rotation import angular_velocity, euler_parameters_to_matrix

    rng = np.random.default_rng(7)
    p = rng.standard_normal(4)
    p /= np.linalg.norm(p)
    p_dot = rng.standard_normal(4)
    p_dot -= (p_dot @ p) * p
    h = 1e-6
    r = euler_parameters_to_matrix(p)
    r_dot = (
        euler_parameters_to_matrix(p + h * p_dot) - euler_parameters_to_matrix(p - h * p_dot)
    ) / (2 * h)
    for frame, spin in (("global", r_dot @ r.T), ("body", r.T @ r_dot)):
        expected = [spin[2, 1], spin[0, 2], spin[1, 0]]
        assert_close(angular_velocity(p, p_dot, frame), expected, abs=1e-8, what=frame)
    # Several rates at once (the columns of a null space, a mode's complex shape).
    rates = np.stack([p_dot, 2j * p_dot])
    both = angular_velocity(p, rates, "body")
    assert_close(both[1], 2j * both[0], abs=1e-14, what="complex rates")
    # The rates of a given angular velocity: tangent to |p| = 1, and turning the matrix as
    # omega does (central differences again).
    from flexmbd.rotation import euler_parameter_rates

    omega = rng.standard_normal(3)
    for frame in ("global", "body"):
        rates = euler_parameter_rates(p, omega, frame)
        assert abs(rates @ p) < 1e-15
        r_dot = (
            euler_parameters_to_matrix(p + h * rates) - euler_parameters_to_matrix(p - h * rates)
        ) / (2 * h)
        spin = r_dot @ r.T if frame == "global" else r.T @ r_dot
        turned = [spin[2, 1], spin[0, 2], spin[1, 0]]
        assert_close(turned, omega, abs=1e-8, what=f"rates of omega ({frame})")
