"""Bad input raises a typed error naming the item; failed runs keep their results."""

import os
import re
import signal
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

import flexmbd as fm


@pytest.fixture
def system():
    s = fm.System(gravity=(0.0, -9.81, 0.0))
    body = s.add_rigid_body(1.0, (0.1, 0.1, 0.1), name="link")
    return s, body


def test_inertia_no_body_has_is_warned_of_and_flat_bodies_are_not(recwarn):
    # The largest principal moment above the sum of the others was taken silently.
    with pytest.warns(fm.InertiaWarning, match=r"body 'wheel': .* 0.5 exceeds .* other two 0.2"):
        fm.System().add_rigid_body(1.0, (0.1, 0.1, 0.5), name="wheel")
    turned = [[3.0, 0.0, 0.0], [0.0, 0.5, 0.4], [0.0, 0.4, 0.5]]  # moments 3, 0.9, 0.1
    with pytest.warns(fm.InertiaWarning, match=r"body 1: .* 3 exceeds .* other two 1\b"):
        fm.System().add_rigid_body(1.0, turned)
    recwarn.clear()
    # A disc (I, I, 2 I) sits on the bound; its moments rounded to four digits cross it.
    fm.System().add_rigid_body(1.0, (0.1235, 0.1235, 0.2471))
    fm.System().add_rigid_body(1.0, (1e-6, 0.5, 0.5))  # a slender rod
    assert not [w for w in recwarn if issubclass(w.category, fm.InertiaWarning)]


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"mass": 0.0}, "mass must be positive"),
        ({"mass": -2.0}, "mass must be positive"),
        ({"mass": float("nan")}, "mass must be positive"),
        ({"inertia": (1.0, 1.0, 0.0)}, "positive definite"),
        ({"inertia": (1.0, -1.0, 1.0)}, "positive definite"),
        ({"inertia": [[1, 0.5, 0], [0, 1, 0], [0, 0, 1]]}, "not symmetric"),
        ({"inertia": (1.0, float("nan"), 1.0)}, "finite"),
        ({"inertia": (1.0, 1.0)}, "3 principal moments"),
        ({"position": (0.0, float("inf"), 0.0)}, "position must be finite"),
        ({"orientation": np.diag([1.0, 1.0, -1.0])}, "proper rotation"),
        ({"orientation": 2 * np.eye(3)}, "proper rotation"),
        ({"angular_velocity": (0.0, float("nan"), 0.0)}, "angular velocity must be finite"),
    ],
)
def test_bad_rigid_body_data(kwargs, match):
    args = {"mass": 1.0, "inertia": (1.0, 1.0, 1.0), **kwargs}
    with pytest.raises(fm.InvalidParameterError, match=match) as info:
        fm.System().add_rigid_body(args.pop("mass"), args.pop("inertia"), name="arm", **args)
    assert info.value.item == "body 'arm'"
    assert isinstance(info.value, ValueError) and isinstance(info.value, fm.FlexmbdError)


def test_unknown_body_and_marker(system):
    s, body = system
    with pytest.raises(fm.UnknownItemError, match="unknown body 7"):
        s.add_marker(fm.BodyId(7))
    marker = s.add_marker(body)
    with pytest.raises(fm.UnknownItemError, match="unknown marker 9 .used by joint 'hinge'"):
        s.add_revolute_joint(marker, fm.MarkerId(9), name="hinge")
    with pytest.raises(fm.UnknownItemError, match="unknown marker 9"):
        s.add_sensor(fm.MarkerId(9), "position")


def test_ids_of_another_system_are_refused():
    # They were taken as indices into this system: a marker on the wrong body, silently.
    import pickle

    first, second = fm.System(), fm.System()
    a = first.add_rigid_body(1.0, (1, 1, 1), name="a")
    x = second.add_rigid_body(5.0, (1, 1, 1), name="x")
    assert a == x == fm.BodyId(1)  # ids still compare by index
    with pytest.raises(fm.UnknownItemError, match="add_marker: BodyId.1. is body 'a' of another"):
        second.add_marker(a)
    m1, m2 = first.add_marker(first.ground), first.add_marker(a, name="on a")
    with pytest.raises(fm.UnknownItemError, match="here there is no marker 1"):
        second.add_revolute_joint(second.add_marker(second.ground), m2)
    with pytest.raises(fm.UnknownItemError, match="add_callback_force.*here body 1 is 'x'"):
        second.add_callback_force([x, a], lambda t, q, qd: [0.0] * len(q))
    # Ids made by hand, the ground's, and those of unnamed items are indices, as before.
    second.add_revolute_joint(second.add_marker(second.ground), second.add_marker(fm.BodyId(1)))
    first.add_revolute_joint(m1, m2)
    result = fm.simulate(second, 0.01, 1e-3)
    with pytest.raises(fm.UnknownItemError, match="this result: BodyId.1. is body 'a'"):
        result.position(a)
    assert result.position(x).shape == result.position("x").shape == (11, 3)
    for state in (result.state(-1), fm.State.of_model(second)):
        with pytest.raises(fm.UnknownItemError, match="this state: BodyId.1. is body 'a'"):
            state.position(a)

    # A system built alike (the same builder called twice) takes the other's ids.
    def build():
        system = fm.System()
        body = system.add_rigid_body(1.0, (1, 1, 1), name="a")
        system.add_point_force(system.add_marker(body, name="on a"), (0.0, 1.0, 0.0))
        return system, body

    (_one, body), (two, _) = build(), build()
    two.add_sensor(two.add_marker(body, name="tip"), "position")
    assert fm.simulate(two, 0.01, 1e-3).position(body).shape == (11, 3)
    # A copy of a system (a variant, or pickled) keeps its identity: its ids hold there.
    copy = pickle.loads(pickle.dumps(first))
    copy.add_point_force(copy.add_marker(a), (0.0, 1.0, 0.0))
    variant = fm.simulate(first.without_loads(), 0.01, 1e-3)
    assert variant.position(a).shape == (11, 3)
    assert pickle.loads(pickle.dumps(a))._system == a._system != 0


