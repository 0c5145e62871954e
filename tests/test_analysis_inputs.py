"""Arguments of the linear analyses (equilibrium, linearize, state-space models, mode
animations, Campbell diagrams, ``flexmbd modes``) that are wrong end in a typed flexmbd error
naming them, never in a raw TypeError, ValueError, IndexError or AttributeError, nor in a
silently wrong result. One regression test per fault a review found; the comments say what
happened before."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

import flexmbd as fm
from flexmbd.campbell import CampbellDiagram
from flexmbd.cli import main
from flexmbd.errors import ArgumentTypeError, InvalidParameterError, UnknownItemError
from flexmbd.fe import Material, Section
from flexmbd.model_file import load_model
from flexmbd.state_space import mode_result

MODELS = Path(__file__).resolve().parents[1] / "examples" / "models"


def rod():
    """A rigid rod (2 kg, 1.2 m) hanging from a hinge on the ground; its marker at the hinge."""
    system = fm.System(gravity=(0, -9.81, 0))
    turned = np.array([[0, 1, 0], [-1, 0, 0], [0, 0, 1]])
    body = system.add_rigid_body(
        2.0, (1e-4, 0.24, 0.24), position=(0, -0.6, 0), orientation=turned, name="rod"
    )
    top = system.add_marker(body, position=(-0.6, 0, 0))
    system.add_revolute_joint(system.add_marker(system.ground), top, name="hinge")
    return system, body, top


def pendulum(length):
    """A point mass on a distance joint of `length` below the ground's origin."""
    system = fm.System(gravity=(0, -9.81, 0))
    bob = system.add_point_mass(1.0, position=(0, -length, 0), name="bob")
    system.add_distance_joint(system.add_marker(system.ground), system.add_marker(bob), name="rod")
    return system


@pytest.fixture(scope="module")
def hanging():
    """The rod, its equilibrium and its linearization."""
    system, body, top = rod()
    state = fm.equilibrium(system)
    return system, body, top, state, fm.linearize(system, state)


def test_body_position_outputs_of_the_ground_or_a_marker_are_refused(hanging):
    # Both gave the row of the rod: the ground's output was the rod's position, and the
    # marker's index 1 was read as body 1. All three rows of C were equal.
    system, body, top, state, _ = hanging
    rows = fm.linearize(system, state, outputs=[fm.BodyPosition(body, (1, 0, 0))])
    assert rows.state_space().c.shape == (1, 2)
    with pytest.raises(InvalidParameterError, match="ground, which does not move") as caught:
        fm.linearize(system, state, outputs=[fm.BodyPosition(system.ground, (1, 0, 0))])
    assert caught.value.item == "ground"
    with pytest.raises(ArgumentTypeError, match="marker's id: pass the body"):
        fm.linearize(system, state, outputs=[fm.BodyPosition(top, (1, 0, 0))])
    with pytest.raises(InvalidParameterError, match="must be an integer"):
        fm.linearize(system, state, outputs=[fm.BodyPosition(1.0, (1, 0, 0))])


def test_a_state_of_another_system_is_refused():
    # A pendulum of 4 m linearized about the equilibrium of one of 1 m gave the 1 m
    # pendulum's frequency (0.498 Hz instead of 0.249 Hz).
    short, long = pendulum(1.0), pendulum(4.0)
    with pytest.raises(InvalidParameterError, match="another System") as caught:
        fm.linearize(long, fm.equilibrium(short))
    assert caught.value.item == "state"


def test_a_state_that_violates_the_constraints_is_refused(assert_close):
    # Coordinates moved off the joint (by hand, or of another model without an identity)
    # were linearized about as they were.
    system = pendulum(1.0)
    state = fm.equilibrium(system)
    moved = np.array(state.coordinates)
    moved[1] -= 0.5
    with pytest.raises(InvalidParameterError, match="joint 'rod' equation 'distance' by 0.5"):
        fm.linearize(system, dataclasses.replace(state, coordinates=moved))
    stray = dataclasses.replace(state, coordinates=moved, system_identity=None)
    with pytest.raises(InvalidParameterError) as caught:
        fm.linearize(system, stray)
    assert caught.value.item == "rod"
    # The states of the analyses and of a run are taken.
    frequency = np.sqrt(9.81) / (2 * np.pi)
    assert_close(fm.linearize(system, state).frequencies(), frequency, rel=1e-9)
    run = fm.simulate(system, 0.2, 1e-3)
    assert_close(fm.linearize(system, run.state(100)).frequencies(), frequency, rel=1e-6)


