"""IFToMM A02 N-four-bar (reference R5), built in 3D from rigid bodies and joints."""

import flexmbd as fm
import pytest
from conftest import relative_drift


def run(n=2, spectral_radius=0.9, step=2e-4, jacobian="modified", end=10.0, tolerance=1e-6):
    example = fm.examples.four_bar(n)
    solver = fm.GeneralizedAlpha(spectral_radius, jacobian=jacobian, newton_tolerance=tolerance)
    result = fm.simulate(example.system, end, step, output_interval=0.01, solver=solver)
    return example, result


@pytest.mark.parametrize("jacobian", ["modified", "full"])
def test_b0_at_10s_matches_the_exact_solution_through_singular_configurations(jacobian):
    example, result = run(jacobian=jacobian)
    errors = example.check(result)
    assert errors["B0 position error at t = 10 s"] < 1e-4
    assert errors["B0 velocity error at t = 10 s"] < 1e-4
    assert result.constraint_violation.max() < 1e-10


def test_energy_drift_without_numerical_dissipation():
    # Spectral radius 0.999: the remaining drift is the O(h^2) energy error of the method.
    # Exactly 1 (the trapezoidal rule) does not pass the singular configurations.
    example, result = run(spectral_radius=0.999, step=1e-4, tolerance=1e-8)
    assert relative_drift(result.total_energy) < 1e-6
    assert example.check(result)["B0 position error at t = 10 s"] < 1e-5


def test_larger_mechanism_stays_on_its_constraints():
    example, result = run(n=6, end=2.0, step=5e-4)
    assert result.constraint_violation.max() < 1e-10
    # All cranks turn together: the tops keep their horizontal spacing of 1 m.
    top0 = result.sensor(example.items["B0 position"])
    assert top0.shape == (len(result), 3)
    assert abs(top0[:, 2]).max() < 1e-12
