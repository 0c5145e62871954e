"""Joint actuators (PD servos at revolute, prismatic and cylindrical joints): the analytic
second-order response, tracking with feed-forward, saturation with its events, and the
refusals. Their Jacobians are checked against finite differences in the core
(tests/jacobians.rs)."""

from __future__ import annotations

import math

import numpy as np
import pytest

import flexmbd as fm

J, KP, KD = 0.5, 200.0, 4.0


def arm(set_point, **settings):
    """A rigid arm turning in a horizontal plane about a hinge at its centre of mass (inertia J
    about the axis), driven by a servo."""
    system = fm.System()
    body = system.add_rigid_body(2.0, (0.1, 0.1, J), name="arm")
    ground, own = system.add_marker(system.ground), system.add_marker(body)
    hinge = system.add_revolute_joint(ground, own, name="hinge")
    settings = {"proportional_gain": KP, "derivative_gain": KD, **settings}
    system.add_joint_actuator(hinge, set_point, name="servo", **settings)
    return system, body


def angle(result, body):
    x = result.orientation(body)[:, :, 0]
    return np.unwrap(np.arctan2(x[:, 1], x[:, 0]))


def step_response(t, target, inertia):
    """x(t) of inertia x'' = KP (target - x) - KD x' from rest at 0 (under-damped)."""
    w = math.sqrt(KP / inertia)
    zeta = KD / (2 * math.sqrt(KP * inertia))
    wd = w * math.sqrt(1 - zeta**2)
    decay = np.exp(-zeta * w * t)
    return target * (1 - decay * (np.cos(wd * t) + zeta * w / wd * np.sin(wd * t)))


@pytest.mark.parametrize(
    "solver, tolerance",
    [
        (fm.ExplicitSolver("rk4", "projection"), 1e-10),
        (fm.ExplicitSolver("rk4", "joint-coordinates"), 1e-10),
        (fm.GeneralizedAlpha(1.0), 1e-6),
    ],
    ids=["rk4", "rk4-joint-coordinates", "generalized-alpha"],
)
def test_a_servo_reaches_its_set_point_with_the_second_order_response(
    solver, tolerance, assert_close
):
    """Natural frequency sqrt(k_p / J) = 20 rad/s, damping ratio k_d / (2 sqrt(k_p J)) = 0.2."""
    system, body = arm(0.8)
    result = fm.simulate(system, 1.0, 1e-4, output_interval=0.01, solver=solver)
    exact = step_response(result.time, 0.8, J)
    assert_close(angle(result, body), exact, rel=0, abs=tolerance, what="servo angle")
    assert result.events == []
    # Generalized-alpha converges at second order to the same response.
    if isinstance(solver, fm.GeneralizedAlpha):
        coarse = fm.simulate(system, 1.0, 2e-4, output_interval=0.01, solver=solver)
        error = np.abs(angle(coarse, body) - exact).max()
        assert 3.5 < error / np.abs(angle(result, body) - exact).max() < 4.5


def test_feed_forward_tracks_a_profile_without_error(assert_close):
    """With the velocity feed-forward (the set point's rate) and the effort J f''(t), the arm
    follows a quintic step exactly: the servo's error stays at the integration error."""
    profile = fm.Step(0.1, 0.6, 0.0, 1.5)
    torque = fm.UserFunction(lambda t: (J * profile.derivatives(t)[2], 0.0, 0.0), derivatives=True)
    system, body = arm(profile, feed_forward=torque)
    result = fm.simulate(
        system, 0.8, 1e-4, output_interval=0.01, solver=fm.ExplicitSolver("rk4", "projection")
    )
    expected = [profile(t) for t in result.time]
    assert_close(angle(result, body), expected, rel=0, abs=1e-9, what="tracked angle")
    # Without it the servo lags behind the moving set point.
    lagging, _ = arm(profile)
    late = fm.simulate(
        lagging, 0.8, 1e-4, output_interval=0.01, solver=fm.ExplicitSolver("rk4", "projection")
    )
    assert np.abs(angle(late, body) - expected).max() > 1e-2