def test_joint_between_a_body_and_itself(system):
    s, body = system
    a, b = s.add_marker(body), s.add_marker(body, position=(1, 0, 0))
    with pytest.raises(fm.InvalidModelError, match="joint 'twin'.*both markers are on 'link'"):
        s.add_revolute_joint(a, b, name="twin")


@pytest.mark.parametrize(
    "call, match",
    [
        (lambda s, g, m: s.add_distance_joint(g, m, -1.0), "distance must be positive"),
        (lambda s, g, m: s.add_spring_damper(g, m, stiffness=-1.0), "stiffness and damping"),
        (lambda s, g, m: s.add_spring_damper(g, m, stiffness=1.0, damping=float("nan")), "finite"),
        (lambda s, g, m: s.add_point_force(m, (1.0, 2.0)), "three components"),
        (lambda s, g, m: s.add_point_force(m, (1.0, 2.0, 3.0), frame="body"), "frame must be"),
        (lambda s, g, m: s.add_point_force(m, (1.0, "x", 3.0)), "expected a number"),
        (lambda s, g, m: s.add_sensor(m, "speed"), "unknown quantity 'speed'"),
        (lambda s, g, m: s.add_angle_driver(g, m, float("nan")), "finite"),
        (lambda s, g, m: s.add_callback_force([s.ground], lambda t, q, qd: q), "ground"),
        (lambda s, g, m: s.add_callback_force([fm.BodyId(1)], 3.0), "callable"),
        (lambda s, g, m: fm.Spline([0.0, 1.0, 1.0], [0.0, 1.0, 2.0]), "increase strictly"),
        (lambda s, g, m: fm.GeneralizedAlpha(1.2), "spectral_radius"),
        (lambda s, g, m: fm.GeneralizedAlpha(0.9, jacobian="sometimes"), "jacobian must be"),
    ],
)
def test_bad_parameters(system, call, match):
    s, body = system
    ground, marker = s.add_marker(s.ground), s.add_marker(body, position=(1, 0, 0))
    with pytest.raises(fm.ModelError, match=match):
        call(s, ground, marker)


def test_duplicate_names_are_rejected(system):
    s, _ = system
    with pytest.raises(fm.InvalidModelError, match="another body already has this name"):
        s.add_rigid_body(1.0, (1, 1, 1), name="link")


def test_bad_simulation_settings(system):
    s, _ = system
    with pytest.raises(fm.InvalidParameterError, match="end time"):
        fm.simulate(s, -1.0, 1e-3)
    with pytest.raises(fm.InvalidParameterError, match="step_size must be above zero"):
        fm.simulate(s, 1.0, 0.0)
    with pytest.raises(fm.InvalidParameterError, match="output_interval must be above zero"):
        fm.simulate(s, 1.0, 1e-3, output_interval=-0.1)
    # Output times finer than the run can resolve (they used to hang the output clock).
    for tiny, match in ((1e-300, "time resolution"), (1e-10, "minimum step size")):
        started = time.perf_counter()
        with pytest.raises(fm.InvalidParameterError, match=match):
            fm.simulate(s, 1.0, 1e-3, output_interval=tiny)
        assert time.perf_counter() - started < 1.0


