"""Floquet analysis of periodic motions (`flexmbd.floquet`): the monodromy matrix from runs of
the model against the fundamental matrix of the linear periodic equation (Mathieu's, of a
pendulum on a shaken support, integrated by scipy), against exp(s T) of the eigenvalues of
`linearize` where the motion is steady, and the refusals."""

import numpy as np
import pytest
from scipy.optimize import linear_sum_assignment

import flexmbd as fm
from flexmbd.errors import ArgumentTypeError, InvalidParameterError
from flexmbd.fe import Material, Section, build_body, straight_beam
from flexmbd.floquet import NEUTRAL

GRAVITY, LENGTH = 9.81, 1.0  # (fm.examples.shaken_pendulum's defaults)


def largest_mismatch(values: np.ndarray, expected: np.ndarray) -> float:
    """The largest distance between `values` and `expected` paired one to one."""
    distance = np.abs(values[:, None] - expected[None, :])
    rows, columns = linear_sum_assignment(distance)
    return float(distance[rows, columns].max())


@pytest.mark.parametrize(
    ("amplitude", "rate", "upright", "stable"),
    [
        (0.05, 2 * np.sqrt(GRAVITY / LENGTH), False, False),  # parametric resonance
        (0.05, 3 * np.sqrt(GRAVITY / LENGTH), False, True),
        (0.05, 200.0, True, True),  # Kapitza: held upright, a^2 w^2 > 2 g L
        (0.01, 200.0, True, False),
    ],
    ids=["hanging at 2w0", "hanging at 3w0", "upright, fast", "upright, too small"],
)
def test_a_pendulum_on_a_shaken_support_has_mathieus_multipliers(amplitude, rate, upright, stable):
    # Frozen in time, the hanging pendulum is stable at every instant; shaken at twice its
    # frequency it grows (|mu| = 1.17), and the upright one is held by a fast shake.
    # Generalized-alpha's error is second order: 2.4e-6 at 400 steps a period, 2e-7 at 1600
    # (spectral radius 1), 2.8e-6 at 800 (0.99, the default).
    model = fm.examples.shaken_pendulum(amplitude, rate, upright=upright).compile()
    period = 2 * np.pi / rate
    analysis = fm.floquet(model, fm.State.of_model(model), period, period / 800)
    expected = fm.examples.shaken_pendulum_multipliers(amplitude, rate, upright=upright)
    assert largest_mismatch(analysis.multipliers, expected) < 5e-6
    assert analysis.stable is stable
    assert analysis.unstable_directions == (0 if stable else 1)
    assert analysis.monodromy.shape == (2, 2)
    assert analysis.independent == ["body 'bob' rotation z (own axes)"]
    # The exponents: log(mu) / T, growing where unstable.
    assert np.allclose(np.exp(analysis.exponents * period), analysis.multipliers, rtol=1e-12)
    assert (np.max(analysis.exponents.real) > 1e-3) is not stable


def turntable(speed: float, damping: float) -> fm.System:
    """A slider on isotropic springs (k = 100, c) in the plane of a turntable driven at
    `speed`, with a torsion spring (5) to it."""
    system = fm.System()
    table = system.add_rigid_body(10.0, (1, 1, 1), name="table")
    fixed, turning = system.add_marker(system.ground), system.add_marker(table)
    system.add_revolute_joint(fixed, turning)
    system.add_angle_driver(fixed, turning, fm.Polynomial([0.0, speed]), name="drive")
    slider = system.add_rigid_body(1.0, (0.01, 0.01, 0.01), name="slider")
    carried, centre = system.add_marker(table), system.add_marker(slider)
    system.add_planar_joint(carried, centre)
    system.add_rotational_spring_damper(carried, centre, stiffness=5.0)
    for anchor in [(-10.0, 0, 0), (0, -10.0, 0)]:
        system.add_spring_damper(
            system.add_marker(table, position=anchor), centre,
            stiffness=100.0, damping=damping, rest_length=10.0,
        )  # fmt: skip
    return system


@pytest.mark.parametrize(("damping", "stable"), [(0.0, True), (0.5, False)])
def test_a_steady_rotation_has_the_multipliers_of_its_eigenvalues(damping, stable):
    # Above its critical speed (15 rad/s against 10) the slider is held by its Coriolis
    # terms and, with damping that turns with it, grows. Over one turn of the table (its
    # Euler parameters change sign) the multipliers are exp(s T) of the eigenvalues s of the
    # time-invariant equations in the turning frame.
    model = turntable(15.0, damping).compile()
    state = fm.steady_rotation(model)
    values = fm.linearize(model, state).eigenvalues()[0]
    period = 2 * np.pi / 15.0
    analysis = fm.floquet(model, state, period, period / 1600)
    assert largest_mismatch(analysis.multipliers, np.exp(values * period)) < 1e-4
    assert analysis.stable is stable
    assert analysis.periodicity < 1e-6  # (its spin's integration error)