@pytest.mark.parametrize("name", ["coordinates", "velocities", "accelerations", "multipliers"])
def test_a_state_with_a_nan_is_refused_naming_its_part(hanging, name):
    # A NaN velocity at t = 0 reached the core: "NonFiniteError: non-finite value in the
    # equation of body 'rod' coordinate x at t = NaN".
    system, _, _, state, _ = hanging
    values = np.array(getattr(state, name), dtype=float)
    values[0] = np.nan
    with pytest.raises(InvalidParameterError, match=f"state's {name} must be finite") as caught:
        fm.linearize(system, dataclasses.replace(state, **{name: values}))
    assert caught.value.item == name


def test_a_state_off_the_velocity_constraints_or_the_equations_of_motion_is_refused(
    assert_close,
):
    # A hanging pendulum's equilibrium edited by hand was linearized as it was: with the bob
    # moving along its rod and turning about it (C_q q_dot = 2 rad/s), eigenvalues +-4.22i
    # for +-3.13i; with its multipliers zeroed (the whole weight, 9.81 N, unbalanced), the
    # gravity stiffness was lost: eigenvalues 0.
    system = pendulum(1.0)
    state = fm.equilibrium(system)
    velocities = np.array(state.velocities)
    velocities[1] = 1.0  # along the rod
    with pytest.raises(InvalidParameterError, match="velocity constraint of joint 'rod'") as caught:
        fm.linearize(system, dataclasses.replace(state, velocities=velocities))
    assert caught.value.item == "velocities"
    unbalanced = dataclasses.replace(state, multipliers=np.zeros_like(state.multipliers))
    with pytest.raises(InvalidParameterError, match="residual 9.81 in body 'bob'") as caught:
        fm.linearize(system, unbalanced)
    assert caught.value.item == "accelerations"
    accelerating = dataclasses.replace(state, accelerations=np.full(3, 5.0))
    with pytest.raises(InvalidParameterError, match="equations of motion"):
        fm.linearize(system, accelerating)
    # The state as found is taken: the pendulum's sqrt(g / l).
    assert_close(fm.linearize(system, state).frequencies(), np.sqrt(9.81) / (2 * np.pi), rel=1e-9)


def test_a_point_load_takes_its_marker_by_name(assert_close):
    # Outputs take names; a marker's name in a PointLoad reached System.add_point_force:
    # "argument 'marker': 'str' object is not an instance of 'MarkerId'".
    system = fm.System(gravity=(0, -9.81, 0))
    bob = system.add_rigid_body(1.0, (1e-3, 1e-3, 1e-3), position=(0, -1, 0), name="bob")
    pin = system.add_marker(bob, position=(0, 1, 0), name="pin")
    system.add_revolute_joint(system.add_marker(system.ground), pin, name="hinge")
    state = fm.equilibrium(system)
    named = fm.linearize(system, state, inputs=[fm.PointLoad("pin", (1, 0, 0))])
    by_id = fm.linearize(system, state, inputs=[fm.PointLoad(pin, (1, 0, 0))])
    # A unit force along x at the bob's pin: 1 N along x on the bob's origin coordinate.
    assert_close(named.input_forces[0, 0], 1.0, rel=1e-12, what="Q_x")
    assert_close(named.input_forces, by_id.input_forces, abs=1e-15, what="by name and by id")
    with pytest.raises(UnknownItemError, match="PointLoad: no marker named 'pen'") as caught:
        fm.linearize(system, state, inputs=[fm.PointLoad("pen", (1, 0, 0))])
    assert caught.value.item == "pen"
    with pytest.raises(ArgumentTypeError, match="PointLoad: marker must be a marker"):
        fm.linearize(system, state, inputs=[fm.PointLoad(bob, (1, 0, 0))])


