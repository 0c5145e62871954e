"""Solver settings are declared once, in the core: the names of every choice and the defaults
reach the Python classes and the model-file schema from there (issue 29)."""

from __future__ import annotations

import inspect
import pickle
import typing

import pytest

import flexmbd as fm
from flexmbd.model_file import ExplicitSolverSpec, GeneralizedAlphaSpec

SOLVERS = [(fm.GeneralizedAlpha, GeneralizedAlphaSpec), (fm.ExplicitSolver, ExplicitSolverSpec)]


def literal_names(spec: type, field: str) -> list[str]:
    (literal, _none) = typing.get_args(spec.model_fields[field].annotation)
    return list(typing.get_args(literal))


@pytest.mark.parametrize("solver, spec", SOLVERS)
def test_the_schema_offers_exactly_the_names_the_solver_takes(solver, spec):
    for field, names in solver.choices().items():
        assert literal_names(spec, field) == names, field
        # (tr-bdf2 is the method with an iteration matrix)
        extra = {"method": "tr-bdf2"} if (solver, field) == (fm.ExplicitSolver, "jacobian") else {}
        for name in names:
            if field == "formulation":
                continue  # each belongs to its strategy: checked below
            assert getattr(solver(**{field: name}, **extra), field) == name
        with pytest.raises(fm.InvalidParameterError) as raised:
            solver(**{field: "no-such-choice"}, **extra)
        listed = ", ".join(f"'{n}'" for n in names)
        assert f"{field} must be one of {listed}, got 'no-such-choice'" in str(raised.value)


def test_joint_coordinates_say_the_formulation_they_run():
    # It said 'augmented' (and refused that value when given), running the joint-space one.
    assert fm.ExplicitSolver("rk4", "joint-coordinates").formulation == "joint-space"
    assert fm.ExplicitSolver("rk4").formulation == "augmented"


def test_every_formulation_name_is_taken_by_its_strategy():
    for name in fm.ExplicitSolver.choices()["formulation"]:
        dense = name in ("augmented", "embedding")
        strategy = "partitioning" if dense else "joint-coordinates"
        assert fm.ExplicitSolver("rk4", strategy, formulation=name).formulation == name


@pytest.mark.parametrize("solver, spec", SOLVERS)
def test_defaults_are_the_cores_and_none_means_the_default(solver, spec):
    default = solver()
    signature = inspect.signature(solver)
    for name, parameter in signature.parameters.items():
        value = getattr(default, name)
        assert parameter.default == value, name  # help() shows the core's default
        assert getattr(solver(**{name: None}), name) == value, name
    # A few values of the core spelled out, so that a changed default is a visible change.
    if solver is fm.GeneralizedAlpha:
        assert (default.spectral_radius, default.newton_tolerance, default.max_iterations) == (
            0.9,
            1e-6,
            12,
        )
    else:
        assert (default.method, default.strategy, default.max_iterations) == (
            "dopri5",
            "partitioning",
            20,
        )


@pytest.mark.parametrize(
    "options, message",
    [
        ({"method": "rk4", "relative_tolerance": 1e-8}, "relative_tolerance is for the error-"),
        ({"method": "rk4", "absolute_tolerance": 1e-8}, "rk4 takes fixed steps"),
        ({"method": "dopri5", "jacobian": "differences"}, "jacobian is for tr-bdf2.*dopri5 has"),
        ({"method": "rk4", "jacobian": "analytic"}, "jacobian is for tr-bdf2"),
        (
            {"strategy": "joint-coordinates", "baumgarte": (5.0, 5.0)},
            "baumgarte is for the strategies that integrate the constrained coordinates",
        ),
        # (partition and its repartitioning: bit-identical joint-coordinate runs before)
        ({"strategy": "joint-coordinates", "partition": "svd"}, "partition is for the partition"),
        (
            {"strategy": "joint-coordinates", "repartition_ratio": 100.0},
            "'joint-coordinates' takes",
        ),
        ({"strategy": "joint-coordinates", "singular_factor": 1e3}, "singular_factor is for"),
        ({"strategy": "joint-coordinates", "independent": [0]}, "independent is for"),
        (
            {"strategy": "joint-coordinates", "formulation": "embedding"},
            "formulation 'embedding' is for the other strategies; 'joint-coordinates' takes "
            "'joint-space', 'coupled', 'decoupled'",
        ),
    ],
)
def test_explicit_options_the_method_or_strategy_ignores_are_refused(options, message):
    # They were accepted and did nothing: rk4 took its fixed steps whatever the tolerances,
    # dopri5 has no iteration matrix, the joint-coordinate strategy neither uses Baumgarte's
    # terms nor the dense formulations.
    with pytest.raises(fm.InvalidParameterError, match=message):
        fm.ExplicitSolver(**options)
    # Where they do something they are taken.
    assert fm.ExplicitSolver("tr-bdf2", jacobian="differences", relative_tolerance=1e-5)
    # Set as attributes they are not checked, and a copy leaves them out (studies pickle it).
    solver = fm.ExplicitSolver("rk4", "projection")
    solver.relative_tolerance, solver.jacobian = 1e-9, "differences"
    copy = pickle.loads(pickle.dumps(solver))
    assert (copy.method, copy.strategy, copy.jacobian) == ("rk4", "projection", "analytic")
    assert fm.ExplicitSolver("rk4", "projection", baumgarte=(5.0, 5.0)).baumgarte == (5.0, 5.0)
    joint = pickle.loads(pickle.dumps(fm.ExplicitSolver("rk4", "joint-coordinates")))
    assert (joint.strategy, joint.formulation) == ("joint-coordinates", "joint-space")