def test_a_saturated_servo_turns_at_its_limit_and_reports_it(assert_close):
    """A limit of 2 N m against a demand of 200 N m: the arm turns at 2 / J rad/s^2 until the
    demand falls below the limit, with an event at each change."""
    limit = 2.0
    system, body = arm(1.0, limit=limit)
    result = fm.simulate(
        system, 1.5, 1e-4, output_interval=0.01, solver=fm.ExplicitSolver("rk4", "projection")
    )
    kinds = [(e["kind"], e["message"]) for e in result.events]
    assert kinds[0][0] == "actuator saturation" and "saturated" in kinds[0][1], kinds
    assert "+2 N m" in kinds[0][1]
    released = [e for e in result.events if "back within" in e["message"]]
    assert released, result.events
    t_free = released[0]["time"]
    # Saturated: the demand k_p (1 - x) - k_d x' = limit with x = limit t^2 / (2 J).
    free = np.roots([KP * limit / (2 * J), KD * limit / J, limit - KP])
    t_expected = free[free > 0][0]
    assert_close(t_free, t_expected, rel=0, abs=2e-4, what="end of saturation")
    saturated = result.time < t_free - 1e-3
    assert_close(
        angle(result, body)[saturated],
        limit * result.time[saturated] ** 2 / (2 * J),
        rel=0,
        abs=1e-10,
        what="angle at the limit",
    )


def test_a_prismatic_servo_positions_a_slider(assert_close):
    mass = 3.0
    system = fm.System()
    slider = system.add_rigid_body(mass, (0.1, 0.1, 0.1), name="slider")
    ground, own = system.add_marker(system.ground), system.add_marker(slider)
    rail = system.add_prismatic_joint(ground, own, name="rail")
    system.add_joint_actuator(rail, 0.05, proportional_gain=KP, derivative_gain=KD)
    result = fm.simulate(
        system, 1.0, 1e-4, output_interval=0.01, solver=fm.ExplicitSolver("rk4", "projection")
    )
    exact = step_response(result.time, 0.05, mass)
    assert_close(result.position(slider)[:, 2], exact, rel=0, abs=1e-10, what="slide")


def test_cylindrical_joints_take_an_actuator_per_coordinate(assert_close):
    system = fm.System()
    body = system.add_rigid_body(1.0, (0.1, 0.1, J), name="sleeve")
    ground, own = system.add_marker(system.ground), system.add_marker(body)
    sleeve = system.add_cylindrical_joint(ground, own, name="sleeve")
    with pytest.raises(fm.InvalidParameterError, match="give the coordinate"):
        system.add_joint_actuator(sleeve, 0.1, proportional_gain=KP)
    system.add_joint_actuator(sleeve, 0.3, proportional_gain=KP, derivative_gain=KD,
                              coordinate="angle")  # fmt: skip
    system.add_joint_actuator(sleeve, 0.02, proportional_gain=KP, derivative_gain=KD,
                              coordinate="slide")  # fmt: skip
    result = fm.simulate(
        system, 0.5, 1e-4, output_interval=0.01, solver=fm.ExplicitSolver("rk4", "projection")
    )
    assert_close(angle(result, body), step_response(result.time, 0.3, J), rel=0, abs=1e-10,
                 what="cylinder angle")  # fmt: skip
    assert_close(result.position(body)[:, 2], step_response(result.time, 0.02, 1.0), rel=0,
                 abs=1e-10, what="cylinder slide")  # fmt: skip