def hub_with_blade():
    """A hub turned by the angle driver "spin" (1 rad/s from 0), a rigid blade on a hinge."""
    system = fm.System()
    hub = system.add_rigid_body(1.0, (1, 1, 1), name="hub")
    ground, turning = system.add_marker(system.ground), system.add_marker(hub)
    system.add_revolute_joint(ground, turning)
    system.add_angle_driver(ground, turning, fm.Polynomial([0, 1.0]), name="spin")
    blade = system.add_rigid_body(1.0, (1e-3, 0.1, 0.1), position=(1, 0, 0), name="blade")
    flap = np.array([[1, 0, 0], [0, 0, 1], [0, -1, 0]], float)
    system.add_revolute_joint(
        system.add_marker(hub, position=(0.5, 0, 0), orientation=flap),
        system.add_marker(blade, position=(-0.5, 0, 0), orientation=flap),
    )
    return system


def test_campbell_names_its_time_and_turns_the_rotor_to_it(assert_close):
    # time=nan blamed a Polynomial's coefficients; time=5 (the hub 5 rad on from the
    # initial configuration) advised "pass coordinates=", which campbell does not take, and
    # then was refused; now the hub and blade are turned to the driver's angle there, and the
    # diagram of this steady rotor is the one at time 0.
    system = hub_with_blade()
    with pytest.raises(InvalidParameterError, match="time must be finite") as caught:
        fm.campbell(system, "spin", [1.0, 2.0], modes=1, time=float("nan"))
    assert caught.value.item == "time"
    at_start = fm.campbell(system, "spin", [1.0, 2.0], modes=1, time=0.0).frequencies
    later = fm.campbell(system, "spin", [1.0, 2.0], modes=1, time=5.0).frequencies
    assert_close(later, at_start, rel=1e-7, what="frequencies at t = 5 s")


def test_mode_result_of_an_overdamped_system_says_it_has_no_oscillating_modes():
    # A slider on a spring (100 N/m) and damper (50 N s/m), 1 kg: s = -2.09, -47.9, no
    # oscillating mode; the message said "indices 0 to -1".
    along_x = np.array([[0, 0, 1], [0, 1, 0], [-1, 0, 0]], float)
    system = fm.System(gravity=(0, 0, 0))
    slider = system.add_rigid_body(1.0, (1, 1, 1), position=(1, 0, 0), name="slider")
    system.add_prismatic_joint(
        system.add_marker(system.ground, orientation=along_x),
        system.add_marker(slider, orientation=along_x),
    )
    ends = system.add_marker(system.ground), system.add_marker(slider)
    system.add_spring_damper(*ends, stiffness=100.0, damping=50.0, rest_length=1.0)
    linear = fm.linearize(system, fm.equilibrium(system))
    assert len(linear.frequencies()) == 0
    with pytest.raises(InvalidParameterError, match="has no oscillating modes") as caught:
        mode_result(linear, system, 0)
    assert "-1" not in str(caught.value) and caught.value.item == "mode"


def test_a_steady_rotation_is_a_state_of_its_system():
    # steady_rotation's state carried no system identity, so a state of another system's
    # steady rotation was not recognized; its unknown options were a raw TypeError.
    steel, strip = Material(2.1e11, 0.3, 7850.0), Section.rectangle(0.02, 0.01)
    spinning = fm.examples.rotating_beam(steel, strip, 1.0, 2, speed=5.0)
    state = fm.steady_rotation(spinning)
    assert state.system_identity == spinning._identity
    with pytest.raises(InvalidParameterError, match="unknown option 'stable'"):
        fm.steady_rotation(spinning, stable=True)
    with pytest.raises(InvalidParameterError, match="max_iterations must be an integer"):
        fm.steady_rotation(spinning, max_iterations=2.5)


@pytest.mark.parametrize(
    "options, name",
    [
        ({"max_iterations": "x"}, "max_iterations"),
        ({"max_iterations": 2.5}, "max_iterations"),
        ({"max_iterations": 0}, "max_iterations"),
        # NaN and -1 ran 100 iterations and raised EquilibriumError "no convergence".
        ({"tolerance": float("nan")}, "tolerance"),
        ({"tolerance": -1.0}, "tolerance"),
        ({"tolerance": "1e-9"}, "tolerance"),
        ({"coordinates": "abc"}, "coordinates"),
        ({"coordinates": [0.0, 1.0, 2.0]}, "coordinates"),
        ({"coordinates": [np.nan] * 7}, "coordinates"),
    ],
)
def test_equilibrium_options_are_checked(hanging, options, name):
    system = hanging[0]
    with pytest.raises(InvalidParameterError) as caught:
        fm.equilibrium(system, **options)
    assert caught.value.item == name


