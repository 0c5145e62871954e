"""Driving constraints (specified motion) and inverse dynamics: the driving effort from the
multiplier against closed-form values."""

import warnings

import numpy as np
import pytest

import flexmbd as fm

G = 9.81


def crank(angle, *, mass=2.0, length=0.8, gravity=True):
    system = fm.System(gravity=(0.0, -G, 0.0) if gravity else None)
    inertia = (1e-4, mass * length**2 / 12, mass * length**2 / 12)
    rod = system.add_rigid_body(mass, inertia, position=(length / 2, 0, 0))
    pivot = system.add_marker(system.ground)
    end = system.add_marker(rod, position=(-length / 2, 0, 0))
    system.add_revolute_joint(pivot, end)
    drive = system.add_angle_driver(pivot, end, angle)
    return system, rod, drive


def body_angle(result, body):
    x = result.orientation(body)[:, :, 0]
    return np.unwrap(np.arctan2(x[:, 1], x[:, 0]))


@pytest.mark.parametrize(
    "function, exact",
    [
        (fm.Harmonic(0.5, 3.0), lambda t: 0.5 * np.sin(3 * t)),
        (fm.Polynomial([0.0, 1.0, -0.5]), lambda t: t - 0.5 * t**2),
        (lambda t: 0.3 * t**3, lambda t: 0.3 * t**3),
        (fm.UserFunction(lambda t: (t**2, 2 * t, 2.0), derivatives=True), lambda t: t**2),
        (
            fm.Step(0.2, 0.8, 0.0, 1.2, shape="quintic"),
            lambda t: (
                1.2 * (lambda s: 10 * s**3 - 15 * s**4 + 6 * s**5)(np.clip((t - 0.2) / 0.6, 0, 1))
            ),
        ),
        (
            fm.Trapezoidal(0.0, 1.0, 0.0, 0.9, blend=0.5),
            lambda t: np.where(t < 0.5, 1.8 * t**2, 0.9 - 1.8 * (1 - t) ** 2),
        ),
    ],
)
def test_angle_driver_imposes_the_function(function, exact, assert_close):
    system, rod, _ = crank(function)
    result = fm.simulate(system, 1.0, 1e-3, output_interval=0.05)
    assert_close(body_angle(result, rod), exact(result.time), rel=1e-7, abs=1e-9, what="angle")


def test_spline_driver_passes_through_its_points(assert_close):
    times = [0.0, 0.5, 1.0, 1.5]
    values = [0.0, 0.4, 0.3, 1.0]
    system, rod, _ = crank(fm.Spline(times, values))
    result = fm.simulate(system, 1.5, 1e-3, output_interval=0.5)
    assert_close(body_angle(result, rod), values, rel=1e-7, abs=1e-9, what="angle")


# The index-3 multipliers carry a start-up transient that alternates from step to step and
# decays within about 1/(1 - spectral radius) steps (docs/solvers.md); effort checks start after
# it, at t >= 0.2 s (200 steps).
LAYER = slice(20, None)


def test_driving_torque_at_constant_speed_balances_gravity(assert_close):
    # Rod turning at constant w about a horizontal axis: the drive supplies m g (L/2) cos(theta)
    # about +z (no angular acceleration).
    mass, length, w = 2.0, 0.8, 2.5
    system, rod, drive = crank(fm.Polynomial([0.0, w]), mass=mass, length=length)
    solver = fm.GeneralizedAlpha(0.9, newton_tolerance=1e-9)
    result = fm.simulate(system, 2.0, 1e-3, output_interval=0.01, solver=solver)
    expected = mass * G * length / 2 * np.cos(w * result.time)
    torque = result.reaction_torque(drive)[:, 2]
    assert_close(torque[LAYER], expected[LAYER], rel=1e-7, abs=1e-5, what="driving torque")
    effort = result.driver_effort(drive)
    assert_close(effort[LAYER], expected[LAYER], rel=1e-7, abs=1e-5, what="driver effort")


def test_velocity_projection_removes_the_start_up_layer(assert_close):
    # With velocities projected and accelerations made consistent after each step, the
    # multipliers are accurate from the first step.
    mass, length, w = 2.0, 0.8, 2.5
    system, rod, drive = crank(fm.Polynomial([0.0, w]), mass=mass, length=length)
    solver = fm.GeneralizedAlpha(0.9, newton_tolerance=1e-9, velocity_projection="always")
    result = fm.simulate(system, 0.5, 1e-3, output_interval=0.01, solver=solver)
    expected = mass * G * length / 2 * np.cos(w * result.time)
    torque = result.reaction_torque(drive)[:, 2]
    assert_close(torque, expected, rel=1e-7, abs=1e-5, what="driving torque")