def test_inconsistent_initial_positions_name_the_joint():
    # A body pinned at the origin cannot also reach a ground point 5 m away with a marker 1 m
    # from its pin.
    s = fm.System()
    body = s.add_rigid_body(1.0, (1, 1, 1))
    s.add_revolute_joint(s.add_marker(s.ground), s.add_marker(body), name="pin")
    s.add_spherical_joint(
        s.add_marker(s.ground, position=(5, 0, 0)),
        s.add_marker(body, position=(1, 0, 0)),
        name="unreachable",
    )
    with pytest.raises((fm.InitialConditionsError, fm.SingularMatrixError)) as info:
        fm.simulate(s, 1.0, 1e-3)
    assert "unreachable" in str(info.value) or "singular" in str(info.value)
    assert info.value.time == 0.0
    assert info.value.result is not None and len(info.value.result) == 0


def test_a_four_bar_that_cannot_close_names_its_joints_not_a_normalization():
    # Ground pivots 5 m apart, links of 1 m: the loop cannot close. The corrections' compromise
    # also leaves Euler parameters unnormalized, and the error blamed "Euler-parameter
    # normalization of body 'rocker'"; it now names the joints left open.
    s = fm.System()
    bodies = {}
    for name, centre in (("crank", (0, 0.5, 0)), ("coupler", (0.5, 1, 0)), ("rocker", (5, 0.5, 0))):
        bodies[name] = s.add_rigid_body(1.0, (0.01, 0.1, 0.1), position=centre, name=name)
    crank, coupler, rocker = bodies.values()
    ends = [
        (s.add_marker(s.ground), s.add_marker(crank, position=(0, -0.5, 0))),
        (s.add_marker(crank, position=(0, 0.5, 0)), s.add_marker(coupler, position=(-0.5, 0, 0))),
        (s.add_marker(coupler, position=(0.5, 0, 0)), s.add_marker(rocker, position=(0, 0.5, 0))),
        (s.add_marker(s.ground, position=(5, 0, 0)), s.add_marker(rocker, position=(0, -0.5, 0))),
    ]
    for name, (a, b) in zip("ABCD", ends, strict=True):
        s.add_revolute_joint(a, b, name=name)
    s.add_angle_driver(*ends[0], fm.Polynomial([0.0, 1.0]), name="drive")
    with pytest.raises(fm.InitialConditionsError) as info:
        fm.simulate(s, 0.1, 1e-3)
    message = str(info.value)
    assert re.search(r"t = 0: joint '[BCD]' \(revolute\)", message), message
    assert "normalization" not in message


def test_slightly_inconsistent_initial_positions_are_corrected(assert_close):
    s = fm.System(gravity=(0.0, -9.81, 0.0))
    mass = s.add_point_mass(1.0, position=(1.02, 0.01, 0.0))
    s.add_distance_joint(s.add_marker(s.ground), s.add_marker(mass), 1.0)
    result = fm.simulate(s, 0.1, 1e-3, output_interval=0.05)
    assert_close(np.linalg.norm(result.position(mass)[0]), 1.0, abs=1e-11, what="distance")


def test_redundant_constraints_are_reported_or_refused():
    # Two revolute joints on the same axis: five of their ten equations are redundant. By
    # default they are removed and reported; with redundant_constraints="error" the model is
    # refused with both joints named.
    s = fm.System()
    body = s.add_rigid_body(1.0, (1, 1, 1))
    for name in ("first", "second"):
        s.add_revolute_joint(s.add_marker(s.ground), s.add_marker(body), name=name)
    result = fm.simulate(s, 0.1, 1e-3)
    assert len(result.redundancy["removed_rows"]) == 5
    assert result.events[0]["kind"] == "redundant constraints"
    message = "5 of 11 constraint equations are redundant"
    with pytest.raises(fm.InvalidModelError, match=message) as info:
        fm.simulate(s, 0.1, 1e-3, solver=fm.GeneralizedAlpha(redundant_constraints="error"))
    assert "'first'" in str(info.value) and "'second'" in str(info.value)
    with pytest.raises(fm.InvalidParameterError, match="redundant"):
        fm.GeneralizedAlpha(redundant_constraints="ignore")


def stiffening(threshold):
    def force(t, q, qd):
        k = 1.0 if t < threshold else 1e4
        return -k * q**5

    return force


def test_diverging_newton_names_time_and_item_and_keeps_results(assert_close):
    s = fm.System()
    body = s.add_point_mass(1.0, position=(1.0, 0, 0), name="bob")
    s.add_callback_force([body], stiffening(0.52), name="hardening")
    solver = fm.GeneralizedAlpha(0.9, step_control="fixed")
    with pytest.raises(fm.NewtonDivergedError, match="body 'bob' coordinate x") as info:
        fm.simulate(s, 2.0, 0.05, solver=solver)
    error = info.value
    assert 0.5 <= error.time < 1.0  # the spring stiffens at 0.52 s
    result = error.result
    assert not result.success and result.error is error
    # Every step before the failing one is kept.
    assert_close(result.time[-1], error.time, rel=1e-6, abs=1e-12, what="last time")
    assert len(result) == round(error.time / 0.05) + 1
    assert np.all(np.isfinite(result.coordinates))