@pytest.mark.parametrize("model", [None, "pendulum", 3.0])
@pytest.mark.parametrize(
    "analysis", [fm.equilibrium, fm.linearize, fm.steady_rotation, fm.linearize_at_rest]
)
def test_what_is_not_a_model_is_refused(analysis, model):
    # equilibrium(None) and equilibrium("pendulum") raised AttributeError ('describe').
    with pytest.raises(ArgumentTypeError, match="must be a flexmbd.System"):
        analysis(model)


@pytest.mark.parametrize(
    "analysis", [fm.equilibrium, fm.linearize, fm.steady_rotation, fm.linearize_at_rest]
)
def test_a_loaded_model_file_is_told_to_pass_its_system(analysis):
    # AttributeError: 'ModelFile' object has no attribute 'describe'.
    loaded = load_model(MODELS / "overhung_rotor.yaml")
    with pytest.raises(ArgumentTypeError, match=r"got a ModelFile: pass its \.system"):
        analysis(loaded)
    with pytest.raises(ArgumentTypeError, match=r"pass its \.system"):
        fm.campbell(loaded, "spin", [0.0, 1.0])


@pytest.mark.parametrize(
    "arguments, item",
    [
        # A single load not in a list: TypeError "'PointLoad' object is not iterable".
        (lambda top: {"inputs": fm.PointLoad(top, (0, 1, 0))}, "inputs"),
        (lambda top: {"inputs": ["x"]}, "inputs[0]"),
        (lambda top: {"inputs": "x"}, "inputs"),
        # AttributeError: 'str' object has no attribute 'body'.
        (lambda top: {"outputs": ["x"]}, "outputs[0]"),
        (lambda top: {"outputs": fm.BodyPosition("rod", (1, 0, 0))}, "outputs"),
    ],
)
def test_inputs_and_outputs_must_be_lists_of_loads_and_outputs(hanging, arguments, item):
    system, _, top, state, _ = hanging
    with pytest.raises(ArgumentTypeError) as caught:
        fm.linearize(system, state, **arguments(top))
    assert caught.value.item == item


@pytest.mark.parametrize("index", [1.5, "1", None, True])
def test_an_elastic_coordinate_index_is_an_integer(index):
    # 1.5 gave IndexError from NumPy at linearize, "1" a TypeError.
    with pytest.raises(InvalidParameterError, match="index must be an integer"):
        fm.ElasticCoordinate("blade", index)
    assert fm.ElasticCoordinate("blade", np.int64(2)).index == 2


@pytest.mark.parametrize("floor", ["x", float("nan"), -1e-9, None])
def test_the_relative_floor_of_the_modes_is_a_number_at_least_zero(hanging, floor):
    # "x" raised TypeError; NaN silently left out every mode.
    linear = hanging[4]
    with pytest.raises(InvalidParameterError) as caught:
        linear.oscillating(relative_floor=floor)
    assert caught.value.item == "relative_floor"
    with pytest.raises(InvalidParameterError):
        linear.free_motions(relative_floor=floor)


def test_an_undamped_mode_has_a_damping_ratio_of_zero_not_minus_zero(hanging):
    # -Re s / |s| of Re s = 0 printed as "-0.".
    _, damping, _ = hanging[4].oscillating()
    assert np.all(damping == 0.0) and not np.any(np.signbit(damping))


@pytest.mark.parametrize(
    "options, item",
    [
        ({"mode": 1.5}, "mode"),  # IndexError from NumPy
        ({"mode": "0"}, "mode"),  # TypeError on '<='
        ({"mode": 0, "frames": -2}, "frames"),  # ValueError: negative dimensions
        ({"mode": 0, "frames": 2.5}, "frames"),
        ({"mode": 0, "amplitude": float("nan")}, "amplitude"),  # frames of NaN coordinates
        ({"mode": 0, "amplitude": 0.0}, "amplitude"),
        ({"mode": 5}, "mode"),
    ],
)
def test_mode_result_checks_its_mode_frames_and_amplitude(hanging, options, item):
    system, _, _, _, linear = hanging
    with pytest.raises(InvalidParameterError) as caught:
        mode_result(linear, system.compile(), **options)
    assert caught.value.item == item


def test_mode_result_refuses_what_is_not_a_model(hanging):
    linear = hanging[4]
    with pytest.raises(ArgumentTypeError, match="must be a flexmbd.System"):
        mode_result(linear, "rod", 0)