def test_driving_torque_accelerates_the_inertia(assert_close):
    # No gravity, theta = a t^2 / 2: torque J a with J = m L^2 / 3 about the pivot.
    mass, length, a = 2.0, 0.8, 4.0
    system, rod, drive = crank(
        fm.Polynomial([0.0, 0.0, a / 2]), mass=mass, length=length, gravity=False
    )
    solver = fm.GeneralizedAlpha(0.9, newton_tolerance=1e-9)
    result = fm.simulate(system, 1.0, 1e-3, output_interval=0.01, solver=solver)
    inertia = mass * length**2 / 12 + mass * (length / 2) ** 2
    torque = result.reaction_torque(drive)[:, 2]
    # Second-order error (h w)^2 ~ 2e-5 at the final speed w = 4 rad/s.
    assert_close(torque[LAYER], inertia * a, rel=5e-5, what="driving torque")


def test_translation_driver_and_lifting_force(assert_close):
    # A mass on a vertical prismatic joint lifted as z(t) = 0.2 sin(2 t): force m (g + z'').
    mass = 1.5
    system = fm.System(gravity=(0.0, 0.0, -G))
    body = system.add_rigid_body(mass, (0.1, 0.1, 0.1))
    rail = system.add_marker(system.ground)
    slider = system.add_marker(body)
    system.add_prismatic_joint(rail, slider)
    drive = system.add_translation_driver(rail, slider, fm.Harmonic(0.2, 2.0))
    solver = fm.GeneralizedAlpha(0.9, newton_tolerance=1e-9)
    result = fm.simulate(system, 2.0, 1e-3, output_interval=0.01, solver=solver)
    t = result.time
    assert_close(result.position(body)[:, 2], 0.2 * np.sin(2 * t), rel=1e-7, abs=1e-10, what="z")
    lift = mass * (G - 0.8 * np.sin(2 * t))
    force = result.reaction_force(drive)[LAYER, 2]
    assert_close(force, lift[LAYER], rel=1e-7, abs=1e-5, what="lifting force")


def test_a_driver_faster_than_the_steps_is_warned_of():
    # 4000 rad/s at h = 1e-3 (4 rad a step) completed without a word, the bar turning
    # 4 - 2 pi = -2.28 rad a step and its kinetic energy 29 times too large.
    def bar(speed):
        system = fm.System(gravity=[0, 0, 0])
        body = system.add_rigid_body(1.0, [0.01, 0.1, 0.1], position=[0.5, 0, 0], name="bar")
        hub, end = system.add_marker(system.ground), system.add_marker(body, position=[-0.5, 0, 0])
        system.add_revolute_joint(hub, end, name="hinge")
        system.add_angle_driver(hub, end, fm.Polynomial([0.0, speed]), name="drive")
        return system

    with pytest.warns(fm.StepSizeWarning, match="the angle driver 'drive' turns 4 rad in one step"):
        fm.simulate(bar(4000.0), 0.01, 1e-3)
    with warnings.catch_warnings():
        warnings.simplefilter("error", fm.StepSizeWarning)
        result = fm.simulate(bar(40.0), 0.01, 1e-3)  # 0.04 rad a step: no warning
    assert result.angular_velocity("bar")[-1][2] == pytest.approx(40.0, rel=1e-4)


@pytest.mark.parametrize(
    "solver",
    [
        fm.GeneralizedAlpha(),
        fm.ExplicitSolver("rk4", "projection"),
        fm.ExplicitSolver("rk4", "joint-coordinates"),
    ],
    ids=["generalized-alpha", "rk4-projection", "rk4-joint-coordinates"],
)
def test_an_angle_driver_started_half_a_turn_off_is_refused(solver):
    # sin(theta - f) = 0 holds at theta = f + pi too: an arm started pointing along -x with
    # the driver prescribing 0 ran on that branch (held the other way, its torque +9.81 N m
    # instead of -9.81) under generalized-alpha, and joint coordinates turned it over to +x.
    def arm(start):
        system = fm.System(gravity=(0, -9.81, 0))
        c, s = np.cos(start), np.sin(start)
        body = system.add_rigid_body(
            2.0,
            (1e-6, 1 / 6, 1 / 6),
            position=(0.5 * c, 0.5 * s, 0),
            orientation=[[c, -s, 0], [s, c, 0], [0, 0, 1]],
            name="arm",
        )
        pivot = system.add_marker(system.ground)
        end = system.add_marker(body, position=(-0.5, 0, 0))
        system.add_revolute_joint(pivot, end, name="hinge")
        system.add_angle_driver(pivot, end, fm.Polynomial([0.0, 0.5]), name="drive")
        return system

    for start in (np.pi, -2.0, 1.7):
        with pytest.raises(fm.InitialConditionsError, match="angle driver 'drive' .*half a turn"):
            fm.simulate(arm(start), 0.01, 1e-3, solver=solver)
    # A start a little off is corrected (and said so), on the right branch.
    with pytest.warns(fm.InitialCorrectionWarning):
        result = fm.simulate(arm(0.1), 0.01, 1e-3, solver=solver)
    assert result.position("arm")[-1][0] > 0.49