def test_a_deformable_body_at_rest_has_the_multipliers_of_its_eigenvalues():
    # A flexible steel beam hanging from a hinge (4 elements: 24 elastic coordinates and
    # the swing): exp(s T) of linearize's eigenvalues for the modes the steps resolve
    # (|s| h < 0.05; generalized-alpha's phase error (s h)^2 / 12 |s| T: 1.5e-4 at 52.7
    # rad/s), every multiplier within the unit circle (none grows).
    nodes, beams = straight_beam(1.0, 4)
    data = build_body(
        nodes, beams, Material(2.1e11, 0.3, 7800.0), section=Section.rectangle(0.02, 0.01),
        reference="clamped", reference_nodes=[0],
    )  # fmt: skip
    system = fm.System(gravity=(0, -9.81, 0))
    beam = system.add_flexible_body(data, orientation=fm.rotation("z", -np.pi / 2), name="beam")
    system.add_revolute_joint(system.add_marker(system.ground), system.add_marker(beam))
    model = system.compile()
    state = fm.equilibrium(model)
    values = fm.linearize(model, state).eigenvalues()[0]
    period, steps = 0.05, 100
    resolved = values[np.abs(values) * period / steps < 0.05]
    analysis = fm.floquet(model, state, period, period / steps)
    assert analysis.monodromy.shape == (2 * 25, 2 * 25)
    distance = np.abs(np.exp(resolved * period)[:, None] - analysis.multipliers[None, :])
    assert len(resolved) >= 4 and distance.min(axis=1).max() < 3e-4
    # No |mu| outside the unit circle beyond the differences' error (1.3e-6 here), below
    # the margin of `stable` (the modes the steps do not resolve are damped by the
    # solver's spectral radius, 0.99: down to |mu| = 0.974).
    assert analysis.stable
    assert np.abs(analysis.multipliers).max() < 1.0 + NEUTRAL


def test_floquet_refuses_a_state_off_its_periodic_motion():
    # The pendulum released at 0.3 rad on a shaken support does not come back after a
    # period of the shake, nor does the hanging one's support after 0.7 of it; a period of
    # 0 or NaN, a list for a state, a state of another system are refused by name.
    period = 2 * np.pi / 9.0
    swinging = fm.examples.shaken_pendulum(0.05, 9.0, angle=0.3).compile()
    with pytest.raises(InvalidParameterError, match="body 'bob' .* changed by"):
        fm.floquet(swinging, fm.State.of_model(swinging), period, period / 100)
    model = fm.examples.shaken_pendulum(0.05, 9.0).compile()
    state = fm.State.of_model(model)
    with pytest.raises(InvalidParameterError, match="body 'support' displacement"):
        fm.floquet(model, state, 0.7 * period, period / 100)
    for wrong in (0.0, float("nan"), -1.0):
        with pytest.raises(InvalidParameterError, match="period must be (positive|finite)"):
            fm.floquet(model, state, wrong, 0.01)
    with pytest.raises(InvalidParameterError, match="step_size must be positive"):
        fm.floquet(model, state, period, 0.0)
    with pytest.raises(InvalidParameterError, match="must be below the period"):
        fm.floquet(model, state, period, period)
    with pytest.raises(ArgumentTypeError, match="state must be a flexmbd.State"):
        fm.floquet(model, list(state.coordinates), period, 0.01)
    with pytest.raises(InvalidParameterError, match="floquet: the state is one of another"):
        fm.floquet(swinging, state, period, 0.01)


@pytest.mark.parametrize("speed", [100.0, 1.0, 0.03])
def test_a_free_spin_drifts_and_does_not_grow(speed):
    # A wheel spinning freely in its bearing: the monodromy in (angle, rate) is [[1, T],
    # [0, 1]], a Jordan block that the differences' round-off split into 1.0018 and 0.9982
    # (at 100 rad/s), which counted as unstable. Its multipliers are a drift (nearly
    # parallel eigenvectors); the turn's rate is T (to the integration's (W h)^2 / 12 =
    # 2e-5).
    system = fm.System()
    wheel = system.add_rigid_body(2.0, (0.5, 0.5, 1.0), angular_velocity=(0, 0, speed))
    system.add_revolute_joint(system.add_marker(system.ground), system.add_marker(wheel))
    model = system.compile()
    period = 2 * np.pi / speed
    analysis = fm.floquet(model, fm.State.of_model(model), period, period / 400)
    assert np.all(analysis.drifts) and analysis.stable and analysis.unstable_directions == 0
    assert np.abs(analysis.multipliers - 1.0).max() < 1e-2
    assert analysis.monodromy[0, 1] == pytest.approx(period, rel=1e-4)
    # A genuine saddle keeps its growing multiplier: Kapitza's pendulum shaken too weakly.
    weak = fm.examples.shaken_pendulum(0.01, 200.0, upright=True).compile()
    short = 2 * np.pi / 200.0
    falling = fm.floquet(weak, fm.State.of_model(weak), short, short / 800)
    assert not np.any(falling.drifts) and falling.unstable_directions == 1


