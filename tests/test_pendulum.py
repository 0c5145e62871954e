"""IFToMM A01 simple pendulum (reference R5): a point mass on a distance constraint."""

import numpy as np
import pytest

import flexmbd as fm


@pytest.fixture(scope="module")
def a01():
    example = fm.examples.pendulum()
    result = fm.simulate(
        example.system,
        example.end_time,
        example.step_size,
        output_interval=example.output_interval,
        solver=fm.GeneralizedAlpha(1.0, newton_tolerance=1e-10),
    )
    return example, result


def test_positions_match_the_exact_solution_to_1e6(a01):
    example, result = a01
    errors = example.check(result)
    assert len(errors) == 4
    for name, error in errors.items():
        assert error < 1e-6, name


def test_energy_is_conserved_at_spectral_radius_1(a01, assert_close):
    # E(0) = 0 (released at rest at y = 0): drift relative to m g L.
    _, result = a01
    energy = result.total_energy
    assert_close(energy, energy[0], abs=1e-6 * 9.81, what="total energy")


def test_link_tension_balances_gravity_and_centripetal_force(assert_close):
    # Radial balance of the point mass: T = m v^2 / L + m g . e_r, with e_r from the pivot.
    # Spectral radius 0.9 (the index-3 multipliers are only first-order accurate at 1) and a
    # Newton tolerance of 1e-8 (multiplier errors follow the tolerance).
    example = fm.examples.pendulum()
    solver = fm.GeneralizedAlpha(0.9, newton_tolerance=1e-8)
    result = fm.simulate(example.system, 3.0, 1e-4, output_interval=0.01, solver=solver)
    mass = example.items["mass"]
    r = result.position(mass)
    v = result.velocity(mass)
    e_r = r / np.linalg.norm(r, axis=1, keepdims=True)
    tension = np.sum(v**2, axis=1) / 1.0 - 9.81 * e_r[:, 1]
    force = result.reaction_force(example.items["link"])
    # The link pulls the mass towards the pivot with the tension.
    assert_close(np.linalg.norm(force, axis=1), tension, abs=1e-4, what="link tension")
    assert np.all(np.sum(force * e_r, axis=1)[1:] < 0.0)  # zero tension at the release


def test_period_matches_the_elliptic_integral_value(a01, assert_close):
    # Released from the horizontal: period 2.367841947576 s (reference R5). The bob is back at
    # rest at y = 0 after one period; y(t) has a parabolic maximum there.
    example, result = a01
    y = result.position(example.items["mass"])[:, 1]
    t = result.time
    k = np.argmax(y[100:300]) + 100  # near t = 2.37 s
    a, b, c = y[k - 1], y[k], y[k + 1]
    dt = t[1] - t[0]
    t_max = t[k] + 0.5 * dt * (a - c) / (a - 2 * b + c)
    assert_close(t_max, 2.367841947576, abs=1e-5, what="period")


def test_error_based_step_control_adapts_the_step_and_converges_with_the_tolerance():
    # Tolerances two decades apart and more: at 1e-4 and 1e-5 the error at t = 10 s is about
    # the same (1.5e-2 to 2.6e-2), and which of the two is larger changes with the round-off
    # of the linear solver (through which steps are rejected); from 1e-6 on it falls steadily
    # (5e-3, 7e-4, 1.3e-4 at 1e-6, 1e-7, 1e-8).
    errors = []
    for tolerance in (1e-4, 1e-7):
        example = fm.examples.pendulum()
        solver = fm.GeneralizedAlpha(
            0.9,
            step_control="error",
            relative_tolerance=tolerance,
            absolute_tolerance=tolerance,
            max_step_size=0.05,
        )
        result = fm.simulate(example.system, 10.0, 1e-3, output_interval=0.5, solver=solver)
        stats = result.statistics
        assert stats["min_step_size"] < 0.5 * stats["max_step_size"]
        errors.append(max(example.check(result).values()))
    # Smaller tolerance, smaller error (global error of a local-error control).
    assert errors[1] < 0.2 * errors[0] and errors[1] < 2e-3