def test_frequency_response_at_an_undamped_resonance_is_inf_with_a_warning(hanging):
    # Exactly at an undamped eigenfrequency the solve returned a finite number of round-off.
    system, body, top, state, linear = hanging
    linear = fm.linearize(
        system,
        state,
        inputs=[fm.PointLoad(top, (1, 0, 0))],
        outputs=[fm.BodyPosition(body, (1, 0, 0))],
    )
    space = linear.state_space()
    eigenvalues = np.linalg.eigvals(space.a)
    resonance = float(np.max(np.abs(eigenvalues.imag))) / (2 * np.pi)
    with pytest.warns(fm.ResonanceWarning, match="Hz is an undamped eigenfrequency of the model"):
        response = space.frequency_response([0.5 * resonance, resonance])
    assert np.isfinite(response[0]).all() and np.isinf(response[1]).all()


@pytest.mark.parametrize("frequencies", [[np.nan], [1.0, np.inf]])
def test_frequency_response_at_a_frequency_that_is_not_finite_is_refused(hanging, frequencies):
    # A response of NaN came back.
    system, body, top, state, _ = hanging
    linear = fm.linearize(
        system,
        state,
        inputs=[fm.PointLoad(top, (1, 0, 0))],
        outputs=[fm.BodyPosition(body, (1, 0, 0))],
    )
    with pytest.raises(InvalidParameterError, match="frequencies must be finite"):
        linear.state_space().frequency_response(frequencies)


def diagram():
    """A Campbell diagram of one mode crossing the order-1 line."""
    speeds = np.array([0.0, 10.0, 20.0])
    return CampbellDiagram(
        speeds=speeds,
        frequencies=np.array([[2.0], [2.0], [2.0]]),
        damping=np.zeros((3, 1)),
        shapes=np.zeros((3, 1, 1)),
        mac=np.ones((3, 1)),
        driver="spin",
        frame="rotating",
        whirl=np.full((3, 1), None, dtype=object),
        whirl_ratio=np.zeros((3, 1)),
    )


@pytest.mark.parametrize("orders", ["x", [np.nan], [1.0, np.inf], None])
def test_critical_speeds_take_finite_orders(orders):
    # "x" raised ValueError from NumPy; NaN found no crossing, silently.
    with pytest.raises(InvalidParameterError) as caught:
        diagram().critical_speeds(orders=orders)
    assert caught.value.item == "orders"


def test_critical_speeds_of_one_order(assert_close):
    (found,) = diagram().critical_speeds(orders=1)
    assert_close(found["speed"], 4 * np.pi, rel=1e-12)


@pytest.mark.parametrize(
    "arguments",
    [
        ["--frames", "-2", "--animate", "1"],  # a traceback (negative dimensions)
        ["--count", "-3"],  # listed nothing
        ["--animate", "0"],
        ["--frames", "x"],
    ],
)
def test_the_modes_command_refuses_counts_that_are_not_positive(arguments, capsys):
    with pytest.raises(SystemExit) as caught:
        main(["modes", "pendulum", *arguments])
    assert caught.value.code == 2
    assert "expected a positive whole number" in capsys.readouterr().err


def test_the_modes_command_counts_one_mode_in_the_singular(capsys):
    # "four-bar: 1 oscillating modes about the static equilibrium".
    assert main(["modes", "four-bar", "--count", "1"]) == 0
    out = capsys.readouterr().out
    assert "four-bar: 1 oscillating mode about" in out
    assert " -0" not in out


def test_the_states_of_a_generalized_alpha_run_are_linearized():
    # Generalized-alpha holds the velocity constraints to its error only (2.6e-6 on this
    # model at h = 1e-3): the check of a state's motion refused 193 of the 201 records of the
    # flexible double pendulum as "changed by hand" at a limit of 1e-6.
    example = fm.examples.flexible_double_pendulum()
    result = fm.simulate(example.system, 0.1, 1e-3, output_interval=0.01)
    for k in range(len(result.time)):
        assert len(fm.linearize(example.system, result.state(k)).frequencies()) > 0