def test_callback_errors_are_chained_and_keep_results(assert_close):
    s = fm.System()
    body = s.add_point_mass(1.0)

    def force(t, q, qd):
        if t > 0.05:
            raise ZeroDivisionError("user bug")
        return np.zeros(3)

    s.add_callback_force([body], force, name="user")
    with pytest.raises(fm.CallbackError, match="force 'user'.*ZeroDivisionError: user bug") as info:
        fm.simulate(s, 1.0, 0.01)
    assert isinstance(info.value.__cause__, ZeroDivisionError)
    assert_close(info.value.result.time[-1], 0.05, rel=1e-6, abs=1e-12, what="last time")


def test_callback_of_wrong_shape_and_nan():
    s = fm.System()
    body = s.add_point_mass(1.0)
    s.add_callback_force([body], lambda t, q, qd: np.zeros(2), name="short")
    with pytest.raises(fm.CallbackError, match="returned 2 values, expected 3"):
        fm.simulate(s, 0.1, 0.01)
    s = fm.System()
    body = s.add_point_mass(1.0)
    s.add_callback_force([body], lambda t, q, qd: np.full(3, np.nan), name="nan")
    with pytest.raises(fm.NonFiniteError, match="force 'nan'"):
        fm.simulate(s, 0.1, 0.01)


def test_driver_function_errors_name_the_joint():
    s = fm.System()
    body = s.add_rigid_body(1.0, (1, 1, 1))
    g, m = s.add_marker(s.ground), s.add_marker(body)
    s.add_revolute_joint(g, m)
    s.add_angle_driver(g, m, lambda t: 1.0 / (0.05 - t) if t < 0.05 else float("nan"), name="drive")
    with pytest.raises((fm.NonFiniteError, fm.NewtonDivergedError)) as info:
        fm.simulate(s, 1.0, 0.01, solver=fm.GeneralizedAlpha(step_control="fixed"))
    assert info.value.result is not None


def test_ctrl_c_stops_cleanly_and_keeps_results():
    model = fm.examples.four_bar(20).system.compile()
    timer = threading.Timer(0.3, lambda: os.kill(os.getpid(), signal.SIGINT))
    timer.start()
    try:
        with pytest.raises(fm.SimulationInterrupted) as info:
            fm.simulate(model, 100.0, 1e-3, output_interval=0.01)
    finally:
        timer.cancel()
    result = info.value.result
    assert 0 < result.time[-1] < 100.0
    assert isinstance(info.value.__cause__, KeyboardInterrupt)
    assert result.constraint_violation.max() < 1e-8


def test_ctrl_c_stops_cleanly_also_where_sigint_was_left_at_its_default_action():
    # gmsh.initialize() sets SIGINT to the system's default, which ends the process at once:
    # a run after meshing with Gmsh lost everything to a Ctrl-C. The run takes Ctrl-C as
    # KeyboardInterrupt and puts the default back after. (Without this, the signal below ends
    # the test session.)
    model = fm.examples.four_bar(20).system.compile()
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    timer = threading.Timer(0.3, lambda: os.kill(os.getpid(), signal.SIGINT))
    timer.start()
    try:
        with pytest.raises(fm.SimulationInterrupted) as info:
            fm.simulate(model, 100.0, 1e-3, output_interval=0.01)
        assert signal.getsignal(signal.SIGINT) == signal.SIG_DFL
    finally:
        timer.cancel()
        signal.signal(signal.SIGINT, signal.default_int_handler)
    assert 0 < info.value.result.time[-1] < 100.0


def test_progress_callback_is_called_and_its_exception_is_a_callback_error(assert_close):
    # Regression (issue 28): an exception of the progress function ended the run as
    # SimulationInterrupted, as if the user had pressed Ctrl-C.
    seen = []

    def progress(time, step, iterations):
        seen.append(time)
        if len(seen) == 2:
            raise RuntimeError("enough")

    example = fm.examples.four_bar(20)
    with pytest.raises(fm.CallbackError, match="progress function.*RuntimeError: enough") as info:
        fm.simulate(example.system, 100.0, 1e-3, output_interval=0.01, progress=progress)
    assert len(seen) == 2 and seen[0] < seen[1]
    assert isinstance(info.value.__cause__, RuntimeError)
    assert_close(info.value.time, seen[1], rel=1e-6, abs=1e-12, what="error time")
    assert len(info.value.result.time) > 1


def test_newton_step_control_recovers_where_a_fixed_step_fails(assert_close):
    s = fm.System()
    body = s.add_point_mass(1.0, position=(1.0, 0, 0), name="bob")
    s.add_callback_force([body], stiffening(0.52), name="hardening")
    result = fm.simulate(s, 2.0, 0.05, output_interval=0.05)
    stats = result.statistics
    assert result.success and stats["rejected_steps"] > 0
    assert stats["min_step_size"] < 0.05
    assert_close(result.time[-1], 2.0, rel=1e-6, abs=1e-12, what="last time")