def test_a_step_longer_than_the_output_interval_warns_and_steps_at_the_interval(assert_close):
    # The steps end on the output times: a nominal step of 2 ms with outputs every 1 ms is a
    # run at 1 ms (its steps the distances to the output times, the other run's 1 ms itself:
    # equal to round-off), and says so (event, Python warning) instead of silently.
    system = fm.examples.pendulum().system
    with pytest.warns(fm.StepSizeWarning, match=r"the step size 2e-3 s is longer than the output"):
        long = fm.simulate(system, 0.1, 2e-3, output_interval=1e-3)
    assert [e["kind"] for e in long.events] == ["step size"]
    exact = fm.simulate(system, 0.1, 1e-3, output_interval=1e-3)
    assert exact.events == [] and (long.time == exact.time).all() and len(long.time) == 101
    assert_close(long.coordinates, exact.coordinates, rel=1e-12, abs=1e-14, what="coordinates")
    # Runge-Kutta 4 (fixed steps) alike; Dormand-Prince, whose step is only its first, not.
    rk4 = fm.ExplicitSolver("rk4", "projection")
    with pytest.warns(fm.StepSizeWarning):
        fm.simulate(system, 0.01, 2e-3, output_interval=1e-3, solver=rk4)
    dopri5 = fm.simulate(
        system, 0.01, 2e-3, output_interval=1e-3, solver=fm.ExplicitSolver("dopri5", "projection")
    )
    assert dopri5.events == []


def test_a_largest_step_below_the_step_size_caps_the_adaptive_steps():
    # It was raised to the step size without a word: dopri5 then took every step at 1e-2
    # (its error control off), generalized-alpha's error control steps up to 1e-2.
    system = fm.examples.pendulum().system
    for solver in (
        fm.GeneralizedAlpha(step_control="error", max_step_size=1e-3),
        fm.ExplicitSolver("dopri5", "projection", max_step_size=1e-3),
    ):
        result = fm.simulate(system, 0.2, 1e-2, output_interval=0.1, solver=solver)
        assert result.statistics["max_step_size"] <= 1e-3 * (1 + 1e-12), solver
    # Where the steps return to the step size, the largest is the step size: refused.
    with pytest.raises(fm.InvalidParameterError, match="max_step_size is for step_control='e"):
        fm.GeneralizedAlpha(max_step_size=1e-3)
    # Without a largest step, the error control's steps grow past the first (they stopped at
    # it: 100,000 steps at h = 1e-4 where dopri5 took 49).
    loose = fm.GeneralizedAlpha(step_control="error", relative_tolerance=1e-2)
    grown = fm.simulate(system, 2.0, 1e-4, output_interval=0.5, solver=loose)
    assert grown.statistics["max_step_size"] > 100 * 1e-4
    assert grown.statistics["steps"] < 2000
    # ... judged against the run's step size, not at construction against 1 ms (refused).
    capped = fm.GeneralizedAlpha(step_control="error", max_step_size=5e-4, min_step_size=1e-5)
    result = fm.simulate(system, 0.01, 1e-4, solver=capped)
    assert result.statistics["max_step_size"] <= 5e-4
    with pytest.raises(fm.InvalidParameterError, match="rk4 takes fixed steps"):
        fm.simulate(system, 0.02, 1e-2, solver=fm.ExplicitSolver("rk4", max_step_size=1e-3))


def test_generalized_alpha_options_its_step_control_ignores_are_refused():
    # Under Newton's control the tolerances and a largest step did nothing (the same run bit
    # for bit), nor a smallest step under a fixed one.
    for options, message in (
        ({"relative_tolerance": 1e-2}, "relative_tolerance is for step_control='error'"),
        ({"absolute_tolerance": 1e-9, "step_control": "fixed"}, "under 'fixed' the steps"),
        ({"max_step_size": 1.0}, "the largest they take"),
        ({"min_step_size": 1e-6, "step_control": "fixed"}, "'fixed' keeps the step size"),
    ):
        with pytest.raises(fm.InvalidParameterError, match=message):
            fm.GeneralizedAlpha(**options)
    assert fm.GeneralizedAlpha(min_step_size=1e-6).min_step_size == 1e-6  # (Newton shortens)
    error = fm.GeneralizedAlpha(step_control="error", relative_tolerance=1e-3, max_step_size=0.1)
    copy = pickle.loads(pickle.dumps(error))
    assert (copy.relative_tolerance, copy.max_step_size) == (1e-3, 0.1)
    # Set as attributes they are not checked, and a copy leaves them out.
    newton = fm.GeneralizedAlpha()
    newton.relative_tolerance = 1e-9
    assert pickle.loads(pickle.dumps(newton)).step_control == "newton"