def test_a_follower_loaded_pendulum_beside_a_stiff_beam_keeps_its_frequencies(assert_close):
    # Ziegler's pendulum (two rigid links on rotational springs k, a follower force P at the
    # tip) in one model with an unconnected clamped steel beam: the beam's stiffness (2.6e9)
    # hid the follower load's asymmetry (0.1) from the symmetry test, and the symmetric
    # eigenproblem gave +-0.1266i and +-0.4837i for +-0.1481i and +-0.4775i (P = 0.1), and a
    # divergence at P = 0.205, where the pendulum is stable. Then, in the first-order problem,
    # the free motions' threshold (1e-11 of the largest singular value of K, 0.05) took one of
    # the pendulum's directions (0.038) for a free motion at P = 0.3: 0, 0 and +-0.2236i for
    # Ziegler's flutter, +-0.1512 +-0.2187i, and `stable` None (a "neutral" direction).
    from flexmbd.fe import build_body, straight_beam

    mass, length, k, rotary = 1.0, 1.0, 0.1, 1e-4

    def system(load):
        s = fm.System()
        inertia = [rotary] * 3
        b1 = s.add_rigid_body(2 * mass, inertia, position=(length, 0, 0))
        b2 = s.add_rigid_body(mass, inertia, position=(2 * length, 0, 0))
        ground, root = s.add_marker(s.ground), s.add_marker(b1, position=(-length, 0, 0))
        s.add_revolute_joint(ground, root)
        s.add_rotational_spring_damper(ground, root, stiffness=k)
        middle, end = s.add_marker(b1), s.add_marker(b2, position=(-length, 0, 0))
        s.add_revolute_joint(middle, end)
        s.add_rotational_spring_damper(middle, end, stiffness=k)
        s.add_point_force(s.add_marker(b2), [-load, 0.0, 0.0], frame="marker")
        nodes, beams = straight_beam(1.0, 20)
        data = build_body(
            nodes, beams, Material(2.1e11, 0.3, 7800.0), section=Section.circle(0.01),
            reference="clamped", reference_nodes=[0],
        )  # fmt: skip
        beam = s.add_flexible_body(data, position=(0, 0, 5.0))
        s.add_fixed_joint(s.add_marker(s.ground, position=(0, 0, 5.0)), s.add_marker(beam))
        return s

    def reference(load):
        # theta_1, theta_2 of the links: M theta_dd + K theta = 0 (the follower load's
        # stiffness P l [[-1, 1], [0, 0]] is not symmetric): s^2 the eigenvalues of -M^-1 K.
        m = mass * length**2 * np.array([[3.0, 1.0], [1.0, 1.0]]) + rotary * np.eye(2)
        stiffness = k * np.array([[2.0, -1.0], [-1.0, 1.0]]) + load * length * np.array(
            [[-1.0, 1.0], [0.0, 0.0]]
        )
        roots = np.sqrt(-np.linalg.eigvals(np.linalg.solve(m, stiffness)).astype(complex))
        return np.concatenate([roots, -roots])

    # Stable (two undamped pairs) below Ziegler's critical load, flutter above it (a pair
    # of complex roots with Re s > 0: one unstable direction).
    for load, stable in ((0.1, True), (0.205, True), (0.3, False)):
        s = system(load)
        state = fm.equilibrium(s, stable=False)
        values = fm.linearize(s, state).eigenvalues()[0]
        slow = values[np.abs(values) < 10]
        assert len(slow) == 4
        expected = reference(load)
        nearest = slow[np.argmin(np.abs(slow[None, :] - expected[:, None]), axis=1)]
        scale = 1e-6 * np.abs(expected)
        assert_close(nearest.real, expected.real, abs=scale, what=f"Re s at P = {load}")
        assert_close(nearest.imag, expected.imag, abs=scale, what=f"Im s at P = {load}")
        assert state.stable is stable
        assert state.unstable_directions == (0 if stable else 1)


@pytest.mark.parametrize("shape", [np.ones(3), np.full(7, np.nan)], ids=["size", "nan"])
def test_body_shapes_refuses_a_shape_that_is_not_one_of_the_model(shape):
    # A 3-entry shape raised numpy's "operands could not be broadcast"; NaN came back as NaN.
    from flexmbd.state_space import body_shapes

    s = fm.System()
    s.add_rigid_body(1.0, (1, 1, 1), name="b")
    with pytest.raises(InvalidParameterError, match="body_shapes: the shape must be 7 finite"):
        body_shapes(s.compile(), shape)