@pytest.mark.parametrize("workers", [1, 2])
def test_a_start_that_cannot_be_put_back_on_the_constraints_is_refused(monkeypatch, workers):
    # A perturbed start is put back on the constraints by Newton's method on the dependent
    # coordinates; where it could not, the run started off them without a word. (One
    # iteration is too few for the pendulum's distance constraint at 0.3 rad.) From the
    # threads of two workers the first failure is raised the same.
    import sys

    monkeypatch.setattr(sys.modules["flexmbd.floquet"], "PROJECTION_ITERATIONS", 1)
    model = fm.examples.pendulum().system.compile()
    with pytest.raises(InvalidParameterError, match="could not be put back on the constraints"):
        period = 2.3678419475762373  # (4 sqrt(L / g) K(1/2): released from the horizontal)
        fm.floquet(
            model,
            fm.State.of_model(model),
            period,
            period / 2000,
            perturbation=0.3,
            workers=workers,
        )


def test_runs_in_threads_give_the_same_monodromy():
    # The runs are independent: made two or three at once (threads) they give the monodromy
    # of the runs made one after the other, to the last bit; the progress still counts the
    # columns, in the caller's thread.
    import threading

    rate = 3 * np.sqrt(GRAVITY / LENGTH)
    model = fm.examples.shaken_pendulum(0.05, rate).compile()
    state, period = fm.State.of_model(model), 2 * np.pi / rate
    alone = fm.floquet(model, state, period, period / 200, workers=1)
    calls = []

    def progress(done, total):
        calls.append((done, total, threading.current_thread() is threading.main_thread()))

    for workers in (2, 3):
        calls.clear()
        together = fm.floquet(
            model, state, period, period / 200, workers=workers, progress=progress
        )
        assert np.array_equal(together.monodromy, alone.monodromy)
        assert together.solver.spectral_radius == alone.solver.spectral_radius == 0.99
        assert [c[:2] for c in calls] == [(1, 2), (2, 2)] and all(c[2] for c in calls)
    for wrong in (0, -1, 1.5, True, "2"):
        with pytest.raises(InvalidParameterError, match="workers must be a whole number"):
            fm.floquet(model, state, period, period / 200, workers=wrong)


def test_a_rotor_with_modes_far_beyond_the_step_is_stable_at_the_default_steps():
    # The overhung rotor of the examples at 100 rad/s (stable: its eigenvalues on the
    # imaginary axis) has modes up to |s| h = 7231 at 400 steps a turn. A run started off the
    # periodic motion sets them moving, and at spectral radius 0.99 they had not died away
    # after the turn: multipliers up to 75, "11 growing motions". The default solver now damps
    # them within the period; the resolved modes' |mu| then differ from 1 by 0.45 times the
    # periodicity (the runs' error, 7.4e-5), which the neutral band holds.
    import sys

    from flexmbd.model_file import load_model

    floquet_module = sys.modules["flexmbd.floquet"]
    model = load_model("examples/models/overhung_rotor.yaml").system.compile()
    state = fm.steady_rotation(model)
    period = 2 * np.pi / 100.0
    analysis = fm.floquet(model, state, period, period / 400)
    assert analysis.stiffest > 7000 and not analysis.fallback
    assert analysis.solver.spectral_radius < 0.96
    assert analysis.stable and analysis.neutral == analysis.periodicity
    assert np.abs(analysis.multipliers).max() - 1 < 0.6 * analysis.periodicity
    # The resolved modes: exp(s T) of the linearization's slowest eigenvalues.
    values = fm.linearize(model, state).eigenvalues()[0]
    slow = values[np.abs(values) * period / 400 < 0.05]
    assert len(slow) >= 6
    expected = np.exp(slow * period)
    near = np.abs(analysis.multipliers[:, None] - expected[None, :]).min(axis=0)
    assert near.max() < 2e-3
    # At 0.99 the unresolved modes stay.
    undamped = fm.floquet(
        model, state, period, period / 400, solver=floquet_module._default_solver(0.99)
    )
    assert np.abs(undamped.multipliers).max() > 10 and not undamped.stable