@pytest.mark.parametrize(
    "change, error, match",
    [
        ({"proportional_gain": -1.0}, fm.InvalidParameterError, "gains must be finite and >= 0"),
        ({"derivative_gain": math.nan}, fm.InvalidParameterError, "gains"),
        ({"limit": 0.0}, fm.InvalidParameterError, "limit must be > 0"),
        ({"coordinate": "slide"}, fm.InvalidParameterError, "has no slide"),
        ({"coordinate": "twist"}, fm.InvalidParameterError, "'angle' or 'slide'"),
        ({"feed_forward": "x"}, fm.InvalidParameterError, "feed_forward: expected a number"),
    ],
)
def test_bad_actuators_are_refused_naming_them(change, error, match):
    system = fm.System()
    body = system.add_rigid_body(1.0, (0.1, 0.1, 0.1))
    hinge = system.add_revolute_joint(system.add_marker(system.ground), system.add_marker(body))
    settings = {"proportional_gain": 1.0, "name": "servo", **change}
    with pytest.raises(error, match=match) as info:
        system.add_joint_actuator(hinge, 0.0, **settings)
    assert "servo" in str(info.value)


def test_joints_without_a_coordinate_to_drive_are_refused():
    system = fm.System()
    body = system.add_rigid_body(1.0, (0.1, 0.1, 0.1))
    ball = system.add_spherical_joint(
        system.add_marker(system.ground), system.add_marker(body), name="ball"
    )
    with pytest.raises(fm.InvalidParameterError, match="joint 'ball' is spherical"):
        system.add_joint_actuator(ball, 0.0, proportional_gain=1.0)
    with pytest.raises(fm.UnknownItemError, match="joint 7"):
        system.add_joint_actuator(fm.JointId(7), 0.0, proportional_gain=1.0)


ACTUATED_MODEL = """\
units: {{length: {length}, time: {time}, angle: {angle}}}
bodies:
  - {{name: arm, type: rigid, mass: 2.0, inertia: [{i}, {i}, {j}]}}
  - {{name: slider, type: rigid, mass: 3.0, inertia: [{i}, {i}, {i}], position: [0, 0, 0]}}
joints:
  - {{name: hinge, type: revolute, marker1: {{body: ground}}, marker2: {{body: arm}}}}
  - {{name: rail, type: prismatic, marker1: {{body: ground}}, marker2: {{body: slider}}}}
forces:
  - {{type: joint-actuator, name: servo, joint: hinge, set_point: {target},
     proportional_gain: {kp}, derivative_gain: {kd}, limit: {limit}}}
  - {{type: joint-actuator, joint: rail, set_point: {{type: step, start_time: 0,
     end_time: {t_end}, start_value: 0, end_value: {slide}}}, proportional_gain: {kp_slide},
     derivative_gain: {kd_slide}, feed_forward: {push}}}
solver: {{type: explicit, method: rk4, strategy: projection}}
simulation: {{end_time: {end}, step_size: {step}, output_interval: {output}}}
"""


def test_actuators_in_model_files_with_their_units(tmp_path, assert_close):
    """The same servos written in SI and in mm, ms and degrees run the same motion."""
    from flexmbd.model_file import load_model, simulate_model

    deg, mm_per_m = 180 / math.pi, 1000.0
    si = {"length": "m", "time": "s", "angle": "rad", "i": 0.1, "j": J, "target": 0.8,
          "kp": KP, "kd": KD, "limit": 500.0, "t_end": 0.3, "slide": 0.05, "kp_slide": 400.0,
          "kd_slide": 30.0, "push": 1.5, "end": 0.5, "step": 1e-4, "output": 0.01}  # fmt: skip
    # Torque N m = kg m^2 / s^2 -> kg mm^2 / ms^2 = 1e6 / 1e6: the same number; N -> 1e-3.
    other = {**si, "length": "mm", "time": "ms", "angle": "deg", "i": 0.1e6, "j": J * 1e6,
             "target": 0.8 * deg, "kp": KP / deg, "kd": KD * 1e3 / deg, "t_end": 300.0,
             "slide": 50.0, "kp_slide": 400.0 * 1e-3 / mm_per_m,
             "kd_slide": 30.0 * 1e-3 * 1e3 / mm_per_m, "push": 1.5e-3, "end": 500.0,
             "step": 0.1, "output": 10.0}  # fmt: skip
    runs = []
    for values in (si, other):
        path = tmp_path / f"servo-{values['length']}.yaml"
        path.write_text(ACTUATED_MODEL.format(**values))
        runs.append(simulate_model(load_model(path)))
    assert_close(runs[1].coordinates, runs[0].coordinates, rel=1e-9, abs=1e-12, what="units")
    exact = step_response(runs[0].time, 0.8, J)
    assert_close(angle(runs[0], "arm"), exact, rel=0, abs=1e-9, what="servo")