@pytest.mark.parametrize(
    "make, match",
    [
        (
            lambda: fm.GeneralizedAlpha(max_iterations=-1),
            "max_iterations must be an integer >= 1, got -1",
        ),
        (lambda: fm.GeneralizedAlpha(max_iterations="12"), "max_iterations .* got '12' \\(str\\)"),
        (lambda: fm.ExplicitSolver("rk4", max_iterations=0), "max_iterations .* got 0"),
        (lambda: fm.BodyId(-1), "BodyId index must be an integer >= 0, got -1"),
        (lambda: fm.JointId(2**70), "JointId index .* got 1180591620717411303424"),
    ],
)
def test_negative_and_mistyped_integers_name_the_parameter(make, match):
    # Regression (issue 28): OverflowError "can't convert negative int to unsigned" or a
    # TypeError, without the parameter's name.
    with pytest.raises(fm.InvalidParameterError, match=match):
        make()


@pytest.mark.parametrize(
    "make, match, item",
    [
        (lambda s, m: s.add_spherical_joint(1.5, m), "add_spherical_joint.*'marker1'", "marker1"),
        (lambda s, m: s.add_marker(fm.BodyId(1), name=3), "add_marker.*'name'", "name"),
        (lambda s, m: s.add_rigid_body(mass="1", inertia=(1, 1, 1)), "'mass'", "mass"),
        (lambda s, m: fm.fe.Material("steel", 0.3, 7850.0), "Material.*'young_modulus'", None),
        (lambda s, m: fm.Harmonic(1.0, "fast"), "Harmonic.*'frequency'", "frequency"),
        (lambda s, m: fm.GeneralizedAlpha(relative_tolerance=[1e-6]), "relative_tolerance", None),
        (lambda s, m: fm.fe.Section.rectangle("b", 0.1), "Section.rectangle.*'b'", "b"),
        (lambda s, m: s.add_sensor(m, quantity=3), "add_sensor.*'quantity'", "quantity"),
    ],
)
def test_arguments_of_the_wrong_type_name_the_call_and_the_parameter(system, make, match, item):
    # Regression (issue 28): PyO3's TypeError ("'float' object is not an instance of
    # 'MarkerId'", "must be real number, not str") named no parameter.
    s, body = system
    marker = s.add_marker(body)
    with pytest.raises(fm.ArgumentTypeError, match=match) as raised:
        make(s, marker)
    assert isinstance(raised.value, TypeError) and isinstance(
        raised.value, fm.InvalidParameterError
    )
    if item is not None:
        assert raised.value.item == item


def test_a_field_of_the_wrong_type_is_named_and_a_bad_value_refused_at_simulate(system):
    settings = fm.GeneralizedAlpha()
    with pytest.raises(fm.ArgumentTypeError, match="newton_tolerance"):
        settings.newton_tolerance = "tight"
    settings.max_step_size = float("nan")
    with pytest.raises(fm.InvalidParameterError, match="max_step_size must be a finite number"):
        fm.simulate(system[0], 0.01, 1e-3, solver=settings)


@pytest.mark.parametrize(
    "make, match",
    [
        (lambda: fm.GeneralizedAlpha(newton_tolerance=0.0), "newton_tolerance .* got 0"),
        (
            lambda: fm.GeneralizedAlpha(newton_error_fraction=1.0),
            r"newton_error_fraction must be in \[0, 1\), got 1",
        ),
        (lambda: fm.GeneralizedAlpha(newton_error_fraction=float("nan")), "newton_error_fraction"),
        (lambda: fm.GeneralizedAlpha(relative_tolerance=float("nan")), "relative_tolerance"),
        (lambda: fm.GeneralizedAlpha(max_step_size=-1.0), "max_step_size .* got -1"),
        (lambda: fm.GeneralizedAlpha(min_step_size=1e-2, max_step_size=1e-3), "min_step_size"),
        (lambda: fm.ExplicitSolver(absolute_tolerance=float("inf")), "absolute_tolerance"),
        (lambda: fm.ExplicitSolver(repartition_ratio=1.0), "repartition_ratio .* > 1, got 1"),
        (lambda: fm.ExplicitSolver(singular_factor=0.5), "singular_factor"),
        (lambda: fm.ExplicitSolver(drift_threshold=-1e-6), "drift_threshold"),
    ],
)
def test_solver_settings_out_of_range_name_the_setting(make, match):
    # Regression (issue 28): NaN, infinite and negative tolerances and step bounds were
    # accepted, refused later without a name, or ignored (max_step_size NaN or -1).
    with pytest.raises(fm.InvalidParameterError, match=match):
        make()


def test_huge_settings_are_shown_in_scientific_notation(system):
    solver = fm.GeneralizedAlpha(min_step_size=1e300)
    with pytest.raises(fm.InvalidParameterError) as raised:
        fm.simulate(system[0], 0.01, 1e-3, solver=solver)
    assert "1e300" in str(raised.value) and "0" * 25 not in str(raised.value)


def test_unknown_items_are_named_in_the_singular():
    result = fm.simulate(pendulum_system(), 0.01, 1e-3)
    with pytest.raises(fm.UnknownItemError, match=r"^body 5 does not exist \(the model has 2"):
        result.position(5)
    with pytest.raises(fm.UnknownItemError, match="no joint named 'hinge'"):
        result.reaction("hinge")


def pendulum_system() -> fm.System:
    system = fm.System(gravity=(0, -9.81, 0))
    mass = system.add_point_mass(1.0, position=(1, 0, 0), name="bob")
    system.add_distance_joint(system.add_marker(system.ground), system.add_marker(mass))
    return system


FOREVER = """
import flexmbd as fm
system = fm.System(gravity=(0, -9.81, 0))
mass = system.add_point_mass(1.0, position=(1, 0, 0))
system.add_distance_joint(system.add_marker(system.ground), system.add_marker(mass))
tight = {"relative_tolerance": 1e-300, "absolute_tolerance": 1e-300, "min_step_size": 1e-300}
solvers = (fm.GeneralizedAlpha(step_control="error", **tight), fm.ExplicitSolver("dopri5", **tight))
for solver in solvers:
    try:
        fm.simulate(system, 1.0, 1e-3, solver=solver)
    except fm.StepSizeTooSmallError as error:
        print("stopped:", error)
"""


def test_a_step_below_the_round_off_of_the_time_is_a_step_size_error():
    # Regression (issue 28): min_step_size 1e-300 with impossible tolerances looped for ever
    # with steps that no longer advanced t. Run apart, so that a regression cannot hang the
    # suite.
    run = subprocess.run(
        [sys.executable, "-c", FOREVER], capture_output=True, text=True, timeout=120
    )
    assert run.returncode == 0, run.stderr
    lines = run.stdout.splitlines()
    assert len(lines) == 2 and all("fell below the minimum 1.421e-14" in line for line in lines)
    with pytest.raises(fm.InvalidParameterError, match="below the round-off of the times"):
        fm.simulate(pendulum_system(), 1.0, 1e-300)


def test_malformed_low_level_body_data_is_a_typed_error_not_a_panic():
    # Regression (issue 28): column pointers out of range and node positions of two columns
    # made the Rust binding panic ("range end index 5 out of range", "index out of bounds").
    from flexmbd import _core

    def csc(data, indices, pointers, n):
        return (
            np.asarray(data, float),
            np.asarray(indices, np.int64),
            np.asarray(pointers, np.int64),
            n,
        )

    good = csc([1.0] * 3, [0, 1, 2], [0, 1, 2, 3], 3)
    base = {
        "mass": 1.0,
        "first_moment": (0, 0, 0),
        "second_moment": np.eye(3),
        "i1": np.zeros((3, 3)),
        "ibar": np.zeros((9, 3)),
        "i_kl": [good] * 9,
        "stiffness": good,
        "damping": good,
    }
    cases = {
        "inconsistent sparse storage": {"stiffness": csc([1.0] * 3, [0, 1, 2], [0, 1, 5, 3], 3)},
        "3 column pointers for 3 columns": {"damping": csc([1.0] * 3, [0, 1, 2], [0, 1, 3], 3)},
        r"node positions must be \(n, 3\)": {
            "dof_nodes": np.array([0, 1, 2]),
            "node_positions": np.zeros((3, 2)),
        },
    }
    for match, changes in cases.items():
        with pytest.raises(fm.InvalidParameterError, match=match):
            _core.System()._add_flexible_body(**{**base, **changes})
    with pytest.raises(fm.InvalidParameterError, match="inconsistent CSC arrays"):
        _core.SymmetricFactor(3, np.array([0, 2, 1, 3]), np.array([0, 1, 2]), np.ones(3))