def test_the_effort_is_recorded_and_plotted(assert_close, tmp_path):
    """The actuator's effort is a sensor ("servo effort"): the law at each record, also after
    a results file, and a panel of the overview in N m."""
    from flexmbd import plotting

    system, body = arm(0.8, limit=100.0)
    result = fm.simulate(
        system,
        0.5,
        1e-4,
        output_interval=0.01,
        solver=fm.ExplicitSolver("rk4", "projection"),
        results_file=tmp_path / "servo.h5",
    )
    x = angle(result, body)
    rate = result.angular_velocity(body)[:, 2]
    expected = np.clip(KP * (0.8 - x) - KD * rate, -100.0, 100.0)
    effort = result.actuator_effort("servo")
    assert_close(effort, expected, rel=1e-9, abs=1e-9, what="recorded effort")
    assert effort[0] == 100.0  # saturated at the start
    np.testing.assert_array_equal(
        fm.read_results(tmp_path / "servo.h5").actuator_effort("servo"), effort
    )
    # Another name: the actuators are listed (it said "no sensor named 'x effort'").
    with pytest.raises(fm.UnknownItemError, match=r"no actuator named 'x' \(actuators: 'servo'\)"):
        result.actuator_effort("x")
    entry = next(s for s in result.layout["sensors"] if s["name"] == "servo effort")
    assert entry["quantity"] == "actuator torque (N m)"
    assert "efforts" in plotting.default_quantities(result)
    assert "sensor:servo effort" not in plotting.default_quantities(result)
    ax = plotting.plot_efforts(result, "angle driver")  # the torques: drivers and actuators
    (line,) = ax.get_lines()
    assert line.get_label() == "servo effort"
    np.testing.assert_array_equal(line.get_ydata(), effort)
    ax = plotting.plot_sensor(result, "servo effort")
    assert ax.get_ylabel().startswith("actuator torque (N m)")
    # A scalar: (n, 1), labelled by its name in tables (it was "servo effort.x").
    assert result.sensor("servo effort").shape == (len(result), 1)
    assert "servo effort" in result._sensor_labels()
    assert "servo effort.x" not in result._sensor_labels()


def test_the_effort_is_found_by_the_id_add_joint_actuator_returned(assert_close):
    # Regression: the ForceId was "no actuator named ForceId(0)", and an unnamed actuator
    # could only be found as "actuator 0".
    system = fm.System()
    body = system.add_rigid_body(2.0, (0.1, 0.1, J))
    ground, own = system.add_marker(system.ground), system.add_marker(body)
    hinge = system.add_revolute_joint(ground, own)
    spring = system.add_rotational_spring_damper(ground, own, stiffness=1.0)
    unnamed = system.add_joint_actuator(hinge, 0.5, proportional_gain=KP)
    named = system.add_joint_actuator(hinge, 0.5, proportional_gain=KP, name="servo")
    result = fm.simulate(system, 0.01, 1e-3)
    assert_close(result.actuator_effort(unnamed), result.actuator_effort("actuator 1"))
    assert_close(result.actuator_effort(named), result.actuator_effort("servo"))
    assert result.actuator_effort(named)[0] == pytest.approx(KP * 0.5)
    with pytest.raises(fm.UnknownItemError, match="is a rotational spring-damper, not a joint"):
        result.actuator_effort(spring)