@pytest.mark.parametrize(
    "arguments, match",
    [
        ({"end_time": "1"}, r"end_time must be a number, got '1' \(str\)"),
        ({"end_time": float("nan")}, "end_time must be finite, got nan"),
        ({"step_size": [1e-3, 2e-3]}, r"step_size must be a number, got \[0.001, 0.002\]"),
        ({"step_size": np.array(["a"])}, "step_size must be a number"),
        ({"start_time": fm.BodyId(0)}, "start_time must be a number"),
        ({"start_time": 1e308}, "end time 0.01 is before start time 1e[+]308"),
        ({"output_interval": "0.1"}, "output_interval must be a number"),
        ({"initial_conditions": np.array(["correct", "strict"])}, "initial_conditions must be"),
        ({"keep_in_memory": 1.0}, "keep_in_memory must be True or False"),
        ({"results_file": 3.5}, "results_file must be a path"),
        ({"results_file": "r.h5", "protect": float("nan")}, "protect must be a tuple of paths"),
    ],
)
def test_simulate_names_the_argument_of_the_wrong_type(arguments, match, tmp_path):
    # Regression (fuzz suite): TypeError or ValueError from the binding or pathlib without the
    # parameter's name; a start time of 1e308 printed with 309 digits.
    arguments = {"end_time": 0.01, "step_size": 1e-3, **arguments}
    if "results_file" in arguments and isinstance(arguments["results_file"], str):
        arguments["results_file"] = tmp_path / arguments["results_file"]
    with pytest.raises(fm.InvalidParameterError, match=match) as caught:
        fm.simulate(pendulum_system(), **arguments)
    assert len(str(caught.value)) < 200


def test_result_and_state_accessors_name_the_argument_of_the_wrong_type():
    # Regression (fuzz suite): IndexError, OverflowError, ValueError and TypeError from NumPy.
    result = fm.simulate(pendulum_system(), 0.003, 1e-3)
    with pytest.raises(fm.InvalidParameterError, match="record index 1180591620717411303424"):
        result.state(2**70)
    with pytest.raises(fm.InvalidParameterError, match=r"index must be an integer, got nan"):
        result.state(float("nan"))
    state = result.state()
    with pytest.raises(fm.InvalidParameterError, match="position must be numbers"):
        state.with_position("bob", ["a", "b", "c"])
    with pytest.raises(fm.InvalidParameterError, match="time must be a number"):
        fm.State([1.0], state.coordinates, state.velocities)
    with pytest.raises(fm.InvalidParameterError, match="coordinates must be numbers"):
        fm.State(0.0, np.array(["a"] * 4), state.velocities)
    with pytest.raises(fm.InvalidParameterError, match="time must be a number"):
        fm.equilibrium(pendulum_system(), lambda t: t)


def test_node_ids_of_the_wrong_type_or_size_are_named():
    # Regression (fuzz suite): a node id of 2**70 raised OverflowError, "a" ValueError, a
    # float or a nested list TypeError.
    from flexmbd import fe

    nodes, elements = fe.straight_beam(0.5, 2)
    beam = fe.build_body(
        nodes,
        elements,
        fe.Material(7e10, 0.33, 2700.0),
        section=fe.Section.circle(0.01),
        reference="clamped",
        reference_nodes=[0],
    )
    system = fm.System()
    body = system.add_flexible_body(beam, name="beam")
    result = fm.simulate(system, 0.002, 1e-3)
    with pytest.raises(fm.UnknownItemError, match=r"no nodes with ids \[1180591620717411303424\]"):
        result.node_displacements(body, [2**70])
    for nodes, match in (("a", "nodes must be an integer"), ([1.5], "nodes must be an integer")):
        with pytest.raises(fm.InvalidParameterError, match=match):
            result.node_positions(body, nodes)
    with pytest.raises(fm.InvalidParameterError, match="nodes must be a node id or a list"):
        result.node_displacements(body, [[1, 2]])
    with pytest.raises(fm.InvalidParameterError, match="node must be an integer"):
        result.deflection(body, [2])


@pytest.mark.parametrize(
    "values, item",
    [
        # PyO3 took a bool as 0 or 1: Material(True, ...) was a material of E = 1 Pa.
        ((True, 0.3, 7800.0), "young_modulus"),
        ((2e11, False, 7800.0), "poisson_ratio"),
        ((2e11, 0.3, "7800"), "density"),
    ],
)
def test_material_values_that_are_not_numbers_are_named(values, item):
    with pytest.raises(fm.ArgumentTypeError, match=f"Material: argument '{item}': must be") as e:
        fm.fe.Material(*values)
    assert e.value.item == item


def test_a_bool_is_not_a_section_value():
    with pytest.raises(TypeError, match="must be a real number, not bool") as raised:
        fm.fe.Section(1e-4, True, 1e-8, 2e-8)
    assert "while processing 'iy'" in getattr(raised.value, "__notes__", ())


@pytest.mark.parametrize(
    "make, match",
    [
        (lambda: fm.fe.Section.circle(-0.01), "circle radius must be positive and finite"),
        (lambda: fm.fe.Section.circle(0.0), "circle radius must be positive"),
        (lambda: fm.fe.Section.rectangle(-0.02, -0.01), "rectangle width must be positive"),
        (lambda: fm.fe.Section.rectangle(0.02, float("inf")), "rectangle height must be positive"),
        (lambda: fm.fe.Section.tube(0.01, -0.005), "0 <= inner < outer"),
    ],
)
def test_section_shapes_of_negative_size_are_refused(make, match):
    # A negative radius or width gives a positive area and positive second moments: wrong
    # numbers that look right, so the shape's lengths themselves are checked.
    with pytest.raises(fm.InvalidParameterError, match=match):
        make()


@pytest.mark.parametrize(
    "orientation, error, match",
    [
        # One orientation for all beams: checked (and named) before the elements.
        ((float("nan"), 0.0, 0.0), fm.InvalidParameterError, "orientation must be one vector"),
        ((0.0, 0.0, 0.0), fm.InvalidParameterError, "orientation must not be the zero vector"),
        ((2.0, 0.0, 0.0), fm.InvalidModelError, "element 1: .*is parallel to the beam axis"),
    ],
)
def test_a_bad_beam_orientation_names_the_element(orientation, error, match):
    nodes = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    with pytest.raises(error, match=match):
        fm.fe.build_body(
            nodes,
            {"beam2": np.array([[0, 1]])},
            fm.fe.Material(7e10, 0.3, 2700.0),
            section=fm.fe.Section.circle(0.01),
            orientation=orientation,
        )


def test_missing_files_are_flexmbd_errors_and_file_not_found_errors(tmp_path):
    # They were bare FileNotFoundErrors, which `except fm.FlexmbdError` let through.
    from flexmbd.fe import load_body, read_mesh

    missing = tmp_path / "nothing.h5"
    for read in (fm.read_results, load_body, read_mesh):
        with pytest.raises(fm.MissingFileError, match="No such .* file") as raised:
            read(missing)
        assert isinstance(raised.value, fm.FlexmbdError)
        assert isinstance(raised.value, FileNotFoundError)
        assert raised.value.filename == raised.value.item == str(missing)


def test_straight_beam_refuses_a_fractional_element_count():
    # straight_beam(1, 4.5) was a raw TypeError from numpy.
    from flexmbd.fe import straight_beam

    with pytest.raises(fm.InvalidParameterError, match="elements must be an integer, got 4.5"):
        straight_beam(1.0, 4.5)
    with pytest.raises(fm.InvalidParameterError, match="length must be a number"):
        straight_beam("1", 3)
    nodes, elements = straight_beam(2.0, 4)
    assert nodes[-1].tolist() == [2.0, 0.0, 0.0] and elements["beam2"].shape == (4, 2)


def test_the_initial_correction_reports_how_far_a_body_moved():
    # A bob given at 1.5 m on a 1 m rod moves 0.5 m; the event said 3.333e-1 (the change
    # relative to the given coordinate), which the threshold uses, not what the user sees.
    system = fm.System(gravity=(0.0, -9.81, 0.0))
    bob = system.add_point_mass(1.0, position=(1.5, 0.0, 0.0), name="bob")
    system.add_distance_joint(system.add_marker(system.ground), system.add_marker(bob), 1.0)
    with pytest.warns(fm.InitialCorrectionWarning, match="move its position by up to 5.000e-1"):
        fm.simulate(system, 0.01, 1e-3)


def test_a_heavy_body_on_a_joint_is_not_singular(assert_close):
    # A 200 t body of inertia (2e6, 2e7, 2e7) kg m^2 on one revolute joint stopped at t = 0
    # with "no pivot" (its multipliers' pivots, C M^-1 C^T ~ 5e-8, were under 1e-15 of the
    # mass matrix's largest entry); the same body 1000 times lighter ran. Gravity alone moves
    # both alike.
    def pendulum(scale):
        system = fm.System(gravity=(0.0, -9.81, 0.0))
        inertia = (2e6 * scale, 2e7 * scale, 2e7 * scale)
        load = system.add_rigid_body(2e5 * scale, inertia, position=(5.0, 0.0, 0.0), name="load")
        hinge = system.add_marker(load, position=(-5.0, 0.0, 0.0))
        system.add_revolute_joint(system.add_marker(system.ground), hinge, name="hinge")
        return fm.simulate(system, 0.05, 1e-3)

    heavy, light = pendulum(1.0), pendulum(1e-3)
    assert_close(heavy.position("load"), light.position("load"), abs=1e-9, what="same motion")
    assert heavy.position("load")[-1][1] < -1e-3


@pytest.mark.parametrize(
    "make, owner, item",
    [
        (
            lambda: fm.Spline([0, 1, 2], [0, 1, 2], end="clamped", slopes=(1, 2, 3)),
            "Spline",
            "slopes",
        ),
        (
            lambda: fm.ExplicitSolver("rk4", "integrate-all", baumgarte=(1, 2, 3)),
            "ExplicitSolver",
            "baumgarte",
        ),
    ],
)
def test_a_tuple_of_the_wrong_length_names_the_call_and_the_argument(make, owner, item):
    # Regression: PyO3's bare ValueError "expected tuple of length 2" named nothing.
    with pytest.raises(
        fm.InvalidParameterError, match=f"{owner}: argument '{item}': expected"
    ) as e:
        make()
    assert e.value.item == item
